"""Training samples for the learned segmenter: synthetic levels rendered at a random GSD, resampled to
0.2 m/px, with their truth class maps on the same grid.

``python -m coastforge.train.seg_data --out DIR --seeds 2000:2240`` writes ``<preset>_<seed>.png`` (RGB)
and ``<preset>_<seed>_classes.png`` (ids) per level and an ``index.json``. Rendering goes through
``coastforge.synth_render`` (lighting, tints, clutter, blur, noise, JPEG). Seeds below 100 are refused:
the segmentation benchmark (seeds 1, 2) and ``coastforge benchmark`` (seed 0) use them, so validation
levels never leak into training.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from ..rng import stage_rng
from .detector_data import parse_seeds

DATA_GSD_M = 0.2  # samples are stored at this resolution (the truth rasters' own)


def level_sample(preset: str, seed: int, gsd_m: float, size_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``DATA_GSD_M``: (rgb, class ids)."""
    from ..synth import synthesize_level
    from ..synth_render import mesh_source, render_level

    level = synthesize_level(preset, seed, size_m=size_m, grid_m=DATA_GSD_M)
    rgb = render_level(level, mesh_source(None), gsd_m, seed)
    ids = np.asarray(level.scene.classes, np.uint8)
    h, w = ids.shape
    if rgb.shape[:2] != (h, w):
        interp = cv2.INTER_AREA if rgb.shape[0] > h else cv2.INTER_LINEAR
        rgb = cv2.resize(rgb, (w, h), interpolation=interp)
    return rgb, ids


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.35), minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written levels)."""
    from ..fsio import atomic_write_text, write_png
    from ..synth import PRESETS

    presets = list(presets or PRESETS)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    idx_path = out / "index.json"
    index = json.loads(idx_path.read_text()) if idx_path.is_file() else {"gsd_m": DATA_GSD_M, "items": []}
    done = {it["image"] for it in index["items"]}
    t0 = time.time()
    for i, seed in enumerate(seeds):
        if minutes is not None and time.time() - t0 > minutes * 60:
            break
        preset = presets[i % len(presets)]
        name = f"{preset}_{seed}"
        if f"{name}.png" in done:
            continue
        rng = stage_rng(seed, "train", "seg_data", preset)
        # log-uniform render GSD: fine and coarse renders equally often (blur/aliasing of both kinds)
        gsd = float(math.exp(rng.uniform(math.log(gsd_range[0]), math.log(gsd_range[1]))))
        size = float(2 * round(rng.uniform(80, 180) / 2))
        try:
            rgb, ids = level_sample(preset, seed, gsd, size)
        except ValueError as exc:  # some presets cannot lay out every small size: skip that level
            print(f"{name}: skipped ({exc})", flush=True)
            continue
        write_png(out / f"{name}.png", rgb)
        write_png(out / f"{name}_classes.png", ids)
        index["items"].append({"image": f"{name}.png", "classes": f"{name}_classes.png", "preset": preset,
                               "seed": seed, "render_gsd_m": round(gsd, 4)})
        atomic_write_text(idx_path, json.dumps(index) + "\n")
        print(f"{name} gsd={gsd:.3f} size={size:.0f} t={time.time() - t0:.0f}s", flush=True)
    return idx_path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", default="2000:2240")
    ap.add_argument("--minutes", type=float, default=None)
    a = ap.parse_args(argv)
    generate(a.out, parse_seeds(a.seeds), minutes=a.minutes)


if __name__ == "__main__":
    main()
