"""Segmentation and detection checked against each other, so that ``generate`` reaches one consistent
answer instead of letting one stage silently veto the other.

- **Moored boats are water** (``water_from_boats``): a cluster of detected boats (rafted, bow-in in rows)
  or boats beside water mark water, whatever the segmenter said there. The boats' footprints and the
  narrow gaps between them become water. A marina whose slate-grey water the segmenter read as pavement
  would otherwise lose every boat to the "boats need water" rule and become a car park.
- **The water filters the detections** (``recategorise``): a "vehicle" standing in open water is a small
  boat (it keeps its box; its heading is left to the matcher), one in a patch of "water" among land keeps
  its category (the class map is what is wrong there), a vehicle on riprap (rocks by the water) is dropped,
  and a boat far from any water, or an unsure one with no water under its box, becomes a vehicle when it has
  a vehicle's size and stands on pavement, or is dropped (``detection.boats_off_water``).

Every change is counted in the returned notes (shown in the report).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from .classes import ROCKS, WATER
from .config import DetectConfig
from .types import ClassMap, Detection

# a boat cluster: footprints grown by half this and closed over it (rafted hulls and the water between
# bow-in rows, ~2-4 m, join; boats across a 10 m fairway do not)
CLUSTER_GAP_M = 4.0
MIN_CLUSTER_BOATS = 3  # fewer boats far from water are no evidence of water (a boat on a trailer)
SEED_MIN_SCORE = 0.4  # only fairly sure boats re-decide the class map
TOUCH_WATER_M = 6.0  # a smaller cluster counts when water lies this close to it...
# ... when its best boat is at least this sure: one weak "boat" is weak evidence (a rock mole taken for a 55 m
# boat, score 0.41, made a synthetic marina's jetty water), while a row of them is strong evidence at 0.4
LONE_MIN_SCORE = 0.5
OPEN_WATER_AROUND = 0.7  # a "vehicle" in water is a boat when this much of its surroundings is water too


@dataclass
class Reconciled:
    dets: list[Detection]
    class_map: ClassMap
    notes: dict = field(default_factory=dict)


def water_from_boats(dets: list[Detection], class_map: ClassMap, gsd_m: float) -> tuple[ClassMap, dict]:
    """The class map with moored-boat clusters made water (see the module docstring) and what changed."""
    ids = class_map.ids
    boats = [d for d in dets if d.category == "boat" and d.score >= SEED_MIN_SCORE]
    if not boats:
        return class_map, {}
    h, w = ids.shape
    # a coarse grid (~0.5 m) is plenty for footprints and gaps, and keeps big images cheap
    f = max(1, int(0.5 / gsd_m))
    hs, ws = -(-h // f), -(-w // f)
    foot = np.zeros((hs, ws), np.uint8)
    for d in boats:
        pts = d.corners_px() / f - 0.5
        cv2.fillPoly(foot, [np.round(pts).astype(np.int32)], 1)
    r = max(1, int(round(CLUSTER_GAP_M / 2 / (gsd_m * f))))
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    closed = cv2.morphologyEx(cv2.dilate(foot, ker), cv2.MORPH_CLOSE, ker)
    n, lab = cv2.connectedComponents(closed, connectivity=8)
    small_ids = ids[::f, ::f][:hs, :ws]
    water_small = small_ids == WATER
    rt = max(1, int(round(TOUCH_WATER_M / (gsd_m * f))))
    near_water = cv2.dilate(water_small.view(np.uint8), cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * rt + 1, 2 * rt + 1))) > 0
    counts = np.zeros(n, int)
    best = np.zeros(n)
    for d in boats:
        c = lab[min(hs - 1, int(d.cy_px / f)), min(ws - 1, int(d.cx_px / f))]
        counts[c] += 1
        best[c] = max(best[c], d.score)
    touching = np.zeros(n, bool)
    touching[np.unique(lab[near_water & (lab > 0)])] = True
    keep = (counts >= MIN_CLUSTER_BOATS) | (touching & (best >= LONE_MIN_SCORE))
    keep[0] = False
    sel = keep[lab] & ~water_small
    if not sel.any():
        return class_map, {}
    # back on the image grid: the cluster's pixels (nearest), land only
    full = cv2.resize(sel.view(np.uint8), (ws * f, hs * f), interpolation=cv2.INTER_NEAREST)[:h, :w] > 0
    full &= ids != WATER
    out = ids.copy()
    out[full] = WATER
    src = class_map.source
    if src is not None:
        from .segmentation.learned import SOURCE_DETECTIONS

        src = src.copy()
        src[full] = SOURCE_DETECTIONS
    note = {"water_from_boats_m2": round(float(full.sum()) * gsd_m * gsd_m, 1),
            "boat_clusters_made_water": int(np.count_nonzero(keep & (np.bincount(lab[sel], minlength=n) > 0)))}
    return replace(class_map, ids=out, source=src), note


def recategorise(dets: list[Detection], class_map: ClassMap, config: DetectConfig) -> tuple[list[Detection], dict]:
    """A vehicle standing in water is decided by what surrounds it: in open water (its surroundings, out to
    one box length, mostly water) it is a small boat; among land the class map under it is what is wrong
    (a dark car park read as water) and it stays a vehicle (``fill_under_objects`` then re-decides the
    ground under it). Vehicles on riprap (rocks within ``near_water_m`` of water) are dropped: the learned
    net takes its blocks for cars."""
    from .detection import values_under_box

    out, to_boat, dropped, kept = [], 0, 0, 0
    dist = None  # metres to the nearest water, computed when a vehicle stands on rocks
    for d in dets:
        if d.category == "vehicle" and config.vehicle_max_wet > 0:
            under = values_under_box(class_map.ids, d)
            if under.size:
                wet, rock = float(np.mean(under == WATER)), float(np.mean(under == ROCKS))
                if wet >= config.vehicle_max_wet:
                    around = values_under_box(class_map.ids, replace(d, length_px=3 * d.length_px,
                                                                     width_px=d.width_px + 2 * d.length_px))
                    if float(np.mean(around == WATER)) >= OPEN_WATER_AROUND:
                        to_boat += 1
                        out.append(replace(d, category="boat", heading_known=False, heading_confidence=0.5))
                    else:
                        kept += 1
                        out.append(d)
                    continue
                if wet + rock >= config.vehicle_max_wet:
                    # riprap lines the water: "rocks" far from any water are textured ground the class
                    # map got wrong (a street of parked cars), and the car stays
                    if dist is None:
                        gsd = float(class_map.grid.gsd_m)
                        dist = cv2.distanceTransform((class_map.ids != WATER).view(np.uint8), cv2.DIST_L2, 3) * gsd
                    if wet > 0 or float(values_under_box(dist, d).min()) <= config.near_water_m:
                        dropped += 1
                        continue
        out.append(d)
    notes = {}
    if to_boat:
        notes["vehicles_in_water_made_boats"] = to_boat
    if dropped:
        notes["vehicles_on_riprap_dropped"] = dropped
    if kept:
        notes["vehicles_on_land_read_as_water_kept"] = kept
    return out, notes


def reconcile(dets: list[Detection], class_map: ClassMap, gsd_m: float, config: DetectConfig,
              rgb: np.ndarray | None = None) -> Reconciled:
    """Detections seed and correct the water, then the water filters the detections."""
    from .detection import boats_off_water

    notes: dict = {}
    if config.boats_make_water:
        class_map, n1 = water_from_boats(dets, class_map, gsd_m)
        notes.update(n1)
    dets, n2 = recategorise(dets, class_map, config)
    notes.update(n2)
    if config.boats_need_water:
        before = sum(d.category == "boat" for d in dets)
        dets = boats_off_water(dets, class_map, gsd_m, config, rgb=rgb)
        gone = before - sum(d.category == "boat" for d in dets)
        if gone:
            notes["boats_off_water_changed"] = gone
    return Reconciled(dets, class_map, notes)
