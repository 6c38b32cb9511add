"""Refinement of small objects (``coastforge.detection.refine``): sun glints told from buoys by their
surroundings and colour, small boats' boxes lengthened to their hull's ends."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from coastforge.detection.refine import boat_ends, refine_box
from coastforge.detection.verify import buoy_features, is_buoy, is_glint
from coastforge.frames import box_corners_px
from coastforge.types import Detection

GSD = 0.2
WATER = np.array([40.0, 105.0, 120.0])


def _water(size: int) -> np.ndarray:
    rgb = np.zeros((size, size, 3), np.float64)
    rgb[:] = WATER
    return rgb


def _glint(rgb: np.ndarray, cx: float, cy: float) -> None:
    """A sun glint: white sunlight added to the water, with fainter ripples around it."""
    yy, xx = np.mgrid[: rgb.shape[0], : rgb.shape[1]]
    r2 = ((xx + 0.5 - cx) ** 2 + (yy + 0.5 - cy) ** 2) * GSD * GSD
    k = 140.0 * np.exp(-r2 / (2 * 0.3 ** 2)) + 12.0 * np.exp(-r2 / (2 * 0.9 ** 2))
    rgb += k[..., None]


def _buoy(rgb: np.ndarray, cx: float, cy: float, colour=(235, 235, 230), shadow: bool = True) -> None:
    """A 1 m float drawn at 8x and area-averaged down, with its shadow beside it."""
    ss = 8
    h, w = rgb.shape[:2]
    big = cv2.resize(rgb.astype(np.float32), (w * ss, h * ss), interpolation=cv2.INTER_NEAREST)
    r = 0.5 / GSD * ss
    if shadow:
        cv2.circle(big, (int((cx + 0.35 / GSD) * ss), int((cy + 0.25 / GSD) * ss)), int(r),
                   tuple(float(c) * 0.6 for c in WATER), -1)
    cv2.circle(big, (int(cx * ss), int(cy * ss)), int(r), tuple(float(c) for c in colour), -1)
    rgb[:] = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)


def _u8(rgb: np.ndarray) -> np.ndarray:
    return np.clip(np.round(rgb), 0, 255).astype(np.uint8)


def test_a_glint_is_no_buoy_but_a_buoy_with_its_shadow_is():
    rgb = _water(80)
    _glint(rgb, 20.0, 20.0)
    _buoy(rgb, 60.0, 60.0)
    img = _u8(rgb)
    glint = Detection("buoy", 0.7, 20.0, 20.0, 5.0, 5.0, 0.0)
    buoy = Detection("buoy", 0.7, 60.0, 60.0, 5.0, 5.0, 0.0)
    g, b = buoy_features(img, glint, GSD), buoy_features(img, buoy, GSD)
    # both pass the shape checks: only the surroundings and colour tell them apart
    for f in (g, b):
        assert f["area"] >= 0.25 and f["aspect"] <= 1.4 and f["peak"] >= 24
    assert g["ring_mean"] > 0 and g["ring_p10"] > -1.4 and g["tint"] < 0.1
    assert is_glint(g) and not is_glint(b)
    assert not is_buoy(img, glint, GSD) and is_buoy(img, buoy, GSD)


def test_a_coloured_buoy_without_a_shadow_is_kept():
    # sun straight above (no shadow beside it): a red float is not the water's colour brightened
    rgb = _water(40)
    _buoy(rgb, 20.0, 20.0, colour=(230, 60, 40), shadow=False)
    img = _u8(rgb)
    det = Detection("buoy", 0.7, 20.0, 20.0, 5.0, 5.0, 0.0)
    f = buoy_features(img, det, GSD)
    assert f["tint"] > 0.5 and not is_glint(f)
    assert is_buoy(img, det, GSD)


def _boat_scene(length_m: float, width_m: float, yaw: float, size: int = 96) -> np.ndarray:
    """A pale hull with a darker cockpit on water, drawn at 8x, blurred like a 0.2 m/px render."""
    ss = 8
    big = np.zeros((size * ss, size * ss, 3), np.uint8)
    big[:] = WATER.astype(np.uint8)
    c = size / 2.0
    hull = box_corners_px(c, c, length_m / GSD, width_m / GSD, yaw)
    cv2.fillPoly(big, [np.round(hull * ss).astype(np.int32)], (200, 190, 170))
    cock = box_corners_px(c, c, 0.4 * length_m / GSD, 0.6 * width_m / GSD, yaw)
    cv2.fillPoly(big, [np.round(cock * ss).astype(np.int32)], (110, 100, 95))
    img = cv2.resize(big, (size, size), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(img, (0, 0), 0.8)


def test_a_small_boat_box_is_lengthened_to_its_ends():
    yaw = 30.0
    rgb = _boat_scene(3.1, 1.5, yaw)
    true_px = 3.1 / GSD
    short = Detection("boat", 0.6, 48.0, 48.0, 0.8 * true_px, 1.5 / GSD, yaw)
    ends = boat_ends(rgb, short)
    # the ends are found where the blurred hull has nearly faded into the water: a little outside
    assert ends is not None and abs((ends[1] - ends[0]) - true_px) < 0.12 * true_px
    out = refine_box(rgb, short, GSD, axis=False)
    assert abs(out.length_px - true_px) < 0.12 * true_px
    assert math.hypot(out.cx_px - 48.0, out.cy_px - 48.0) < 1.0
    # a box longer than the hull is not shortened; one far too short is left alone
    assert refine_box(rgb, Detection("boat", 0.6, 48.0, 48.0, 1.2 * true_px, 7.5, yaw), GSD,
                      axis=False).length_px == 1.2 * true_px
    tiny = Detection("boat", 0.6, 48.0, 48.0, 0.5 * true_px, 7.5, yaw)
    assert refine_box(rgb, tiny, GSD, axis=False).length_px == tiny.length_px


def test_large_boats_keep_the_detector_length():
    yaw = -20.0
    rgb = _boat_scene(8.0, 3.0, yaw, size=128)
    det = Detection("boat", 0.8, 64.0, 64.0, 0.85 * 8.0 / GSD, 3.0 / GSD, yaw)
    assert refine_box(rgb, det, GSD, axis=False).length_px == det.length_px


def test_a_box_whose_middle_is_mostly_water_is_no_boat():
    from coastforge.detection.verify import core_evidence, is_dark_water

    # two pale foam blobs with churned, slightly paler water between them (a broken wake: as much
    # unlike the calm water as to pass the contrast test), and a pale hull
    ss = 8
    big = np.zeros((100 * ss, 160 * ss, 3), np.uint8)
    big[:] = WATER.astype(np.uint8)
    cv2.rectangle(big, (14 * ss, 42 * ss), (66 * ss, 58 * ss), tuple(int(c) + 7 for c in WATER), -1)
    for cx in (22, 58):
        cv2.circle(big, (cx * ss, 50 * ss), 5 * ss, (215, 225, 225), -1)
    cv2.fillPoly(big, [np.round(box_corners_px(120, 50, 36, 12, 0.0) * ss).astype(np.int32)], (215, 210, 200))
    rgb = cv2.resize(big, (160, 100), interpolation=cv2.INTER_AREA)
    wake = Detection("boat", 0.5, 40.0, 50.0, 46.0, 12.0, 0.0)
    hull = Detection("boat", 0.5, 120.0, 50.0, 36.0, 12.0, 0.0)
    assert core_evidence(rgb, wake, 0.2)["water"] > 0.5 > core_evidence(rgb, hull, 0.2)["water"]
    assert is_dark_water(rgb, wake, 0.2) and not is_dark_water(rgb, hull, 0.2)


@pytest.mark.parametrize("features, expected", [
    # passes the shape checks, no glint
    (dict(peak=30.0, area=0.4, aspect=1.1, ring_p10=-2.0, ring_mean=-0.5, tint=0.2), True),
    # a faint, 5 px buoy of the synthetic beach (peak and area just short, elongated by blur) with a clear
    # shadow in its own colour: kept
    (dict(peak=22.8, area=0.455, aspect=2.03, ring_p10=-6.07, ring_mean=-2.39, tint=0.40), True),
    (dict(peak=23.9, area=0.248, aspect=1.27, ring_p10=-3.56, ring_mean=-1.63, tint=0.19), True),
    # the same shape with the water's tint, or a brighter ring (a glint's ripples): dropped
    (dict(peak=22.8, area=0.455, aspect=2.03, ring_p10=-6.07, ring_mean=-2.39, tint=0.02), False),
    (dict(peak=22.8, area=0.455, aspect=2.03, ring_p10=-0.8, ring_mean=0.9, tint=0.40), False),
    # far smaller than a buoy (a speck beside its shadow): dropped
    (dict(peak=30.0, area=0.12, aspect=2.0, ring_p10=-7.3, ring_mean=-5.5, tint=0.24), False),
])
def test_a_faint_buoy_with_a_clear_shadow_of_its_own_colour_is_kept(monkeypatch, features, expected):
    from coastforge.detection import verify

    monkeypatch.setattr(verify, "buoy_features", lambda *a: features)
    det = Detection("buoy", 0.7, 10.0, 10.0, 5.0, 5.0, 0.0)
    assert verify.is_buoy(np.zeros((20, 20, 3), np.uint8), det, GSD) is expected
