"""``coastforge render``: a scene seen from straight above, as an aerial photograph."""

from __future__ import annotations

import click

from .options import overwrite_option


@click.command()
@click.argument("scene_path", metavar="SCENE_DIR_OR_JSON", type=click.Path())
@click.option("--gsd", type=float, required=True, metavar="M", help="Metres per output pixel.")
@click.option(
    "--out",
    "out_path",
    required=True,
    type=click.Path(dir_okay=False),
    metavar="FILE.png",
    help="Output image (.png or .jpg).",
)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
              help="Seed for textures, ripples and jitter.")
@click.option(
    "--sun-azimuth",
    type=float,
    default=None,
    metavar="DEG",
    help="Sun direction, degrees counter-clockwise from east (default 135).",
)
@click.option(
    "--sun-elevation",
    type=float,
    default=None,
    metavar="DEG",
    help="Sun height above the horizon in degrees (default 55).",
)
@click.option("--random-lighting", is_flag=True, help="Draw a plausible random lighting from --seed.")
@overwrite_option
def render(
    scene_path: str,
    gsd: float,
    out_path: str,
    seed: int,
    sun_azimuth,
    sun_elevation,
    random_lighting: bool,
    overwrite: bool,
) -> None:
    """Render SCENE_DIR_OR_JSON (a scene folder, scene.json or truth.json) orthographically from above.

    Meshes come from the starter asset kit. Example: coastforge render out/marina --gsd 0.1 --out top.png
    """
    import dataclasses
    import math

    from ..errors import InputError
    from ..render import Lighting, render_scene_file
    from ..render import random_lighting as draw_lighting
    from ..rng import stage_rng

    lighting = draw_lighting(stage_rng(seed, "render", "lighting")) if random_lighting else Lighting()
    if sun_azimuth is not None and not math.isfinite(sun_azimuth):
        raise InputError(f"--sun-azimuth {sun_azimuth} must be a finite angle in degrees (e.g. 135)")
    if sun_azimuth is not None:
        lighting = dataclasses.replace(lighting, sun_azimuth_deg=sun_azimuth)
    if sun_elevation is not None:
        if not 1.0 <= sun_elevation <= 90.0:
            raise InputError(f"--sun-elevation {sun_elevation} must be between 1 and 90 degrees")
        lighting = dataclasses.replace(lighting, sun_elevation_deg=sun_elevation)
    from ..scene import load_scene

    if math.isfinite(gsd) and gsd > 0:  # (render_scene_file refuses the others)
        ext = load_scene(scene_path, rasters=False).extent_m
        w_px, h_px = round(ext[0] / gsd), round(ext[1] / gsd)
        if min(w_px, h_px) < 16:
            raise InputError(f"--gsd {gsd:g} m/px renders the {ext[0]:g} x {ext[1]:g} m scene as {w_px}x{h_px} px, "
                             f"too small to be an image; use --gsd {min(ext) / 16:.3g} or finer (at least 16 px a "
                             "side)")
    path = render_scene_file(scene_path, gsd, out_path, seed=seed, overwrite=overwrite, lighting=lighting)
    click.echo(f"wrote {path}")
