"""Segmentation benchmark: ``python -m coastforge.bench.segmentation [--only marina|synth|speed]
[--backend classical|learned|...] [--weights F] [--cache DIR]``.

Prints the figures of the segmentation issue:

- real marina (DOTA crop in ../shared/data): mIoU and water IoU against the hand-drawn polygons in
  ``tests/data/marina_p0861_classes.json``;
- synthetic levels (``coastforge.synth``, when installed): mIoU per class at each rendered resolution;
- speed: segmentation of a 2048 x 2048 image made of the real marina (wall time; the machine may be
  shared); for ``learned`` that is its slowest path (the self-check rejects the network on this photo,
  so the classical segmenter runs as well).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ..classes import CLASS_IDS, CLASS_NAMES, N_CLASSES
from ..errors import InputError

IGNORE = 255
ROOT = Path(__file__).resolve().parents[3]
SHARED = ROOT.parent / "shared" / "data"
MARINA_TRUTH = ROOT / "tests" / "data" / "marina_p0861_classes.json"


def rasterize_polygons(spec: dict | str | Path, shape: tuple[int, int] | None = None) -> np.ndarray:
    """Paint a class-polygon file (``coastforge.class_polygons/1``) into class ids; ``ignore`` → 255.

    ``shape`` (H, W) rescales the polygons from the file's ``image_size`` to another grid."""
    import cv2

    if not isinstance(spec, dict):
        spec = json.loads(Path(spec).read_text(encoding="utf-8"))
    w0, h0 = spec["image_size"]
    h, w = shape if shape is not None else (h0, w0)
    names = dict(CLASS_IDS, ignore=IGNORE)
    default = spec.get("default", "ignore")
    if default not in names:
        raise InputError(f"class polygons: unknown default class {default!r}; use one of {', '.join(names)}")
    out = np.full((h, w), names[default], np.uint8)
    sx, sy = w / w0, h / h0
    for i, poly in enumerate(spec["polygons"]):
        cls = poly["class"]
        if cls not in names:
            raise InputError(f"class polygons: polygon {i} has unknown class {cls!r}; use one of {', '.join(names)}")
        pts = np.asarray(poly["points"], np.float64) * [sx, sy]
        cv2.fillPoly(out, [np.round(pts).astype(np.int32)], int(names[cls]))
    return out


def class_ious(pred: np.ndarray, truth: np.ndarray, ignore: int = IGNORE) -> dict:
    """Per-class IoU (None for a class absent from both), mIoU over classes present in the truth,
    and pixel accuracy; ``ignore`` pixels of the truth are left out."""
    if pred.shape != truth.shape:
        raise InputError(f"prediction {pred.shape} and truth {truth.shape} differ in shape; resample first")
    m = truth != ignore
    p, t = pred[m].astype(np.int64), truth[m].astype(np.int64)
    cm = np.bincount(t * N_CLASSES + np.clip(p, 0, N_CLASSES - 1), minlength=N_CLASSES * N_CLASSES)
    cm = cm.reshape(N_CLASSES, N_CLASSES)
    inter = np.diag(cm).astype(np.float64)
    union = cm.sum(0) + cm.sum(1) - inter
    ious = {CLASS_NAMES[c]: (float(inter[c] / union[c]) if union[c] > 0 else None) for c in range(N_CLASSES)}
    present = [CLASS_NAMES[c] for c in range(N_CLASSES) if cm[c].sum() > 0]
    miou = float(np.mean([ious[n] for n in present])) if present else float("nan")
    acc = float(inter.sum() / max(cm.sum(), 1))
    return {"iou": ious, "miou": miou, "accuracy": acc, "present": present}


def class_ious_from_confusion(cm: np.ndarray) -> dict:
    inter = np.diag(cm).astype(np.float64)
    union = cm.sum(0) + cm.sum(1) - inter
    present = [c for c in range(N_CLASSES) if cm[c].sum() > 0]
    ious = {CLASS_NAMES[c]: float(inter[c] / union[c]) for c in present}
    return {"iou": ious, "miou": float(np.mean(list(ious.values()))) if ious else float("nan")}


def _fmt(res: dict) -> str:
    parts = [f"{n}={res['iou'][n]:.3f}" for n in CLASS_NAMES if res["iou"][n] is not None and n in res["present"]]
    return f"mIoU {res['miou']:.3f}  acc {res['accuracy']:.3f}  | " + " ".join(parts)


def bench_marina(backend: str = "classical", save_preview: Path | None = None, **options) -> dict | None:
    from ..config import SegmentConfig
    from ..io import read_image
    from ..segmentation import segment

    img_path = SHARED / "aerial" / "marina_p0861" / "image.jpg"
    if not img_path.exists():
        print(f"marina: skipped ({img_path} not found)")
        return None
    spec = json.loads(MARINA_TRUTH.read_text(encoding="utf-8"))
    image = read_image(img_path, gsd_m=float(spec["gsd_m"]))
    t0 = time.perf_counter()
    cm = segment(image, SegmentConfig(backend=backend), **options)
    dt = time.perf_counter() - t0
    truth = rasterize_polygons(spec, cm.ids.shape)
    res = class_ious(cm.ids, truth)
    print(f"marina_p0861 ({backend}, {image.grid.width_px}x{image.grid.height_px}, {dt:.2f} s): {_fmt(res)}")
    print(f"  water IoU {res['iou']['water']:.4f} (target >= 0.95), mIoU {res['miou']:.3f} (target >= 0.6)")
    if save_preview is not None:
        from ..segmentation.outputs import preview

        from ..fsio import write_png

        write_png(save_preview, preview(image.rgb, cm.ids))
        print(f"  preview written to {save_preview}")
    return res


def _synth_cases(root: Path, presets: tuple[str, ...], seeds: tuple[int, ...], gsds: tuple[float, ...]):
    """Yield (name, image path, gsd, truth ids) for synthetic levels written by coastforge.synth into
    ``root/<preset>_<seed>`` (levels already there are reused)."""
    import importlib

    synth = importlib.import_module("coastforge.synth")
    from ..fsio import read_png

    for preset in presets:
        for seed in seeds:
            out = root / f"{preset}_{seed}"
            if not (out / "inputs.json").exists():
                synth.synth_to_dir(preset, seed, out, gsds=gsds, overwrite=True)
            inputs = json.loads((out / "inputs.json").read_text(encoding="utf-8"))
            truth_scene = json.loads((out / "truth.json").read_text(encoding="utf-8"))
            truth = read_png(out / truth_scene["terrain"]["classes"])
            for item in _input_items(inputs):
                if any(abs(float(item["gsd_m"]) - g) < 1e-9 for g in gsds):
                    yield f"{preset}/{seed}", out / item["image"], float(item["gsd_m"]), truth


def _input_items(inputs) -> list[dict]:
    """inputs.json lists rendered images with their gsd; accept a list or {"images": [...]}."""
    items = inputs.get("images", inputs) if isinstance(inputs, dict) else inputs
    out = []
    for it in items:
        path = it.get("image") or it.get("path") or it.get("file")
        gsd = it.get("gsd_m") or it.get("gsd")
        if path and gsd:
            out.append({"image": path, "gsd_m": gsd})
    return out


SYNTH_PRESETS = ("marina", "beach", "rocky_shore", "lake_harbor", "pier_parking", "simple_pier_a", "simple_pier_b")


def bench_synth(backend: str = "classical", presets: tuple[str, ...] = SYNTH_PRESETS, seeds: tuple[int, ...] = (1,),
                gsds: tuple[float, ...] = (0.1, 0.2), cache: Path | None = None, **options) -> dict | None:
    import importlib.util
    import tempfile

    import cv2

    from ..config import SegmentConfig
    from ..io import read_image
    from ..segmentation import segment

    if importlib.util.find_spec("coastforge.synth") is None:
        print("synthetic: skipped (coastforge.synth is not available yet)")
        return None
    per_gsd: dict[float, list[np.ndarray]] = {}
    with tempfile.TemporaryDirectory(prefix="cf_segbench_") as tmp:
        root = Path(cache) if cache is not None else Path(tmp)
        for name, path, gsd, truth in _synth_cases(root, presets, seeds, gsds):
            image = read_image(path, gsd_m=gsd)
            cm = segment(image, SegmentConfig(backend=backend), **options)
            t = cv2.resize(truth, (cm.ids.shape[1], cm.ids.shape[0]), interpolation=cv2.INTER_NEAREST)
            res = class_ious(cm.ids, t)
            print(f"synthetic {name} @ {gsd:g} m/px: {_fmt(res)}")
            cmx = np.bincount(t.ravel().astype(np.int64) * N_CLASSES + cm.ids.ravel(), minlength=N_CLASSES**2)
            per_gsd.setdefault(gsd, []).append(cmx.reshape(N_CLASSES, N_CLASSES))
    summary = {}
    for gsd, mats in sorted(per_gsd.items()):
        cm = np.sum(mats, axis=0)
        inter = np.diag(cm).astype(float)
        union = cm.sum(0) + cm.sum(1) - inter
        present = [c for c in range(N_CLASSES) if cm[c].sum() > 0]
        ious = {CLASS_NAMES[c]: float(inter[c] / union[c]) for c in present}
        miou = float(np.mean(list(ious.values()))) if ious else float("nan")
        per_level = [class_ious_from_confusion(m)["miou"] for m in mats]
        summary[gsd] = {"miou": miou, "iou": ious, "mean_level_miou": float(np.mean(per_level))}
        print(f"synthetic mean of per-level mIoU @ {gsd:g} m/px: {np.mean(per_level):.3f}")
        print(f"synthetic overall @ {gsd:g} m/px: mIoU {miou:.3f} (target >= 0.85) | "
              + " ".join(f"{k}={v:.3f}" for k, v in ious.items()))
    return summary


def bench_speed(size: int = 2048, repeats: int = 2, backend: str = "classical", **options) -> float:
    """Segmentation (``backend``) of a size x size image built from the marina crop (tiled and mirrored, so it
    holds real content), or a synthetic pattern when the shared data is absent."""
    from .. import registry
    from ..config import SegmentConfig
    from ..types import GeoImage, Grid

    img_path = SHARED / "aerial" / "marina_p0861" / "image.jpg"
    if img_path.exists():
        from ..io import read_image

        base = read_image(img_path, gsd_m=0.2).rgb
        tile = np.concatenate([np.concatenate([base, base[:, ::-1]], 1),
                               np.concatenate([base[::-1], base[::-1, ::-1]], 1)], 0)
        reps = -(-size // tile.shape[0])
        rgb = np.ascontiguousarray(np.tile(tile, (reps, reps, 1))[:size, :size])
    else:
        rng = np.random.default_rng(0)
        rgb = rng.integers(0, 255, (size, size, 3), dtype=np.uint8)
    image = GeoImage(rgb=rgb, grid=Grid(size, size, 0.1))
    seg = registry.load("segment", backend)(SegmentConfig(backend=backend), **options)
    seg.segment(image, 0)  # warm-up: imports and first-call allocations are not the algorithm
    times, cpus = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        seg.segment(image, 0)
        times.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    best = min(times)
    import os

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"speed: {backend} {size}x{size} @ 0.1 m/px: best wall {best:.2f} s of {repeats}, CPU {min(cpus):.2f} s "
          f"(target <= 3 s on 2 cores; load average {load:.1f} while measuring)")
    return best


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.segmentation", description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("marina", "synth", "speed"), action="append")
    ap.add_argument("--backend", default="classical")
    ap.add_argument("--preview", type=Path, default=None, help="write the marina colour preview here")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(9)))
    ap.add_argument("--weights", type=Path, default=None, help="model file for the learned/onnx backends")
    ap.add_argument("--presets", nargs="+", default=list(SYNTH_PRESETS))
    ap.add_argument("--cache", type=Path, default=None,
                    help="keep (and reuse) the synthetic levels in this folder; rendering them is the slow part")
    args = ap.parse_args(argv)
    which = set(args.only or ("marina", "synth", "speed"))
    opts = {"weights": args.weights} if args.weights is not None else {}
    if "marina" in which:
        bench_marina(args.backend, args.preview, **opts)
    if "synth" in which:
        bench_synth(args.backend, tuple(args.presets), tuple(args.seeds), cache=args.cache, **opts)
    if "speed" in which:
        bench_speed(backend=args.backend, **opts)


if __name__ == "__main__":
    main()
