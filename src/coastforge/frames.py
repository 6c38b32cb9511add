"""Frames and units (DESIGN.md §2): image pixels ↔ scene metres ↔ Unreal ↔ HoloOcean.

- Image frame: (col, row) pixels, origin at the top-left corner of the top-left pixel, row down.
  The centre of pixel (i, j) is at (i + 0.5, j + 0.5).
- Scene frame: metres, x = east = image right, y = north = image up, z = up, origin at the image
  centre, z = 0 at the water surface. Yaw in degrees counter-clockwise from +x, in (-180, 180].
- HoloOcean: identical to the scene frame.
- Unreal: centimetres, left-handed: X = 100 x, Y = -100 y, Z = 100 z, yaw_ue = -yaw.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def wrap_deg(angle: ArrayLike) -> np.ndarray | float:
    """Wrap degrees to (-180, 180]."""
    a = np.asarray(angle, dtype=np.float64)
    w = -((-a + 180.0) % 360.0) + 180.0  # maps 180 -> 180, -180 -> 180
    return float(w) if w.ndim == 0 else w


def wrap_half_deg(angle: ArrayLike) -> np.ndarray | float:
    """Wrap degrees modulo 180 to (-90, 90] (orientation without heading)."""
    a = np.asarray(angle, dtype=np.float64)
    w = -((-a + 90.0) % 180.0) + 90.0
    return float(w) if w.ndim == 0 else w


def pixel_to_scene(col: ArrayLike, row: ArrayLike, width_px: int, height_px: int, gsd_m: float):
    """Continuous pixel coordinates → scene metres (x east, y north, origin at the image centre)."""
    x = (np.asarray(col, dtype=np.float64) - width_px / 2.0) * gsd_m
    y = (height_px / 2.0 - np.asarray(row, dtype=np.float64)) * gsd_m
    return x, y


def scene_to_pixel(x_m: ArrayLike, y_m: ArrayLike, width_px: int, height_px: int, gsd_m: float):
    """Scene metres → continuous pixel coordinates (col, row)."""
    col = np.asarray(x_m, dtype=np.float64) / gsd_m + width_px / 2.0
    row = height_px / 2.0 - np.asarray(y_m, dtype=np.float64) / gsd_m
    return col, row


def image_yaw_to_scene(yaw_image_deg: ArrayLike):
    """Image yaw (CCW from image-right with image-up positive) is the scene yaw: x right, y up."""
    return wrap_deg(yaw_image_deg)


def direction_px(yaw_deg: ArrayLike):
    """Unit vector (dcol, drow) in the image for a scene yaw (row points down, so drow = -sin)."""
    r = np.deg2rad(np.asarray(yaw_deg, dtype=np.float64))
    return np.cos(r), -np.sin(r)


def yaw_from_direction_px(dcol: ArrayLike, drow: ArrayLike):
    """Scene yaw (degrees) of an image-space direction vector."""
    return wrap_deg(np.rad2deg(np.arctan2(-np.asarray(drow, float), np.asarray(dcol, float))))


def scene_to_unreal(x_m: ArrayLike, y_m: ArrayLike, z_m: ArrayLike):
    """Scene metres → Unreal centimetres (left-handed: Y flips)."""
    return (np.asarray(x_m, float) * 100.0, np.asarray(y_m, float) * -100.0, np.asarray(z_m, float) * 100.0)


def unreal_to_scene(x_cm: ArrayLike, y_cm: ArrayLike, z_cm: ArrayLike):
    """Unreal centimetres → scene metres."""
    return (np.asarray(x_cm, float) / 100.0, np.asarray(y_cm, float) / -100.0, np.asarray(z_cm, float) / 100.0)


def yaw_to_unreal(yaw_deg: ArrayLike):
    """Scene yaw (CCW from +x, right-handed) → Unreal yaw (left-handed, so the sign flips)."""
    return wrap_deg(-np.asarray(yaw_deg, dtype=np.float64))


def yaw_from_unreal(yaw_ue_deg: ArrayLike):
    return wrap_deg(-np.asarray(yaw_ue_deg, dtype=np.float64))


def scene_to_holoocean(x_m: ArrayLike, y_m: ArrayLike, z_m: ArrayLike):
    """HoloOcean uses the scene frame (metres, right-handed, x east, y north, z up)."""
    return (np.asarray(x_m, float), np.asarray(y_m, float), np.asarray(z_m, float))


def holoocean_to_scene(x_m: ArrayLike, y_m: ArrayLike, z_m: ArrayLike):
    return (np.asarray(x_m, float), np.asarray(y_m, float), np.asarray(z_m, float))


def yaw_to_holoocean(yaw_deg: ArrayLike):
    return wrap_deg(yaw_deg)


def box_corners_px(cx: float, cy: float, length: float, width: float, yaw_deg: float) -> np.ndarray:
    """The 4 (col, row) corners of an oriented box in the image, front-left first, counter-clockwise
    as seen on a map (front-left, rear-left, rear-right, front-right)."""
    fx, fy = direction_px(yaw_deg)  # forward in image coords
    lx, ly = direction_px(wrap_deg(yaw_deg + 90.0))  # left of the forward axis
    hl, hw = length / 2.0, width / 2.0
    c = np.array([cx, cy])
    f = np.array([fx, fy]) * hl
    left = np.array([lx, ly]) * hw
    return np.array([c + f + left, c - f + left, c - f - left, c + f - left])
