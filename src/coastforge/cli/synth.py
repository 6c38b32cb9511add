"""``coastforge synth``: a synthetic ground-truth level (truth.json + rendered images + inputs.json)."""

from __future__ import annotations

import click


@click.command()
@click.option("--preset", required=True, metavar="NAME",
              help="Level: simple_pier_a, simple_pier_b, pier_parking, marina, lake_harbor, beach, "
                   "rocky_shore, or 'all' (one subfolder per level).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
              help="Root seed (layout, terrain, lighting, clutter).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--gsd", "gsd", default="0.1,0.2", show_default=True, metavar="M[,M...]",
              help="Metres per pixel of the rendered images, comma-separated (one image per value).")
@click.option("--library", type=click.Path(), default=None,
              help="Place and render this asset library's assets (each layout role filled by the library "
                   "asset of the same category and closest size) instead of the starter kit's.")
@click.option("--overwrite", is_flag=True, help="Replace a non-empty --out folder that an earlier run made.")
def synth(preset: str, seed: int, out_dir: str, gsd: str, library: str | None, overwrite: bool) -> None:
    """Synthesize a ground-truth coastal level and render its aerial images.

    Writes OUT/truth.json (a scene file; objects have source "synthetic") with its rasters, one
    image per GSD (image_0.10m.png, ...) and OUT/inputs.json listing the images and their GSDs.
    """
    from pathlib import Path

    from ..synth import synth_many
    from .options import staged

    with staged(out_dir, overwrite=overwrite, inputs=(library,)) as stage:  # all-or-nothing: every level, or none
        results = synth_many(preset, seed, stage, gsd, library, overwrite=True)

    def final(p) -> Path:  # a path in the staging folder -> where it is now
        return Path(out_dir) / Path(p).relative_to(stage)

    for r in results:
        t = " ".join(f"{k} {v:.1f}s" for k, v in r.timings)
        click.echo(f"{r.preset}: {r.n_objects} objects, {r.n_vegetation} plants/rocks, "
                   f"{r.extent_m[0]:.0f}x{r.extent_m[1]:.0f} m -> {final(r.truth_path)} ({t})")
        for p, g in zip(r.image_paths, r.gsds):
            click.echo(f"  image {g:g} m/px: {final(p)}")
