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
    from ..export import export_scene, export_summary

    library = None
    if library_dir is not None:
        from ..assets.library import Library

        library = Library.load(library_dir)
    written = export_scene(scene_dir, formats or config.export.formats, out_dir=out_dir, overwrite=overwrite,
                           config=config.export, library=library)
    for line in export_summary(written):
        click.echo(line)
