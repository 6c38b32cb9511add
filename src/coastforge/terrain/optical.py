"""Optical depth: the Stumpf et al. (2003) log-ratio ``ln(n·B) / ln(n·G)`` as a relative depth in clear
shallow water, scaled to metres by regressing it against the model's own depth, then blended in
where the water is shallow and clear (never at quay berths). Off by default (``terrain.optical_depth``).

Blue light is absorbed less than green, so the ratio grows with depth over a bright bottom; the
linear fit ``depth ≈ gain · ratio + offset`` replaces the in-situ calibration the method needs. The
fit is rejected (and the model depth kept) if it is weak or has the wrong sign.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..config import TerrainConfig

STUMPF_N = 1000.0  # the constant n keeps both logarithms positive for any reflectance


@dataclass(frozen=True)
class OpticalFit:
    used: bool
    gain: float
    offset: float
    r2: float
    n_pixels: int
    note: str

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("gain", "offset", "r2"):
            d[k] = round(float(d[k]), 6)
        return d


def stumpf_ratio(rgb: np.ndarray, n: float = STUMPF_N) -> np.ndarray:
    """ln(n·B) / ln(n·G) with reflectances taken as the 8-bit values / 255 (floored at 1/255)."""
    b = np.maximum(rgb[..., 2].astype(np.float32), 1.0) / 255.0
    g = np.maximum(rgb[..., 1].astype(np.float32), 1.0) / 255.0
    return (np.log(n * b) / np.log(n * g)).astype(np.float32)


def apply_optical_depth(z: np.ndarray, shore, rgb: np.ndarray, config: TerrainConfig):
    """Heights with shallow-water depth modulated by the optical estimate, and the fit summary."""
    import cv2

    from .default import QUAY, smooth

    water = shore.water
    depth = np.where(water, -z, 0.0).astype(np.float32)
    dmax = float(config.optical_max_depth_m)
    ratio = stumpf_ratio(rgb)
    mx = rgb.max(axis=2).astype(np.int16)
    mn = rgb.min(axis=2).astype(np.int16)
    # clear water: not glint/white hulls (bright and grey), not shadow (very dark), shallow in the model
    clear = water & (mx < 235) & (mx > 12) & ~((mn > 170) & (mx - mn < 30)) & (depth < dmax)
    clear &= np.isfinite(ratio)
    # pixel noise and small dark/bright objects are averaged out over about a metre
    k = max(1, int(round(1.0 / shore.gsd_m))) | 1
    num = cv2.blur(np.where(clear, ratio, 0).astype(np.float32), (k, k))
    den = cv2.blur(clear.astype(np.float32), (k, k))
    r_s = np.divide(num, den, out=np.zeros_like(num), where=den > 0.2)
    sel = np.flatnonzero((clear & (den > 0.5)).ravel())
    if sel.size < 200:
        return z, OpticalFit(False, 0.0, 0.0, 0.0, int(sel.size), "too few clear shallow water pixels")
    sel = sel[np.linspace(0, sel.size - 1, min(sel.size, 200_000)).astype(int)]  # deterministic subsample
    x = r_s.ravel()[sel].astype(np.float64)
    y = depth.ravel()[sel].astype(np.float64)
    if x.std() < 1e-6:
        return z, OpticalFit(False, 0.0, 0.0, 0.0, int(sel.size), "the blue/green ratio does not vary")
    gain, offset = np.polyfit(x, y, 1)
    pred = gain * x + offset
    r2 = 1.0 - float(((y - pred) ** 2).sum()) / max(float(((y - y.mean()) ** 2).sum()), 1e-12)
    if gain <= 0 or r2 < 0.2:
        return z, OpticalFit(False, float(gain), float(offset), r2, int(sel.size),
                             "weak or inverted relation between the ratio and depth "
                             "(turbid or dark-bottom water)")
    d_opt = np.clip(gain * r_s + offset, 0.05, dmax).astype(np.float32)
    # trust: clear and shallow, fading out towards optical_max_depth_m and near quay walls (dredged berths)
    w = smooth(clear.astype(np.float32), 1.0 / shore.gsd_m)
    w *= np.clip(1.0 - depth / dmax, 0.0, 1.0)
    w *= 1.0 - shore.weights[QUAY]
    w *= min(1.0, max(r2, 0.0) / 0.5)  # a mediocre fit only nudges the model
    new_depth = (1.0 - w) * depth + w * d_opt
    out = np.where(water, -new_depth, z).astype(np.float32)  # both depths are > 0: water stays below 0
    return out, OpticalFit(True, float(gain), float(offset), r2, int(sel.size), "")
