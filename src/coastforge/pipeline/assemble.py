"""The scene's parts from the stages' results: classes under the detected objects, placed objects, the
boxes vegetation keeps clear of, the provenance and the object counts."""

from __future__ import annotations

import platform
import sys
from dataclasses import dataclass

import numpy as np

from .. import __version__
from ..classes import PAVED, WATER
from ..config import Config
from ..scene import SceneObject
from ..types import ClassMap, Detection
from .request import GenerateRequest


def fill_under_objects(class_map: ClassMap, dets: list[Detection], margin_px: float = 2.0) -> ClassMap:
    """Classes under transient objects (boats, vehicles) and pier decks are what surrounds them: a boat sits on
    water, a car on asphalt, and a pier deck over water must not become land in the height map.

    "Around" leaves out the other detected boxes: in a row of dark parked cars the neighbours (often
    segmented as trees) are no evidence of the ground. A vehicle takes the paved class when its free
    surroundings show pavement at all, since cars stand on roads and car parks, not in tree crowns."""
    import cv2

    ids = class_map.ids.copy()
    h, w = ids.shape
    boxes = []
    taken = np.zeros((h, w), np.uint8)  # every detected box, grown by the margin
    for d in dets:
        grow = margin_px
        corners = Detection(d.category, d.score, d.cx_px, d.cy_px, d.length_px + 2 * grow, d.width_px + 2 * grow,
                            d.yaw_deg).corners_px()
        poly = np.round(corners).astype(np.int32)
        boxes.append(poly)
        cv2.fillPoly(taken, [poly], 1)
    for d, poly in zip(dets, boxes):
        x0, y0 = np.maximum(poly.min(0) - 4, 0)
        x1, y1 = np.minimum(poly.max(0) + 5, [w, h])
        if x1 <= x0 or y1 <= y0:
            continue
        inner = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillPoly(inner, [poly - [x0, y0]], 1)
        ring = cv2.dilate(inner, np.ones((7, 7), np.uint8)) & (1 - inner)
        sub = ids[y0:y1, x0:x1]
        free = ring & (1 - taken[y0:y1, x0:x1])
        around = sub[(free if free.sum() >= 0.2 * ring.sum() else ring).astype(bool)]
        if around.size == 0:
            continue
        counts = np.bincount(around, minlength=8)
        if d.category in ("pier_walkway", "pier_finger"):
            # a pier is over water where water dominates its sides; its landward root stays land
            if counts[WATER] < 0.35 * around.size:
                continue
            fill = WATER
        elif d.category == "vehicle" and counts[list(PAVED)].sum() >= 0.15 * around.size:
            fill = int(PAVED[int(np.argmax(counts[list(PAVED)]))])
        else:
            fill = int(counts.argmax())
        sub[inner.astype(bool)] = fill
    return ClassMap(ids, class_map.grid, class_map.proba, class_map.confidence, class_map.source)


def place_decisions(decisions, dets: list[Detection], library, grid, config: Config, height, kit=None) -> list:
    """Scene objects for the matched detections, ids numbered per category (``boat_000``, ...); ``kit``:
    the fallback library of the categories ``library`` lacks."""
    from ..placement import place

    assets = {a.id: a for a in (kit.assets if kit is not None else ())}
    assets.update({a.id: a for a in library.assets})
    objects = []
    counters: dict[str, int] = {}
    for dec in decisions:
        d = dets[dec.index]
        k = counters.get(d.category, 0)
        counters[d.category] = k + 1
        objects.append(place(d, assets[dec.asset_id], grid, f"{d.category}_{k:03d}", config.match, height=height,
                             water_level_m=0.0, yaw_deg=dec.yaw_deg, score=dec.confidence,  # in [0, 1]
                             attrs={"heading": dec.heading_source, "detector_score": round(d.score, 4),
                                    "match": dec.index},
                             shape_scale=dec.fit_scale, shape_offset_m=dec.fit_offset_m if dec.fit_scale else None))
    return objects


@dataclass(frozen=True)
class BoxFootprint:
    """A detected object's box in scene metres, for what must keep clear of the object before it is placed
    (a placed object's footprint is its detected box: position, yaw and scale come from it)."""

    x_m: float
    y_m: float
    yaw_deg: float
    length_m: float
    width_m: float

    footprint_m = SceneObject.footprint_m


def detection_footprints(dets: list[Detection], grid) -> list[BoxFootprint]:
    """The boxes of the detections that become placed objects (boats, vehicles, buoys)."""
    from ..placement import box_in_metres

    out = []
    for d in dets:
        if d.category in ("boat", "vehicle", "buoy"):
            x, y, length, width = box_in_metres(d, grid)
            out.append(BoxFootprint(x, y, d.yaw_deg, length, width))
    return out


def scene_provenance(req: GenerateRequest, config: Config, library, gsd_m: float, size_px: tuple[int, int], dets,
                     objects, vegetation, pier_report: dict, decisions, **extra) -> dict:
    """What made a scene: tool, command, seed, input, library, backends, config, counts, decisions."""
    return {
        "tool": "coastforge", "version": __version__, "command": req.command, "seed": config.seed,
        "input": {"image": str(req.image), "gsd_m": gsd_m, "size_px": list(size_px)},
        **extra,
        "library": str(req.library) if req.library else "starter-kit",
        "backends": {"segment": config.segment.backend, "terrain": config.terrain.backend,
                     "detect": config.detect.backend, "embedder": getattr(library.embedder, "name", "?")},
        "config": config.to_dict(),
        "counts": {"detections": len(dets), "objects": len(objects), "vegetation": len(vegetation)},
        "piers": pier_report,
        "matches": [m.to_dict() for m in decisions],
        "python": sys.version.split()[0], "platform": platform.platform(),
    }


def object_counts(objects, n_vegetation: int) -> dict[str, int]:
    counts: dict[str, int] = {}
    for o in objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    counts["vegetation"] = n_vegetation
    return counts
