"""The pier-deck network: where an image shows a pier's deck (walkways and fingers), as a probability per pixel.

The classical pier detector finds walkways and fingers as long thin runs of a "structure over water" mask made
by colour thresholds; a deck whose colour is close to the water's, or darker (dark timber), falls out of it, and
a boat moored alongside merges with the deck into a blob too wide to be one. This network (the segmenter's small
U-Net with one output, ``coastforge.train.pier_train``, renders only) marks decks apart from the boats on them;
``ClassicalDetector`` adds its decks to the structure mask the line openings search (``detect.pier_net``).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..registry import require

TILE_PX, OVERLAP_PX = 768, 48
# images coarser than this go without the network unless its card says otherwise (``max_gsd_m``): one trained
# on 0.08-0.35 m/px renders sees a coarser image upsampled several times, its decks a few pixels wide
DEFAULT_MAX_GSD_M = 0.4
FORMAT = "coastforge.pier_net/1"


def default_weights() -> Path:
    return Path(__file__).resolve().parent.parent / "data" / "models" / "piers.onnx"


class PierNet:
    """Deck probabilities from an exported ``piers.onnx`` (its card beside it gives the working GSD)."""

    def __init__(self, weights: str | Path | None = None):
        self.weights = Path(weights) if weights is not None else default_weights()
        if not self.weights.is_file():
            raise InputError(f"pier-deck network {self.weights} not found; train one with "
                             "python -m coastforge.train.pier_train, or set detect.pier_net = false")
        card = self.weights.with_suffix(".json")
        # max_gsd_m: the coarsest image it is meant for (a card without it: trained on 0.08-0.35 m/px renders)
        self.meta = {"work_gsd_m": 0.2, "multiple": 16, "max_gsd_m": DEFAULT_MAX_GSD_M}
        if card.is_file():
            try:
                doc = json.loads(card.read_text(encoding="utf-8"))
            except json.JSONDecodeError as exc:
                raise InputError(f"pier-deck network card {card} is not valid JSON ({exc})") from exc
            if doc.get("format") != FORMAT:
                raise InputError(f"{card} has format {doc.get('format')!r}, not {FORMAT!r}: not a pier-deck card")
            self.meta.update({k: doc[k] for k in ("work_gsd_m", "multiple", "max_gsd_m") if k in doc})
            for k in ("work_gsd_m", "max_gsd_m"):
                v = self.meta[k]
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
                    raise InputError(f"{card}: {k} is {v!r}; expected a positive number of metres per pixel")
        ort = require("onnxruntime", "onnx", "the pier-deck network")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 2
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self.session = ort.InferenceSession(str(self.weights), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime has its own exception types
            raise InputError(f"{self.weights} is not a loadable ONNX model ({exc})") from exc
        self.input = self.session.get_inputs()[0].name

    @property
    def max_gsd_m(self) -> float:
        return float(self.meta["max_gsd_m"])

    def probability_small(self, rgb: np.ndarray) -> np.ndarray:
        """Deck probability (h, w) float32 of an RGB uint8 image already at the working GSD."""
        from ..segmentation.learned import tiled_logits

        def run(x: np.ndarray) -> np.ndarray:
            res = self.session.run(None, {self.input: x})[0]
            if res.ndim != 4 or res.shape[1] != 1:
                raise InputError(f"{self.weights} outputs shape {res.shape}; expected (1, 1, H, W)")
            return res

        out = tiled_logits(rgb, run, 1, TILE_PX, OVERLAP_PX, int(self.meta["multiple"]))[..., 0]
        return (1.0 / (1.0 + np.exp(-np.clip(out, -30, 30)))).astype(np.float32)

    def probability(self, rgb: np.ndarray, gsd_m: float, shape: tuple[int, int]) -> np.ndarray:
        """Deck probability of an image at ``gsd_m`` on a grid of ``shape`` (rows, cols) covering the same area."""
        work = float(self.meta["work_gsd_m"])
        h, w = rgb.shape[:2]
        s = gsd_m / work
        nw, nh = max(16, int(round(w * s))), max(16, int(round(h * s)))
        small = rgb if (nw, nh) == (w, h) else cv2.resize(
            rgb, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        p = self.probability_small(np.ascontiguousarray(small))
        if p.shape != tuple(shape):
            p = cv2.resize(p, (shape[1], shape[0]), interpolation=cv2.INTER_LINEAR)
        return p
