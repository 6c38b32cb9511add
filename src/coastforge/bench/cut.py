"""Objects the picture's edge cuts: ``python -m coastforge.bench.cut [LEVEL ...] [--library DIR]``.

Real sets label a crop as DOTA's split tool does: an object less than 70 % inside the crop is left out (to
the picture holding more of it), so a detector that finds a boat the frame cuts in half scores a false box
there. Whether a change to the detector handles such boats as the labels do can be measured on renders,
without the real marina (evaluation only): random square crops of rendered levels, their boats and vehicles
labelled only when at least ``--min-inside`` of their box is inside, matched as ``bench.real`` matches (the
centre inside the label box grown by 25 %, one-to-one by the Hungarian method). Unmatched boxes touching the
crop's edge are counted apart. Levels: the folders given (``coastforge synth`` output: ``truth.json`` and
an image), else the marina, pier_parking and lake_harbor presets at seeds 4 and 5 rendered into ``--work``
(``--library``: with that asset library, e.g. the Quaternius models the detector never trained on).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..types import Detection, GeoImage, Grid

CATEGORIES = ("boat", "vehicle")
EDGE_PX = 3  # a box within this of the crop's border touches its edge


@dataclass
class CutScore:
    labels: int = 0
    preds: int = 0
    matched: int = 0
    unmatched_at_edge: int = 0

    @property
    def recall(self) -> float:
        return self.matched / self.labels if self.labels else float("nan")

    @property
    def precision(self) -> float:
        return self.matched / self.preds if self.preds else float("nan")

    @property
    def precision_without_edge(self) -> float:
        n = self.preds - self.unmatched_at_edge
        return self.matched / n if n else float("nan")


def crop_labels(truth: list, x0: int, y0: int, size: int, category: str, min_inside: float) -> np.ndarray:
    """(N, 4, 2) corners, in the crop's pixels, of the ``category`` objects of ``truth`` (``bench.detection
    .Truth`` in the level's pixels) lying at least ``min_inside`` of their area inside the crop."""
    from shapely.geometry import Polygon, box

    from ..frames import box_corners_px

    frame = box(0, 0, size, size)
    out = []
    for t in truth:
        if t.category != category:
            continue
        c = box_corners_px(t.cx - x0, t.cy - y0, t.length, t.width, t.yaw)
        poly = Polygon(c)
        if poly.area > 0 and poly.intersection(frame).area >= min_inside * poly.area:
            out.append(c)
    return np.array(out, np.float64).reshape(-1, 4, 2)


def score_crop(dets: list[Detection], labels: dict[str, np.ndarray], size: int,
               scores: dict[str, CutScore]) -> None:
    """Add one crop's detections, matched to its labels per category, to ``scores``."""
    from .real import match_centres_in_quads

    for cat in CATEGORIES:
        ds = [d for d in dets if d.category == cat]
        q = labels.get(cat, np.zeros((0, 4, 2)))
        pairs = match_centres_in_quads(np.array([[d.cx_px, d.cy_px] for d in ds]).reshape(-1, 2), q)
        hit = {i for i, _ in pairs}
        s = scores[cat]
        s.labels += len(q)
        s.preds += len(ds)
        s.matched += len(pairs)
        for i, d in enumerate(ds):
            c = d.corners_px()
            if i not in hit and (c.min() < EDGE_PX or c.max() > size - EDGE_PX):
                s.unmatched_at_edge += 1


def bench_levels(levels: list[Path], config, crops: int = 16, size: int = 400, min_inside: float = 0.7,
                 seed: int = 0, backend: str | None = None) -> dict[str, CutScore]:
    """``crops`` random ``size`` px crops of each level's first image (the same crops for every run of the
    same ``seed``), detected with ``config`` (a ``DetectConfig``) and scored per category."""
    from ..detection import detect
    from ..rng import stage_rng
    from .detection import synth_truth

    scores = {c: CutScore() for c in CATEGORIES}
    for lv in levels:
        inputs = json.loads((lv / "inputs.json").read_text()) if (lv / "inputs.json").is_file() else {}
        images = inputs.get("images") or []
        if not (lv / "truth.json").is_file() or not images:
            raise InputError(f"{lv} is not a coastforge synth level (truth.json and inputs.json with images); "
                             "make one with: coastforge synth --preset marina --seed 4 --out DIR")
        gsd = float(images[0]["gsd_m"])
        img, truth, _piers = synth_truth(lv / "truth.json", lv / images[0]["path"], gsd)
        h, w = img.rgb.shape[:2]
        if min(h, w) <= size:
            raise InputError(f"{lv}: the image ({w} x {h} px) is not larger than a crop ({size} px); "
                             "use a smaller --size")
        rng = stage_rng(seed, "bench", "cut", lv.name)
        for _ in range(crops):
            x0, y0 = int(rng.integers(0, w - size)), int(rng.integers(0, h - size))
            rgb = np.ascontiguousarray(img.rgb[y0:y0 + size, x0:x0 + size])
            dets = detect(GeoImage(rgb=rgb, grid=Grid(size, size, gsd)), config, backend=backend)
            labels = {c: crop_labels(truth, x0, y0, size, c, min_inside) for c in CATEGORIES}
            score_crop(dets, labels, size, scores)
    return scores


def main(argv: list[str] | None = None) -> None:
    from ..config import load_config

    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.cut", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("levels", nargs="*", type=Path, help="coastforge synth output folders")
    ap.add_argument("--library", type=Path, default=None, help="render the default levels with this library")
    ap.add_argument("--work", type=Path, default=Path("/tmp/coastforge-bench-cut"))
    ap.add_argument("--crops", type=int, default=16, help="crops per level")
    ap.add_argument("--size", type=int, default=400, help="crop side in pixels")
    ap.add_argument("--min-inside", type=float, default=0.7, help="the labels' rule (DOTA's split: 0.7)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--backend", default=None)
    ap.add_argument("--set", dest="sets", action="append", default=[])
    a = ap.parse_args(argv)
    if a.crops < 1 or a.size < 64 or not 0.0 < a.min_inside <= 1.0:
        raise SystemExit("--crops must be at least 1, --size at least 64 and --min-inside in (0, 1]")
    levels = list(a.levels)
    if not levels:
        from ..synth.level import synth_to_dir

        tag = "kit" if a.library is None else a.library.name
        for preset in ("marina", "pier_parking", "lake_harbor"):
            for s in (4, 5):
                out = a.work / f"{tag}_{preset}_{s}"
                if not (out / "truth.json").is_file():
                    synth_to_dir(preset, s, out, gsds="0.2", library=a.library, overwrite=True)
                levels.append(out)
    try:
        scores = bench_levels(levels, load_config(sets=a.sets).detect, a.crops, a.size, a.min_inside, a.seed,
                              a.backend)
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from exc
    print(f"{len(levels)} levels x {a.crops} crops of {a.size} px; labels: objects at least {a.min_inside:.0%} "
          "inside; a match: the centre in the label box grown by 25 %")
    for cat, s in scores.items():
        print(f"  {cat:8s} labels {s.labels:4d} preds {s.preds:4d} recall {s.recall:.3f} prec {s.precision:.3f}"
              f"  unmatched {s.preds - s.matched} ({s.unmatched_at_edge} at the crop's edge: prec "
              f"{s.precision_without_edge:.3f} without them)")


if __name__ == "__main__":
    main()
