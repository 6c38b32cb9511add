"""``coastforge batch``: many scenes on a Dask cluster, resumable, failures isolated."""

from __future__ import annotations

import click

from .options import pass_config


@click.command()
@click.argument("batch_list", type=click.Path())
@click.option("--out", required=True, type=click.Path(), help="Output folder: one subfolder per item.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A dask.distributed scheduler address (default: a local cluster).")
@click.option("--workers", default=2, show_default=True, help="Workers of the local cluster.")
@click.option("--library", type=click.Path(), default=None, help="Asset library (default: the starter kit).")
@click.option("--export", "exports", default="", metavar="LIST", help="Export formats for every scene.")
@pass_config
def batch(batch_list, out, scheduler, workers, library, exports, config):
    """Generate every image of BATCH_LIST (JSON items or 'IMAGE [GSD]' lines). Re-running skips finished items."""
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import Progress

    from ..batch import read_batch_list, run_batch

    items = read_batch_list(batch_list)
    console = Console(stderr=True)
    fmts = tuple(f.strip() for f in exports.split(",") if f.strip())
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("batch", total=len(items))

        def progress(r, n, total):
            bar.update(task, completed=n)
            if r.status == "failed":
                first = r.error.splitlines()[0] if r.error else ""
                console.print(f"[red]failed[/red] {escape(r.name)}: {escape(first)}")

        rep = run_batch(items, out, config, library, fmts, scheduler, workers, progress)
    console.print(f"{rep['done']} done, {rep['skipped']} skipped, {rep['failed']} failed in {rep['wall_s']:.1f} s; "
                  f"report: {escape(str(out))}/batch_report.json")
    if rep["failed"]:
        raise SystemExit(1)
