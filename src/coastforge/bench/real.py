"""Real-photograph benchmark (DESIGN.md §5 "Real photographs"): ``python -m coastforge.bench.real
[--only seg|det] [--split all|train|val] [--limit N] [--segment-backend B] [--detect-backend B]
[--with-classmap] [--gsd-sweep] [--weather-sweep] [--preset P] [--set KEY=VALUE] [--json PATH] [--verbose]``.

Segmentation: ``real/landcover_dubai`` at a nominal 0.6 m/px, water IoU and a coarse mIoU (water / paved /
vegetation / bare; building and unlabeled ignored, a rocks prediction is wrong everywhere); the DOTA marina
against ``tests/data/marina_p0861_classes.json`` (8-class mIoU, water IoU).

Detection: ``real/ships_aerial`` (images with >= 3 boats, GSD = 10 m / median labelled long side, derived
from the labels because the set does not record it) and ``real/cars_munich`` (0.13 m/px): recall and
detection precision, a prediction matching a label when its centre lies inside the label box grown by 25 %,
one-to-one by Hungarian assignment on centre distance. DOTA marina (oriented labels): the same rule on the
oriented label boxes, orientation RMSE over its pairs, ``bench.detection``'s rule (gate = half the labelled
length) beside it, harbor structures hit by a pier box. ``--gsd-sweep`` measures again on the same photos
averaged down 2, 3 and 5 times (cars_munich 0.26-0.65 m/px, the DOTA marina 0.4-1 m/px): the range the
detector is meant for, which no real set covers by itself. ``--weather-sweep`` measures again on the same
photos (ships_aerial too) under haze, under- and over-exposure, noise, no colour, blur and JPEG at fixed
strengths (``weathered``): the looks a user's picture may have that the sets do not.

Train and validation images (``coastforge.realdata``'s fixed split) are always reported apart; the DOTA
marina is evaluation-only (never trained on) and is measured unless ``--split train``. Backends default to
the preset's, as ``coastforge generate`` uses them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable

import numpy as np

from .. import realdata as rd
from ..classes import ASPHALT, DIRT, GRASS, N_CLASSES, ROCKS, SAND, SIDEWALK, TREES, WATER

DUBAI_GSD_M = 0.6  # nominal (DESIGN.md §5); the set does not record it
MARINA_GSD_M = 0.2  # DOTA marina estimate (../shared/data/README.md), as bench.detection uses
GROW = 1.25
MIN_SHIP_LABELS = 3
SWEEP_FACTORS = (2.0, 3.0, 5.0)  # --gsd-sweep: the photos seen from 2, 3 and 5 times higher (DOTA: 1 m/px)
N_WORST = 5

# our 8 classes -> coarse code (0 water, 1 paved, 2 vegetation, 3 bare); rocks has no coarse class: it goes to
# a separate "other" column so that it is wrong wherever the truth is one of the four
N_COARSE = len(rd.COARSE)
OTHER = N_COARSE
COARSE_OF_CLASS = np.full(N_CLASSES, OTHER, np.int64)
for _ids, _code in (((WATER,), 0), ((ASPHALT, SIDEWALK), 1), ((GRASS, TREES), 2), ((SAND, DIRT), 3)):
    COARSE_OF_CLASS[list(_ids)] = _code
assert COARSE_OF_CLASS[ROCKS] == OTHER


# ------------------------------------------------------------------------------------------ helpers

def default_config(segment_backend: str | None = None, detect_backend: str | None = None,
                   preset: str = "default", sets: list[str] | tuple[str, ...] = ()):
    """The config ``coastforge generate`` would use (preset + ``--set``), with optional backend overrides."""
    from ..config import load_config

    cfg = load_config(preset, sets=list(sets))
    if segment_backend:
        cfg = dataclasses.replace(cfg, segment=dataclasses.replace(cfg.segment, backend=segment_backend))
    if detect_backend:
        cfg = dataclasses.replace(cfg, detect=dataclasses.replace(cfg.detect, backend=detect_backend))
    return cfg


def _ratio(a: float, b: float) -> float:
    return float(a / b) if b else float("nan")


def _select(items: list, split: str, limit: int | None, is_val: Callable[[Any], bool]) -> list:
    """Items of ``split``; with ``limit``, alternate train and validation items so both are measured."""
    if split not in ("all", "train", "val"):
        raise ValueError(f"split must be all, train or val, got {split!r}")
    train = [it for it in items if not is_val(it)] if split != "val" else []
    val = [it for it in items if is_val(it)] if split != "train" else []
    if limit is None:
        return train + val
    out = []
    for k in range(max(len(train), len(val))):
        out += [lst[k] for lst in (train, val) if k < len(lst)]
    return out[:max(0, int(limit))]


def _split(item) -> str:
    return "val" if item.val else "train"


def _skipped(name: str, path: Path) -> dict:
    return {"set": name, "skipped": f"{path} not found"}


# ------------------------------------------------------------------------------------------ matching

def match_centres_in_boxes(pred_xy: np.ndarray, boxes: np.ndarray,
                           grow: float = GROW) -> list[tuple[int, int]]:
    """One-to-one (pred_idx, label_idx) pairs for axis-aligned label boxes (x0, y0, x1, y1); see
    ``match_centres_in_quads``."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    quads = np.stack([b[:, [0, 1]], b[:, [2, 1]], b[:, [2, 3]], b[:, [0, 3]]], 1)
    return match_centres_in_quads(pred_xy, quads, grow)


def match_centres_in_quads(pred_xy: np.ndarray, quads: np.ndarray,
                           grow: float = GROW) -> list[tuple[int, int]]:
    """One-to-one (pred_idx, label_idx) pairs: a prediction may match a label only when its centre lies inside
    the label's box (4 corners in order, axis-aligned or oriented) grown by ``grow`` about its centre; among
    those, Hungarian assignment on the distance to the box centre (the most pairs first, then the least total
    distance)."""
    from scipy.optimize import linear_sum_assignment

    p = np.asarray(pred_xy, np.float64).reshape(-1, 2)
    q = np.asarray(quads, np.float64).reshape(-1, 4, 2)
    if len(p) == 0 or len(q) == 0:
        return []
    c = q.mean(1)
    e1, e2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 1]  # the box's two side vectors
    d = p[:, None, :] - c[None, :, :]
    ok = np.ones((len(p), len(q)), bool)
    for e in (e1, e2):
        n = np.linalg.norm(e, axis=1)
        u = np.divide(e, n[:, None], out=np.zeros_like(e), where=n[:, None] > 0)
        ok &= np.abs(np.einsum("pqk,qk->pq", d, u)) <= n[None, :] * (grow / 2.0) + 1e-9
    dist = np.hypot(d[..., 0], d[..., 1])
    # a forbidden pair costs more than any sum of allowed ones, so the assignment first maximises the pairs
    big = 1.0 + dist[ok].sum() * 2.0 if ok.any() else 1.0
    cost = np.where(ok, dist, big)
    ri, ci = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(ri, ci) if ok[i, j]]


def cut_by_edge(det, width_px: int, height_px: int) -> bool:
    """Whether a box reaches past the image's edge (the object is cut by the crop)."""
    from ..detection import reaches_past_edge

    return reaches_past_edge(det, width_px, height_px)


# ------------------------------------------------------------------------------------------ segmentation

def coarse_confusion(pred_ids: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(4, 5) pixel counts: rows the coarse truth (water, paved, vegetation, bare), columns our prediction
    mapped to coarse plus "other" (rocks). Truth building (254) and unlabeled (255) pixels are left out."""
    if pred_ids.shape != truth.shape:
        raise ValueError(f"prediction {pred_ids.shape} and truth {truth.shape} differ in shape")
    m = truth < N_COARSE
    p = COARSE_OF_CLASS[np.clip(pred_ids[m].astype(np.int64), 0, N_CLASSES - 1)]
    t = truth[m].astype(np.int64)
    k = N_COARSE + 1
    return np.bincount(t * k + p, minlength=N_COARSE * k).reshape(N_COARSE, k)


def coarse_scores(cm: np.ndarray) -> dict:
    """Per-class IoU (None when neither truth nor prediction holds it), water IoU and mIoU over the coarse
    classes present in the truth (NaN when none is)."""
    cm = np.asarray(cm, np.int64)
    inter = np.diag(cm[:, :N_COARSE]).astype(np.float64)
    union = cm.sum(1) + cm[:, :N_COARSE].sum(0) - inter
    iou = {n: (float(inter[c] / union[c]) if union[c] > 0 else None) for c, n in enumerate(rd.COARSE)}
    present = [n for c, n in enumerate(rd.COARSE) if cm[c].sum() > 0]
    miou = float(np.mean([iou[n] for n in present])) if present else float("nan")
    water = iou["water"] if iou["water"] is not None else float("nan")
    return {"iou": iou, "water_iou": water, "miou": miou, "present": present, "pixels": int(cm.sum())}


def _worst(rows: list[dict], key: str, n: int = N_WORST) -> list[dict]:
    ok = [r for r in rows if not r.get("na") and r.get(key) == r.get(key)]
    return [{"name": r["name"], key: r[key]} for r in sorted(ok, key=lambda r: (r[key], r["name"]))[:n]]


def seg_dubai(config=None, split: str = "all", limit: int | None = None) -> dict:
    """Coarse land-cover figures on ``landcover_dubai`` (confusion pixel-summed per split)."""
    import cv2

    from ..io import read_image
    from ..segmentation import segment

    items = rd.dubai_items()
    if not items:
        return _skipped("landcover_dubai", rd.SHARED / "real" / "landcover_dubai")
    cfg = config or default_config()
    t0 = time.perf_counter()
    rows, cms = [], {"train": np.zeros((N_COARSE, N_COARSE + 1), np.int64)}
    cms["val"] = cms["train"].copy()
    for name, img_path, mask_path, val in _select(items, split, limit, lambda it: it[3]):
        image = read_image(img_path, gsd_m=DUBAI_GSD_M, config=cfg.io)
        ids = segment(image, cfg).ids
        truth = rd.dubai_coarse(rd.read_rgb(mask_path))
        if truth.shape != ids.shape:  # the class map should be on the image grid; never compare misaligned
            truth = cv2.resize(truth, (ids.shape[1], ids.shape[0]), interpolation=cv2.INTER_NEAREST)
        cm = coarse_confusion(ids, truth)
        cms["val" if val else "train"] += cm
        s = coarse_scores(cm)
        rows.append({"name": name, "split": "val" if val else "train", "water_iou": s["water_iou"],
                     "miou": s["miou"], "iou": s["iou"]})
    out: dict = {"set": "landcover_dubai", "gsd_m": DUBAI_GSD_M, "backend": cfg.segment.backend,
                 "images": rows}
    for sp in ("train", "val"):
        n = sum(r["split"] == sp for r in rows)
        out[sp] = {"images": n, **coarse_scores(cms[sp]), "confusion": cms[sp].tolist()}
    out["worst"] = _worst(rows, "miou")
    out["seconds"] = round(time.perf_counter() - t0, 2)
    return out


def seg_marina(config=None) -> dict:
    """8-class mIoU and water IoU of the DOTA marina against the hand-drawn polygons."""
    from ..io import read_image
    from ..segmentation import segment
    from .segmentation import MARINA_TRUTH, class_ious, rasterize_polygons

    path = rd.SHARED / "aerial" / "marina_p0861" / "image.jpg"
    if not path.is_file():
        return _skipped("marina_p0861", path)
    cfg = config or default_config()
    spec = json.loads(MARINA_TRUTH.read_text(encoding="utf-8"))
    t0 = time.perf_counter()
    image = read_image(path, gsd_m=float(spec["gsd_m"]), config=cfg.io)
    ids = segment(image, cfg).ids
    res = class_ious(ids, rasterize_polygons(spec, ids.shape))
    return {"set": "marina_p0861", "gsd_m": float(spec["gsd_m"]), "backend": cfg.segment.backend,
            "miou": res["miou"], "water_iou": res["iou"]["water"], "accuracy": res["accuracy"],
            "iou": res["iou"], "seconds": round(time.perf_counter() - t0, 2)}


# ------------------------------------------------------------------------------------------ detection

def _detect(image, cfg, with_classmap: bool):
    """Detections and seconds, as ``coastforge detect`` (``--segment`` with ``with_classmap``) runs them."""
    from .detection import timed_detect

    opts = {"segment_config": cfg.segment} if with_classmap else {}
    return timed_detect(image, cfg.detect.backend, cfg.detect, **opts)


def _det_boxes(name: str, items: list, gsd_of: Callable[[Any], float], config, with_classmap: bool) -> dict:
    """Recall / detection precision of the grown-box rule over axis-aligned labelled images."""
    from ..errors import InputError
    from ..io import read_image

    cfg = config or default_config()
    t0 = time.perf_counter()
    rows = []
    for it in items:
        gsd = gsd_of(it)
        row = {"name": it.name, "split": _split(it), "gsd_m": round(gsd, 4),
               "labels": int(len(it.boxes))}
        image = read_image(it.path, gsd_m=gsd, config=cfg.io)
        try:
            dets, dt = _detect(image, cfg, with_classmap)
        except InputError as exc:  # e.g. the learned detector refuses > 1 m/px: say so, measure the others
            rows.append({**row, "na": str(exc).split(";")[0]})
            continue
        preds = [d for d in dets if d.category == it.category]
        xy = np.array([[d.cx_px, d.cy_px] for d in preds], np.float64).reshape(-1, 2)
        m = len(match_centres_in_boxes(xy, it.boxes))
        rows.append({**row, "preds": len(preds), "matched": m, "recall": _ratio(m, len(it.boxes)),
                     "precision": _ratio(m, len(preds)), "seconds": round(dt, 3)})
    out: dict = {"set": name, "category": items[0].category if items else None, "backend": cfg.detect.backend,
                 "with_classmap": with_classmap, "images": rows}
    for sp in ("train", "val"):
        r = [x for x in rows if x["split"] == sp and not x.get("na")]
        lab, pred, m = (sum(x[k] for x in r) for k in ("labels", "preds", "matched"))
        out[sp] = {"images": len(r), "objects": lab, "preds": pred, "matched": m, "recall": _ratio(m, lab),
                   "precision": _ratio(m, pred), "na_images": sum(x["split"] == sp and bool(x.get("na"))
                                                                  for x in rows)}
    gsds = [x["gsd_m"] for x in rows]
    out["gsd_range_m"] = [min(gsds), max(gsds)] if gsds else None
    out["worst"] = _worst(rows, "recall")
    out["seconds"] = round(time.perf_counter() - t0, 2)
    return out


def det_ships(config=None, split: str = "all", limit: int | None = None, with_classmap: bool = False) -> dict:
    """Boats on ``ships_aerial`` images with >= 3 labelled boats, GSD derived per image from the labels."""
    items = [it for it in rd.ships_items() if len(it.boxes) >= MIN_SHIP_LABELS]
    if not items:
        return _skipped("ships_aerial", rd.SHARED / "real" / "ships_aerial")
    items = _select(items, split, limit, lambda it: it.val)
    out = _det_boxes("ships_aerial", items, lambda it: rd.ships_gsd(it.boxes), config, with_classmap)
    out["gsd_rule"] = ("10 m / median labelled long side, clipped to [0.15, 1.2] m/px "
                       "(derived from the labels)")
    return out


def det_munich(config=None, split: str = "all", limit: int | None = None,
               with_classmap: bool = False) -> dict:
    """Vehicles (car, truck, bus, minibus) on ``cars_munich`` at 0.13 m/px."""
    items = rd.munich_items()
    if not items:
        return _skipped("cars_munich", rd.SHARED / "real" / "cars_munich")
    items = _select(items, split, limit, lambda it: it.val)
    return _det_boxes("cars_munich", items, lambda _it: rd.MUNICH_GSD_M, config, with_classmap)


def det_marina(config=None, with_classmap: bool = False) -> dict:
    """DOTA marina: boats matched by the benchmark's rule (centre inside the oriented label box grown by 25 %,
    Hungarian on centre distance) with orientation RMSE over those pairs; ``bench.detection``'s rule (gate =
    half the labelled length) beside it for comparison with the synthetic figures; harbor structures hit."""
    from shapely.geometry import Polygon

    from ..frames import wrap_half_deg
    from ..io import read_image
    from .detection import Score, match, piers_found, read_dota_yolo

    folder = rd.SHARED / "aerial" / "marina_p0861"
    if not (folder / "image.jpg").is_file():
        return _skipped("marina_p0861", folder)
    cfg = config or default_config()
    t0 = time.perf_counter()
    image = read_image(folder / "image.jpg", gsd_m=MARINA_GSD_M, config=cfg.io)
    dets, dt = _detect(image, cfg, with_classmap)
    lab = read_dota_yolo(folder / "labels_yolo_obb.txt", image.grid.width_px, image.grid.height_px)
    ships = [t for c, t in lab if c == "ship"]
    harbors = [t for c, t in lab if c == "harbor"]
    boats = [d for d in dets if d.category == "boat"]
    pairs = match_centres_in_quads(np.array([[d.cx_px, d.cy_px] for d in boats]).reshape(-1, 2),
                                   np.array([t.corners for t in ships]).reshape(-1, 4, 2))
    s = Score("marina_p0861 boats", n_truth=len(ships), n_pred=len(boats), matched=len(pairs), gsd_m=MARINA_GSD_M,
              orient_err=[float(wrap_half_deg(boats[i].yaw_deg - ships[j].yaw)) for i, j in pairs])
    gate = Score("marina_p0861 boats", gsd_m=MARINA_GSD_M)
    match(ships, boats, gate)
    # the crop's labels leave out boats the crop edge cuts (DOTA's crops drop truncated objects): unmatched
    # boxes reaching past the edge are counted apart, and a precision without them is printed beside
    w, h = image.grid.width_px, image.grid.height_px
    matched = {i for i, _ in pairs}
    cut = sum(1 for i, d in enumerate(boats) if i not in matched and cut_by_edge(d, w, h))
    # detections name pier boxes pier_walkway / pier_finger (coastforge.classes.DETECTION_CATEGORIES)
    piers = [d for d in dets if d.category.startswith("pier")]
    pier_polys = [Polygon(d.corners_px()) for d in piers]
    hit = 0
    for h in harbors:
        poly = Polygon(h.corners)
        hit += any(poly.intersects(pp) for pp in pier_polys)
    return {"set": "marina_p0861", "backend": cfg.detect.backend, "with_classmap": with_classmap,
            "gsd_m": MARINA_GSD_M, "objects": s.n_truth, "preds": s.n_pred, "matched": s.matched,
            "recall": s.recall, "precision": s.precision, "orient_rmse_deg": s.orient_rmse,
            "unmatched_cut_by_edge": cut, "precision_without_edge_cut": _ratio(s.matched, s.n_pred - cut),
            "half_length_gate": {"matched": gate.matched, "recall": gate.recall, "precision": gate.precision,
                                 "orient_rmse_deg": gate.orient_rmse},
            "harbors": len(harbors), "harbors_hit": int(hit), "pier_boxes": len(piers),
            "harbors_found_bench_detection": piers_found(harbors, dets),
            "detect_seconds": round(dt, 2), "seconds": round(time.perf_counter() - t0, 2)}


def coarser(image, factor: float):
    """``image`` as a camera ``factor`` times higher would see it: averaged down (area interpolation), its
    GSD multiplied."""
    import cv2

    from ..types import GeoImage, Grid

    if factor == 1.0:
        return image
    rgb = cv2.resize(image.rgb, None, fx=1.0 / factor, fy=1.0 / factor, interpolation=cv2.INTER_AREA)
    return GeoImage(np.ascontiguousarray(rgb), Grid(rgb.shape[1], rgb.shape[0], image.grid.gsd_m * factor))


# --weather-sweep: the same photos under fixed changes a user's picture may bring (haze, exposure, noise, no
# colour, softness, compression); fixed strengths, so that runs compare
WEATHER = ("haze", "dark", "bright", "noise", "grey", "blur", "jpeg")


def _check_weather(kind: str) -> None:
    if kind not in WEATHER:
        raise ValueError(f"unknown weather {kind!r}; one of {', '.join(WEATHER)}")


def weathered(image, kind: str):
    """``image`` under one of ``WEATHER``: haze (30 % of a light grey airlight blended in), dark / bright
    (gamma 1.6 / 0.6), noise (Gaussian, sigma 8 grey levels, seed 0), grey (luma only), blur (Gaussian,
    sigma 1.2 px), jpeg (quality 40). Same size and GSD."""
    import cv2

    _check_weather(kind)
    x = image.rgb.astype(np.float32)
    if kind == "haze":
        x = 0.7 * x + 0.3 * np.array([200.0, 205.0, 210.0], np.float32)
    elif kind in ("dark", "bright"):
        x = 255.0 * (x / 255.0) ** (1.6 if kind == "dark" else 0.6)
    elif kind == "noise":
        x = x + np.random.default_rng(0).normal(0.0, 8.0, x.shape).astype(np.float32)
    elif kind == "grey":
        x = np.repeat(x @ np.array([0.299, 0.587, 0.114], np.float32), 3).reshape(x.shape)
    elif kind == "blur":
        x = cv2.GaussianBlur(x, (0, 0), 1.2)
    else:  # jpeg
        _ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image.rgb[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, 40])
        x = cv2.imdecode(buf, cv2.IMREAD_COLOR)[:, :, ::-1].astype(np.float32)
    return dataclasses.replace(image, rgb=np.ascontiguousarray(np.clip(np.round(x), 0, 255).astype(np.uint8)))


def _sweep_photos(cfg, split: str, limit: int | None, with_ships: bool) -> tuple[list, dict]:
    """(name, category, [(image, truth, oriented, split)]) per real set a sweep measures, and skip notes:
    ships_aerial (when ``with_ships``) and cars_munich of ``split``, the DOTA marina (split "eval") unless
    ``split`` is train."""
    from ..io import read_image
    from .detection import read_dota_yolo

    sets, skipped = [], {}
    if with_ships:
        items = [it for it in rd.ships_items() if len(it.boxes) >= MIN_SHIP_LABELS]
        if items:
            sets.append(("ships_aerial", "boat", [
                (read_image(it.path, gsd_m=rd.ships_gsd(it.boxes), config=cfg.io), it.boxes, False, _split(it))
                for it in _select(items, split, limit, lambda it: it.val)]))
        else:
            skipped["ships_aerial"] = _skipped("ships_aerial", rd.SHARED / "real" / "ships_aerial")
    items = rd.munich_items()
    if items:
        sets.append(("cars_munich", "vehicle", [(read_image(it.path, gsd_m=rd.MUNICH_GSD_M, config=cfg.io),
                                                  it.boxes, False, _split(it))
                                                 for it in _select(items, split, limit, lambda it: it.val)]))
    else:
        skipped["cars_munich"] = _skipped("cars_munich", rd.SHARED / "real" / "cars_munich")
    folder = rd.SHARED / "aerial" / "marina_p0861"
    if split != "train" and (folder / "image.jpg").is_file():
        image = read_image(folder / "image.jpg", gsd_m=MARINA_GSD_M, config=cfg.io)
        lab = read_dota_yolo(folder / "labels_yolo_obb.txt", image.grid.width_px, image.grid.height_px)
        quads = np.array([t.corners for c, t in lab if c == "ship"]).reshape(-1, 4, 2)
        sets.append(("marina_p0861", "boat", [(image, quads, True, "eval")]))
    return sets, skipped


def _sweep(cfg, sets: list, conditions: list, with_classmap: bool, out: dict) -> dict:
    """Recall and precision of each set under each condition (key, transform of an image, label scale), one
    row per condition and split (training and validation photos are never pooled), with the median GSD the
    detector saw."""
    from ..errors import InputError

    for name, category, photos in sets:
        by_split: dict[str, list] = {}
        for p in photos:
            by_split.setdefault(p[3], []).append(p)
        rows = []
        for key, transform, scale in conditions:
            for sp, group in by_split.items():
                n_lab = n_pred = n_m = 0
                gsds = []
                for image, truth, oriented, _ in group:
                    seen = transform(image)
                    gsds.append(seen.grid.gsd_m)
                    try:
                        dets, _ = _detect(seen, cfg, with_classmap)
                    except InputError as exc:  # a backend refusing that GSD: counted as finding nothing
                        dets = []
                        out.setdefault("refused", []).append(f"{name} at {seen.grid.gsd_m:.2f} m/px: "
                                                             + str(exc).split(";")[0])
                    xy = np.array([[d.cx_px, d.cy_px] for d in dets if d.category == category]).reshape(-1, 2)
                    pairs = (match_centres_in_quads(xy, truth * scale) if oriented
                             else match_centres_in_boxes(xy, truth * scale))
                    n_lab, n_pred, n_m = n_lab + len(truth), n_pred + len(xy), n_m + len(pairs)
                rows.append({**key, "gsd_m": round(float(np.median(gsds)), 3), "split": sp, "objects": n_lab,
                             "preds": n_pred, "matched": n_m, "recall": _ratio(n_m, n_lab),
                             "precision": _ratio(n_m, n_pred)})
        out[name] = {"set": name, "category": category, "images": len(photos), "rows": rows}
    return out


def det_weather_sweep(config=None, split: str = "all", limit: int | None = None, with_classmap: bool = False,
                      kinds: tuple[str, ...] = WEATHER) -> dict:
    """Recall and precision on ships_aerial and cars_munich (the chosen split) and the DOTA marina (unless
    ``split`` is train) as they are and under each of ``kinds`` (``weathered``)."""
    for k in kinds:  # before the photos are read
        _check_weather(k)
    cfg = config or default_config()
    t0 = time.perf_counter()
    sets, skipped = _sweep_photos(cfg, split, limit, with_ships=True)
    out: dict = {"kinds": ["none", *kinds], **skipped}
    conditions = [({"kind": "none"}, lambda im: im, 1.0)]
    conditions += [({"kind": k}, lambda im, k=k: weathered(im, k), 1.0) for k in kinds]
    _sweep(cfg, sets, conditions, with_classmap, out)
    out["seconds"] = round(time.perf_counter() - t0, 2)
    return out


def det_gsd_sweep(config=None, split: str = "all", limit: int | None = None, with_classmap: bool = False,
                  factors: tuple[float, ...] = SWEEP_FACTORS) -> dict:
    """Recall and precision on cars_munich (the chosen split) and the DOTA marina (unless ``split`` is
    train) at their own GSD and averaged down by each of ``factors``; labels scaled alike."""
    cfg = config or default_config()
    t0 = time.perf_counter()
    sets, skipped = _sweep_photos(cfg, split, limit, with_ships=False)
    out: dict = {"factors": [1.0, *factors], **skipped}
    conditions = [({"factor": f}, lambda im, f=f: coarser(im, f), 1.0 / f) for f in out["factors"]]
    _sweep(cfg, sets, conditions, with_classmap, out)
    out["seconds"] = round(time.perf_counter() - t0, 2)
    return out


# ------------------------------------------------------------------------------------------ printing

def _f(v, nd: int = 3) -> str:
    return "  -  " if v is None or v != v else f"{v:.{nd}f}"


def print_seg_dubai(r: dict, verbose: bool = False) -> None:
    print(f"landcover_dubai (segment {r['backend']}, nominal {r['gsd_m']} m/px): {r['seconds']:.1f} s")
    print(f"  {'split':5s} {'images':>6s} {'waterIoU':>8s} {'mIoU':>6s}   "
          + " ".join(f"{n:>10s}" for n in rd.COARSE))
    for sp in ("train", "val"):
        s = r[sp]
        print(f"  {sp:5s} {s['images']:6d} {_f(s['water_iou']):>8s} {_f(s['miou']):>6s}   "
              + " ".join(f"{_f(s['iou'][n]):>10s}" for n in rd.COARSE))
    if verbose:
        for x in r["images"]:
            print(f"    {x['name']:28s} {x['split']:5s} water {_f(x['water_iou'])} mIoU {_f(x['miou'])}")
    print("  worst: " + ", ".join(f"{w['name']} {_f(w['miou'], 2)}" for w in r["worst"]))


def print_seg_marina(r: dict) -> None:
    print(f"marina_p0861 (segment {r['backend']}, {r['gsd_m']} m/px, DOTA: evaluation only): "
          f"mIoU {_f(r['miou'])}, "
          f"water IoU {_f(r['water_iou'])}  {r['seconds']:.1f} s")


def print_det_boxes(r: dict, verbose: bool = False) -> None:
    lo_hi = r["gsd_range_m"]
    gsd = "" if lo_hi is None else (f"{lo_hi[0]:.2f} m/px" if lo_hi[0] == lo_hi[1]
                                    else f"GSD {lo_hi[0]:.2f}-{lo_hi[1]:.2f} m/px from labels")
    cm = ", with class map" if r["with_classmap"] else ""
    print(f"{r['set']} ({r['category']}, detect {r['backend']}{cm}, {gsd}): {r['seconds']:.1f} s")
    print(f"  {'split':5s} {'images':>6s} {'objects':>7s} {'preds':>6s} {'recall':>6s} {'prec':>6s}  n/a")
    for sp in ("train", "val"):
        s = r[sp]
        print(f"  {sp:5s} {s['images']:6d} {s['objects']:7d} {s['preds']:6d} {_f(s['recall']):>6s} "
              f"{_f(s['precision']):>6s}  {s['na_images']}")
    if verbose:
        for x in r["images"]:
            if x.get("na"):
                print(f"    {x['name']:12s} {x['split']:5s} gsd {x['gsd_m']:.3f}  n/a ({x['na']})")
            else:
                print(f"    {x['name']:12s} {x['split']:5s} gsd {x['gsd_m']:.3f}  "
                      f"{x['matched']:3d}/{x['labels']:<3d} "
                      f"preds {x['preds']:3d}  recall {_f(x['recall'])} prec {_f(x['precision'])}")
    print("  worst: " + ", ".join(f"{w['name']} {_f(w['recall'], 2)}" for w in r["worst"]))


def _print_sweep(r: dict, names: tuple[str, ...], cell: Callable[[dict], str]) -> None:
    for name in names:
        s = r.get(name)
        if s is None:
            continue
        if "skipped" in s:
            print(f"  skipped: {name}: {s['skipped']}")
            continue
        for sp in dict.fromkeys(x["split"] for x in s["rows"]):
            rows = [x for x in s["rows"] if x["split"] == sp]
            cells = ", ".join(f"{cell(x)} {_f(x['recall'])} / {_f(x['precision'])}" for x in rows)
            print(f"  {name} {sp} ({s['category']}, {rows[0]['objects']} objects), recall / prec: {cells}")
    for why in sorted(set(r.get("refused", []))):
        print(f"  refused: {why}")


def print_gsd_sweep(r: dict) -> None:
    print(f"GSD sweep (the photos averaged down {', '.join(f'{f:g}x' for f in r['factors'][1:])}): "
          f"{r['seconds']:.1f} s")
    _print_sweep(r, ("cars_munich", "marina_p0861"), lambda x: f"{x['gsd_m']:.2f} m/px")


def print_weather_sweep(r: dict) -> None:
    print(f"weather sweep (the photos under {', '.join(r['kinds'][1:])}; bench.real.weathered): "
          f"{r['seconds']:.1f} s")
    _print_sweep(r, ("ships_aerial", "cars_munich", "marina_p0861"), lambda x: x["kind"])


def print_det_marina(r: dict) -> None:
    cm = ", with class map" if r["with_classmap"] else ""
    g = r["half_length_gate"]
    print(f"marina_p0861 boats (detect {r['backend']}{cm}, {r['gsd_m']} m/px, DOTA: evaluation only): "
          f"{r['seconds']:.1f} s")
    print(f"  objects {r['objects']} preds {r['preds']} recall {_f(r['recall'])} prec {_f(r['precision'])} "
          f"orient RMSE {_f(r['orient_rmse_deg'], 2)} deg (centre in the oriented label box grown by 25 %)")
    if r.get("unmatched_cut_by_edge"):
        print(f"  {r['unmatched_cut_by_edge']} unmatched boxes reach past the image edge (the crop's labels leave "
              f"out the boats it cuts): prec {_f(r['precision_without_edge_cut'])} without them")
    print(f"  bench.detection's rule (gate half the labelled length): recall {_f(g['recall'])} "
          f"prec {_f(g['precision'])} orient RMSE {_f(g['orient_rmse_deg'], 2)} deg")
    print(f"  harbor structures hit by a pier box: {r['harbors_hit']}/{r['harbors']} "
          f"({r['pier_boxes']} pier boxes; "
          f"bench.detection's cover rule {r['harbors_found_bench_detection']}/{r['harbors']})")


def _jsonable(v):
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None  # JSON has no NaN
    return v


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.real", description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("seg", "det"), default=None, help="one part (default both)")
    ap.add_argument("--segment-backend", default=None, help="default: the preset's, as generate uses")
    ap.add_argument("--detect-backend", default=None, help="default: the preset's, as generate uses")
    ap.add_argument("--with-classmap", action="store_true",
                    help="segment first and detect with the class map, as generate does")
    ap.add_argument("--gsd-sweep", action="store_true",
                    help="detection again on the photos averaged down 2, 3 and 5 times (cars_munich, DOTA marina)")
    ap.add_argument("--weather-sweep", action="store_true",
                    help="detection again on the photos under haze, exposure, noise, no colour, blur and JPEG "
                         "(ships_aerial, cars_munich, DOTA marina)")
    ap.add_argument("--split", choices=("all", "train", "val"), default="all")
    ap.add_argument("--limit", type=int, default=None, help="at most N images per set (quick runs)")
    ap.add_argument("--preset", default="default")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--json", type=Path, default=None, help="write all figures here")
    ap.add_argument("--verbose", action="store_true",
                    help="per-image rows (ships: the GSD derived per image)")
    a = ap.parse_args(argv)
    cfg = default_config(a.segment_backend, a.detect_backend, a.preset, a.sets)
    print(f"data: {rd.SHARED}; split {a.split}" + (f", at most {a.limit} images per set" if a.limit else ""))
    results: dict = {"split": a.split, "limit": a.limit, "segment_backend": cfg.segment.backend,
                     "detect_backend": cfg.detect.backend, "with_classmap": a.with_classmap}

    def show(r: dict, printer: Callable[[dict], None]) -> dict:
        if "skipped" in r:
            print(f"skipped: {r['set']}: {r['skipped']}")
        else:
            printer(r)
        return r

    if a.only in (None, "seg"):
        t0 = time.perf_counter()
        dubai = seg_dubai(cfg, a.split, a.limit)
        seg = {"landcover_dubai": show(dubai, lambda r: print_seg_dubai(r, a.verbose))}
        if a.split != "train":
            seg["marina_p0861"] = show(seg_marina(cfg), print_seg_marina)
        seg["seconds"] = round(time.perf_counter() - t0, 2)
        print(f"segmentation part: {seg['seconds']:.1f} s\n")
        results["seg"] = seg
    if a.only in (None, "det"):
        t0 = time.perf_counter()
        pr = lambda r: print_det_boxes(r, a.verbose)  # noqa: E731
        det = {"ships_aerial": show(det_ships(cfg, a.split, a.limit, a.with_classmap), pr),
               "cars_munich": show(det_munich(cfg, a.split, a.limit, a.with_classmap), pr)}
        if a.split != "train":
            det["marina_p0861"] = show(det_marina(cfg, a.with_classmap), print_det_marina)
        if a.gsd_sweep:
            det["gsd_sweep"] = det_gsd_sweep(cfg, a.split, a.limit, a.with_classmap)
            print_gsd_sweep(det["gsd_sweep"])
        if a.weather_sweep:
            det["weather_sweep"] = det_weather_sweep(cfg, a.split, a.limit, a.with_classmap)
            print_weather_sweep(det["weather_sweep"])
        det["seconds"] = round(time.perf_counter() - t0, 2)
        print(f"detection part: {det['seconds']:.1f} s")
        results["det"] = det
    if a.json is not None:
        a.json.write_text(json.dumps(_jsonable(results), indent=1), encoding="utf-8")
        print(f"figures written to {a.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
