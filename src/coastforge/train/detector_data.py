"""Training samples for the learned detector: synthetic levels rendered at a random GSD, resampled to
the detector's working GSD, with their oriented boxes.

``python -m coastforge.train.detector_data --out DIR --seeds 100:400`` writes one PNG per level and an
``index.json`` listing, per image, the boxes ``[class_id, cx_px, cy_px, length_px, width_px, yaw_deg]``
(yaw = direction of the front, scene convention). Rendering goes through ``coastforge.synth_render``
(lighting, tints, clutter, blur, noise, JPEG), so the training images look like the benchmark's; the
benchmark's own seed (0) is refused so that validation never leaks into training. ``--mix training``
draws the rare asset types more often (``synth_layout.TRAINING_MIX``: buses and box trucks, hatchbacks,
dinghies, kayaks, rowboats, centre consoles); the default draws them as the benchmark's levels do.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .common import RESERVED_SEEDS, data_main, parse_seeds, render_levels  # noqa: F401 (re-exported)

WORK_GSD_M = 0.2  # the detector's working resolution (metres per pixel)
CLASSES: tuple[str, ...] = ("boat", "vehicle", "buoy")


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
                 work_gsd_m: float = WORK_GSD_M,
                 mix: str = "benchmark") -> tuple[np.ndarray, list[list[float]]]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``work_gsd_m``: (rgb, boxes).

    ``mix="training"`` draws the rare asset types more often (``synth_layout.TRAINING_MIX``)."""
    from .. import frames
    from ..synth import synthesize_level
    from ..synth_layout import BENCHMARK_MIX, TRAINING_MIX
    from ..synth_render import mesh_source, render_level

    level = synthesize_level(preset, seed, size_m=size_m,
                             mix=TRAINING_MIX if mix == "training" else BENCHMARK_MIX)
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


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.3), minutes: float | None = None,
             mix: str = "benchmark") -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written images).

    The index is rewritten after every level so that a run cut short still leaves usable data."""
    from ..fsio import write_png

    def make_item(preset: str, seed: int, gsd: float, size: float, out: Path) -> tuple[dict, str]:
        rgb, boxes = level_sample(preset, seed, gsd, size, mix=mix)
        name = f"{preset}_{seed}.png"
        write_png(out / name, rgb)
        return ({"image": name, "preset": preset, "seed": seed, "render_gsd_m": round(gsd, 4),
                 "boxes": [[round(v, 3) for v in b] for b in boxes]}, f"boxes={len(boxes)}")

    # level sizes kept small (fast, many layouts)
    head = {"work_gsd_m": WORK_GSD_M, "mix": mix}
    return render_levels(out_dir, seeds, make_item, stage="detector_data", index_head=head, presets=presets,
                         gsd_range=gsd_range, size_range_m=(70.0, 150.0), minutes=minutes)


def main(argv: list[str] | None = None) -> None:
    data_main(argv, __doc__.splitlines()[0], "100:400", generate, mix_option=True)


if __name__ == "__main__":
    main()
