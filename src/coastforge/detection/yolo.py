"""ultralytics YOLO-OBB from a local ``.pt``: sliced inference with overlap, rotated NMS across slices.

Class names of the model are mapped to our categories (``DEFAULT_CLASS_MAP`` covers DOTA: ship → boat,
small/large vehicle → vehicle, harbor → pier_walkway); unmapped classes are dropped. YOLO gives no
bow/stern, so the front is decided afterwards from the silhouette inside each box (``heading.py``).
Nothing is downloaded: the weights path must exist and ultralytics runs with ``YOLO_OFFLINE=1``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any
from collections.abc import Iterable

import numpy as np

from ..config import DetectConfig
from ..errors import BackendUnavailable, InputError
from ..frames import yaw_from_direction_px
from ..types import ClassMap, Detection, GeoImage
from . import heading as hd
from .nms import rotated_nms

DEFAULT_CLASS_MAP: dict[str, str] = {
    "ship": "boat",
    "boat": "boat",
    "vessel": "boat",
    "small vehicle": "vehicle",
    "large vehicle": "vehicle",
    "small-vehicle": "vehicle",
    "large-vehicle": "vehicle",
    "car": "vehicle",
    "vehicle": "vehicle",
    "harbor": "pier_walkway",
    "pier": "pier_walkway",
    "pier_walkway": "pier_walkway",
    "pier_finger": "pier_finger",
    "buoy": "buoy",
}


def slice_windows(width: int, height: int, slice_px: int, overlap_px: int) -> list[tuple[int, int, int, int]]:
    """(col0, row0, col1, row1) windows of at most ``slice_px`` covering the image with ``overlap_px``."""
    if slice_px <= overlap_px:
        raise InputError(f"detect.slice_px {slice_px} must be larger than detect.slice_overlap_px {overlap_px}")

    def starts(n: int) -> list[int]:
        if n <= slice_px:
            return [0]
        step = slice_px - overlap_px
        s = list(range(0, n - slice_px, step)) + [n - slice_px]
        return sorted(set(s))

    return [(c, r, min(c + slice_px, width), min(r + slice_px, height))
            for r in starts(height) for c in starts(width)]


def box_from_xywhr(cx: float, cy: float, w: float, h: float, r: float) -> tuple[float, float, float, float]:
    """ultralytics xywhr (side ``w`` along image direction (cos r, sin r), rows down) → (cx, cy, length,
    width, axis yaw in degrees): the long side is the length."""
    dc, dr = np.cos(r), np.sin(r)
    if h > w:
        w, h = h, w
        dc, dr = -dr, dc  # the other side is perpendicular
    return cx, cy, float(w), float(h), float(yaw_from_direction_px(dc, dr))


def map_class(name: str, mapping: dict[str, str]) -> str | None:
    return mapping.get(name) or mapping.get(name.lower()) or mapping.get(name.lower().replace("_", " "))


def results_to_detections(result: Any, names: dict[int, str], mapping: dict[str, str], offset: tuple[int, int],
                          min_score: float) -> list[Detection]:
    """One ultralytics ``Results`` (with ``.obb``: ``xywhr``, ``conf``, ``cls``) → our detections."""
    obb = getattr(result, "obb", None)
    if obb is None or len(obb) == 0:
        return []

    def arr(x):
        return np.asarray(x.cpu().numpy() if hasattr(x, "cpu") else x, dtype=np.float64)

    xywhr, conf, cls = arr(obb.xywhr), arr(obb.conf), arr(obb.cls).astype(int)
    out = []
    for (cx, cy, w, h, r), s, c in zip(xywhr, conf, cls):
        cat = map_class(str(names.get(int(c), c)), mapping)
        if cat is None or s < min_score or w <= 0 or h <= 0:
            continue
        cx, cy, length, width, yaw = box_from_xywhr(cx + offset[0], cy + offset[1], w, h, r)
        out.append(Detection(cat, float(s), cx, cy, length, width, yaw))
    return out


class YoloDetector:
    """YOLO-OBB from ``weights`` (a local .pt). ``names_map``: model class name → our category
    (added to ``DEFAULT_CLASS_MAP``)."""

    def __init__(self, config: DetectConfig | None = None, weights: str | os.PathLike | None = None,
                 names_map: dict[str, str] | None = None, imgsz: int | None = None, model: Any = None, **_opts):
        self.config = config or DetectConfig()
        self.mapping = dict(DEFAULT_CLASS_MAP)
        if names_map:
            self.mapping.update(names_map)
        self.imgsz = imgsz
        self._model = model  # an already-built model (tests); else loaded from weights on first use
        if model is None:
            if weights is None:
                raise BackendUnavailable(
                    "the yolo detect backend needs local YOLO-OBB weights; pass --weights model.pt "
                    "(nothing is downloaded)")
            p = Path(weights)
            if not p.is_file():
                raise InputError(f"YOLO weights {p} do not exist; pass the path of a local .pt file with --weights")
            self.weights = p

    def _load(self):
        if self._model is not None:
            return self._model
        os.environ.setdefault("YOLO_OFFLINE", "1")  # never reach the network from ultralytics
        from ..registry import require

        ul = require("ultralytics", "yolo", "the yolo detect backend")
        try:
            self._model = ul.YOLO(str(self.weights), task="obb")
        except Exception as exc:  # corrupted or non-YOLO files
            raise InputError(f"cannot load YOLO weights {self.weights}: {exc}") from exc
        return self._model

    def _names(self, model) -> dict[int, str]:
        names = getattr(model, "names", None) or {}
        return dict(names) if isinstance(names, dict) else dict(enumerate(names))

    def predict_windows(self, rgb: np.ndarray, windows: Iterable[tuple[int, int, int, int]]) -> list[Detection]:
        model = self._load()
        names = self._names(model)
        dets: list[Detection] = []
        for c0, r0, c1, r1 in windows:
            tile = np.ascontiguousarray(rgb[r0:r1, c0:c1, ::-1])  # ultralytics takes BGR arrays
            imgsz = self.imgsz or int(max(32, int(np.ceil(max(r1 - r0, c1 - c0) / 32.0)) * 32))
            res = model.predict(tile, imgsz=imgsz, conf=self.config.min_score, verbose=False)
            for r in res:
                dets += results_to_detections(r, names, self.mapping, (c0, r0), self.config.min_score)
        return dets

    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0) -> list[Detection]:
        rgb = image.rgb
        h, w = rgb.shape[:2]
        wins = slice_windows(w, h, self.config.slice_px, self.config.slice_overlap_px)
        dets = self.predict_windows(rgb, wins)
        dets = rotated_nms(dets, self.config.nms_iou, class_aware=True, ioa_threshold=0.8)
        return [hd.resolve_heading(rgb, d) for d in dets]
