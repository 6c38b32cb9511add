"""``onnx`` terrain backend: a learned height model from local ``.onnx`` weights (never downloaded).

Inputs are NCHW float32 and recognised by their channel count: 3 = RGB in [0, 1], 8 = one-hot terrain
classes (ids 0..7), 11 = both concatenated (RGB first). A model may take one input or two (RGB and
classes). The first output is the height in metres, (N, 1, H, W) or (N, H, W). Models with a fixed
spatial size run tile by tile (overlapping, centre crops kept); dynamic ones run tiled by ``tile_px``.
By default heights are made consistent with the class map (water below 0, land above), as the
DESIGN.md §4 rules ask of every backend.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..classes import N_CLASSES, WATER
from ..config import TerrainConfig
from ..errors import BackendUnavailable, InputError
from ..registry import require
from ..types import ClassMap, GeoImage, HeightMap


class OnnxTerrain:
    name = "onnx"

    def __init__(self, config: TerrainConfig, weights: str | Path | None = None, tile_px: int = 1024,
                 overlap_px: int = 32, enforce_classes: bool = True) -> None:
        if not weights:
            raise InputError("the onnx terrain backend needs local weights: pass --weights model.onnx")
        path = Path(weights)
        if not path.is_file():
            raise InputError(f"--weights {path} does not exist; give the path of a local .onnx height model")
        ort = require("onnxruntime", "onnx", "the onnx terrain backend")
        try:
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = 2
            self.session = ort.InferenceSession(str(path), sess_options=opts,
                                                providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for bad files
            raise InputError(f"--weights {path} is not a loadable ONNX model ({exc})") from exc
        self.config = config
        self.path = path
        self.tile_px = int(tile_px)
        self.overlap_px = int(overlap_px)
        self.enforce_classes = bool(enforce_classes)
        self.inputs = []
        fixed = None
        for inp in self.session.get_inputs():
            shape = list(inp.shape)
            c = shape[1] if len(shape) > 1 else None
            channels_ok = isinstance(c, int) and c in (3, N_CLASSES, 3 + N_CLASSES)
            if len(shape) != 4 or not channels_ok:
                raise InputError(f"{path}: input {inp.name!r} has shape {shape}; expected NCHW with 3 (RGB), "
                                 f"{N_CLASSES} (one-hot classes) or {3 + N_CLASSES} channels")
            self.inputs.append((inp.name, shape[1]))
            if isinstance(shape[2], int) and isinstance(shape[3], int):
                fixed = (shape[2], shape[3])
        self.fixed = fixed
        self.needs_rgb = any(c in (3, 3 + N_CLASSES) for _n, c in self.inputs)

    def _feeds(self, onehot: np.ndarray, rgb: np.ndarray | None) -> dict:
        feeds = {}
        for name, c in self.inputs:
            if c == N_CLASSES:
                feeds[name] = onehot
            elif c == 3:
                feeds[name] = rgb
            else:
                feeds[name] = np.concatenate([rgb, onehot], axis=1)
        return feeds

    def _run(self, onehot: np.ndarray, rgb: np.ndarray | None) -> np.ndarray:
        out = self.session.run(None, self._feeds(onehot, rgb))[0]
        out = np.asarray(out, dtype=np.float32)
        if out.ndim == 4:
            out = out[:, 0]
        if out.ndim != 3 or out.shape[1:] != onehot.shape[2:]:
            raise InputError(f"{self.path}: output shape {out.shape} does not match the input tile "
                             f"{onehot.shape[2:]}; expected (N, 1, H, W) heights")
        return out[0]

    def estimate(self, class_map: ClassMap, image: GeoImage | None, seed: int) -> HeightMap:
        ids = np.asarray(class_map.ids)
        h, w = ids.shape
        if self.needs_rgb and image is None:
            raise BackendUnavailable(f"the ONNX model {self.path} takes RGB input; "
                                     "pass the image (--image FILE)")
        onehot = np.zeros((1, N_CLASSES, h, w), np.float32)
        np.put_along_axis(onehot[0], ids[None].astype(np.intp), 1.0, axis=0)
        rgb = None
        if image is not None:
            rgb = np.ascontiguousarray(np.moveaxis(image.rgb.astype(np.float32) / 255.0, -1, 0)[None])
        th, tw = self.fixed or (min(self.tile_px, h), min(self.tile_px, w))
        z = self._run(onehot, rgb) if (th, tw) == (h, w) else self._tiled(onehot, rgb, th, tw)
        if self.enforce_classes:
            water = ids == WATER
            z = np.where(water, np.minimum(z, -0.01), np.maximum(z, 0.01))
        return HeightMap(z_m=z.astype(np.float32), grid=class_map.grid)

    def _tiled(self, onehot, rgb, th: int, tw: int) -> np.ndarray:
        """Run overlapping tiles (edge-padded to the tile size) and keep each tile's centre."""
        _, _, h, w = onehot.shape
        o = min(self.overlap_px, th // 4, tw // 4)
        ph, pw = max(h, th), max(w, tw)
        pad = ((0, 0), (0, 0), (0, ph - h), (0, pw - w))
        onehot_p = np.pad(onehot, pad, mode="edge")
        rgb_p = np.pad(rgb, pad, mode="edge") if rgb is not None else None
        out = np.zeros((ph, pw), np.float32)
        sy, sx = th - 2 * o, tw - 2 * o
        ys = list(range(0, max(ph - th, 0) + 1, max(sy, 1)))
        xs = list(range(0, max(pw - tw, 0) + 1, max(sx, 1)))
        if ys[-1] != ph - th:
            ys.append(ph - th)
        if xs[-1] != pw - tw:
            xs.append(pw - tw)
        for y in ys:
            for x in xs:
                win = (slice(None), slice(None), slice(y, y + th), slice(x, x + tw))
                t = self._run(onehot_p[win], rgb_p[win] if rgb_p is not None else None)
                # keep the centre, except at the image edges where the tile's edge is the image's edge
                y0 = 0 if y == 0 else o
                x0 = 0 if x == 0 else o
                out[y + y0:y + th, x + x0:x + tw] = t[y0:, x0:]
        return out[:h, :w]
