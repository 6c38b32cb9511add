"""Training samples for the learned detector from real labelled photos (the training split of
``coastforge.realdata``; the validation groups are never written).

``python -m coastforge.train.detector_real --out DIR`` writes, at the detector's working GSD, one PNG per
image and an ``index.json`` in the format of ``detector_data`` with two more keys per item:
``aligned`` (the labels are axis-aligned boxes: they teach centres and what an object looks like, not its
size along its axis nor its heading, so training supervises only the centre heatmap and offset) and
``labelled`` (the class ids labelled in that image: ``ships_aerial`` labels boats only, so its parked
cars must not be taught as background for the vehicle class).

- ``ships_aerial`` (reported CC0 1.0): every image with a boat, at the benchmark's GSD rule
  (``realdata.ships_gsd``; with one or two boats the scale is a rougher guess, which the training's scale
  jitter covers).
- ``cars_munich`` (KIT AIS, CC BY 3.0, attribution KIT IPF): at 0.13 m/px; cars, trucks, buses and minibuses
  are ``vehicle``.
DOTA crops are evaluation-only and never used.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .. import realdata
from .detector_data import CLASSES, WORK_GSD_M, resample_to_gsd

DATASETS = {
    "ships_aerial": {"name": "Ship Detection from Aerial Images (Kaggle andrewmvd), training groups",
                     "licence": "CC0 1.0 as reported (not verified); the imagery's own terms may also apply",
                     "attribution": "andrewmvd; via github.com/urielFamien95/RESNET_101 (66af054f)"},
    "cars_munich": {"name": "KIT AIS vehicle data (Munich crops), training crops",
                    "licence": "CC BY 3.0", "attribution": "KIT IPF; via github.com/jekhor/aerial-cars-dataset "
                                                          "(d2ed927f)"},
}


def aligned_boxes(xyxy: np.ndarray, cls: int, scale: float) -> list[list[float]]:
    """Axis-aligned pixel boxes → detector rows [class, cx, cy, length, width, yaw] at ``scale``."""
    rows = []
    for x0, y0, x1, y1 in xyxy * scale:
        w, h = x1 - x0, y1 - y0
        L, W, yaw = (w, h, 0.0) if w >= h else (h, w, 90.0)
        rows.append([float(cls), round((x0 + x1) / 2, 3), round((y0 + y1) / 2, 3), round(L, 3), round(W, 3), yaw])
    return rows


def generate(out_dir: str | Path, sets: tuple[str, ...] = ("ships_aerial", "cars_munich")) -> Path:
    """Write the training split of ``sets`` into ``out_dir``; returns the index path."""
    from ..errors import InputError
    from ..fsio import atomic_write_text, write_png

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    items, used = [], []
    for name in sets:
        if name == "ships_aerial":
            src = [(it, realdata.ships_gsd(it.boxes)) for it in realdata.ships_items() if len(it.boxes)]
        elif name == "cars_munich":
            src = [(it, realdata.MUNICH_GSD_M) for it in realdata.munich_items()]
        else:
            raise InputError(f"unknown real set {name!r}; use ships_aerial or cars_munich")
        src = [(it, g) for it, g in src if not it.val]
        for it, gsd in src:
            rgb, s = resample_to_gsd(realdata.read_rgb(it.path), gsd, WORK_GSD_M)
            cls = CLASSES.index(it.category)
            fname = f"{name}_{it.name}.png"
            write_png(out / fname, rgb)
            items.append({"image": fname, "dataset": name, "source_gsd_m": round(gsd, 4), "aligned": True,
                          "labelled": [cls], "boxes": aligned_boxes(it.boxes, cls, s)})
        if src:
            used.append({**DATASETS[name], "images": len(src)})
        print(f"{name}: {len(src)} training images", flush=True)
    if not items:
        raise InputError(f"no real training images found under {realdata.SHARED}; the real sets must be beside "
                         "the project in ../shared/data")
    idx = out / "index.json"
    atomic_write_text(idx, json.dumps({"work_gsd_m": WORK_GSD_M, "datasets": used, "items": items}) + "\n")
    return idx


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--sets", default="ships_aerial,cars_munich")
    a = ap.parse_args(argv)
    print(generate(a.out, tuple(s.strip() for s in a.sets.split(",") if s.strip())))


if __name__ == "__main__":
    main()
