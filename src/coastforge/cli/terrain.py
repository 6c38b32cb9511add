"""``coastforge terrain SCENE_DIR``: the height map (land and bathymetry) of a scene, with DEM fusion."""

from __future__ import annotations

import click

from .options import overwrite_option, pass_config, staged


@click.command()
@click.argument("scene_dir", type=click.Path(exists=True))
@click.option("--dem", "dems", multiple=True, metavar="FILE[:offset=M][,scale=S]",
              help="A DEM / bathymetry GeoTIFF in any CRS (repeatable; later files win where they overlap). "
                   "offset is added to its values to refer them to the water level, scale converts units.")
@click.option("--dem-crs", default=None, metavar="CRS",
              help="Place a scene without georeference on the map: its projected CRS (e.g. EPSG:32633).")
@click.option("--dem-origin", nargs=2, type=float, default=None, metavar="X Y",
              help="With --dem-crs: map coordinates of the image's top-left corner.")
@click.option("--image", "image_path", type=click.Path(dir_okay=False), default=None,
              help="The scene's RGB image (for terrain.optical_depth or an RGB ONNX model).")
@click.option("--backend", default=None, help="Terrain backend (default: terrain.backend, 'default').")
@click.option("--weights", type=click.Path(dir_okay=False), default=None,
              help="Local .onnx weights for --backend onnx.")
@overwrite_option
@pass_config
def terrain(scene_dir, dems, dem_crs, dem_origin, image_path, backend, weights, overwrite, config) -> None:
    """Estimate the height map of SCENE_DIR (its scene.json and class raster) and write it into the scene,
    with a hillshade, a shore-type map and shore cross-sections under SCENE_DIR/terrain/."""
    import dataclasses
    import math
    from pathlib import Path

    from ..errors import InputError
    from ..terrain import load_terrain_scene, terrain_scene
    from ..terrain.dem import Placement, check_dem_files

    if (dem_crs is None) != (dem_origin is None):
        raise InputError("--dem-crs and --dem-origin go together: give both (CRS and top-left X Y) "
                         "or neither")
    if dem_origin is not None and not all(math.isfinite(v) for v in dem_origin):
        raise InputError(f"--dem-origin {dem_origin[0]:g} {dem_origin[1]:g} must be two finite map coordinates "
                         "(X Y of the image's top-left corner in --dem-crs)")
    placement = Placement(dem_crs, dem_origin[0], dem_origin[1]) if dem_crs else None
    if backend:
        config = dataclasses.replace(config, terrain=dataclasses.replace(config.terrain, backend=backend))
    opts = {"weights": weights} if weights else {}
    # every check before anything is written, with the scene's real paths in the messages
    check_dem_files(dems)
    src = Path(scene_dir)
    folder, scene = load_terrain_scene(src, overwrite)
    image = None
    if image_path is not None:
        from ..io import read_image

        image = read_image(image_path, size_m=tuple(scene.extent_m), config=config.io)
    with staged(folder, update=True) as stage:  # the scene changes only once the new terrain is complete
        res = terrain_scene(stage, config, dems=dems, placement=placement, backend_opts=opts,
                            overwrite=overwrite, scene=scene, image=image)
    d = res.diagnostics
    z = res.height.z_m
    click.echo(f"terrain: {z.shape[1]}x{z.shape[0]} px, "
               f"heights {float(z.min()):.2f} .. {float(z.max()):.2f} m, "
               f"shore types: {', '.join(d.shore_types) or 'none'}, {d.seconds:.2f} s")
    if d.dem_files:
        click.echo(f"  DEM coverage {100 * d.dem_coverage:.1f} % from {len(d.dem_files)} file(s)")
    if d.optical:
        click.echo(f"  optical depth: {'used' if d.optical.get('used') else 'not used'}"
                   f"{' (' + d.optical['note'] + ')' if d.optical.get('note') else ''}")
    if d.water_at_or_above or d.land_at_or_below:
        click.echo(f"  note: {d.water_at_or_above} water px at/above and {d.land_at_or_below} land px "
                   "at/below "
                   "the water level (from DEM data or the backend)")
