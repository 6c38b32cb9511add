"""Segmentation and detection reconciled (coastforge.consistency): each rule has a test that fails
without it."""

import numpy as np

from coastforge.classes import ASPHALT, GRASS, WATER
from coastforge.config import DetectConfig
from coastforge.consistency import reconcile, water_from_boats
from coastforge.types import ClassMap, Detection, Grid

GSD = 0.25


def _boat(cx, cy, yaw=90.0, length_m=8.0, width_m=3.0, score=0.8):
    return Detection("boat", score, float(cx), float(cy), length_m / GSD, width_m / GSD, yaw, heading_known=True,
                     heading_confidence=0.9)


def _rows(x0: float, n: int, cy: float) -> list[Detection]:
    """``n`` boats moored bow-in side by side, 3.5 m apart (centres), pointing north."""
    return [_boat(x0 + i * 3.5 / GSD, cy) for i in range(n)]


def test_a_marina_read_as_pavement_keeps_its_boats_and_gets_its_water():
    """All asphalt (the segmenter missed slate-grey water): a row of eight moored boats marks water, so
    the boats are neither dropped nor turned into cars, and the rafted row's footprint is water."""
    ids = np.full((400, 600), ASPHALT, np.uint8)
    cm = ClassMap(ids, Grid(600, 400, GSD))
    boats = _rows(100, 8, 200)
    rec = reconcile(boats, cm, GSD, DetectConfig())
    assert [d.category for d in rec.dets] == ["boat"] * 8
    water = rec.class_map.ids == WATER
    assert all(water[int(d.cy_px), int(d.cx_px)] for d in boats)
    gap = (200, int(100 + 1.75 / GSD))  # between the first two hulls
    assert water[gap]
    assert water[:, 450:].sum() == 0 and water[:100].sum() == 0  # nowhere else
    assert rec.notes["boat_clusters_made_water"] == 1
    # without the rule the same boats are judged against a map without water around them
    off = reconcile(boats, cm, GSD, DetectConfig(boats_make_water=False))
    assert (off.class_map.ids == WATER).sum() == 0


def test_two_boats_on_land_far_from_water_are_no_evidence():
    """Two boats on trailers in a car park far from the harbour do not make a pond."""
    ids = np.full((400, 800), ASPHALT, np.uint8)
    ids[:, :60] = WATER
    cm = ClassMap(ids, Grid(800, 400, GSD))
    boats = _rows(500, 2, 200)
    new, notes = water_from_boats(boats, cm, GSD)
    assert (new.ids == WATER).sum() == (ids == WATER).sum() and notes == {}


def test_a_boat_beside_water_extends_the_water_under_it():
    """A single boat at the edge of the segmented water (its hull read as land) is water under it."""
    ids = np.full((400, 600), GRASS, np.uint8)
    ids[:, :200] = WATER
    cm = ClassMap(ids, Grid(600, 400, GSD))
    boat = _boat(210, 200, yaw=0.0)  # 8 m long, from x = 194 to 226 px: mostly over "grass"
    new, notes = water_from_boats([boat], cm, GSD)
    assert new.ids[200, 220] == WATER and new.ids[200, 300] == GRASS
    assert notes["water_from_boats_m2"] > 0


def test_one_weak_boat_beside_water_is_no_evidence_but_a_weak_row_is():
    """A lone boat the detector is barely sure of (a rock mole taken for a boat) leaves the class map alone;
    three as unsure in a row still mark water."""
    ids = np.full((400, 600), GRASS, np.uint8)
    ids[:, :200] = WATER
    cm = ClassMap(ids, Grid(600, 400, GSD))
    new, notes = water_from_boats([_boat(210, 200, yaw=0.0, score=0.45)], cm, GSD)
    assert (new.ids == WATER).sum() == (ids == WATER).sum() and notes == {}
    row = [_boat(300, 100 + i * 14, yaw=0.0, score=0.45) for i in range(3)]  # moored side by side, far out
    new, notes = water_from_boats(row, cm, GSD)
    assert new.ids[114, 300] == WATER and notes["boat_clusters_made_water"] == 1


def test_unsure_boats_do_not_move_the_water():
    ids = np.full((400, 600), ASPHALT, np.uint8)
    cm = ClassMap(ids, Grid(600, 400, GSD))
    new, _ = water_from_boats([_boat(100 + i * 14, 200, score=0.3) for i in range(8)], cm, GSD)
    assert (new.ids == WATER).sum() == 0


def test_a_car_in_a_patch_of_water_among_land_stays_a_car():
    """A dark car park partly read as water: the car standing in that patch keeps its category (the class
    map is what is wrong there); the same car in open water would be a boat."""
    from coastforge.consistency import recategorise

    ids = np.full((400, 600), ASPHALT, np.uint8)
    ids[194:206, 290:312] = WATER  # a 5.5 x 3 m "water" patch (a dark bay) under the car
    car = Detection("vehicle", 0.7, 300.0, 200.0, 4.6 / GSD, 1.9 / GSD, 0.0)
    out, notes = recategorise([car], ClassMap(ids, Grid(600, 400, GSD)), DetectConfig())
    assert out[0].category == "vehicle" and notes == {"vehicles_on_land_read_as_water_kept": 1}
    ids[:] = WATER
    out, _ = recategorise([car], ClassMap(ids, Grid(600, 400, GSD)), DetectConfig())
    assert out[0].category == "boat"


def test_cars_on_rocks_far_from_water_stay():
    """Riprap lines the water: a car on "rocks" by the water goes (the net takes riprap blocks for cars),
    one on "rocks" 40 m from any water is on textured ground the class map got wrong and stays."""
    from coastforge.classes import ROCKS
    from coastforge.consistency import recategorise

    ids = np.full((400, 800), ASPHALT, np.uint8)
    ids[:, :40] = WATER
    ids[150:250, 40:80] = ROCKS  # a revetment by the water
    ids[150:250, 600:700] = ROCKS  # cobbles in a street far inland
    cm = ClassMap(ids, Grid(800, 400, GSD))
    by_water = Detection("vehicle", 0.7, 60.0, 200.0, 4.6 / GSD, 1.9 / GSD, 90.0)
    inland = Detection("vehicle", 0.7, 650.0, 200.0, 4.6 / GSD, 1.9 / GSD, 90.0)
    out, notes = recategorise([by_water, inland], cm, DetectConfig())
    assert out == [inland] and notes == {"vehicles_on_riprap_dropped": 1}
