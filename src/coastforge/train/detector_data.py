"""Training samples for the learned detector: synthetic levels rendered at a random GSD, resampled to
the detector's working GSD, with their oriented boxes.

``python -m coastforge.train.detector_data --out DIR --seeds 100:400`` writes one PNG per level and an
``index.json`` listing, per image, the boxes ``[class_id, cx_px, cy_px, length_px, width_px, yaw_deg]``
(yaw = direction of the front, scene convention). Rendering goes through ``coastforge.synth_render``
(lighting, tints, clutter, blur, noise, JPEG), so the training images look like the benchmark's; the
benchmark's own seed (0) is refused so that validation never leaks into training.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..rng import stage_rng

WORK_GSD_M = 0.2  # the detector's working resolution (metres per pixel)
CLASSES: tuple[str, ...] = ("boat", "vehicle", "buoy")
RESERVED_SEEDS = range(0, 100)  # validation levels (the synthetic benchmark uses seed 0)


def resample_to_gsd(rgb: np.ndarray, gsd_m: float, work_gsd_m: float = WORK_GSD_M) -> tuple[np.ndarray, float]:
    """Resample an image to ``work_gsd_m``; returns (image, scale = new px per old px)."""
    s = gsd_m / work_gsd_m
    if abs(s - 1.0) < 1e-3:
        return rgb, 1.0
    h, w = rgb.shape[:2]
    nw, nh = max(1, int(round(w * s))), max(1, int(round(h * s)))
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    return cv2.resize(rgb, (nw, nh), interpolation=interp), nw / w


def level_sample(preset: str, seed: int, gsd_m: float, size_m: float | None,
                 work_gsd_m: float = WORK_GSD_M) -> tuple[np.ndarray, list[list[float]]]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``work_gsd_m``: (rgb, boxes)."""
    from .. import frames
    from ..synth import synthesize_level
    from ..synth_render import mesh_source, render_level

    level = synthesize_level(preset, seed, size_m=size_m)
    rgb = render_level(level, mesh_source(None), gsd_m, seed)
    sx, sy = level.scene.extent_m
    work, _ = resample_to_gsd(rgb, sx / rgb.shape[1], work_gsd_m)
    h, w = work.shape[:2]
    g = sx / w
    boxes = []
    for o in level.scene.objects:
        if o.category not in CLASSES:
            continue
        col, row = frames.scene_to_pixel(o.x_m, o.y_m, w, h, g)
        length, width = o.length_m / g, o.width_m / g
        yaw = float(o.yaw_deg)
        if width > length:  # the long side is the length; the front then is ambiguous, keep the axis
            length, width, yaw = width, length, yaw + 90.0
        boxes.append([CLASSES.index(o.category), float(col), float(row), float(length), float(width),
                      float(frames.wrap_deg(yaw))])
    return work, boxes


def parse_seeds(text: str) -> list[int]:
    """``"100:400"`` (half-open) or ``"100,101"`` → seeds; validation seeds (< 100) are refused."""
    try:
        if ":" in text:
            a, b = text.split(":")
            seeds = list(range(int(a), int(b)))
        else:
            seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise InputError(f"--seeds {text!r} must be 'A:B' or a comma list of integers") from None
    bad = [s for s in seeds if s in RESERVED_SEEDS]
    if bad or not seeds:
        raise InputError(f"--seeds {text!r}: seeds below 100 are reserved for validation (got {bad[:5]}); "
                         "use e.g. 100:400")
    return seeds


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.3), minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written images).

    The index is rewritten after every level so that a run cut short still leaves usable data."""
    from ..fsio import atomic_write_text, write_png
    from ..synth import PRESETS

    presets = list(presets or PRESETS)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    idx_path = out / "index.json"
    index = json.loads(idx_path.read_text()) if idx_path.is_file() else {"work_gsd_m": WORK_GSD_M, "items": []}
    done = {it["image"] for it in index["items"]}
    t0 = time.time()
    for i, seed in enumerate(seeds):
        if minutes is not None and time.time() - t0 > minutes * 60:
            break
        preset = presets[i % len(presets)]
        name = f"{preset}_{seed}.png"
        if name in done:
            continue
        rng = stage_rng(seed, "train", "detector_data", preset)
        # log-uniform GSD: as many fine as coarse renders; level sizes kept small (fast, many layouts)
        gsd = float(math.exp(rng.uniform(math.log(gsd_range[0]), math.log(gsd_range[1]))))
        size = float(2 * round(rng.uniform(70, 150) / 2))
        try:
            rgb, boxes = level_sample(preset, seed, gsd, size)
        except ValueError as exc:  # some presets cannot lay out every small size: skip that level
            print(f"{name}: skipped ({exc})", flush=True)
            continue
        write_png(out / name, rgb)
        index["items"].append({"image": name, "preset": preset, "seed": seed, "render_gsd_m": round(gsd, 4),
                               "boxes": [[round(v, 3) for v in b] for b in boxes]})
        atomic_write_text(idx_path, json.dumps(index) + "\n")
        print(f"{name} gsd={gsd:.3f} boxes={len(boxes)} t={time.time() - t0:.0f}s", flush=True)
    return idx_path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", default="100:400")
    ap.add_argument("--minutes", type=float, default=None)
    a = ap.parse_args(argv)
    generate(a.out, parse_seeds(a.seeds), minutes=a.minutes)


if __name__ == "__main__":
    main()
