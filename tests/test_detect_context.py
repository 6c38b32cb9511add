"""Detections checked against the terrain classes: no boats far from water (any backend)."""

import numpy as np

from coastforge.classes import ASPHALT, GRASS, WATER
from coastforge.config import DetectConfig
from coastforge.detection import boats_off_water, drop_cut_by_frame, inside_share
from coastforge.types import ClassMap, Detection, Grid

GSD = 0.125


def _map(water_cols: int) -> ClassMap:
    ids = np.full((400, 800), ASPHALT, np.uint8)
    ids[:, 600:] = GRASS
    ids[:, :water_cols] = WATER
    return ClassMap(ids, Grid(800, 400, GSD))


def _boat(cx, length_m, width_m, category="boat"):
    return Detection(category, 0.8, float(cx), 200.0, length_m / GSD, width_m / GSD, 90.0, heading_known=True,
                     heading_confidence=0.9)


def test_boats_far_from_water_become_vehicles_or_go():
    cfg = DetectConfig()  # near_water_m = 15 m = 120 px
    car = _boat(400, 4.6, 1.9)  # on asphalt, 300 px (37 m) from the water
    planter = _boat(500, 10.0, 4.0)  # too wide for a vehicle
    on_grass = _boat(700, 4.6, 1.9)  # car-sized, but on grass
    buoy = _boat(450, 1.0, 1.0, "buoy")
    near = _boat(150, 6.0, 2.4)  # 50 px (6 m) from the water: a boat on the slip stays a boat
    vehicle = _boat(300, 4.5, 1.8, "vehicle")
    out = boats_off_water([car, planter, on_grass, buoy, near, vehicle], _map(100), GSD, cfg)
    assert [(d.category, d.cx_px) for d in out] == [("vehicle", 400.0), ("boat", 150.0), ("vehicle", 300.0)]
    assert out[0].heading_known is False  # the matcher decides a converted car's front
    assert out[1].heading_known is True


def test_a_class_map_without_water_decides_nothing_and_a_harbour_keeps_its_boats():
    car = _boat(400, 4.6, 1.9)
    # no water segmented (a sea painted as grass would otherwise cost every boat): left as they are
    assert [d.category for d in boats_off_water([car], _map(0), GSD, DetectConfig())] == ["boat"]
    # water reaches to 20 px of the box's end: kept
    assert [d.category for d in boats_off_water([car], _map(370), GSD, DetectConfig())] == ["boat"]


def test_an_unsure_boat_with_no_water_under_it_is_no_boat_however_near_the_water():
    """``DRY_BOAT_MAX_SCORE``: the detector unsure and the class map calling the whole box land; either alone
    is not enough (a sure boat on the slip stays, so does an unsure one touching the water)."""
    from dataclasses import replace

    from coastforge.detection import DRY_BOAT_MAX_SCORE

    unsure = DRY_BOAT_MAX_SCORE - 0.05
    car = replace(_boat(150, 4.6, 1.9), score=unsure)  # on the quay road, 6 m from the water
    log = replace(_boat(680, 4.6, 1.9), score=unsure)  # on the grass beyond
    sure = _boat(150, 4.6, 1.9)  # score 0.8: a boat on its trailer
    moored = replace(_boat(105, 4.6, 1.9), score=unsure)  # its box (x 97-113) reaches into the water (x < 100)
    out = boats_off_water([car, log, sure, moored], _map(100), GSD, DetectConfig())
    assert [(d.category, d.cx_px, d.score) for d in out] == [
        ("vehicle", 150.0, unsure), ("boat", 150.0, 0.8), ("boat", 105.0, unsure)]
    assert out[0].heading_known is False


def _rgb(water_cols: int) -> np.ndarray:
    """Grey asphalt (a little grain); a smooth blue-green sea over the first ``water_cols`` columns."""
    rng = np.random.default_rng(0)
    rgb = np.clip(np.full((400, 800, 3), (95, 97, 100), np.float32) + rng.normal(0, 6, (400, 800, 1)), 0, 255)
    rgb[:, :water_cols] = (40, 90, 110)
    return rgb.astype(np.uint8)


def test_without_water_in_the_map_nor_in_the_image_boats_are_on_land():
    # an inland tile (a car park, a tennis club): the class map has no water, and neither has the image
    car = _boat(400, 4.6, 1.9)
    on_grass = _boat(700, 4.6, 1.9)
    buoy = _boat(450, 1.0, 1.0, "buoy")
    out = boats_off_water([car, on_grass, buoy], _map(0), GSD, DetectConfig(), rgb=_rgb(0))
    assert [(d.category, d.cx_px) for d in out] == [("vehicle", 400.0)]
    # the image shows a sea the segmenter missed (300 x 400 px = 1875 m²): nothing is decided
    kept = boats_off_water([car, buoy], _map(0), GSD, DetectConfig(), rgb=_rgb(300))
    assert [d.category for d in kept] == ["boat", "buoy"]


def test_vehicles_on_riprap_go_and_vehicles_in_water_are_boats():
    """A breakwater: a 2 m walkway between riprap, water beyond. Car-sized boxes on its riprap (the learned
    net took the blocks for cars) go; one standing in the water is a small boat (category from context);
    a car on the walkway, one at the quay's edge and one on the car park stay; boats are not concerned."""
    from coastforge.classes import ROCKS, SIDEWALK
    from coastforge.consistency import recategorise

    ids = np.full((400, 800), WATER, np.uint8)
    ids[200:400, :] = ASPHALT  # a quay and car park in the south half
    ids[60:156, :] = ROCKS  # a breakwater: riprap ...
    ids[100:116, :] = SIDEWALK  # ... around a 2 m walkway
    cm = ClassMap(ids, Grid(800, 400, GSD))

    def car(cx, cy, yaw=0.0):
        return Detection("vehicle", 0.7, float(cx), float(cy), 4.6 / GSD, 1.9 / GSD, yaw)

    on_riprap = car(300, 80)
    half_on_riprap = car(500, 117.5)  # about 60 % on the riprap, 40 % on the walkway
    in_water = car(300, 30)
    on_walkway = car(400, 108)  # the walkway is 16 px wide, the car 15 px
    at_quay_edge = car(300, 212)  # water right north of it, asphalt under it
    in_car_park = car(300, 320, yaw=90.0)
    boat = Detection("boat", 0.8, 600.0, 30.0, 6 / GSD, 2.4 / GSD, 0.0)
    dets = [on_riprap, half_on_riprap, in_water, on_walkway, at_quay_edge, in_car_park, boat]
    out, notes = recategorise(dets, cm, DetectConfig())
    assert [(d.category, d.cx_px, d.cy_px) for d in out] == [
        ("boat", 300.0, 30.0), ("vehicle", 400.0, 108.0), ("vehicle", 300.0, 212.0), ("vehicle", 300.0, 320.0),
        ("boat", 600.0, 30.0)]
    assert out[0].heading_known is False  # the matcher decides the converted boat's front
    assert notes == {"vehicles_in_water_made_boats": 1, "vehicles_on_riprap_dropped": 2}
    out, _ = recategorise(dets, cm, DetectConfig(vehicle_max_wet=0.7))
    assert half_on_riprap in out and on_riprap not in out


def test_objects_mostly_outside_the_picture_are_left_out_and_piers_run_on():
    # a 200 x 100 px image; boats 40 px long lying along x
    half_out = Detection("boat", 0.9, 200.0, 50.0, 40.0, 10.0, 0.0)   # 20 of 40 px inside
    most_in = Detection("boat", 0.9, 185.0, 50.0, 40.0, 10.0, 0.0)    # 35 of 40 px inside
    car_top = Detection("vehicle", 0.9, 60.0, 1.0, 20.0, 8.0, 90.0)   # 11 of 20 px inside
    walkway = Detection("pier_walkway", 0.8, 190.0, 20.0, 60.0, 4.0, 0.0)
    inner = Detection("boat", 0.9, 100.0, 50.0, 40.0, 10.0, 30.0)
    assert abs(inside_share(half_out, 200, 100) - 0.5) < 1e-6
    kept = drop_cut_by_frame([half_out, most_in, car_top, walkway, inner], 200, 100, 0.7)
    assert kept == [most_in, walkway, inner]
    assert len(drop_cut_by_frame([half_out, most_in, car_top, walkway, inner], 200, 100, 0.0)) == 5
