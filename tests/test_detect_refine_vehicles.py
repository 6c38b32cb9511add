"""Issue #6: vehicle axes at 0.2 m/px (``refine._vehicle_axis``), cars seen shifted onto the empty bay
beside them (``verify.drop_shifted_cars``), boat specks (``refine.BOAT_MIN_M``) and white glints (``is_glint``)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from coastforge.detection.refine import BOAT_MIN_M, VEH_SYM_PRIOR, _vehicle_axis, refine_boxes, symmetry_axis
from coastforge.detection.verify import SHIFTED_SCORE_RATIO, core_std_l, drop_shifted_cars
from coastforge.frames import box_corners_px
from coastforge.types import Detection

SS = 8  # drawn at 8x and area-averaged down: anti-aliased, sub-pixel exact edges
ASPHALT = (95, 97, 100)


def _cars(cars, size=120, ground=ASPHALT, blur=0.0, shadow=(1.0, 0.8)):
    """Ground with each car (cx, cy, length, width, yaw, colour) drawn as a body with a dark
    windscreen band and a cast shadow offset by ``shadow`` pixels; optionally Gaussian-blurred
    (``blur``: sigma in output pixels, as the 0.2 m/px renders are)."""
    big = np.zeros((size * SS, size * SS, 3), np.uint8)
    big[:] = ground
    dark = tuple(int(c * 0.5) for c in ground)
    for cx, cy, length, width, yaw, _colour in cars:
        sh = box_corners_px(cx + shadow[0], cy + shadow[1], length, width, yaw)
        cv2.fillPoly(big, [np.round(sh * SS).astype(np.int32)], dark)
    for cx, cy, length, width, yaw, colour in cars:
        cv2.fillPoly(big, [np.round(box_corners_px(cx, cy, length, width, yaw) * SS).astype(np.int32)], colour)
        f = np.array([math.cos(math.radians(yaw)), -math.sin(math.radians(yaw))])
        g = 0.15 * length
        glass = box_corners_px(cx + f[0] * g, cy + f[1] * g, length * 0.14, width * 0.8, yaw)
        cv2.fillPoly(big, [np.round(glass * SS).astype(np.int32)], (25, 30, 35))
    rgb = cv2.resize(big, (size, size), interpolation=cv2.INTER_AREA)
    if blur > 0:
        rgb = cv2.GaussianBlur(rgb, (0, 0), blur)
    return rgb


def _err(a, b):
    return abs((a - b + 90.0) % 180.0 - 90.0)


@pytest.mark.parametrize("yaw,off", [(14.0, 4.0), (-37.0, -3.0), (101.0, 6.0)])
def test_vehicle_axis_recovered_at_low_resolution(yaw, off):
    # a 4.6 x 1.9 m car at 0.2 m/px (23 x 9.5 px), blurred, its shadow beside it; the box is off
    rgb = _cars([(60.3, 59.6, 23.0, 9.5, yaw, (170, 40, 40))], blur=0.7)
    det = Detection("vehicle", 0.9, 60.0, 60.0, 22.0, 9.0, yaw + off, heading_known=True, heading_confidence=0.9)
    dyaw, _dv, contrast = symmetry_axis(rgb, det)
    assert _err(det.yaw_deg + dyaw, yaw) < 1.0 and contrast > 1.1


def test_vehicle_axis_stays_when_nothing_is_there():
    # a flat cost: the turn's cost keeps the detector's axis (the old search ended anywhere in +-12°)
    rgb = np.full((120, 120, 3), ASPHALT, np.uint8)
    det = Detection("vehicle", 0.9, 60.0, 60.0, 23.0, 9.5, 30.0)
    dyaw, dv, _ = _vehicle_axis(rgb, det)
    assert abs(dyaw) < 0.5 and abs(dv) < 1.0
    assert VEH_SYM_PRIOR > 0


def test_boats_keep_their_mirror_search():
    # only vehicles take the new search: a boat's result is that of the general mirror search
    rgb = _cars([(60.0, 60.0, 40.0, 14.0, 20.0, (230, 230, 225))], size=120, ground=(40, 100, 120))
    boat = Detection("boat", 0.9, 60.0, 60.0, 40.0, 14.0, 24.0)
    car = Detection("vehicle", 0.9, 60.0, 60.0, 40.0, 14.0, 24.0)
    sb, sc = symmetry_axis(rgb, boat), symmetry_axis(rgb, car)
    assert _err(24.0 + sb[0], 20.0) < 1.0 and _err(24.0 + sc[0], 20.0) < 1.0
    assert sb != sc


def _row_scene():
    # a textured red car (windscreen) at the left of a row; beside it, one width to its right, the
    # empty bay with its shadow
    return _cars([(40.0, 60.0, 23.0, 9.5, 90.0, (170, 40, 40))], shadow=(3.0, 0.0))


def test_a_weaker_box_on_the_empty_bay_beside_a_car_is_dropped():
    rgb = _row_scene()
    car = Detection("vehicle", 0.85, 40.0, 60.0, 23.0, 9.5, 90.0)
    ghost = Detection("vehicle", 0.85 / (SHIFTED_SCORE_RATIO + 0.1), 51.5, 60.0, 23.0, 9.5, 90.0)
    assert core_std_l(rgb, ghost) < 4.0 <= core_std_l(rgb, car)
    assert drop_shifted_cars(rgb, [car, ghost]) == [car]


def test_neighbours_scored_alike_or_with_a_varied_core_are_kept():
    rgb = _cars([(40.0, 60.0, 23.0, 9.5, 90.0, (170, 40, 40)), (50.5, 60.0, 23.0, 9.5, 90.0, (40, 40, 170))])
    strong = Detection("vehicle", 0.9, 40.0, 60.0, 23.0, 9.5, 90.0)
    weak_car = Detection("vehicle", 0.5, 50.5, 60.0, 23.0, 9.5, 90.0)  # a real car: glass across its core
    assert drop_shifted_cars(rgb, [strong, weak_car]) == [strong, weak_car]
    plain = _row_scene()
    alike = Detection("vehicle", 0.8, 50.0, 60.0, 23.0, 9.5, 90.0)  # scored alike: not a shifted ghost
    assert drop_shifted_cars(plain, [strong, alike]) == [strong, alike]
    far = Detection("vehicle", 0.5, 70.0, 60.0, 23.0, 9.5, 90.0)  # three widths aside
    assert drop_shifted_cars(plain, [strong, far]) == [strong, far]


def test_boat_specks_are_dropped_and_small_boats_kept():
    water = (40, 100, 120)
    rgb = np.zeros((200, 200, 3), np.uint8)
    rgb[:] = water
    cv2.ellipse(rgb, (60, 100), (7, 3), 0, 0, 360, (230, 230, 225), -1)  # a 3 m dinghy at 0.2 m/px
    cv2.circle(rgb, (150, 100), 3, (230, 230, 225), -1)  # a 1.4 m speck
    dinghy = Detection("boat", 0.8, 60.5, 100.5, 14.0, 6.0, 0.0)
    speck = Detection("boat", 0.5, 150.5, 100.5, 6.0, 4.0, 0.0)
    out = refine_boxes(rgb, [dinghy, speck], 0.2)
    assert [round(d.cx_px) for d in out] == [60] or [round(d.cx_px) for d in out] == [61]
    assert all(d.length_px * 0.2 >= BOAT_MIN_M for d in out)


def test_white_glints_on_a_wavy_sea_are_glints_where_the_ring_is_resolved():
    from coastforge.detection.verify import is_glint

    white_glint = {"ring_p10": -0.8, "ring_mean": 2.4, "tint": 0.47}  # lake_harbor seed 3, 0.1 m/px
    assert is_glint(white_glint, 0.1)
    assert not is_glint(white_glint, 0.2)  # at 0.2 m/px the blob's blur reaches the ring: true buoys too
    assert not is_glint(white_glint)
    buoy = {"ring_p10": -1.5, "ring_mean": -0.2, "tint": 0.7}  # the brightest-ringed true buoy at 0.1 m/px
    assert not is_glint(buoy, 0.1)
    assert is_glint({"ring_p10": -1.0, "ring_mean": 0.5, "tint": 0.05})  # the water's own tint: as before


def test_vehicle_boxes_on_blank_ground_are_dropped_but_dark_cars_kept():
    from coastforge.detection.verify import is_blank_ground

    rng = np.random.default_rng(0)
    sand = np.clip(np.full((160, 160, 3), (200, 185, 150), np.float32) + rng.normal(0, 3, (160, 160, 1)), 0, 255)
    blank = Detection("vehicle", 0.42, 80.0, 80.0, 46.0, 18.0, 30.0)  # 4.6 m at 0.1 m/px, on nothing
    assert is_blank_ground(sand.astype(np.uint8), blank, 0.1)
    # a dark car on dark asphalt: little contrast, but its own colour
    rgb = _cars([(80.0, 80.0, 46.0, 18.0, 30.0, (38, 40, 44))], size=160, ground=(70, 72, 76))
    car = Detection("vehicle", 0.75, 80.0, 80.0, 46.0, 18.0, 30.0)
    assert not is_blank_ground(rgb, car, 0.1)
