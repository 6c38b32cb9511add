"""DINOv3 embedder (the paper's choice): transformers' ``DINOv3ViTModel`` from a local folder only.

The folder holds ``config.json`` (``model_type: dinov3_vit``) and the weights (``model.safetensors``);
``preprocessor_config.json`` is used when present (``AutoImageProcessor``), else the DINOv3 defaults
(resize to the config's image size, ImageNet mean/std). Nothing is ever downloaded.

Crops are first put in a canonical pose with the default embedder's segmentation (major axis
horizontal, heavier end right), because ViT features are not rotation invariant and queries come at
any yaw. The pooled (CLS) feature is L2-normalised and concatenated with a small metric-footprint
code (DINO features do not know metres), then normalised again.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from ..errors import BackendUnavailable, InputError
from ..registry import require
from .embed import as_rgb, object_mask, rbf, unit

_VERSION = 1
_IMAGENET_MEAN = (0.485, 0.456, 0.406)
_IMAGENET_STD = (0.229, 0.224, 0.225)


def _weights_digest(folder: Path) -> str:
    """Config plus the weights' size and first/last MiB: detects another model without reading GBs."""
    h = hashlib.sha256()
    h.update((folder / "config.json").read_bytes())
    for p in sorted(folder.glob("*.safetensors")) + sorted(folder.glob("*.bin")):
        size = p.stat().st_size
        h.update(f"{p.name}:{size}".encode())
        with open(p, "rb") as fh:
            h.update(fh.read(1 << 20))
            if size > (2 << 20):
                fh.seek(-(1 << 20), 2)
                h.update(fh.read())
    return h.hexdigest()[:24]


def pose_crop(rgb: np.ndarray, mask: np.ndarray, margin: float = 0.15):
    """The crop rotated so the object's major axis is horizontal (heavier end right), cut square around
    the object with a margin; returns (square RGB, length_px, width_px, area_px)."""
    import cv2

    m8 = mask.astype(np.uint8)
    mo = cv2.moments(m8, binaryImage=True)
    h, w = mask.shape
    if mo["m00"] <= 0:
        return rgb, w, h, float(h * w)
    cx, cy = mo["m10"] / mo["m00"], mo["m01"] / mo["m00"]
    theta = 0.5 * math.degrees(math.atan2(2 * mo["mu11"], mo["mu20"] - mo["mu02"]))
    side = int(math.ceil(math.hypot(h, w))) + 2

    def rotate(a, t, interp):
        r = cv2.getRotationMatrix2D((cx, cy), t, 1.0)
        r[0, 2] += side / 2 - cx
        r[1, 2] += side / 2 - cy
        return cv2.warpAffine(a, r, (side, side), flags=interp, borderMode=cv2.BORDER_REPLICATE)

    mr = rotate(m8 * 255, theta, cv2.INTER_LINEAR) > 127
    ys, xs = np.nonzero(mr)
    if len(xs) and float(((xs - xs.mean()) ** 3).mean()) < 0:
        theta += 180.0
        mr = rotate(m8 * 255, theta, cv2.INTER_LINEAR) > 127
        ys, xs = np.nonzero(mr)
    img = rotate(rgb, theta, cv2.INTER_LINEAR)
    if not len(xs):
        return rgb, w, h, float(h * w)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    half = int(math.ceil(max(x1 - x0, y1 - y0) * (0.5 + margin)))
    mx, my = (x0 + x1) // 2, (y0 + y1) // 2
    pad = cv2.copyMakeBorder(img, half, half, half, half, cv2.BORDER_REPLICATE)
    sq = pad[my:my + 2 * half, mx:mx + 2 * half]
    return sq, int(x1 - x0), int(y1 - y0), float(mr.sum())


class Dinov3Embedder:
    """DINOv3 ViT features of pose-normalised crops + a metric-footprint code."""

    name = "dinov3"
    SIZE_DIM = 48 + 40

    def __init__(self, weights: str | Path | None = None, size_weight: float = 0.35, batch_size: int = 16):
        if weights is None:
            raise BackendUnavailable(
                "the dinov3 embedder needs --weights DIR: a local DINOv3 folder (config.json + model.safetensors, "
                "e.g. from facebook/dinov3-vits16-pretrain-lvd1689m downloaded beforehand); nothing is downloaded"
            )
        folder = Path(weights)
        cfg_path = folder / "config.json"
        if not cfg_path.is_file():
            raise BackendUnavailable(f"--weights {folder} has no config.json; give a DINOv3 model folder saved with "
                                     "save_pretrained (config.json + model.safetensors)")
        try:
            cfg = json.loads(cfg_path.read_text(encoding="utf-8"))
        except ValueError as exc:
            raise InputError(f"{cfg_path} is not valid JSON: {exc}") from exc
        if cfg.get("model_type") != "dinov3_vit":
            raise InputError(f"{cfg_path} has model_type {cfg.get('model_type')!r}; the dinov3 embedder needs a "
                             "'dinov3_vit' model (DINOv3 ViT)")
        if not (list(folder.glob("*.safetensors")) or list(folder.glob("*.bin"))):
            raise BackendUnavailable(f"--weights {folder} holds no model.safetensors; copy the weights there")
        self.folder = folder.resolve()
        self.hidden = int(cfg.get("hidden_size", 384))
        self.image_size = int(cfg.get("image_size", 224)) if not isinstance(cfg.get("image_size"), list) \
            else int(cfg["image_size"][0])
        self.size_weight = float(size_weight)
        self.batch_size = int(batch_size)
        self.dim = self.hidden + self.SIZE_DIM
        self._digest = _weights_digest(folder)
        self._model = None
        self._processor = None

    @property
    def settings(self) -> dict:
        return {"version": _VERSION, "model_type": "dinov3_vit", "hidden_size": self.hidden,
                "weights_digest": self._digest, "image_size": self.image_size, "size_weight": self.size_weight,
                "pose_normalised": True}

    def _load(self):
        if self._model is not None:
            return
        transformers = require("transformers", "dinov3", "the dinov3 embedder")
        require("torch", "dinov3", "the dinov3 embedder")
        cls = getattr(transformers, "DINOv3ViTModel", None)
        if cls is None:
            raise BackendUnavailable(f"transformers {transformers.__version__} has no DINOv3ViTModel; run: "
                                     "pip install 'coastforge[dinov3]' (transformers >= 4.56)")
        try:
            self._model = cls.from_pretrained(str(self.folder), local_files_only=True).eval()
        except (OSError, ValueError) as exc:
            raise BackendUnavailable(f"cannot load DINOv3 weights from {self.folder}: {exc}") from exc
        if (self.folder / "preprocessor_config.json").is_file():
            try:
                self._processor = transformers.AutoImageProcessor.from_pretrained(str(self.folder),
                                                                                  local_files_only=True)
            except (OSError, ValueError, ImportError):
                self._processor = None  # fall back to the documented DINOv3 defaults below

    def _pixels(self, crops: list[np.ndarray]):
        import cv2
        import torch

        if self._processor is not None:
            return self._processor(images=crops, return_tensors="pt")["pixel_values"]
        s = self.image_size
        arr = np.stack([cv2.resize(c, (s, s), interpolation=cv2.INTER_AREA if c.shape[0] > s else cv2.INTER_LINEAR)
                        for c in crops]).astype(np.float32) / 255.0
        arr = (arr - np.array(_IMAGENET_MEAN, np.float32)) / np.array(_IMAGENET_STD, np.float32)
        return torch.from_numpy(arr.transpose(0, 3, 1, 2).copy())

    def embed(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray:
        images = list(images)
        gsds = [float(g) for g in gsd_m]
        if len(gsds) != len(images):
            raise InputError(f"embed got {len(images)} images but {len(gsds)} gsd values; give one gsd per image")
        if not images:
            return np.zeros((0, self.dim), np.float32)
        self._load()
        import torch

        crops, sizes = [], []
        for i, (img, g) in enumerate(zip(images, gsds)):
            if not (g > 0 and math.isfinite(g)):
                raise InputError(f"gsd {g!r} of image {i} must be a positive number of metres per pixel")
            rgb = as_rgb(img, i)
            sq, length_px, width_px, _area = pose_crop(rgb, object_mask(rgb))
            crops.append(np.ascontiguousarray(sq))
            sizes.append(unit(np.concatenate([
                rbf(math.log(max(length_px * g, 1e-3)), math.log(0.1), math.log(400.0), 48),
                rbf(math.log(max(width_px * g, 1e-3)), math.log(0.05), math.log(80.0), 40),
            ])))
        feats = []
        with torch.inference_mode():
            for s in range(0, len(crops), self.batch_size):
                px = self._pixels(crops[s:s + self.batch_size])
                out = self._model(pixel_values=px)
                pooled = out.pooler_output if getattr(out, "pooler_output", None) is not None \
                    else out.last_hidden_state[:, 0]
                feats.append(pooled.float().cpu().numpy())
        f = np.concatenate(feats)
        f /= np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-12)
        v = np.hstack([f, self.size_weight * np.asarray(sizes, np.float32)])
        v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
        return v.astype(np.float32)
