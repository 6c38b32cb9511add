"""``coastforge report``: (re)build report.html of a generated scene."""

from __future__ import annotations

import click

from .options import overwrite_option


@click.command()
@click.argument("scene_dir", type=click.Path())
@click.option("--truth", type=click.Path(), default=None,
              help="A truth scene (truth.json): adds the metrics section.")
@click.option("--out", type=click.Path(dir_okay=False), default=None,
              help="Where to write the page (default SCENE_DIR/report.html, always rebuilt).")
@overwrite_option
def report(scene_dir, truth, out, overwrite):
    """Build SCENE_DIR/report.html: overlays, plots, objects, metrics and a 3D preview; works offline."""
    from rich.console import Console

    from ..report import build_report

    console = Console(stderr=True)
    with console.status("report: starting", spinner="dots") as status:
        path = build_report(scene_dir, truth, out, overwrite=overwrite,
                            progress=lambda step: status.update(f"report: {step}"))
    size = path.stat().st_size / 1e6
    console.print(f"[green]report[/green] {size:.1f} MB — open it in a browser (works offline):")
    click.echo(str(path))
