"""Training samples for the learned segmenter: synthetic levels rendered at a random GSD, resampled to
0.2 m/px, with their truth class maps on the same grid.

``python -m coastforge.train.seg_data --out DIR --seeds 2000:2240`` writes ``<preset>_<seed>.png`` (RGB)
and ``<preset>_<seed>_classes.png`` (ids) per level and an ``index.json``. Rendering goes through
``coastforge.synth.render`` (lighting, tints, clutter, blur, noise, JPEG). Seeds below 100 are refused:
the segmentation benchmark (seeds 1, 2) and ``coastforge benchmark`` (seed 0) use them, so validation
levels never leak into training.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .common import data_main, render_levels

DATA_GSD_M = 0.2  # samples are stored at this resolution (the truth rasters' own)


def rendered_level(preset: str, seed: int, gsd_m: float, size_m: float | None):
    """One synthetic level on a ``DATA_GSD_M`` grid, rendered at ``gsd_m`` and resampled to that grid:
    (level, rgb)."""
    from ..synth import synthesize_level
    from ..synth.render import mesh_source, render_level

    level = synthesize_level(preset, seed, size_m=size_m, grid_m=DATA_GSD_M)
    rgb = render_level(level, mesh_source(None), gsd_m, seed)
    h, w = level.scene.classes.shape
    if rgb.shape[:2] != (h, w):
        interp = cv2.INTER_AREA if rgb.shape[0] > h else cv2.INTER_LINEAR
        rgb = cv2.resize(rgb, (w, h), interpolation=interp)
    return level, rgb


def level_sample(preset: str, seed: int, gsd_m: float, size_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``DATA_GSD_M``: (rgb, class ids)."""
    level, rgb = rendered_level(preset, seed, gsd_m, size_m)
    return rgb, np.asarray(level.scene.classes, np.uint8)


def write_levels(out_dir: str | Path, seeds: list[int], sample, key: str, stage: str,
                 presets: list[str] | None = None, gsd_range: tuple[float, float] = (0.08, 0.35),
                 minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir`` as ``<preset>_<seed>.png`` and its label raster
    ``<preset>_<seed>_<key>.png`` from ``sample(preset, seed, gsd_m, size_m) -> (rgb, labels)``; resumable (skips
    written levels). ``stage`` names the random stream of the render GSDs and sizes."""
    from ..fsio import write_png

    def make_item(preset: str, seed: int, gsd: float, size: float, out: Path) -> tuple[dict, str]:
        rgb, labels = sample(preset, seed, gsd, size)
        name = f"{preset}_{seed}"
        write_png(out / f"{name}.png", rgb)
        write_png(out / f"{name}_{key}.png", labels)
        return ({"image": f"{name}.png", key: f"{name}_{key}.png", "preset": preset, "seed": seed,
                 "render_gsd_m": round(gsd, 4)}, f"size={size:.0f}")

    return render_levels(out_dir, seeds, make_item, stage=stage, index_head={"gsd_m": DATA_GSD_M},
                         presets=presets, gsd_range=gsd_range, size_range_m=(80.0, 180.0), minutes=minutes)


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.35), minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written levels)."""
    return write_levels(out_dir, seeds, level_sample, "classes", "seg_data", presets, gsd_range, minutes)


def main(argv: list[str] | None = None) -> None:
    data_main(argv, __doc__.splitlines()[0], "2000:2240", generate)


if __name__ == "__main__":
    main()
