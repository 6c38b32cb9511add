"""A box's pixels for the checks after detection: rotation-normalised crops of the image in Lab (one
conversion per image, ``LabCache``), and the colour modes of the background around a box."""

from __future__ import annotations

import math

import numpy as np

from ..types import Detection


def _to_lab(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)


class LabCache:
    """An RGB image whose Lab is converted block by block as ``lab_window`` asks for it, each pixel
    once: the checks of ``refine_boxes`` look at several overlapping windows around every box (speed).
    The conversion is per pixel, so the windows are the same as converting each on its own. Pass it
    wherever these functions take ``rgb`` (read-only views are returned: do not write into them)."""

    BLOCK = 32
    MAX_PIXELS = 40_000_000  # larger images (a 0.5 GB float cache) convert each window on its own

    def __init__(self, rgb: np.ndarray):
        self.rgb = rgb
        self.shape = rgb.shape
        h, w = rgb.shape[:2]
        self.lab = np.empty((h, w, 3), np.float32) if h * w <= self.MAX_PIXELS else None
        b = self.BLOCK
        self.done = np.zeros((-(-h // b), -(-w // b)), bool)

    def window(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        if self.lab is None:
            return _to_lab(self.rgb[r0:r1, c0:c1])
        b = self.BLOCK
        h, w = self.shape[:2]
        br0, bc0 = r0 // b, c0 // b
        todo = ~self.done[br0:-(-r1 // b), bc0:-(-c1 // b)]
        for i in np.nonzero(todo.any(1))[0]:  # each row of blocks: from its first to its last missing one
            js = np.nonzero(todo[i])[0]
            ra, rb = (br0 + i) * b, min(h, (br0 + i + 1) * b)
            ca, cb = (bc0 + js[0]) * b, min(w, (bc0 + js[-1] + 1) * b)
            self.lab[ra:rb, ca:cb] = _to_lab(self.rgb[ra:rb, ca:cb])
            self.done[br0 + i, bc0 + js[0]:bc0 + js[-1] + 1] = True
        v = self.lab[r0:r1, c0:c1]
        v.flags.writeable = False
        return v


def lab_window(rgb: np.ndarray | LabCache, cx: float, cy: float,
                reach: float) -> tuple[np.ndarray, tuple[int, int]]:
    """The Lab (float32, L 0-100) window of ``rgb`` (or of a ``LabCache``) within ``reach`` pixels of
    (cx, cy), and its origin."""
    h, w = rgb.shape[:2]
    c0, r0 = max(0, int(cx - reach)), max(0, int(cy - reach))
    c1, r1 = min(w, int(cx + reach) + 2), min(h, int(cy + reach) + 2)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return np.zeros((2, 2, 3), np.float32), (c0, r0)
    if isinstance(rgb, LabCache):
        return rgb.window(r0, r1, c0, c1), (c0, r0)
    return _to_lab(rgb[r0:r1, c0:c1]), (c0, r0)


def crop_box(win: tuple[np.ndarray, tuple[int, int]], cx: float, cy: float, yaw_deg: float, half_u: float,
          half_v: float, scale: float, scale_v: float | None = None) -> np.ndarray:
    """Bilinear crop of a Lab window (``lab_window``) on a grid aligned with ``yaw_deg`` (u forward
    along the columns, v to the left = up the rows), centred on (cx, cy): (2*half_v*scale,
    2*half_u*scale) samples, ``scale`` samples per image pixel (``scale_v`` across, if given)."""
    import cv2

    lab, (c0, r0) = win
    sv = scale if scale_v is None else scale_v
    nu, nv = int(math.ceil(2 * half_u * scale)), int(math.ceil(2 * half_v * sv))
    r = math.radians(yaw_deg)
    cr, sr = math.cos(r), math.sin(r)  # forward (cr, -sr) and its left (-sr, -cr) in (col, row)
    a = np.array([[cr / scale, sr / sv], [-sr / scale, cr / sv]])  # 2x2: d(col,row)/d(j,i) (forward, -left)
    c = np.array([cx - 0.5 - c0, cy - 0.5 - r0])  # continuous image coords → window pixel index
    m = np.empty((2, 3))
    m[:, :2] = a
    m[:, 2] = c - a @ np.array([(nu - 1) / 2.0, (nv - 1) / 2.0])
    return cv2.warpAffine(lab, m, (nu, nv), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REFLECT)


def sq_dist(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``((a - m) ** 2).sum(-1)`` for colours ``a`` (..., 3) and one colour ``m``, channel by channel:
    the same values, several times faster than numpy's reduction over a short last axis (speed)."""
    m = np.asarray(m)
    t = a[..., 0] - m[0]
    acc = t * t
    for c in range(1, a.shape[-1]):
        t = a[..., c] - m[c]
        acc += t * t
    return acc


def _median0(a: np.ndarray) -> np.ndarray:
    """``np.median(a, 0)`` of a non-empty (n, c) array, the same values without its overhead (speed:
    called in every k-means step of ``background_modes``)."""
    n = a.shape[0]
    h = n // 2
    if n % 2:
        return np.partition(a, h, axis=0)[h]
    p = np.partition(a, (h - 1, h), axis=0)
    return (p[h - 1] + p[h]) / 2


def background_modes(ring: np.ndarray, core: np.ndarray, k: int = 3, iters: int = 6,
                     min_share: float = 0.12, max_in_core: float = 0.3,
                     tol: float = 8.0) -> list[tuple[np.ndarray, float]]:
    """The background's colours (Lab) from the ring pixels: a small deterministic k-means (water and a
    pier deck, pavement and grass...). A mode that also covers much of the box's core is the object's
    own colour seen on a neighbour (rafted boats, cars in a row) and is dropped. Returns (colour,
    share of the ring) pairs, the commonest first."""
    x = ring.reshape(-1, 3)
    if len(x) > 1200:
        x = x[:: len(x) // 1200 + 1]
    if len(x) < 10:
        return []
    centres = np.quantile(x, np.linspace(0.15, 0.85, k), axis=0)  # spread along all channels
    prev = None
    for _ in range(iters):
        lab = np.argmin(np.stack([sq_dist(x, m) for m in centres], 1), 1)
        if prev is not None and np.array_equal(lab, prev):
            break  # converged: the same members give the same medians from here on
        prev = lab
        for j in range(k):
            sel = x[lab == j]
            if len(sel):
                centres[j] = _median0(sel)
    else:
        lab = np.argmin(np.stack([sq_dist(x, m) for m in centres], 1), 1)
    c = core.reshape(-1, 3)
    out = []
    for j in range(k):
        share = float((lab == j).mean())
        if share < min_share:
            continue
        if len(c) and (np.sqrt(sq_dist(c, centres[j])) < tol).mean() > max_in_core:
            continue
        out.append((centres[j].copy(), share))
    return sorted(out, key=lambda m: -m[1])


def box_core(rgb: np.ndarray | LabCache, det: Detection, half_u: float,
              half_v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Lab crop aligned with ``det`` (±``half_u`` px along its axis, ±``half_v`` across, sampled
    so the box is about 12 samples wide) and each sample's (u, v) offset from the centre in image px
    (broadcastable: u (1, nu), v (nv, 1))."""
    s = max(1.0, min(4.0, 12.0 / max(det.width_px, 1.0)))
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, s)
    nv, nu = crop.shape[:2]
    u = ((np.arange(nu) - (nu - 1) / 2.0) / s)[None, :]
    v = ((np.arange(nv) - (nv - 1) / 2.0) / s)[:, None]
    return crop, u, v
