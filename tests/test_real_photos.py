"""Regression tests on crops of real photographs no model of ours was trained on (the validation groups of
``coastforge.realdata``): water where the water is, whatever its colour, and vegetation that never
becomes water. They skip when ../shared/data is absent."""

from __future__ import annotations

import numpy as np
import pytest

from coastforge import realdata
from coastforge.classes import GRASS, TREES, WATER
from coastforge.config import load_config
from coastforge.segmentation import segment
from coastforge.types import GeoImage, Grid

GSD = 0.6  # the Dubai set's nominal GSD (DESIGN.md §5)


def _crop(shared_data, name: str, r0: int, c0: int, size: int = 512):
    assert name.startswith(realdata.DUBAI_VAL_TILES), "regression crops come from tiles nobody trained on"
    items = {n: (i, m) for n, i, m, _v in realdata.dubai_items()}
    if name not in items:
        pytest.skip(f"{name} not found under {shared_data}")
    img, mask = items[name]
    rgb = realdata.read_rgb(img)[r0:r0 + size, c0:c0 + size]
    truth = realdata.dubai_coarse(realdata.read_rgb(mask))[r0:r0 + size, c0:c0 + size]
    cfg = load_config("default")
    ids = segment(GeoImage(np.ascontiguousarray(rgb), Grid(size, size, GSD)), cfg).ids
    return ids, truth


def test_a_creek_is_water(shared_data):
    """A creek between desert, roads and roofs (Dubai tile 8; the first crop of a fixed scan on which the
    code before the learned fusion failed: water IoU 0.17, it called the land around the creek water)."""
    ids, truth = _crop(shared_data, "tile_8/image_part_007", 512, 0)
    t, p = truth == 0, ids == WATER
    assert t.mean() > 0.1  # the crop holds a fair share of water
    iou = (t & p).sum() / (t | p).sum()
    assert iou >= 0.6


def test_vegetation_becomes_water_less_often(shared_data):
    """Lawns and tree rows (Dubai tile 8). The code before the learned fusion called 81 % of them water;
    today's 44 % is still far from the goal (never water): dark lawns at ~0.6 m/px are the segmenter's
    weakest case. The bar guards against going back."""
    ids, truth = _crop(shared_data, "tile_8/image_part_001", 832, 0)
    veg = truth == 2
    assert veg.mean() > 0.6
    assert (ids[veg] == WATER).mean() < 0.6
    assert np.isin(ids[veg], (GRASS, TREES)).mean() >= 0.3
