"""An oriented-box detector exported to ONNX, run with onnxruntime on the CPU, sliced like ``yolo``.

Expected model (document for exporters):
- one input, float32 ``(1, 3, H, W)``, RGB scaled to [0, 1]. A fixed H, W is honoured (each slice is
  letterboxed into it, padding grey 114); a dynamic one uses the slice size rounded up to 32.
- one output in either layout:
  * ``rows``: ``(1, N, 7)`` or ``(N, 7)``: ``cx, cy, w, h, angle_rad, score, class_id`` in input pixels,
    already NMS-ed; the side ``w`` points along image direction ``(cos a, sin a)`` with rows down
    (the ultralytics xywhr convention);
  * ``ultralytics``: ``(1, 4 + nc + 1, A)`` raw anchors ``cx, cy, w, h, score_0..score_nc-1, angle``
    (``yolo export format=onnx`` of an OBB model); the best class is taken and rotated NMS applied here.
- class names from the model metadata ``names`` (a dict literal as ultralytics writes it) or the
  ``class_names`` option; they are mapped to our categories as in the yolo backend.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import numpy as np

from ..config import DetectConfig
from ..errors import BackendUnavailable, InputError
from ..types import ClassMap, Detection, GeoImage
from . import heading as hd
from .nms import rotated_nms
from .yolo import DEFAULT_CLASS_MAP, box_from_xywhr, map_class, slice_windows


def _letterbox(tile: np.ndarray, in_h: int, in_w: int) -> tuple[np.ndarray, float]:
    import cv2

    h, w = tile.shape[:2]
    s = min(in_w / w, in_h / h)
    nw, nh = max(1, int(round(w * s))), max(1, int(round(h * s)))
    out = np.full((in_h, in_w, 3), 114, np.uint8)
    out[:nh, :nw] = cv2.resize(tile, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    return out, s


def decode_output(out: np.ndarray, n_names: int | None = None) -> np.ndarray:
    """Either output layout → rows ``(N, 7)``: cx, cy, w, h, angle, score, class_id."""
    a = np.asarray(out, dtype=np.float32)
    if a.ndim == 3 and a.shape[0] == 1:
        a = a[0]
    if a.ndim != 2:
        raise InputError(f"ONNX detector output has shape {out.shape}; expected (1, N, 7) rows or (1, 5+nc, A)")
    if a.shape[1] == 7 and not (n_names and a.shape[0] == 5 + n_names):
        return a
    # ultralytics raw: (4 + nc + 1, A)
    if a.shape[0] < 6:
        raise InputError(f"ONNX detector output has shape {out.shape}; expected (1, N, 7) rows or (1, 5+nc, A)")
    nc = a.shape[0] - 5
    scores = a[4:4 + nc]
    cls = scores.argmax(0)
    conf = scores.max(0)
    return np.stack([a[0], a[1], a[2], a[3], a[4 + nc], conf, cls.astype(np.float32)], 1)


class OnnxDetector:
    """ONNX oriented-box detector from ``weights`` (a local .onnx)."""

    def __init__(self, config: DetectConfig | None = None, weights: str | os.PathLike | None = None,
                 class_names: list[str] | dict[int, str] | None = None, names_map: dict[str, str] | None = None,
                 **_opts):
        self.config = config or DetectConfig()
        if weights is None:
            raise BackendUnavailable("the onnx detect backend needs a model; pass --weights model.onnx")
        p = Path(weights)
        if not p.is_file():
            raise InputError(f"ONNX model {p} does not exist; pass the path of a local .onnx file with --weights")
        from ..registry import require

        ort = require("onnxruntime", "onnx", "the onnx detect backend")
        try:
            self.session = ort.InferenceSession(str(p), providers=["CPUExecutionProvider"])
        except Exception as exc:
            raise InputError(f"cannot load ONNX model {p}: {exc}") from exc
        self.mapping = dict(DEFAULT_CLASS_MAP)
        if names_map:
            self.mapping.update(names_map)
        self.names = self._names(class_names)
        inp = self.session.get_inputs()[0]
        self.input_name = inp.name
        shp = inp.shape
        if len(shp) != 4:
            raise InputError(f"ONNX model {p} input {inp.name} has shape {shp}; expected (1, 3, H, W)")
        self.fixed_hw = (shp[2], shp[3]) if all(isinstance(v, int) and v > 0 for v in shp[2:]) else None

    def _names(self, class_names) -> dict[int, str]:
        if class_names is not None:
            if isinstance(class_names, dict):
                return {int(k): str(v) for k, v in class_names.items()}
            return {i: str(n) for i, n in enumerate(class_names)}
        meta = self.session.get_modelmeta().custom_metadata_map
        raw = meta.get("names")
        if raw:
            try:
                v = ast.literal_eval(raw)
                if isinstance(v, dict):
                    return {int(k): str(n) for k, n in v.items()}
                if isinstance(v, (list, tuple)):
                    return {i: str(n) for i, n in enumerate(v)}
            except (ValueError, SyntaxError):
                pass
        raise InputError("the ONNX model has no 'names' metadata; pass class_names=[...] (index order)")

    def run_tile(self, tile: np.ndarray) -> np.ndarray:
        """Rows (N, 7) in tile pixels."""
        h, w = tile.shape[:2]
        if self.fixed_hw:
            in_h, in_w = self.fixed_hw
        else:
            in_h, in_w = int(np.ceil(h / 32) * 32), int(np.ceil(w / 32) * 32)
        lb, s = _letterbox(tile, in_h, in_w)
        x = (lb.astype(np.float32) / 255.0).transpose(2, 0, 1)[None]
        out = self.session.run(None, {self.input_name: x})[0]
        rows = decode_output(out, len(self.names)).copy()
        rows[:, :4] /= s
        return rows

    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0) -> list[Detection]:
        rgb = image.rgb
        h, w = rgb.shape[:2]
        dets: list[Detection] = []
        for c0, r0, c1, r1 in slice_windows(w, h, self.config.slice_px, self.config.slice_overlap_px):
            rows = self.run_tile(np.ascontiguousarray(rgb[r0:r1, c0:c1]))
            for cx, cy, bw, bh, ang, score, cid in rows:
                if score < self.config.min_score or bw <= 0 or bh <= 0:
                    continue
                cat = map_class(self.names.get(int(cid), str(int(cid))), self.mapping)
                if cat is None:
                    continue
                cx, cy, length, width, yaw = box_from_xywhr(cx + c0, cy + r0, bw, bh, ang)
                dets.append(Detection(cat, float(score), cx, cy, length, width, yaw))
        dets = rotated_nms(dets, self.config.nms_iou, class_aware=True, ioa_threshold=0.8)
        return [hd.resolve_heading(rgb, d) for d in dets]
