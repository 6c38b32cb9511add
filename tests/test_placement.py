"""Placement of floating objects: afloat at the waterline, ashore on the ground."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from coastforge.config import MatchConfig
from coastforge.placement import place
from coastforge.types import Detection, Grid, HeightMap

GRID = Grid(400, 400, 0.25)  # 100 m x 100 m


@dataclass(frozen=True)
class A:
    id: str
    category: str
    dims_m: tuple
    floating: bool = True
    draft_m: float = 0.5


def det(x, y, length=6.0, width=2.4, yaw=30.0):
    col, row = GRID.to_pixel(x, y)
    return Detection("boat", 0.9, float(col), float(row), length / GRID.gsd_m, width / GRID.gsd_m, yaw, True, 0.9)


def quay_heights():
    z = np.full(GRID.shape, -3.0, np.float32)  # water 3 m deep
    z[:, :160] = 2.0  # a quay 2 m above the water west of x = -10 m
    return HeightMap(z, GRID)


def test_boat_afloat_next_to_a_quay_stays_at_the_waterline():
    o = place(det(-8.9, 0.0), A("runabout", "boat", (6.0, 2.4, 1.5)), GRID, "b0", MatchConfig(),
              height=quay_heights(), water_level_m=0.0)
    assert o.z_m == 0.0 and "ashore" not in o.attrs


def test_boat_ashore_rests_on_the_ground_with_its_hull():
    o = place(det(-30.0, 10.0), A("runabout", "boat", (6.0, 2.4, 1.5)), GRID, "b1", MatchConfig(),
              height=quay_heights(), water_level_m=0.0)
    assert o.z_m == pytest.approx(2.5) and o.attrs["ashore"] is True


def test_no_height_map_means_afloat():
    o = place(det(-30.0, 10.0), A("runabout", "boat", (6.0, 2.4, 1.5)), GRID, "b2", MatchConfig())
    assert o.z_m == 0.0
