"""The self-check the user sees: implausible scenes are flagged, plausible ones are not."""

import numpy as np

from coastforge.classes import ASPHALT, GRASS, SAND, WATER
from coastforge.selfcheck import check_scene
from coastforge.types import Detection

GSD = 0.25


def _dets(cat: str, n: int, length_m: float, width_m: float) -> list[Detection]:
    return [Detection(cat, 0.8, 10.0 + 20 * i, 50.0, length_m / GSD, width_m / GSD, 0.0) for i in range(n)]


def _codes(w):
    return {x.code for x in w}


def test_a_plausible_marina_gives_no_warning():
    ids = np.full((800, 800), WATER, np.uint8)
    ids[:, 500:] = ASPHALT
    ids[:100, 500:] = GRASS
    dets = _dets("boat", 60, 9.0, 3.2) + _dets("vehicle", 30, 4.6, 1.9)
    assert check_scene(ids, GSD, dets) == []


def test_many_boats_little_water_and_one_class():
    ids = np.full((800, 800), ASPHALT, np.uint8)
    w = check_scene(ids, GSD, _dets("boat", 40, 9.0, 3.2))
    assert _codes(w) == {"boats_without_water", "one_class"}
    assert "segment.learned_water" in w[0].hint  # says what to try


def test_open_water_with_boats_is_plausible():
    ids = np.full((800, 800), WATER, np.uint8)
    assert check_scene(ids, GSD, _dets("boat", 12, 9.0, 3.2)) == []
    assert _codes(check_scene(ids, GSD, [])) == {"one_class"}  # no boat, no shore: say so


def test_density_and_size_say_the_gsd_is_wrong():
    ids = np.full((200, 200), WATER, np.uint8)  # 50 x 50 m of water
    ids[:, :60] = SAND
    w = check_scene(ids, GSD, _dets("boat", 120, 1.2, 0.5))  # 120 boats of 1.2 m: GSD ~x8 too coarse
    assert {"boat_density", "boat_size"} <= _codes(w)
    ids[:, 100:] = ASPHALT
    cars = _dets("vehicle", 400, 60.0, 25.0)
    assert {"vehicle_density", "vehicle_size"} <= _codes(check_scene(ids, GSD, cars))
