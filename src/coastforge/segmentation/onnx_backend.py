"""Any ONNX segmentation model: image in, logits (1, C, h, w) out, argmax, model classes → our ids.

The mapping file (JSON/TOML, optional when the model has exactly our 8 classes in our order)::

    {"classes": {"0": "water", "1": "asphalt", "2": "grass", ...},   # model class index → our class
     "default": "dirt",                   # optional: model classes not listed
     "mean": [0.485, 0.456, 0.406], "std": [0.229, 0.224, 0.225],   # optional input normalisation
     "input_size": [512, 512]}            # optional, for models with a dynamic input size

Input: float32 RGB scaled to 0..1, normalised by ``mean``/``std`` (default: none), NCHW. A model with a
fixed input size sees the image resized to it; otherwise the image is resized so its longer side is
at most ``max_side`` (default 1024) and both sides are multiples of 32.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np

from ..classes import N_CLASSES
from ..config import SegmentConfig
from ..errors import BackendUnavailable, InputError
from ..registry import require
from ..types import ClassMap, GeoImage
from .labels import class_id

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def _read_spec(mapping) -> dict:
    if mapping is None:
        return {}
    if isinstance(mapping, dict):
        return mapping
    p = Path(mapping)
    if not p.is_file():
        raise InputError(f"mapping file {p} does not exist; pass the model's class mapping with --mapping")
    text = p.read_text(encoding="utf-8")
    try:
        return tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"mapping file {p} is not valid: {exc}") from exc


class OnnxSegmenter:
    """Run a local ``.onnx`` segmentation model with onnxruntime (CPU)."""

    def __init__(self, config: SegmentConfig | None = None, weights: str | Path | None = None,
                 mapping: str | Path | dict | None = None, max_side: int = 1024, **options):
        if options:
            raise InputError(f"the onnx segmenter takes weights=, mapping=, max_side=, not {', '.join(sorted(options))}")
        if weights is None:
            raise InputError("the onnx backend needs --weights model.onnx (a local segmentation model)")
        self.config = config or SegmentConfig()
        self.weights = Path(weights)
        if not self.weights.is_file():
            raise InputError(f"ONNX model {self.weights} does not exist; pass a local .onnx file with --weights")
        self.spec = _read_spec(mapping)
        self.max_side = int(max_side)

    def _session(self):
        ort = require("onnxruntime", "onnx", "the onnx segmenter")
        try:
            return ort.InferenceSession(str(self.weights), providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for bad files
            raise InputError(f"{self.weights} is not a loadable ONNX model ({exc})") from exc

    def _lut(self, n_out: int) -> np.ndarray:
        table = self.spec.get("classes")
        default = self.spec.get("default")
        if table is None:
            if n_out == N_CLASSES:
                return np.arange(N_CLASSES, dtype=np.int16)
            raise InputError(
                f"ONNX model {self.weights} outputs {n_out} classes; pass --mapping with a \"classes\" table "
                "from model class index to our class names"
            )
        lut = np.full(n_out, -1, np.int16)
        for k, v in table.items():
            try:
                i = int(k)
            except ValueError:
                raise InputError(f"mapping key {k!r} must be a model class index (0..{n_out - 1})") from None
            if not 0 <= i < n_out:
                raise InputError(f"mapping key {i} is outside the model's {n_out} output classes (0..{n_out - 1})")
            lut[i] = class_id(v, f"mapping [{k}]")
        if default is not None:
            lut[lut < 0] = class_id(default, "mapping default")
        return lut

    def segment(self, image: GeoImage, seed: int = 0) -> ClassMap:
        sess = self._session()
        inp = sess.get_inputs()[0]
        shape = list(inp.shape)
        if len(shape) != 4:
            raise InputError(f"ONNX model {self.weights} input {inp.name} has shape {shape}; expected (1, 3, H, W)")
        H, W = image.grid.shape
        fixed = self.spec.get("input_size")
        if isinstance(shape[2], int) and isinstance(shape[3], int) and shape[2] > 0 and shape[3] > 0:
            h, w = shape[2], shape[3]
        elif fixed:
            h, w = int(fixed[0]), int(fixed[1])
        else:
            s = min(1.0, self.max_side / max(H, W))
            h, w = max(32, int(round(H * s / 32)) * 32), max(32, int(round(W * s / 32)) * 32)
        x = cv2.resize(image.rgb, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
        mean, std = self.spec.get("mean"), self.spec.get("std")
        if mean is not None:
            x = x - np.asarray(mean, np.float32)
        if std is not None:
            x = x / np.asarray(std, np.float32)
        x = np.ascontiguousarray(x.transpose(2, 0, 1)[None])
        try:
            out = sess.run(None, {inp.name: x})[0]
        except Exception as exc:
            raise BackendUnavailable(f"ONNX model {self.weights} failed to run on a {w}x{h} input ({exc})") from exc
        out = np.asarray(out)
        if out.ndim != 4 or out.shape[0] != 1:
            raise InputError(f"ONNX model {self.weights} output has shape {out.shape}; expected logits (1, C, H, W)")
        arg = out[0].argmax(axis=0)
        lut = self._lut(out.shape[1])
        used = np.unique(arg)
        bad = [int(u) for u in used if lut[u] < 0]
        if bad:
            raise InputError(
                f"ONNX model {self.weights} predicts class index(es) {', '.join(map(str, bad))} that the mapping does "
                "not list; add them to \"classes\" (or set \"default\")"
            )
        ids = lut[arg].astype(np.uint8)
        if ids.shape != (H, W):
            ids = cv2.resize(ids, (W, H), interpolation=cv2.INTER_NEAREST)
        return ClassMap(ids=ids, grid=image.grid)
