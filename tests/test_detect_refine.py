"""Box refinement (``coastforge.detection.refine``) on small drawn scenes with known geometry."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from coastforge.config import DetectConfig
from coastforge.detection import detect
from coastforge.detection.refine import refine_box, refine_boxes, symmetry_axis
from coastforge.detection.verify import is_buoy
from coastforge.frames import box_corners_px, wrap_deg
from coastforge.types import Detection, GeoImage, Grid

SS = 8  # drawn at 8x and area-averaged down: anti-aliased, sub-pixel exact edges


def _scene(objects, size=160, ground=(60, 110, 120), shadow=(2.5, 2.0)):
    """Ground with each object (cx, cy, length, width, yaw, colour) drawn as a rectangle with a dark
    glass band across it and a cast shadow offset by ``shadow`` pixels."""
    big = np.zeros((size * SS, size * SS, 3), np.uint8)
    big[:] = ground
    dark = tuple(int(c * 0.45) for c in ground)
    for cx, cy, length, width, yaw, _colour in objects:
        sh = box_corners_px(cx + shadow[0], cy + shadow[1], length, width, yaw)
        cv2.fillPoly(big, [np.round(sh * SS).astype(np.int32)], dark)
    for cx, cy, length, width, yaw, colour in objects:
        body = box_corners_px(cx, cy, length, width, yaw)
        cv2.fillPoly(big, [np.round(body * SS).astype(np.int32)], colour)
        f = np.array([math.cos(math.radians(yaw)), -math.sin(math.radians(yaw))])
        g = 0.18 * length
        glass = box_corners_px(cx + f[0] * g, cy + f[1] * g, length * 0.12, width * 0.85, yaw)
        cv2.fillPoly(big, [np.round(glass * SS).astype(np.int32)], (25, 30, 35))
    return cv2.resize(big, (size, size), interpolation=cv2.INTER_AREA)


def _err(a, b):
    return abs((a - b + 90.0) % 180.0 - 90.0)


@pytest.mark.parametrize("yaw,off", [(23.0, 4.0), (-61.0, -3.0), (100.0, 2.5)])
def test_refined_yaw_recovers_a_drawn_vehicle(yaw, off):
    # a 4.6 x 1.9 m car at 0.1 m/px; the detector's box is off by `off` degrees and 2 px sideways
    rgb = _scene([(80.3, 79.6, 46.0, 19.0, yaw, (200, 40, 40))])
    det = Detection("vehicle", 0.9, 81.0, 78.5, 44.0, 20.0, yaw + off, heading_known=True,
                    heading_confidence=0.9)
    out = refine_box(rgb, det, 0.1)
    assert _err(out.yaw_deg, yaw) < 0.5
    assert abs(wrap_deg(out.yaw_deg - yaw)) < 90  # the front stays where the detector put it
    assert out.heading_known and out.heading_confidence == det.heading_confidence
    # the centre moves onto the car's axis and its ends (the shadow is not part of it)
    assert math.hypot(out.cx_px - 80.3, out.cy_px - 79.6) < 1.0
    assert abs(out.length_px - 46.0) < 2.0


def test_symmetry_axis_sign_and_shift():
    rgb = _scene([(80.0, 80.0, 60.0, 22.0, 10.0, (230, 230, 225))], shadow=(0.0, 0.0))
    det = Detection("boat", 0.9, 80.0, 80.0, 60.0, 22.0, 13.0)
    dyaw, dv, contrast = symmetry_axis(rgb, det)
    assert abs(dyaw + 3.0) < 0.4 and abs(dv) < 0.6 and contrast > 1.2


def test_refinement_keeps_the_box_when_nothing_is_there():
    rgb = np.full((120, 120, 3), (60, 110, 120), np.uint8)
    det = Detection("vehicle", 0.9, 60.0, 60.0, 40.0, 16.0, 30.0)
    out = refine_box(rgb, det, 0.1)
    assert (out.cx_px, out.cy_px, out.length_px, out.width_px) == (60.0, 60.0, 40.0, 16.0)
    assert _err(out.yaw_deg, 30.0) < 10.0  # no structure: at most the search range


def test_piers_are_untouched_and_glints_are_not_buoys():
    water = (40, 100, 120)
    big = np.zeros((200 * SS, 200 * SS, 3), np.uint8)
    big[:] = water
    cv2.circle(big, (50 * SS, 50 * SS), int(5 * SS), (235, 235, 230), -1)  # a 1 m buoy at 0.1 m/px
    cv2.ellipse(big, (150 * SS, 150 * SS), (int(2.5 * SS), int(0.8 * SS)), 30, 0, 360, (235, 235, 235), -1)
    rgb = cv2.resize(big, (200, 200), interpolation=cv2.INTER_AREA)
    buoy = Detection("buoy", 0.8, 50.5, 49.5, 10.0, 10.0, 0.0)
    glint = Detection("buoy", 0.8, 150.0, 150.0, 10.0, 9.0, 0.0)
    pier = Detection("pier_walkway", 0.8, 100.0, 100.0, 80.0, 10.0, 5.0)
    assert is_buoy(rgb, buoy, 0.1) and not is_buoy(rgb, glint, 0.1)
    out = refine_boxes(rgb, [buoy, glint, pier], 0.1)
    assert [d.category for d in out] == ["buoy", "pier_walkway"]
    assert out[1] == pier
    assert math.hypot(out[0].cx_px - 50.0, out[0].cy_px - 50.0) < 0.5  # centre onto the disc


def test_detect_applies_refinement_after_the_backend(monkeypatch):
    rgb = _scene([(80.3, 79.6, 46.0, 19.0, 23.0, (200, 40, 40))])
    img = GeoImage(rgb=rgb, grid=Grid(160, 160, 0.1))
    rough = Detection("vehicle", 0.9, 81.0, 78.5, 44.0, 20.0, 27.0, heading_known=True, heading_confidence=0.8)

    class Fixed:
        def __init__(self, config, **_):
            pass

        def detect(self, image, class_map, seed):
            return [rough]

    from coastforge import registry

    monkeypatch.setattr(registry, "load", lambda stage, name: Fixed)
    on = detect(img, DetectConfig(), backend="fixed")
    off = detect(img, replace(DetectConfig(), refine=False), backend="fixed")
    assert off == [rough]
    assert _err(on[0].yaw_deg, 23.0) < 0.5


def test_dark_water_patches_are_not_boats():
    water = (50, 105, 115)
    big = np.zeros((160 * SS, 160 * SS, 3), np.uint8)
    big[:] = water
    # a weed patch: the water's colour at 60 % brightness; a white hull next to it
    # (cv2 angles turn clockwise on screen: -yaw)
    cv2.ellipse(big, (50 * SS, 80 * SS), (20 * SS, 8 * SS), -20, 0, 360, tuple(int(c * 0.6) for c in water), -1)
    cv2.ellipse(big, (115 * SS, 80 * SS), (22 * SS, 8 * SS), 20, 0, 360, (225, 225, 220), -1)
    rgb = cv2.resize(big, (160, 160), interpolation=cv2.INTER_AREA)
    weed = Detection("boat", 0.5, 50.0, 80.0, 40.0, 16.0, 20.0)
    hull = Detection("boat", 0.5, 115.0, 80.0, 44.0, 16.0, -20.0)
    out = refine_boxes(rgb, [weed, hull], 0.1)
    assert len(out) == 1 and out[0].cx_px > 100


def test_a_large_dark_hull_is_kept_a_small_dark_patch_is_not():
    # 0.2 m/px: a 9 m dark-blue hull with a lighter deck line and a 4 m patch of darker water
    # (the water's colour at 60 %), both darker than the water with about its chromaticity
    water = (50, 105, 115)
    big = np.zeros((160 * SS, 200 * SS, 3), np.uint8)
    big[:] = water
    dark = tuple(int(c * 0.45) for c in water)
    cv2.ellipse(big, (60 * SS, 80 * SS), (22 * SS, 8 * SS), -10, 0, 360, dark, -1)  # 45 px = 9 m
    cv2.ellipse(big, (60 * SS, 80 * SS), (10 * SS, 1 * SS), -10, 0, 360, (90, 110, 120), -1)
    weed = tuple(int(c * 0.6) for c in water)
    cv2.ellipse(big, (150 * SS, 80 * SS), (10 * SS, 4 * SS), 20, 0, 360, weed, -1)
    rgb = cv2.resize(big, (200, 160), interpolation=cv2.INTER_AREA)
    hull = Detection("boat", 0.6, 60.0, 80.0, 45.0, 17.0, 10.0)
    patch = Detection("boat", 0.5, 150.0, 80.0, 20.0, 8.0, 20.0)
    from coastforge.detection.verify import core_evidence, is_dark_water

    assert 0.8 <= core_evidence(rgb, hull, 0.2)["shadow"] < 0.95  # a dark-water-like core, yet ...
    assert not is_dark_water(rgb, hull, 0.2)  # ... yacht-sized: a dark hull
    assert is_dark_water(rgb, patch, 0.2)
    assert [d.cx_px for d in refine_boxes(rgb, [hull, patch], 0.2)] == [pytest.approx(60.0, abs=2.0)]


def test_an_axis_off_by_more_than_the_search_is_still_turned_when_clear():
    # a white boat at 0.2 m/px, the detector's axis 13° off: the optimum lies at the search's edge
    rgb = _scene([(80.0, 80.0, 40.0, 15.0, 25.0, (230, 230, 225))], shadow=(0.0, 0.0))
    det = Detection("boat", 0.9, 80.0, 80.0, 40.0, 15.0, 38.0, heading_known=True, heading_confidence=0.9)
    sym = symmetry_axis(rgb, det)
    assert sym is not None and abs(sym[0]) > 11.75 and sym[2] >= 1.4  # beyond the old limit, clear
    out = refine_box(rgb, det, 0.2)
    assert _err(out.yaw_deg, 25.0) < 1.5
