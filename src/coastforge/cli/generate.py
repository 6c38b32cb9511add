"""``coastforge generate``: the whole pipeline, one image in, one scene out."""

from __future__ import annotations

import shlex
import sys

import click

from .options import overwrite_option, pass_config, size_options


@click.command()
@click.argument("image", type=click.Path())
@size_options
@click.option("--library", type=click.Path(), default=None,
              help="Asset library folder (coastforge library build); default: the bundled starter kit.")
@click.option("--out", required=True, type=click.Path(), help="Output folder for scene.json and everything else.")
@click.option("--export", "exports", default="", metavar="LIST",
              help="Comma-separated export formats: ue5,holoocean,gltf,usd,sdf,ue5_tiles (none by default; "
                   "'coastforge export OUT' writes the config's export.formats later).")
@click.option("--dem", "dems", multiple=True, type=click.Path(), help="A DEM/bathymetry GeoTIFF to fuse (repeatable).")
@click.option("--no-report", is_flag=True, help="Do not build report.html.")
@overwrite_option
@pass_config
def generate(image, gsd, size_m, library, out, exports, dems, no_report, overwrite, config):
    """Turn IMAGE (PNG/JPEG with --gsd or --size-m, or a GeoTIFF) into a simulation scene in --out."""
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..api import generate as run

    console = Console(stderr=True)
    with Progress(TextColumn("{task.description:<12}"), BarColumn(), TimeElapsedColumn(), console=console,
                  transient=True) as bar:
        task = bar.add_task("starting", total=None)

        def progress(stage: str, frac: float) -> None:
            bar.update(task, description=stage)

        result = run(image, out=out, gsd=gsd, size_m=tuple(size_m) if size_m else None, export=exports,
                     library=library, dem=dems, report=not no_report, overwrite=overwrite, config=config,
                     progress=progress, side_process=True, command=shlex.join(["coastforge", *sys.argv[1:]]))
    for n in result.notes:
        console.print(f"note     {escape(n)}")
    counts = ", ".join(f"{v} {k}" for k, v in result.n_objects.items())
    console.print(f"[bold]scene[/bold]  {escape(str(result.scene_path))}  ({counts})")
    console.print("timings  " + ", ".join(f"{k} {v:.2f}s" for k, v in result.timings_s.items()))
    from ..export import export_summary

    for line in export_summary(result.exports):  # plain paths, not lists of PosixPath reprs
        console.print(f"export   {escape(line)}")
    if result.report_path:
        console.print(f"[bold]report[/bold] {escape(str(result.report_path))}")
    for w in result.warnings:  # the self-check: the scene looks implausible (also in the report)
        console.print(f"[bold yellow]warning[/bold yellow] {escape(w.message)} [dim]{escape(w.hint)}[/dim]")
