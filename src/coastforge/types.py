"""Small typed dataclasses that flow between the pipeline's stages.

Arrays live in frozen dataclasses with ``eq=False`` (numpy arrays do not compare to a bool).
Field names carry their units (``gsd_m``, ``yaw_deg``, ``_px``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from . import frames


Affine = tuple[float, float, float, float, float, float]


def affine6(values: Iterable[float]) -> Affine:
    """An affine transform (a, b, c, d, e, f) as six floats; any other count raises ``ValueError``."""
    a, b, c, d, e, f = (float(v) for v in values)
    return (a, b, c, d, e, f)

@dataclass(frozen=True)
class Grid:
    """A raster grid: size in pixels, metres per pixel, and the georeference if any."""

    width_px: int
    height_px: int
    gsd_m: float
    crs: str | None = None  # WKT or "EPSG:xxxx" of the input GeoTIFF
    transform: tuple[float, float, float, float, float, float] | None = None  # affine a,b,c,d,e,f

    @property
    def extent_m(self) -> tuple[float, float]:
        return (self.width_px * self.gsd_m, self.height_px * self.gsd_m)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height_px, self.width_px)

    def to_scene(self, col, row):
        return frames.pixel_to_scene(col, row, self.width_px, self.height_px, self.gsd_m)

    def to_pixel(self, x_m, y_m):
        return frames.scene_to_pixel(x_m, y_m, self.width_px, self.height_px, self.gsd_m)

    def scene_transform(self) -> tuple[float, float, float, float, float, float]:
        """Affine (a, b, c, d, e, f) mapping pixel (col, row) to scene metres: for rasters without a CRS."""
        w, h = self.extent_m
        return (self.gsd_m, 0.0, -w / 2.0, 0.0, -self.gsd_m, h / 2.0)

    def resized(self, width_px: int, height_px: int) -> Grid:
        """The same extent on another pixel grid (gsd follows the width)."""
        gsd = self.extent_m[0] / width_px
        t = None
        if self.transform is not None:
            a, b, c, d, e, f = self.transform
            t = (a * self.width_px / width_px, b, c, d, e * self.height_px / height_px, f)
        return Grid(width_px, height_px, gsd, self.crs, t)


@dataclass(frozen=True, eq=False)
class GeoImage:
    """An RGB image (H, W, 3) uint8 on its grid."""

    rgb: np.ndarray
    grid: Grid
    path: str | None = None


@dataclass(frozen=True, eq=False)
class ClassMap:
    """Terrain class ids (H, W) uint8 on the scene grid; optional per-class probabilities (H, W, 8), a
    confidence (H, W) uint8 (255 = sure) and which source decided each pixel (H, W) uint8 (see
    ``segmentation.learned.SOURCE_NAMES``)."""

    ids: np.ndarray
    grid: Grid
    proba: np.ndarray | None = None
    confidence: np.ndarray | None = None
    source: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class HeightMap:
    """Heights (H, W) float32 in metres, z = 0 at the water surface."""

    z_m: np.ndarray
    grid: Grid


@dataclass(frozen=True, eq=False)
class Detection:
    """An oriented box in image pixels. ``yaw_deg`` is the direction of the object's front, CCW from
    image-right with image-up positive (the scene convention). If ``heading_known`` is False the
    front may be at ``yaw_deg + 180``."""

    category: str  # boat | vehicle | pier_walkway | pier_finger | buoy
    score: float
    cx_px: float
    cy_px: float
    length_px: float  # long side
    width_px: float
    yaw_deg: float
    heading_known: bool = False
    heading_confidence: float = 0.0  # 0.5 = a coin flip, 1 = certain
    mask: np.ndarray | None = None  # bool mask of the object's bounding window, if any
    mask_origin_px: tuple[int, int] | None = None  # (col, row) of the mask's top-left pixel

    def corners_px(self) -> np.ndarray:
        return frames.box_corners_px(self.cx_px, self.cy_px, self.length_px, self.width_px, self.yaw_deg)
