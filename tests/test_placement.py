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


def test_shape_fit_moves_the_centre_along_the_final_yaw_and_sets_the_scale():
    cfg = MatchConfig()
    boat = A("runabout", "boat", (6.0, 2.4, 1.5))
    d = det(10.0, -5.0, length=6.6, yaw=90.0)  # a box pointing north (+y)
    plain = place(d, boat, GRID, "b3", cfg)
    assert plain.scale[0] == pytest.approx(1.1, rel=0.05)  # from the box
    fitted = place(d, boat, GRID, "b3", cfg, yaw_deg=90.0, shape_scale=0.95, shape_offset_m=(0.4, 0.2))
    assert fitted.scale == (0.95, 0.95, 0.95)
    # 0.25 m/px is coarse: the fit's centre weighs less than at 0.1 m/px (config), never more
    from coastforge.placement import shape_offset_weight
    w = shape_offset_weight(GRID.gsd_m, cfg)
    assert 0.0 <= w < cfg.shape_offset_weight_fine
    # along the yaw (north) by w * 0.4, to its left (west) by w * 0.2
    assert fitted.y_m - plain.y_m == pytest.approx(w * 0.4, abs=1e-6)
    assert fitted.x_m - plain.x_m == pytest.approx(-w * 0.2, abs=1e-6)
    fine = Grid(1000, 1000, 0.1)
    col, row = fine.to_pixel(10.0, -5.0)
    d_fine = Detection("boat", 0.9, float(col), float(row), 66.0, 24.0, 90.0, True, 0.9)
    a = place(d_fine, boat, fine, "b4", cfg, yaw_deg=-90.0, shape_offset_m=(0.4, 0.0), shape_scale=1.0)
    # after a flip the final yaw points south: the offset follows it
    assert a.y_m - (-5.0) == pytest.approx(-cfg.shape_offset_weight_fine * 0.4, abs=0.06)


def test_shape_fit_is_ignored_for_buoys_per_axis_and_when_disabled():
    from dataclasses import replace
    buoy = A("buoy_can", "buoy", (1.0, 1.0, 1.5))
    d = det(0.0, 0.0, length=1.0, width=1.0, yaw=0.0)
    base = place(d, buoy, GRID, "u0", MatchConfig())
    moved = place(d, buoy, GRID, "u0", MatchConfig(), shape_offset_m=(0.5, 0.5), shape_scale=1.2)
    assert (moved.x_m, moved.y_m) == (base.x_m, base.y_m)
    boat = A("runabout", "boat", (6.0, 2.4, 1.5))
    off = place(det(0.0, 0.0), boat, GRID, "b5", replace(MatchConfig(), use_shape_fit=False), shape_scale=1.5,
                shape_offset_m=(1.0, 0.0))
    assert off.scale[0] == pytest.approx(1.0, rel=0.02) and off.x_m == pytest.approx(place(
        det(0.0, 0.0), boat, GRID, "b5", MatchConfig()).x_m)
    per_axis = place(det(0.0, 0.0), boat, GRID, "b6", replace(MatchConfig(), scale_mode="per_axis"), shape_scale=1.5)
    assert per_axis.scale[0] == pytest.approx(1.0, rel=0.02)
