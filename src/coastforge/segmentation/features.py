"""What the classical segmenter sees of an image: colour (CIE Lab, saturation, excess green, blue
dominance) and texture at two metric scales, averaged context, and the raster helpers its rules share."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# fine texture: std of L* over ~FINE_TEX_M measured on the image itself (the working raster is ~0.4 m/px,
# where a riprap's 0.3-1 m stones average out), then averaged onto the working grid; a classifier feature,
# and paths and pavements are smooth at that scale (marina photo: sidewalk median 1.8, riprap 5.1)
FINE_TEX_M = 0.6


def odd_px(n: float) -> int:
    """``n`` rounded to an odd window size in pixels, at least 3."""
    k = max(3, int(round(n)))
    return k if k % 2 else k + 1


def box_std(x: np.ndarray, k: int) -> np.ndarray:
    m = cv2.blur(x, (k, k))
    sq = cv2.blur(x * x, (k, k))
    return np.sqrt(np.maximum(sq - m * m, 0.0))


@dataclass(frozen=True, eq=False)
class Features:
    """Per-pixel features at the working resolution (float32 arrays, H x W)."""

    L: np.ndarray  # CIE lightness 0..100
    a: np.ndarray  # green (-) .. red (+)
    b: np.ndarray  # blue (-) .. yellow (+)
    sat: np.ndarray  # HSV saturation 0..1
    exg: np.ndarray  # excess green on chromatic coordinates
    bdom: np.ndarray  # blue minus max(red, green), 0..1 units
    tex1: np.ndarray  # std of L over ~1.2 m
    tex2: np.ndarray  # std of L over ~4 m
    grad: np.ndarray  # mean gradient magnitude over ~1.2 m
    bright: np.ndarray  # share of bright pixels (L > 62) within ~3 m: car roofs, decks, not canopies
    coh: np.ndarray  # gradient coherence over ~2 m: 1 at straight edges, low in isotropic texture (canopies)
    ctx: np.ndarray  # (H, W, 4) L, a, b, tex1 averaged over ~8 m
    exg_m: np.ndarray  # excess green of the mean RGB over ~3 m (bright pixels weigh more than dark ones)
    gsd_m: float
    fine: np.ndarray | None = None  # std of L over ~FINE_TEX_M at the image's resolution (None: not finer)

    def stack(self) -> np.ndarray:
        """(H*W, F) matrix for the classifier."""
        # texture is heavy-tailed: its logarithm suits the Gaussian class models far better
        lg = np.log1p
        cols = [self.L, self.a, self.b, self.sat, self.exg, self.bdom, lg(self.tex1), lg(self.tex2), lg(self.grad),
                self.bright, self.coh, self.ctx[..., 0], self.ctx[..., 1], self.ctx[..., 2], lg(self.ctx[..., 3])]
        if self.fine is not None:
            cols.append(lg(self.fine))
        return np.stack([c.ravel() for c in cols], axis=1).astype(np.float32)


def outline_share(lab: np.ndarray, n: int, hit: np.ndarray, radius_px: int = 1) -> np.ndarray:
    """Per label of ``lab`` (``n`` labels, 0 = background), the share of its outline (background pixels
    within ``radius_px``, square neighbourhood) where ``hit`` holds."""
    k = 2 * radius_px + 1
    lab_d = cv2.dilate(lab.astype(np.float32), np.ones((k, k), np.uint8)).astype(np.int32)
    ring = (lab_d > 0) & (lab == 0)
    ring_n = np.bincount(lab_d[ring], minlength=n).astype(np.float64)
    ring_h = np.bincount(lab_d[ring & hit], minlength=n).astype(np.float64)
    return ring_h / np.maximum(ring_n, 1.0)


def labels_in(lab: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """``np.isin(lab, ids)`` for labels in [0, n), by a lookup table (several times faster)."""
    table = np.zeros(n, bool)
    table[ids] = True
    return table[lab]


def fine_texture(rgb: np.ndarray, gsd_m: float, shape: tuple[int, int]) -> np.ndarray:
    """Std of L* over ~``FINE_TEX_M`` on ``rgb`` (the full-resolution image), averaged onto a grid of
    ``shape`` (H, W): texture the working raster is too coarse to show (riprap's stones, a verge's tufts)."""
    # 8-bit Lab (L* x 255/100) is several times faster on a large image than float Lab, and its 0.4-unit
    # steps are far below the texture that matters here
    L = cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)[..., 0].astype(np.float32) * (100.0 / 255.0)
    t = box_std(L, odd_px(FINE_TEX_M / gsd_m))
    h, w = shape
    return t if t.shape == (h, w) else cv2.resize(t, (w, h), interpolation=cv2.INTER_AREA)


def compute_features(rgb: np.ndarray, gsd_m: float, fine: np.ndarray | None = None) -> Features:
    """Features of ``rgb`` at ``gsd_m``; ``fine``: ``fine_texture`` of the full-resolution image, when
    ``rgb`` is a downsampled copy."""
    f = rgb.astype(np.float32) * (1.0 / 255.0)
    lab = cv2.cvtColor(f, cv2.COLOR_RGB2LAB)
    L, a, b = lab[..., 0], lab[..., 1], lab[..., 2]
    # channel by channel (speed: numpy's reductions over a short last axis are slow), same values
    r, g, b_ = f[..., 0], f[..., 1], f[..., 2]
    mx, mn = np.maximum(np.maximum(r, g), b_), np.minimum(np.minimum(r, g), b_)
    sat = (mx - mn) / (mx + 1e-3)
    s = (r + g) + b_ + 1e-3  # f.sum(axis=2) adds in this order
    exg = (2.0 * f[..., 1] - f[..., 0] - f[..., 2]) / s
    bdom = f[..., 2] - np.maximum(f[..., 0], f[..., 1])
    k1, k2, kc = odd_px(1.2 / gsd_m), odd_px(4.0 / gsd_m), odd_px(8.0 / gsd_m)
    tex1 = box_std(L, k1)
    tex2 = box_std(L, k2)
    gx = cv2.Sobel(L, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(L, cv2.CV_32F, 0, 1, ksize=3)
    grad = cv2.blur(np.sqrt(gx * gx + gy * gy), (k1, k1))
    ctx = cv2.blur(np.dstack([L, a, b, tex1]), (kc, kc))
    kb = odd_px(3.0 / gsd_m)
    bright = cv2.blur((L > 62.0).astype(np.float32), (kb, kb))
    kh = odd_px(2.0 / gsd_m)
    jxx, jyy, jxy = (cv2.blur(v, (kh, kh)) for v in (gx * gx, gy * gy, gx * gy))
    coh = np.sqrt((jxx - jyy) ** 2 + 4.0 * jxy * jxy) / (jxx + jyy + 1e-3)
    k3 = odd_px(3.0 / gsd_m)
    fm = cv2.blur(f, (k3, k3))
    exg_m = (2.0 * fm[..., 1] - fm[..., 0] - fm[..., 2]) / (fm.sum(axis=2) + 1e-3)
    return Features(L, a, b, sat, exg, bdom, tex1, tex2, grad, bright, coh, ctx, exg_m, gsd_m, fine)


# ---------------------------------------------------------------------------------------------- water


def disk(radius_px: float) -> np.ndarray:
    r = max(1, int(round(radius_px)))
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
