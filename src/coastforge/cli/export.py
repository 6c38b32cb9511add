"""``coastforge export SCENE_DIR --format ue5,holoocean,gltf,usd,sdf [--out DIR]``."""

from __future__ import annotations

import click

from .options import overwrite_option, pass_config


@click.command("export")
@click.argument("scene_dir", type=click.Path(exists=True, file_okay=True, dir_okay=True))
@click.option("--format", "formats", default=None, metavar="LIST",
              help="Comma-separated formats: ue5, holoocean, gltf, usd, sdf (default: export.formats of the config).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Output folder (default: the scene folder); files go to OUT/<format>/.")
@click.option("--library", "library_dir", type=click.Path(exists=True, file_okay=False), default=None,
              help="Asset library folder holding the scene's assets (default: the starter kit).")
@overwrite_option
@pass_config
def export(scene_dir, formats, out_dir, library_dir, overwrite, config):
    """Export a scene to simulator formats, each under OUT/<format>/."""
    import shlex
    import sys

    from ..api import export_scene
    from ..export import export_summary

    res = export_scene(scene_dir, formats or None, out=out_dir, library=library_dir, overwrite=overwrite,
                       config=config, command=shlex.join(["coastforge", *sys.argv[1:]]))
    for n in res.notes:  # what recovery did (an earlier run's leftovers)
        click.echo(f"note: {n}", err=True)
    for line in export_summary(res.files):
        click.echo(line)
