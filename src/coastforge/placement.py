"""Placement: a detection plus its chosen asset → an object in the scene frame.

Position from the box centre, yaw from the heading, scale from the box against the asset's real
dimensions (uniform by default, per axis as an option, clamped), z at the water level for floating
objects and on the terrain for the rest.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .config import MatchConfig
from .frames import wrap_deg
from .scene import SceneObject
from .types import Detection, Grid, HeightMap

FLOATING_CATEGORIES = ("boat", "buoy")
DRY_MARGIN_M = 0.3  # terrain this far above the water under a boat's centre means the boat is ashore


class AssetLike(Protocol):
    id: str
    category: str
    dims_m: tuple[float, float, float]
    floating: bool


def box_in_metres(det: Detection, grid: Grid) -> tuple[float, float, float, float]:
    """(x_m, y_m, length_m, width_m) of a detection."""
    x, y = grid.to_scene(det.cx_px, det.cy_px)
    return float(x), float(y), det.length_px * grid.gsd_m, det.width_px * grid.gsd_m


def fit_scale(length_m: float, width_m: float, dims_m: tuple[float, float, float], config: MatchConfig
              ) -> tuple[float, float, float]:
    """Scale that makes the asset's footprint match the box. Uniform: the geometric mean of the length and
    width ratios (robust to a box that is a little too wide); per-axis: each ratio, height follows width."""
    L, W, _H = dims_m
    rl, rw = length_m / max(L, 1e-6), width_m / max(W, 1e-6)
    lo, hi = config.scale_min, config.scale_max
    if config.scale_mode == "per_axis":
        sx, sy = float(np.clip(rl, lo, hi)), float(np.clip(rw, lo, hi))
        return (sx, sy, float(np.sqrt(sx * sy)))
    # length is measured more reliably than width (shadows and fenders widen boxes): weight it more
    s = float(np.clip(np.exp(0.75 * np.log(max(rl, 1e-6)) + 0.25 * np.log(max(rw, 1e-6))), lo, hi))
    return (s, s, s)


def shape_offset_weight(gsd_m: float, config: MatchConfig) -> float:
    """Weight of the shape fit's centre against the box centre at this GSD (see MatchConfig)."""
    w1, w2 = config.shape_offset_weight_fine, config.shape_offset_weight_coarse
    w = w1 + (w2 - w1) * (gsd_m - 0.1) / 0.1
    return float(min(max(w, 0.0), max(w1, w2)))


def ground_height(height: HeightMap | None, grid: Grid, x_m: float, y_m: float, radius_m: float) -> float:
    """Highest terrain under a small disc (so a car never sinks into a slope)."""
    if height is None:
        return 0.0
    hg = height.grid
    col, row = hg.to_pixel(x_m, y_m)
    r = max(1, int(np.ceil(radius_m / hg.gsd_m)))
    c0, c1 = int(max(0, col - r)), int(min(hg.width_px, col + r + 1))
    r0, r1 = int(max(0, row - r)), int(min(hg.height_px, row + r + 1))
    if c1 <= c0 or r1 <= r0:
        return 0.0
    return float(np.max(height.z_m[r0:r1, c0:c1]))


def centre_height(height: HeightMap | None, grid: Grid, x_m: float, y_m: float, radius_m: float) -> float | None:
    """Median terrain height in a small disc at the object's centre (None without a height map or outside it)."""
    if height is None:
        return None
    hg = height.grid
    col, row = hg.to_pixel(x_m, y_m)
    r = max(0, int(np.ceil(radius_m / hg.gsd_m)))
    c0, c1 = int(max(0, np.floor(col) - r)), int(min(hg.width_px, np.floor(col) + r + 1))
    r0, r1 = int(max(0, np.floor(row) - r)), int(min(hg.height_px, np.floor(row) + r + 1))
    if c1 <= c0 or r1 <= r0:
        return None
    return float(np.median(height.z_m[r0:r1, c0:c1]))


def place(det: Detection, asset: AssetLike, grid: Grid, object_id: str, config: MatchConfig,
          height: HeightMap | None = None, water_level_m: float = 0.0, yaw_deg: float | None = None,
          score: float | None = None, attrs: dict | None = None, shape_scale: float | None = None,
          shape_offset_m: tuple[float, float] | None = None) -> SceneObject:
    """A scene object for ``det`` rendered with ``asset``. ``yaw_deg`` overrides the detection's heading
    (e.g. after the matcher resolved bow versus stern). ``shape_scale`` and ``shape_offset_m`` are the
    matcher's shape fit of the asset to the image (its scale, and its centre relative to the box centre along
    the final yaw and to its left): see ``MatchConfig.use_shape_fit``."""
    x, y, length, width = box_in_metres(det, grid)
    yaw = float(wrap_deg(det.yaw_deg if yaw_deg is None else yaw_deg))
    scale = fit_scale(length, width, asset.dims_m, config)
    if config.use_shape_fit and shape_scale is not None and config.scale_mode != "per_axis":
        # the asset's silhouette fitted to the pixels measures size better than the box (whose length is
        # thrown off by shadows, fenders and a soft bow); the box keeps the per-axis mode
        s = float(np.clip(shape_scale, config.scale_min, config.scale_max))
        scale = (s, s, s)
    w = shape_offset_weight(grid.gsd_m, config)
    if config.use_shape_fit and shape_offset_m is not None and w > 0 and asset.category != "buoy":
        # the asset's own outline fitted to the image is a second estimate of the centre (a box's centre lies
        # toward the stern of a tapered hull); round buoys are centred on their silhouette already
        ox, oy = w * shape_offset_m[0], w * shape_offset_m[1]
        c, sn = np.cos(np.radians(yaw)), np.sin(np.radians(yaw))
        x, y = x + ox * c - oy * sn, y + ox * sn + oy * c
    category = "boat" if asset.category == "boat" else asset.category
    attrs = dict(attrs or {})
    if asset.floating or asset.category in FLOATING_CATEGORIES:
        z = water_level_m  # meshes are normalised with z = 0 at their waterline
        ground = centre_height(height, grid, x, y, radius_m=min(length, width) / 4)
        if ground is not None and ground > water_level_m + DRY_MARGIN_M:
            # a boat ashore (boatyard, trailer, slipway) rests on the ground, hull and all; the centre
            # decides, so a boat moored against a quay wall stays afloat
            z = ground + float(getattr(asset, "draft_m", 0.0) or 0.0)
            attrs["ashore"] = True
    else:
        z = ground_height(height, grid, x, y, radius_m=min(length, width) / 2)
    return SceneObject(
        id=object_id, category=category, asset_id=asset.id, x_m=x, y_m=y, z_m=float(z), yaw_deg=yaw,
        scale=scale, length_m=float(asset.dims_m[0] * scale[0]), width_m=float(asset.dims_m[1] * scale[1]),
        source="detection", score=float(det.score if score is None else score), attrs=attrs,
    )
