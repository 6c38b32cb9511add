"""Validation of a detector backend on data it never trained on.

``python -m coastforge.train.eval_detector [--backend learned] [--weights detector.onnx] [--data DIR]
[--work DIR] [--write-meta]``

Synthetic: the benchmark levels at seed 0 (marina, pier_parking, simple_pier_a at 0.1 and 0.2 m/px;
the training data uses seeds from 100). Real: ``aerial/marina_p0861`` (105 ships, 0.2 m/px) and
``aerial/vehicles_p1053`` from ``../shared/data``. Metrics come from ``coastforge.bench.detection``
(Hungarian matching on centres within half the labelled length). ``--write-meta`` stores the figures
in the model's ``.json`` sidecar.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from ..config import DetectConfig

VAL_PRESETS = ("marina", "pier_parking", "simple_pier_a")
VAL_SEEDS = (0,)


def _row(s) -> dict:
    def r(v):
        return None if isinstance(v, float) and math.isnan(v) else round(float(v), 4)

    return {"n_truth": s.n_truth, "n_pred": s.n_pred, "recall": r(s.recall), "precision": r(s.precision),
            "orient_rmse_deg": r(s.orient_rmse), "heading_acc": r(s.heading_acc),
            **s.extra}


def evaluate(backend: str, weights: str | None, data: Path | None, work: Path) -> dict:
    from ..bench.detection import Score, timed_detect, bench_synth, match, read_dota_yolo
    from ..io import read_image

    cfg = DetectConfig()
    opts = {"weights": weights} if weights else {}
    out: dict = {"backend": backend, "synthetic": {}, "real": {}}
    for s in bench_synth(list(VAL_PRESETS), list(VAL_SEEDS), backend, cfg, work, **opts):
        out["synthetic"][s.name] = _row(s)
    if data is not None:
        marina = data / "aerial" / "marina_p0861"
        if marina.is_dir():
            img = read_image(marina / "image.jpg", gsd_m=0.2)
            dets, dt = timed_detect(img, backend, cfg, **opts)
            lab = read_dota_yolo(marina / "labels_yolo_obb.txt", img.grid.width_px, img.grid.height_px)
            s = Score("marina_p0861 boats")
            match([t for c, t in lab if c == "ship"], [d for d in dets if d.category == "boat"], s)
            s.extra = {"vehicles_reported(unlabelled)": sum(d.category == "vehicle" for d in dets),
                       "seconds": round(dt, 2)}
            out["real"][s.name] = _row(s)
        veh = data / "aerial" / "vehicles_p1053"
        if veh.is_dir():
            img = read_image(veh / "image.jpg", gsd_m=0.125)
            dets, dt = timed_detect(img, backend, cfg, **opts)
            lab = read_dota_yolo(veh / "labels_yolo_obb.txt", img.grid.width_px, img.grid.height_px)
            s = Score("vehicles_p1053 vehicles")
            match([t for c, t in lab if c in ("small vehicle", "large vehicle")],
                  [d for d in dets if d.category == "vehicle"], s)
            s.extra = {"boats_reported": sum(d.category == "boat" for d in dets), "seconds": round(dt, 2)}
            out["real"][s.name] = _row(s)
    return out


def tune_thresholds(weights: str | None, data_dir: Path, n_levels: int = 40) -> dict[str, float]:
    """Per-class score thresholds maximising F1 on training-distribution levels (seeds >= 100 from
    ``detector_data``; never the validation levels)."""
    from ..bench.detection import Score, Truth, match
    from ..detection.learned import LearnedDetector
    from ..types import GeoImage, Grid

    index = json.loads((data_dir / "index.json").read_text())
    items = [it for it in index["items"] if it["seed"] >= 100][-n_levels:]
    det = LearnedDetector(DetectConfig(), weights=weights, threshold=0.05)
    classes = list(det.meta["classes"])
    grid_t = [round(0.3 + 0.05 * k, 2) for k in range(13)]  # detect() drops scores below min_score 0.3
    scores = {(c, t): Score(c) for c in classes for t in grid_t}
    import cv2

    for it in items:
        rgb = cv2.imread(str(data_dir / it["image"]), cv2.IMREAD_COLOR)[:, :, ::-1]
        img = GeoImage(rgb=np.ascontiguousarray(rgb), grid=Grid(rgb.shape[1], rgb.shape[0],
                                                                float(index["work_gsd_m"])))
        dets = det.detect(img, None, 0)
        for ci, c in enumerate(classes):
            truth = [Truth(c, b[1], b[2], b[3], b[4], b[5]) for b in it["boxes"] if int(b[0]) == ci]
            for t in grid_t:
                match(truth, [d for d in dets if d.category == c and d.score >= t], scores[(c, t)])
    out = {}
    for c in classes:
        def f1(t, c=c):
            s = scores[(c, t)]
            p, r = s.matched / max(1, s.n_pred), s.matched / max(1, s.n_truth)
            return 2 * p * r / max(1e-9, p + r)
        out[c] = max(grid_t, key=f1)
        print(f"threshold {c}: {out[c]} (F1 {f1(out[c]):.3f})")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="learned")
    ap.add_argument("--weights", default=None)
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[4] / "shared" / "data"))
    ap.add_argument("--work", default="/tmp/coastforge_detector_val")
    ap.add_argument("--tune", default=None, help="detector_data dir: tune per-class thresholds first")
    ap.add_argument("--write-meta", action="store_true", help="store the figures in the model's .json")
    a = ap.parse_args(argv)
    data = Path(a.data) if Path(a.data).is_dir() else None
    if a.tune:
        from ..detection.learned import default_weights
        from ..fsio import atomic_write_text

        th = tune_thresholds(a.weights, Path(a.tune))
        side = Path(a.weights or default_weights()).with_suffix(".json")
        meta = json.loads(side.read_text()) if side.is_file() else {}
        meta["thresholds"] = th
        atomic_write_text(side, json.dumps(meta, indent=1) + "\n")
    res = evaluate(a.backend, a.weights, data, Path(a.work))
    for part in ("synthetic", "real"):
        for name, row in res[part].items():
            print(f"{name:36s} " + " ".join(f"{k}={v}" for k, v in row.items()))
    if a.write_meta:
        from ..detection.learned import default_weights
        from ..fsio import atomic_write_text

        side = Path(a.weights or default_weights()).with_suffix(".json")
        meta = json.loads(side.read_text()) if side.is_file() else {}
        meta.setdefault("validation", {})[a.backend] = res
        atomic_write_text(side, json.dumps(meta, indent=1) + "\n")


if __name__ == "__main__":
    main()
