"""Placement, pier chains and vegetation scatter (the parts of `generate` that need no library)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from coastforge.classes import ASPHALT, GRASS, ROCKS, TREES, WATER
from coastforge.config import MatchConfig, PierConfig, VegetationConfig
from coastforge.evaluate import pier_connectivity
from coastforge.pier_chains import build_piers
from coastforge.placement import fit_scale, place
from coastforge.scene import Scene
from coastforge.types import ClassMap, Detection, Grid, HeightMap
from coastforge.vegetation import scatter


@dataclass(frozen=True)
class A:
    id: str
    category: str
    dims_m: tuple
    floating: bool = False
    draft_m: float = 0.0


GRID = Grid(400, 400, 0.25)  # 100 m x 100 m, x and y in [-50, 50]


def det(cat, x, y, length, width, yaw, known=True):
    col, row = GRID.to_pixel(x, y)
    return Detection(cat, 0.9, float(col), float(row), length / GRID.gsd_m, width / GRID.gsd_m, yaw, known, 0.9)


def test_place_boat_on_water_with_scale_and_yaw():
    boat = A("runabout", "boat", (6.0, 2.4, 1.5), floating=True)
    o = place(det("boat", 10, -5, 7.2, 2.88, 135), boat, GRID, "b0", MatchConfig(), water_level_m=0.0)
    assert (o.x_m, o.y_m) == pytest.approx((10, -5))
    assert o.yaw_deg == pytest.approx(135) and o.z_m == 0.0
    assert o.scale[0] == pytest.approx(1.2) and o.length_m == pytest.approx(7.2)
    flipped = place(det("boat", 10, -5, 7.2, 2.88, 135), boat, GRID, "b1", MatchConfig(), yaw_deg=-45)
    assert flipped.yaw_deg == pytest.approx(-45)


def test_place_vehicle_on_terrain_and_scale_clamped():
    car = A("sedan", "vehicle", (4.6, 1.8, 1.4))
    h = HeightMap(np.full(GRID.shape, 2.5, np.float32), GRID)
    o = place(det("vehicle", 0, 0, 40, 18, 0), car, GRID, "c0", MatchConfig(), height=h)
    assert o.z_m == pytest.approx(2.5) and o.scale[0] == MatchConfig().scale_max
    sx, sy, sz = fit_scale(4.6 * 1.1, 1.8 * 0.9, car.dims_m, MatchConfig(scale_mode="per_axis"))
    assert (sx, sy) == pytest.approx((1.1, 0.9)) and sz == pytest.approx(np.sqrt(1.1 * 0.9))


def harbor_classes():
    ids = np.full(GRID.shape, WATER, np.uint8)
    ids[:, :80] = ASPHALT  # land west of x = -30
    return ClassMap(ids, GRID)


WALK = A("pier_walkway", "pier", (10.0, 2.5, 1.0))
FINGER = A("pier_finger", "pier", (8.0, 1.2, 1.0))


def test_pier_chain_segments_fit_exactly_and_connect():
    cm = harbor_classes()
    # a walkway detected from x = -31 (on the quay) to x = +4 (23 m... chained), fingers attached to it
    dets = [det("pier_walkway", -13.5, 0, 35, 2.5, 0), det("pier_finger", -5, -5.2, 8, 1.2, 90),
            det("pier_finger", 0, 5.2, 8, 1.2, -90)]
    r = build_piers(dets, cm, WALK, FINGER, PierConfig())
    walk = [o for o in r.objects if o.attrs["role"] == "walkway"]
    assert len(walk) == 4  # ceil(35 / 10)
    assert sum(o.length_m for o in walk) == pytest.approx(35, abs=0.6)
    assert all(o.scale[0] == pytest.approx(35 / 40, abs=0.02) for o in walk)
    assert r.report["n_structures"] == 1 and all(r.structure_on_land)
    s = Scene("t", 0, GRID.gsd_m, GRID.extent_m, classes=cm.ids, objects=r.objects)
    assert pier_connectivity(s)["all_connected"] is True


def test_pier_gap_to_land_is_bridged():
    cm = harbor_classes()
    # a walkway that stops 4 m short of the quay (detector missed its root), and a far-out finger 3 m from it
    dets = [det("pier_walkway", -11, 0, 30, 2.5, 0), det("pier_finger", 4, 8, 8, 1.2, 90)]
    r = build_piers(dets, cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert max(r.extensions_m) > 3
    s = Scene("t", 0, GRID.gsd_m, GRID.extent_m, classes=cm.ids, objects=r.objects)
    assert pier_connectivity(s)["all_connected"] is True


@pytest.mark.parametrize("gap_m", [0.8, 1.2])
def test_pier_end_just_short_of_the_quay_is_extended_to_touch_it(gap_m):
    # the end is close enough that land fills a good part of a disc around it, but the deck does not reach the
    # shore: the builder must not call it grounded (the evaluation would find it floating)
    cm = harbor_classes()  # land ends at x = -30
    dets = [det("pier_walkway", -30 + gap_m + 10, 0, 20, 2.5, 0)]
    r = build_piers(dets, cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert r.extensions_m[0] >= gap_m - 0.3
    s = Scene("t", 0, GRID.gsd_m, GRID.extent_m, classes=cm.ids, objects=r.objects)
    assert pier_connectivity(s, tol_m=0.6)["all_connected"] is True


def test_isolated_pier_gets_a_connector():
    cm = harbor_classes()
    dets = [det("pier_walkway", -12, 20, 20, 2.5, 90)]  # 18 m from the quay, parallel to it, 20 m long
    r = build_piers(dets, cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert r.report["connectors_added"] == 1 and all(r.structure_on_land)
    # beyond 4 x max_gap_m nothing is invented: the floating structure is reported instead
    r = build_piers([det("pier_walkway", 30, 20, 12, 2.5, 90)], cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert r.report["connectors_added"] == 0 and r.structure_on_land == (False,)


def test_vegetation_rules():
    ids = np.full(GRID.shape, GRASS, np.uint8)
    ids[:, :100] = WATER
    ids[:100, 100:200] = TREES
    ids[300:, 100:] = ASPHALT
    ids[100:200, 300:] = ROCKS
    h = np.where(ids == WATER, -2.0, 1.0).astype(np.float32)
    h[200:300, 300:] = 1.0 + np.arange(100)[None, :] * 0.25  # a 45 degree slope: no trees there
    from coastforge.scene import SceneObject

    car = SceneObject("c", "vehicle", "sedan", 25, 25, 1, 0, (1, 1, 1), 10, 10, "manual", 1)  # keep clear
    assets = {"tree": ["tree_a", "tree_b"], "bush": ["bush_a"], "grass": ["grass_a"], "rock": ["rock_a"],
              "seaweed": ["kelp"]}
    r = scatter(ids, h, GRID, assets, [car], VegetationConfig(), seed=3)
    v = r.vegetation
    assert len(v) > 50
    col, row = GRID.to_pixel(v.x_m, v.y_m)
    cls = ids[row.astype(int), col.astype(int)]
    trees = np.isin(v.asset_id, ["tree_a", "tree_b"])
    assert np.all(cls[trees] != ASPHALT) and np.mean(cls[trees] == TREES) > 0.7
    assert not np.any(cls == ASPHALT)  # nothing on paving
    assert np.all(cls[v.asset_id == "rock_a"] != WATER)
    kelp = v.asset_id == "kelp"
    assert kelp.any() and np.all(v.z_m[kelp] < 0)
    land = ~kelp
    assert np.all(v.z_m[land] > 0)
    steep = (row.astype(int) >= 200) & (row.astype(int) < 300) & (col.astype(int) >= 300)
    assert not np.any(trees & steep)
    assert not np.any((np.abs(v.x_m - 25) < 5.5) & (np.abs(v.y_m - 25) < 5.5))  # clear of the car
    # spacing: trees at least ~0.8 of their spacing apart
    from scipy.spatial import cKDTree

    tp = np.stack([v.x_m[trees], v.y_m[trees]], 1)
    d, _ = cKDTree(tp).query(tp, k=2)
    assert d[:, 1].min() >= 0.8 * 4.0 - 1e-6
    assert set(r.masks) >= {"trees", "rocks"} and r.masks["trees"].dtype == np.uint8
    again = scatter(ids, h, GRID, assets, [car], VegetationConfig(), seed=3).vegetation
    assert np.array_equal(again.x_m, v.x_m)


def test_a_short_piece_far_out_is_dropped_not_connected():
    """A connector longer than all the deck seen of a floating piece would invent more pier than was found: the
    piece (more likely a hull or a wake read as deck) is dropped, and nothing is built across the water."""
    cm = harbor_classes()
    r = build_piers([det("pier_walkway", -12, 20, 8, 2.5, 90)], cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert r.objects == () and r.report["dropped_floating"] == 1 and r.report.get("connectors_added", 0) == 0
    # the same piece 4.5 m beside a grounded walkway (14 m from the quay) attaches to the walkway instead
    dets = [det("pier_walkway", -20, 0, 20, 2.5, 0), det("pier_walkway", -12, 7, 8, 2.5, 0)]
    r = build_piers(dets, cm, WALK, FINGER, PierConfig(max_gap_m=6))
    assert r.report["dropped_floating"] == 0 and r.report["connectors_added"] == 1 and all(r.structure_on_land)
    conn = [b for b in r.boxes if b.role == "connector"]
    assert conn[0].length_m < 7


def test_report_says_when_floating_pier_pieces_were_left_out():
    from coastforge.report.sections import piers_section

    cm = harbor_classes()
    r = build_piers([det("pier_walkway", -12, 20, 8, 2.5, 90)], cm, WALK, FINGER, PierConfig(max_gap_m=6))
    s = Scene("t", 0, GRID.gsd_m, GRID.extent_m, classes=cm.ids, objects=r.objects,
              provenance={"piers": r.report})
    assert "1 floating pier piece left out" in piers_section(s, None)
    s = Scene("t", 0, GRID.gsd_m, GRID.extent_m, classes=cm.ids, objects=r.objects, provenance={})
    assert "left out" not in piers_section(s, None)
