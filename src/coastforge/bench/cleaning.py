"""Cleaning benchmark: how well removing boats and vehicles restores what lies under them.

    python -m coastforge.bench.cleaning [--presets marina,pier_parking] [--seeds 1] [--gsds 0.1,0.2]
                                        [--boxes detected|truth]

Each synthetic level is rendered twice at the same moment: as the benchmark renders it, and without its
boats, vehicles and buoys (what a perfect cleaning would give). The objects are removed with the boxes the
detector finds, with the segmenter's class map filled under them, as ``generate`` does (``--boxes
detected``), or with their true boxes (``--boxes truth``: the cleaning alone). Over the removed objects'
footprints, grown by 1 m for their shadows, it prints per level and overall:

- ``MAE``: mean absolute RGB difference (0-255) between the cleaned image and the truth;
- ``left``: the share of those pixels still more than 40 off the truth (object parts left behind, or a
  fill far from the surface around it);
- the same two figures for the input image itself (nothing removed), for scale.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from ..segmentation.clean import TRANSIENT

LEFT_DIFF = 40.0  # a pixel this far from the truth (max over R, G, B) is "left over"
GROW_M = 1.0  # footprints grown by this much: the shadows go with the objects


def _truth_boxes(scene, n: int, gsd: float, grow_m: float = 0.0) -> list:
    """The scene's boats, vehicles, buoys and piers as pixel boxes (piers as walkways), grown by
    ``grow_m``."""
    from ..types import Detection, Grid

    grid = Grid(n, n, gsd)
    out = []
    for o in scene.objects:
        if o.category in TRANSIENT or o.category == "pier":
            col, row = grid.to_pixel(o.x_m, o.y_m)
            cat = o.category if o.category != "pier" else "pier_walkway"
            out.append(Detection(cat, 1.0, col, row, (o.length_m + 2 * grow_m) / gsd,
                                 (o.width_m + 2 * grow_m) / gsd, o.yaw_deg))
    return out


def _footprints(scene, n: int, gsd: float) -> np.ndarray:
    import cv2

    mask = np.zeros((n, n), np.uint8)
    for d in _truth_boxes(scene, n, gsd, GROW_M):
        if d.category in TRANSIENT:
            cv2.fillPoly(mask, [np.round(d.corners_px()).astype(np.int32)], 1)
    return mask.astype(bool)


def _score(img: np.ndarray, truth: np.ndarray, where: np.ndarray) -> tuple[float, float]:
    diff = np.abs(img[where].astype(np.float32) - truth[where].astype(np.float32))
    return float(diff.mean()), float((diff.max(axis=1) > LEFT_DIFF).mean())


def clean_level(preset: str, seed: int, gsd: float, boxes: str = "detected",
                size_m: float | None = None) -> dict:
    """One level at one GSD: the scores of the input and of the cleaned image (see the module docstring)."""
    from ..config import load_config
    from ..detection import detect
    from ..pipeline import fill_under_objects
    from ..segmentation import segment
    from ..segmentation.clean import clean_image
    from ..synth import synthesize_level
    from ..synth.render import mesh_source, render_level
    from ..types import GeoImage, Grid

    level = synthesize_level(preset, seed, size_m=size_m)
    meshes = mesh_source(None)
    rgb = render_level(level, meshes, gsd, seed)
    empty = replace(level, scene=replace(level.scene, objects=[o for o in level.scene.objects
                                                               if o.category not in TRANSIENT]))
    truth = render_level(empty, meshes, gsd, seed)
    n = rgb.shape[0]
    g = level.scene.extent_m[0] / n
    image = GeoImage(rgb=rgb, grid=Grid(n, n, g))
    cfg = load_config()
    class_map = segment(image, cfg.segment, seed=seed)
    t0 = time.perf_counter()
    if boxes == "truth":
        dets = _truth_boxes(level.scene, n, g)
    else:
        dets = detect(image, cfg.detect, class_map=class_map, seed=seed)
    class_map = fill_under_objects(class_map, dets)
    t1 = time.perf_counter()
    cleaned = clean_image(image, dets, class_map, seed)
    dt = time.perf_counter() - t1
    where = _footprints(level.scene, n, g)
    mae0, left0 = _score(rgb, truth, where)
    mae, left = _score(cleaned, truth, where)
    return {"level": f"{preset}_{seed}", "gsd_m": gsd, "pixels": int(where.sum()), "input_mae": mae0,
            "input_left": left0, "mae": mae, "left": left, "clean_s": dt, "detect_s": t1 - t0}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.cleaning",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="marina,pier_parking,simple_pier_a,lake_harbor")
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--gsds", default="0.1,0.2")
    ap.add_argument("--boxes", choices=("detected", "truth"), default="detected")
    a = ap.parse_args(argv)
    rows = [clean_level(p, int(s), float(g), a.boxes)
            for p in a.presets.split(",") for s in a.seeds.split(",") for g in a.gsds.split(",")]
    print(f"boxes: {a.boxes}; scores over the removed objects' footprints grown by {GROW_M:g} m "
          f"(MAE in 0-255 RGB; left = share still > {LEFT_DIFF:g} off)")
    print(f"{'level':22s} {'gsd':>5s} {'pixels':>8s} {'input MAE':>10s} {'input left':>11s} {'MAE':>7s} "
          f"{'left':>7s} {'clean s':>8s}")
    for r in rows:
        print(f"{r['level']:22s} {r['gsd_m']:5.2f} {r['pixels']:8d} {r['input_mae']:10.1f} "
              f"{r['input_left']:11.3f} {r['mae']:7.1f} {r['left']:7.3f} {r['clean_s']:8.2f}")
    for g in sorted({r["gsd_m"] for r in rows}):
        sel = [r for r in rows if r["gsd_m"] == g]
        w = np.array([r["pixels"] for r in sel], float)
        avg = {k: float(np.average([r[k] for r in sel], weights=w))
               for k in ("input_mae", "input_left", "mae", "left")}
        print(f"{'all (pixel-weighted)':22s} {g:5.2f} {int(w.sum()):8d} {avg['input_mae']:10.1f} "
              f"{avg['input_left']:11.3f} {avg['mae']:7.1f} {avg['left']:7.3f}")


if __name__ == "__main__":
    main()
