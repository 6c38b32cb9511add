"""Big vessels: ``python -m coastforge.bench.big [--library DIR] [--levels N] [--seed S] [--set K=V] [--json F]``.

The detector's working scale (0.2 m/px) never saw a boat over 22 m in training; 20-60 m vessels are in the
range coastforge is built for. This renders levels of the ``big`` mix (kit boats scaled to 20-50 m at anchor
and tied alongside walkways, ``synth.layout.BIG_MIX``), the presets in turn, at a random 0.1-0.25 m/px
resampled to 0.2 m/px as ``train.detector_data`` makes its samples (seeds from 9000 up: never trained on),
detects as ``coastforge detect`` does and matches boats as ``bench.real`` does (the centre in the label box
grown by 25 %, one-to-one by the Hungarian method). It prints recall under and over 20 m, precision, and the
boxes of 20 m or more: how many, how many true, and their length against the truth's. ``--library``: render
with that asset library (e.g. the held-aside Quaternius models, which the detector never saw).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..synth.level import PRESETS
from ..train.detector_data import WORK_GSD_M
from ..types import Detection

BIG_M = 20.0  # a big vessel: at least this long


@dataclass
class BigScore:
    labels: int = 0
    big_labels: int = 0
    preds: int = 0
    matched: int = 0
    big_matched: int = 0
    big_preds: int = 0  # boxes of BIG_M or more
    big_preds_true: int = 0
    length_ratios: list = field(default_factory=list)  # a matched big vessel's box length / its label's

    def summary(self) -> dict:
        r = lambda a, b: round(a / b, 3) if b else None  # noqa: E731
        return {"boats": self.labels, "big_vessels": self.big_labels, "predicted": self.preds,
                "recall": r(self.matched, self.labels), "precision": r(self.matched, self.preds),
                "recall_under_20m": r(self.matched - self.big_matched, self.labels - self.big_labels),
                "recall_20m_and_more": r(self.big_matched, self.big_labels),
                "boxes_20m_and_more": self.big_preds, "boxes_20m_and_more_true": self.big_preds_true,
                "big_length_ratio_median": round(float(np.median(self.length_ratios)), 3)
                if self.length_ratios else None}


def score_level(dets: list[Detection], boxes: np.ndarray, gsd_m: float, into: BigScore) -> None:
    """Add one level's boats to ``into``: ``dets`` (any categories), ``boxes`` the boat labels (N, 5: cx, cy,
    length, width, yaw in pixels and degrees), ``gsd_m`` the pixels' size."""
    from ..frames import box_corners_px
    from .real import match_centres_in_quads

    boats = [d for d in dets if d.category == "boat"]
    boxes = np.asarray(boxes, np.float64).reshape(-1, 5)
    quads = np.array([box_corners_px(*b) for b in boxes]).reshape(-1, 4, 2)
    xy = np.array([[d.cx_px, d.cy_px] for d in boats], np.float64).reshape(-1, 2)
    pairs = match_centres_in_quads(xy, quads)
    big = boxes[:, 2] * gsd_m >= BIG_M
    long_pred = {i for i, d in enumerate(boats) if d.length_px * gsd_m >= BIG_M}
    into.labels += len(boxes)
    into.big_labels += int(big.sum())
    into.preds += len(boats)
    into.matched += len(pairs)
    into.big_preds += len(long_pred)
    for i, j in pairs:
        if big[j]:
            into.big_matched += 1
            into.length_ratios.append(boats[i].length_px / boxes[j, 2])
        into.big_preds_true += i in long_pred


def big_levels(n: int, seed: int, library: Path | None = None):
    """``n`` (name, rgb at WORK_GSD_M, boat label boxes) of the big mix, reproducible from ``seed``."""
    from ..train.detector_data import CLASSES, level_sample

    rng = np.random.default_rng(seed)
    for k in range(n):
        preset = PRESETS[k % len(PRESETS)]
        gsd, size = float(rng.uniform(0.1, 0.25)), float(rng.uniform(120, 220))
        rgb, boxes = level_sample(preset, seed + k, gsd, size, mix="big", library=library, looks="kit")
        b = np.array([r[1:6] for r in boxes if r[0] == CLASSES.index("boat")], np.float64).reshape(-1, 5)
        yield f"{preset}_{seed + k}", rgb, b


def bench(config, n: int = 42, seed: int = 9000, library: Path | None = None) -> BigScore:
    from ..detection import detect
    from ..types import GeoImage, Grid

    out = BigScore()
    for _name, rgb, boxes in big_levels(n, seed, library):
        h, w = rgb.shape[:2]
        dets = detect(GeoImage(rgb=rgb, grid=Grid(w, h, WORK_GSD_M)), config.detect)
        score_level(dets, boxes, WORK_GSD_M, out)
    return out


def main(argv: list[str] | None = None) -> None:
    from ..config import load_config

    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.big", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--library", type=Path, default=None, help="render with this asset library (default: the kit)")
    ap.add_argument("--levels", type=int, default=42, help="how many levels (the presets in turn)")
    ap.add_argument("--seed", type=int, default=9000, help="the first level's seed (training uses seeds below 9000)")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="config KEY=VALUE, e.g. detect.big_pass=0")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    a = ap.parse_args(argv)
    if a.levels < 1 or a.seed < 100:
        raise SystemExit("--levels must be at least 1 and --seed at least 100 (seeds below 100 are the benchmark's)")
    if a.library is not None and not (a.library / "library.json").is_file():
        raise SystemExit(f"--library {a.library} is no asset library (no library.json); build one with "
                         "coastforge library build")
    try:
        s = bench(load_config(sets=a.sets), a.levels, a.seed, a.library).summary()
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from exc
    print(f"{a.levels} levels of the big mix (seeds {a.seed}-{a.seed + a.levels - 1}, "
          f"{'the kit' if a.library is None else a.library}), detected at {WORK_GSD_M} m/px")
    print(f"  boats {s['boats']} (of {BIG_M:g} m or more: {s['big_vessels']}), predicted {s['predicted']}: "
          f"recall {s['recall']} precision {s['precision']}")
    print(f"  recall under {BIG_M:g} m {s['recall_under_20m']}, {BIG_M:g} m and more {s['recall_20m_and_more']}")
    print(f"  boxes of {BIG_M:g} m or more: {s['boxes_20m_and_more']} ({s['boxes_20m_and_more_true']} true); "
          f"matched big vessels' length / truth, median {s['big_length_ratio_median']}")
    if a.json:
        from ..fsio import atomic_write_text

        atomic_write_text(a.json, json.dumps({**s, "levels": a.levels, "seed": a.seed,
                                              "library": str(a.library) if a.library else "kit"}, indent=1) + "\n")


if __name__ == "__main__":
    main()
