"""The category head: a small CNN, trained on coastforge's own renders of the starter kit and shipped as
ONNX (``data/models/category.onnx``), that gives a crop's category posteriors. ``Library.search`` weighs the
embedding's category vote by them (``Library.CATEGORY_PRIOR_BETA``) when no category is given.

Input: the crop resized to ``INPUT_PX`` square (RGB / 255 - 0.5, NCHW) and two scalars, the crop's side in
metres and its GSD (logs, see ``net_scalars``): a few-pixel tuft and a boat fill the same 48 px, so the
metric scale must come separately. Trained by ``python -m coastforge.train.category_train``.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError

FORMAT = "coastforge.category_head/1"
CATEGORIES = ("boat", "buoy", "bush", "grass", "pier", "rock", "seaweed", "tree", "vehicle")
INPUT_PX = 48


def default_weights() -> Path:
    return Path(__file__).resolve().parent.parent / "data" / "models" / "category.onnx"


def net_image(img: np.ndarray) -> np.ndarray:
    """One crop (H x W x 3 uint8) at the network's size (uint8, INPUT_PX square)."""
    import cv2

    h, w = img.shape[:2]
    interp = cv2.INTER_AREA if max(h, w) > INPUT_PX else cv2.INTER_LINEAR
    return cv2.resize(np.ascontiguousarray(img[:, :, :3]), (INPUT_PX, INPUT_PX), interpolation=interp)


def net_scalars(side_m: Sequence[float], gsd_m: Sequence[float]) -> np.ndarray:
    """(N, 2) float32: log of the crop's side over 10 m and of its GSD over 0.15 m."""
    return np.stack([np.log(np.asarray(side_m, np.float64) / 10.0),
                     np.log(np.asarray(gsd_m, np.float64) / 0.15)], 1).astype(np.float32)


def net_batch(images: Sequence[np.ndarray]) -> np.ndarray:
    """(N, 3, INPUT_PX, INPUT_PX) float32 network input of uint8 images already at ``INPUT_PX``."""
    x = np.asarray(images, np.float32) / 255.0 - 0.5
    return np.ascontiguousarray(x.transpose(0, 3, 1, 2))


class CategoryHead:
    """Category posteriors of crops from the shipped (or a given) ONNX model."""

    def __init__(self, weights: str | Path | None = None):
        self.weights = Path(weights) if weights is not None else default_weights()
        meta_path = self.weights.with_suffix(".json")
        if not self.weights.is_file() or not meta_path.is_file():
            raise InputError(f"category head {self.weights} (and its .json) not found; train it with "
                             "python -m coastforge.train.category_train")
        try:
            self.meta = json.loads(meta_path.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"{meta_path} is not readable JSON ({exc})") from exc
        if self.meta.get("format") != FORMAT or tuple(self.meta.get("categories", ())) != CATEGORIES:
            raise InputError(f"{meta_path} is not a {FORMAT} file for categories {list(CATEGORIES)}")
        self._sess = None

    def _session(self):
        if self._sess is None:
            from ..registry import require

            ort = require("onnxruntime", "onnx", "the category head")
            try:
                opts = ort.SessionOptions()
                opts.intra_op_num_threads = 1  # small batches: threads only spin
                self._sess = ort.InferenceSession(str(self.weights), opts, providers=["CPUExecutionProvider"])
            except Exception as exc:  # onnxruntime has its own exception types
                raise InputError(f"{self.weights} is not a loadable ONNX model ({exc})") from exc
        return self._sess

    def posteriors(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray:
        """(N, len(CATEGORIES)) float32 probabilities, rows summing to 1."""
        images = list(images)
        gsds = [float(g) for g in gsd_m]
        if len(gsds) != len(images):
            raise InputError(f"{len(images)} images but {len(gsds)} gsd values; give one gsd per image")
        if not images:
            return np.zeros((0, len(CATEGORIES)), np.float32)
        sess = self._session()
        names = [i.name for i in sess.get_inputs()]
        sides = [max(im.shape[:2]) * g for im, g in zip(images, gsds)]
        out = []
        for i in range(0, len(images), 256):
            x = net_batch([net_image(im) for im in images[i:i + 256]])
            s = net_scalars(sides[i:i + 256], gsds[i:i + 256])
            logits = sess.run(None, {names[0]: x, names[1]: s})[0]
            e = np.exp(logits - logits.max(1, keepdims=True))
            out.append(e / e.sum(1, keepdims=True))
        return np.concatenate(out).astype(np.float32)


@functools.lru_cache(maxsize=4)
def shipped_head(weights: str | None = None) -> CategoryHead | None:
    """The shipped head, or None when its files are absent (a trimmed install)."""
    try:
        return CategoryHead(weights)
    except InputError:
        return None
