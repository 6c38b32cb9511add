"""``coastforge backends``: every stage's backends and whether each is usable here."""

from __future__ import annotations

import json

import click


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def backends(as_json: bool) -> None:
    """List every stage's backends, whether each is usable here, and how to install it if not."""
    from ..registry import install_hint, missing_modules, specs

    rows = []
    for s in specs():
        miss = missing_modules(s)
        rows.append({"stage": s.stage, "name": s.name, "default": s.default, "usable": not miss,
                     "missing": miss, "install": None if not miss else install_hint(s), "needs": s.needs,
                     "description": s.description})
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    t = Table(title="coastforge backends")
    for col in ("stage", "backend", "usable here", "needs", "description"):
        t.add_column(col)
    for r in rows:
        usable = "[green]yes[/green]" if r["usable"] else f"[red]no[/red]: {escape(r['install'])}"
        name = r["name"] + (" (default)" if r["default"] else "")
        t.add_row(r["stage"], name, usable, r["needs"], r["description"])
    Console().print(t)
