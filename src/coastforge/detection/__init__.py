"""Detection: boats, vehicles, buoys and pier walkways/fingers as oriented boxes with a heading.

A backend is a class built with ``(config: DetectConfig, **opts)`` whose
``detect(image: GeoImage, class_map: ClassMap | None, seed: int) -> list[Detection]`` returns oriented
boxes in image pixels (see ``coastforge.types.Detection``). Backends are registered in
``coastforge.registry`` (``classical`` default, ``yolo``, ``onnx``).

This module also holds the JSON form of detections (``detections_to_json`` / ``detections_from_json``)
and the overlay drawing used by ``coastforge detect --overlay``.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal, Protocol, overload

import numpy as np

from ..classes import DETECTION_CATEGORIES
from ..config import DetectConfig
from ..errors import InputError
from ..types import ClassMap, Detection, GeoImage

JSON_FORMAT = "coastforge.detections/1"


class Detector(Protocol):
    def detect(self, image: GeoImage, class_map: ClassMap | None, seed: int) -> list[Detection]: ...


@overload
def detect(image: GeoImage, config: DetectConfig | None = None, class_map: ClassMap | None = None,
           backend: str | None = None, seed: int = 0, return_class_map: Literal[False] = False,
           **opts: Any) -> list[Detection]: ...
@overload
def detect(image: GeoImage, config: DetectConfig | None = None, class_map: ClassMap | None = None,
           backend: str | None = None, seed: int = 0, *, return_class_map: Literal[True],
           **opts: Any) -> tuple[list[Detection], ClassMap | None, dict]: ...
def detect(image: GeoImage, config: DetectConfig | None = None, class_map: ClassMap | None = None,
           backend: str | None = None, seed: int = 0, return_class_map: bool = False, whole_image: bool = True,
           **opts: Any) -> list[Detection] | tuple[list[Detection], ClassMap | None, dict]:
    """Run one detector backend on an image; returns detections sorted by descending score.

    Boats and vehicles mostly outside the image go (``drop_cut_by_frame``) unless ``whole_image`` is False
    (a tile of a larger image: its caller applies the rule at the whole image's edges).

    With a ``class_map`` the two are reconciled (``coastforge.consistency``): moored boats make water,
    vehicles in water become boats, boats far from water become vehicles or go. ``return_class_map``:
    return (detections, the corrected class map, what the reconciliation changed)."""
    from .. import registry

    config = config or DetectConfig()
    name = backend or config.backend
    if not isinstance(image, GeoImage):
        raise InputError(f"detect needs a GeoImage (from coastforge.io.read_image), got {type(image).__name__}")
    rgb = image.rgb
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise InputError(f"detect needs an (H, W, 3) uint8 RGB image, got shape {rgb.shape} dtype {rgb.dtype}")
    if class_map is not None and class_map.ids.shape != rgb.shape[:2]:
        raise InputError(
            f"class map shape {class_map.ids.shape} differs from the image shape {rgb.shape[:2]}; "
            "segment the same image (or resample the class map to it)"
        )
    cls = registry.load("detect", name)
    detector = cls(config, **opts)
    dets = detector.detect(image, class_map, seed)
    if whole_image:
        dets = drop_cut_by_frame(dets, image.grid.width_px, image.grid.height_px, config.min_inside)
    if config.refine:
        from .refine import refine_boxes

        # the classical backend snaps boats to their pier's direction, which on the real marina beat
        # the mirror-symmetry axis (median error 1.4° vs 2.4°): its axes are kept
        dets = refine_boxes(rgb, dets, image.grid.gsd_m, axis=name != "classical")
        if name != "classical":  # the classical backend already used the glass cue (heading.resolve_heading)
            from .heading import vehicle_fronts

            # vehicles: the backend's front (the learned net's) is a prior, the windscreen cue is added
            dets = vehicle_fronts(rgb, dets)
    notes: dict = {}
    if class_map is not None:
        from ..consistency import reconcile

        rec = reconcile(dets, class_map, image.grid.gsd_m, config, rgb=rgb)
        dets, class_map, notes = rec.dets, rec.class_map, rec.notes
    out = []
    for d in dets:
        if d.category not in DETECTION_CATEGORIES:
            raise ValueError(f"backend {name!r} returned unknown category {d.category!r}")
        if d.score >= config.min_score:
            out.append(d)
    out.sort(key=lambda d: (-d.score, d.cy_px, d.cx_px))
    if return_class_map:
        return out, class_map, notes
    return out


FRAMED_CATEGORIES = ("boat", "vehicle")  # piers and walkways run on past the edge: they are kept


def reaches_past_edge(det: Detection, width_px: int, height_px: int) -> bool:
    """Whether a box reaches past the image's edge (the object is cut by the picture)."""
    c = det.corners_px()
    return bool((c < 0).any() or (c[:, 0] > width_px).any() or (c[:, 1] > height_px).any())


def inside_share(det: Detection, width_px: int, height_px: int) -> float:
    """The share of ``det``'s box area inside the image (0 … 1)."""
    from shapely.geometry import Polygon, box

    poly = Polygon(det.corners_px())
    if poly.area <= 0:
        return 1.0
    return float(poly.intersection(box(0, 0, width_px, height_px)).area / poly.area)


def drop_cut_by_frame(dets: list[Detection], width_px: int, height_px: int, min_inside: float) -> list[Detection]:
    """``dets`` without the boats and vehicles whose box lies less than ``min_inside`` of its area inside the
    image. On the real training splits nearly all such boxes were unlabelled objects the crop cut
    (ships_aerial 9 of 9, cars_munich 52 of 53 under 0.7): the labellers, like a mosaic's next image,
    leave an object to the picture holding most of it."""
    if min_inside <= 0:
        return dets
    out = []
    for d in dets:
        if d.category in FRAMED_CATEGORIES and reaches_past_edge(d, width_px, height_px) \
                and inside_share(d, width_px, height_px) < min_inside:
            continue
        out.append(d)
    return out


def values_under_box(raster: np.ndarray, det: Detection, scale: float = 1.0) -> np.ndarray:
    """The values of ``raster`` under the oriented box of ``det`` (its pixel corners times ``scale``, for a
    raster on a coarser grid), flat; empty when the box lies outside the raster."""
    import cv2

    h, w = raster.shape[:2]
    pts = np.round(det.corners_px() * scale - 0.5).astype(np.int32)
    c0, r0 = np.clip(pts.min(0) - 1, 0, [w, h])
    c1, r1 = np.clip(pts.max(0) + 2, 0, [w, h])
    if c1 <= c0 or r1 <= r0:
        return np.empty(0, raster.dtype)
    inside = np.zeros((r1 - r0, c1 - c0), np.uint8)
    cv2.fillPoly(inside, [pts - [c0, r0]], 1)
    return raster[r0:r1, c0:c1][inside > 0]


# an unsure boat (the hybrid's "sure" score: ``hybrid.SURE_BOAT_SCORE``) standing wholly on land is no boat, however
# near the water (``boats_off_water``); ships_aerial training split, with the class map after the boats made
# water: 12 boats of 809 had no water under their box, all scored 0.36-0.50, 11 of them false
DRY_BOAT_MAX_SCORE = 0.5


def boats_off_water(dets: list[Detection], class_map: ClassMap, gsd_m: float, config: DetectConfig,
                    rgb: np.ndarray | None = None) -> list[Detection]:
    """Boats and buoys whose box stays further than ``near_water_m`` from any water are not boats (when the
    class map has water at all: at least ``min_water_area_m2``).

    The learned detector has only seen cars beside water; in a car park far from any shore it calls some
    cars (and car-sized planters) boats. Such a box becomes a vehicle when it has a vehicle's size and stands
    on paving (its heading left to the matcher), and is dropped otherwise. Nearer the water the same goes for
    an unsure boat (score under ``DRY_BOAT_MAX_SCORE``) with no water under any of its box: the detector and
    the class map both doubt it (a car on the quay road of a marina photo).

    A class map with (almost) no water says more about the segmenter than about the boats when the image
    has water after all (a sea painted as grass, seen on a synthetic beach, would otherwise cost every
    boat): then nothing is decided. With ``rgb``, the classical detector's photometric water model gives a
    second opinion: when it finds no water either (an inland tile of an orthophoto, a tennis club), every
    boat is on land."""
    import cv2

    from ..classes import PAVED, WATER

    cats = ("boat", "buoy")
    if not any(d.category in cats for d in dets):
        return dets
    ids = class_map.ids
    if np.count_nonzero(ids == WATER) * gsd_m * gsd_m < config.min_water_area_m2:
        if rgb is None or _photometric_water_m2(rgb, gsd_m, config) >= config.min_water_area_m2:
            return dets
        dist = np.full(ids.shape, np.inf, np.float32)  # no water anywhere
    else:
        # distance (px) from every pixel to the nearest water pixel
        dist = cv2.distanceTransform((ids != WATER).astype(np.uint8), cv2.DIST_L2, 3)
    far_px = config.near_water_m / gsd_m
    out = []
    for d in dets:
        if d.category not in cats:
            out.append(d)
            continue
        near = values_under_box(dist, d)
        dry = d.category == "boat" and d.score < DRY_BOAT_MAX_SCORE and near.size > 0 and near.min() > 0
        if near.size == 0 or (near.min() <= far_px and not dry):
            out.append(d)
            continue
        length_m, width_m = d.length_px * gsd_m, d.width_px * gsd_m
        paved = np.isin(values_under_box(ids, d), PAVED).mean()
        if (d.category == "boat" and config.min_vehicle_length_m <= length_m <= config.max_vehicle_length_m
                and 1.3 <= width_m <= 3.0 and paved >= 0.5):
            out.append(replace(d, category="vehicle", heading_known=False, heading_confidence=0.5))
    return out


def _photometric_water_m2(rgb: np.ndarray, gsd_m: float, config: DetectConfig) -> float:
    """Square metres of water the classical detector's colour-and-texture model finds, at its working
    resolution (``work_gsd_m``, or the image's if coarser)."""
    import cv2

    from .classical import ClassicalDetector

    work = max(gsd_m, float(config.work_gsd_m))
    s = gsd_m / work
    small = rgb if s >= 1.0 else cv2.resize(rgb, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    lab = cv2.cvtColor(np.ascontiguousarray(small), cv2.COLOR_RGB2LAB).astype(np.float32)
    water = ClassicalDetector(config).photometric_water(lab, work)
    return float(np.count_nonzero(water)) * work * work


# ----------------------------------------------------------------------------------------------- JSON

def detection_to_dict(d: Detection) -> dict:
    return {
        "category": d.category,
        "score": round(float(d.score), 4),
        "corners_px": [[round(float(c), 2), round(float(r), 2)] for c, r in d.corners_px()],
        "cx_px": round(float(d.cx_px), 3),
        "cy_px": round(float(d.cy_px), 3),
        "length_px": round(float(d.length_px), 3),
        "width_px": round(float(d.width_px), 3),
        "yaw_deg": round(float(d.yaw_deg), 3),
        "heading_known": bool(d.heading_known),
        "heading_confidence": round(float(d.heading_confidence), 3),
    }


def detections_to_json(detections: list[Detection], gsd_m: float, image_size: tuple[int, int],
                       provenance: dict | None = None) -> str:
    """The detections file: ``{"gsd_m", "image_size": [w, h], "detections": [...]}``."""
    doc: dict[str, Any] = {
        "format": JSON_FORMAT,
        "gsd_m": float(gsd_m),
        "image_size": [int(image_size[0]), int(image_size[1])],
        "detections": [detection_to_dict(d) for d in detections],
    }
    if provenance:
        doc["provenance"] = provenance
    return json.dumps(doc, indent=1) + "\n"


def _num(d: dict, key: str, i: int, where: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"{where}: detection {i} field {key!r} = {v!r} must be a finite number")
    return float(v)


def detections_from_json(text: str | bytes | Path, where: str = "detections JSON") -> tuple[list[Detection], dict]:
    """Parse a detections file (text, or a path). Returns (detections, header with gsd_m and image_size)."""
    if isinstance(text, Path):
        where = str(text)
        if not text.is_file():
            raise InputError(f"detections file {text} does not exist")
        text = text.read_text(encoding="utf-8")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where} is not valid JSON ({exc}); write it with coastforge detect") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("detections"), list):
        raise InputError(f"{where} must be an object with a 'detections' list")
    dets = []
    for i, d in enumerate(doc["detections"]):
        if not isinstance(d, dict):
            raise InputError(f"{where}: detection {i} must be an object, got {d!r}")
        cat = d.get("category")
        if cat not in DETECTION_CATEGORIES:
            raise InputError(f"{where}: detection {i} has category {cat!r}; valid: {', '.join(DETECTION_CATEGORIES)}")
        length, width = _num(d, "length_px", i, where), _num(d, "width_px", i, where)
        if length <= 0 or width <= 0:
            raise InputError(f"{where}: detection {i} has a non-positive size {length} x {width} px")
        dets.append(Detection(
            category=cat, score=_num(d, "score", i, where), cx_px=_num(d, "cx_px", i, where),
            cy_px=_num(d, "cy_px", i, where), length_px=length, width_px=width,
            yaw_deg=_num(d, "yaw_deg", i, where), heading_known=bool(d.get("heading_known", False)),
            heading_confidence=float(d.get("heading_confidence", 0.5 if d.get("heading_known") else 0.0)),
        ))
    header = {"gsd_m": doc.get("gsd_m"), "image_size": doc.get("image_size")}
    return dets, header


# -------------------------------------------------------------------------------------------- overlay

CATEGORY_COLOURS: dict[str, tuple[int, int, int]] = {  # RGB
    "boat": (255, 60, 60),
    "vehicle": (255, 220, 0),
    "pier_walkway": (0, 255, 120),
    "pier_finger": (0, 200, 255),
    "buoy": (255, 0, 255),
}


def draw_overlay(rgb: np.ndarray, detections: list[Detection], thickness: int = 1) -> np.ndarray:
    """The image with each box outlined in its category colour and an arrow toward its front
    (a plain line through the box when the heading is unknown)."""
    import cv2

    from ..frames import direction_px

    out = np.ascontiguousarray(rgb.copy())
    for d in detections:
        col = CATEGORY_COLOURS.get(d.category, (255, 255, 255))
        pts = np.round(d.corners_px() - 0.5).astype(np.int32)  # continuous coords -> pixel index
        cv2.polylines(out, [pts], True, col, thickness, cv2.LINE_AA)
        if d.category in ("boat", "vehicle"):
            fx, fy = direction_px(d.yaw_deg)
            c = np.array([d.cx_px - 0.5, d.cy_px - 0.5])
            tip = c + np.array([fx, fy]) * d.length_px * 0.5
            if d.heading_known:
                cv2.arrowedLine(out, tuple(int(round(v)) for v in c), tuple(int(round(v)) for v in tip),
                                (255, 255, 255), thickness, cv2.LINE_AA, tipLength=0.35)
            else:
                tail = c - np.array([fx, fy]) * d.length_px * 0.35
                cv2.line(out, tuple(int(round(v)) for v in tail), tuple(int(round(v)) for v in tip - (tip - c) * 0.3),
                         (160, 160, 160), thickness, cv2.LINE_AA)
    return out


def write_overlay(path: str | Path, rgb: np.ndarray, detections: list[Detection]) -> Path:
    from ..fsio import write_png

    return write_png(path, draw_overlay(rgb, detections, thickness=max(1, round(max(rgb.shape[:2]) / 1500))))


def with_mask_dropped(dets: list[Detection]) -> list[Detection]:
    """Detections without their masks (smaller to keep around)."""
    return [replace(d, mask=None, mask_origin_px=None) for d in dets]


def detect_file(image_path: str | Path, out: str | Path, gsd_m: float | None = None,
                size_m: tuple[float, float] | None = None, backend: str | None = None,
                weights: str | Path | None = None, overlay: str | Path | None = None, overwrite: bool = False,
                config=None, segment: bool = False) -> list[Detection]:
    """``coastforge detect``: read an image, detect, write the JSON (and the overlay PNG), atomically.

    ``segment``: run the configured segmenter first and give its class map to the detector, as generate does."""
    import time

    from ..config import Config
    from ..fsio import atomic_write_bytes, atomic_write_text, check_writable_file
    from ..io import read_image

    from ..errors import InputError
    from ..fsio import same_file

    cfg = config or Config()
    out = Path(out)
    if overlay is not None:
        if Path(overlay).suffix.lower() != ".png":
            raise InputError(f"--overlay {overlay} must end in .png (the overlay is written as PNG)")
        if Path(overlay).resolve() == out.resolve():
            raise InputError(f"--overlay {overlay} is the same file as --out; give the overlay PNG its own name")
    for what, p in (("--out", out), ("--overlay", overlay)):
        if p is not None and same_file(p, image_path):
            raise InputError(f"{what} {p} is the input image; write the detections to another file")
    check_writable_file(out, overwrite)
    if overlay is not None:
        check_writable_file(overlay, overwrite)
    image = read_image(image_path, gsd_m=gsd_m, size_m=size_m, config=cfg.io)
    opts: dict[str, Any] = {}
    if weights is not None:
        opts["weights"] = weights
    name = backend or cfg.detect.backend
    class_map = None
    if segment:
        from ..segmentation import segment as run_segment

        class_map = run_segment(image, cfg.segment, seed=cfg.seed)
    t0 = time.perf_counter()
    dets = detect(image, cfg.detect, class_map=class_map, backend=name, seed=cfg.seed, **opts)
    dt = time.perf_counter() - t0
    prov = {"backend": name, "seconds": round(dt, 3), "image": str(image_path),
            "segmenter": cfg.segment.backend if segment else None}
    text = detections_to_json(dets, image.grid.gsd_m, (image.grid.width_px, image.grid.height_px), prov)
    # both outputs are made in memory first, then written back to back: a failure never pairs a new JSON
    # with an old overlay
    png = None
    if overlay is not None:
        from ..fsio import png_bytes

        png = png_bytes(draw_overlay(image.rgb, dets, thickness=max(1, round(max(image.rgb.shape[:2]) / 1500))))
    if png is not None:
        atomic_write_bytes(overlay, png)
    atomic_write_text(out, text)
    return dets
