"""``coastforge report``: (re)build report.html of a generated scene."""

from __future__ import annotations

import click


@click.command()
@click.argument("scene_dir", type=click.Path())
@click.option("--truth", type=click.Path(), default=None, help="A truth scene: adds the metrics section.")
@click.option("--out", type=click.Path(), default=None, help="Where to write the page (default SCENE_DIR/report.html).")
def report(scene_dir, truth, out):
    """Build SCENE_DIR/report.html: overlays, plots, objects, metrics and a 3D preview; works offline."""
    from ..report import build_report

    click.echo(str(build_report(scene_dir, truth, out)))
