"""The eight terrain classes (fixed ids), their colours and HoloOcean semantic labels (DESIGN.md §2).

The HoloOcean label is a name ``ATagger::GetLabelByFolderName`` accepts, with its ``holoocean::ObjectLabel``
stencil value (see ``export/labels.py`` for the sources). Ground classes take HoloOcean's ground labels
(GroundGrass, GroundRock, Ground): Grass, Tree and Rock are the props scattered on them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TerrainClass:
    id: int
    name: str
    rgb: tuple[int, int, int]
    holoocean_label: int
    holoocean_name: str


TERRAIN_CLASSES: tuple[TerrainClass, ...] = (
    TerrainClass(0, "water", (0, 90, 160), 9, "WaterPlane"),
    TerrainClass(1, "asphalt", (70, 70, 70), 26, "Asphalt"),
    TerrainClass(2, "sidewalk", (200, 200, 200), 47, "Sidewalk"),
    TerrainClass(3, "grass", (90, 170, 60), 5, "GroundGrass"),
    TerrainClass(4, "trees", (20, 100, 30), 7, "Ground"),  # the forest floor under the trees
    TerrainClass(5, "dirt", (140, 100, 60), 7, "Ground"),
    TerrainClass(6, "rocks", (130, 120, 110), 6, "GroundRock"),
    TerrainClass(7, "sand", (230, 210, 150), 7, "Ground"),  # HoloOcean has no sand label
)

N_CLASSES = len(TERRAIN_CLASSES)
CLASS_NAMES: tuple[str, ...] = tuple(c.name for c in TERRAIN_CLASSES)
CLASS_IDS: dict[str, int] = {c.name: c.id for c in TERRAIN_CLASSES}
PALETTE = np.array([c.rgb for c in TERRAIN_CLASSES], dtype=np.uint8)  # (8, 3)

WATER, ASPHALT, SIDEWALK, GRASS, TREES, DIRT, ROCKS, SAND = range(8)
PAVED = (ASPHALT, SIDEWALK)

OBJECT_CATEGORIES = ("boat", "vehicle", "pier", "buoy", "vegetation", "rock")
DETECTION_CATEGORIES = ("boat", "vehicle", "pier_walkway", "pier_finger", "buoy")
ASSET_CATEGORIES = ("boat", "vehicle", "pier", "buoy", "tree", "bush", "rock", "grass", "seaweed")
EVALUATED_CATEGORIES = ("boat", "vehicle", "buoy")


def colorize(ids: np.ndarray) -> np.ndarray:
    """Class ids (H, W) → RGB preview (H, W, 3) in the fixed palette."""
    import cv2

    ids = np.asarray(ids)
    if ids.dtype == np.uint8 and ids.ndim == 2 and ids.size:  # a lookup table: ~20x faster on big maps
        lut = PALETTE[np.minimum(np.arange(256), N_CLASSES - 1)].astype(np.uint8)
        return cv2.LUT(cv2.merge([ids, ids, ids]), lut.reshape(256, 1, 3))
    return PALETTE[np.clip(ids, 0, N_CLASSES - 1)]


def snap_to_palette(rgb: np.ndarray) -> np.ndarray:
    """RGB image (H, W, 3) → class ids by the nearest palette colour (for images painted by models)."""
    flat = rgb.reshape(-1, 3).astype(np.int32)
    d = ((flat[:, None, :] - PALETTE[None, :, :].astype(np.int32)) ** 2).sum(-1)
    return d.argmin(1).astype(np.uint8).reshape(rgb.shape[:2])
