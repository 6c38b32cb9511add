"""``coastforge export SCENE_DIR --format ue5,holoocean,gltf,usd,sdf [--out DIR]``."""

from __future__ import annotations

import click

from .options import overwrite_option, pass_config, staged


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
    from pathlib import Path

    from ..errors import OutputExistsError
    from ..export import export_scene, export_summary, parse_formats, require_rasters
    from ..scene import load_scene

    library = None
    if library_dir is not None:
        from ..assets.library import Library

        library = Library.load(library_dir)

    fmts = parse_formats(formats or config.export.formats)  # checked before anything is written
    src = Path(scene_dir)
    require_rasters(load_scene(src))  # so is the scene, with its real paths in the messages
    target = Path(out_dir) if out_dir is not None else (src.parent if src.is_file() else src)
    if not overwrite:  # before any work: an existing export is replaced only on request
        done = [f for f in fmts if (target / f).is_dir() and any((target / f).iterdir())]
        if done:
            raise OutputExistsError(f"{target / done[0]} exists; pass --overwrite to replace the {done[0]} "
                                    "export, or choose another --out")
    # all-or-nothing: every format is written into a staging copy of the target, swapped in when all are done
    with staged(target, update=True) as stage:
        written = export_scene(src, fmts, out_dir=stage, overwrite=overwrite, config=config.export,
                               library=library)
    for line in export_summary({f: [target / p.relative_to(stage) for p in ps] for f, ps in written.items()}):
        click.echo(line)
