"""Training samples for the pier-deck network: synthetic levels rendered at a random GSD, resampled to 0.2 m/px,
with the mask of their pier decks (walkways and fingers) on the same grid.

``python -m coastforge.train.pier_data --out DIR --seeds 6000:6600`` writes ``<preset>_<seed>.png`` (RGB) and
``<preset>_<seed>_piers.png`` (1 on a deck, 0 elsewhere) per level and an ``index.json``. Rendering goes through
``coastforge.synth.render`` as the other training data do; every preset is used (the beach has no pier: a
negative example). Seeds below 100 are refused (the benchmarks' levels).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .common import data_main
from .seg_data import rendered_level, write_levels


def deck_mask(scene) -> np.ndarray:
    """The scene's pier footprints rasterised on its grid (uint8, 1 on a deck)."""
    grid = scene.grid
    mask = np.zeros((grid.height_px, grid.width_px), np.uint8)
    for o in scene.objects:
        if o.category != "pier":
            continue
        fp = np.asarray(o.footprint_m(), np.float64)
        cols, rows = grid.to_pixel(fp[:, 0], fp[:, 1])
        # pixel centres: corner coordinates shifted by half a pixel
        cv2.fillPoly(mask, [np.round(np.stack([cols, rows], 1) * 8 - 4).astype(np.int32)], 1, shift=3)
    return mask


def level_sample(preset: str, seed: int, gsd_m: float, size_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``seg_data.DATA_GSD_M``: (rgb, deck mask)."""
    level, rgb = rendered_level(preset, seed, gsd_m, size_m)
    return rgb, deck_mask(level.scene)


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.35), minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written levels)."""
    return write_levels(out_dir, seeds, level_sample, "piers", "pier_data", presets, gsd_range, minutes)


def main(argv: list[str] | None = None) -> None:
    data_main(argv, __doc__.splitlines()[0], "6000:6600", generate)


if __name__ == "__main__":
    main()
