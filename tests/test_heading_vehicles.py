"""Vehicle fronts when the glass is not darker than the paint: the contrast cue
(``heading.glass_contrast``) and the weighted combination with the detector (``heading.vehicle_fronts``),
on cars drawn from above in numpy."""

from dataclasses import replace

import numpy as np
import pytest

from coastforge.detection.heading import (FRONT_MAX_CUE, FRONT_W_NET, box_coords, glass_contrast,
                                          glass_evidence, vehicle_fronts)
from coastforge.frames import wrap_deg
from coastforge.types import Detection

GROUND = (110, 110, 105)


def draw_car(yaw, paint, screen, rear, size=(96, 96), length=46.0, width=18.0, bed=None):
    """A car from above, front at ``yaw``: ``paint`` body, a long windscreen (colour ``screen``) in front
    of the roof and a short rear window (colour ``rear``); ``bed``: colour of an open rear bed."""
    h, w = size
    det = Detection("vehicle", 0.9, w / 2, h / 2, length, width, yaw)
    rr, cc = np.mgrid[0:h, 0:w]
    u, v = box_coords(det, cc, rr)
    un, vn = u / length, v / width
    rgb = np.empty((h, w, 3), np.uint8)
    rgb[:] = GROUND
    body = (np.abs(un) <= 0.5) & (np.abs(vn) <= 0.5)
    rgb[body] = paint
    glass = body & (np.abs(vn) <= 0.42)
    rgb[glass & (un >= 0.04) & (un <= 0.20)] = screen
    if bed is not None:
        rgb[glass & (un >= -0.48) & (un <= -0.16)] = bed
    else:
        rgb[glass & (un >= -0.27) & (un <= -0.18)] = rear
    return rgb, det


BLACK, SKY_GLASS, DARK_GLASS = (22, 24, 28), (95, 100, 110), (10, 12, 16)


@pytest.mark.parametrize("yaw", [0.0, 53.0, -120.0])
def test_contrast_cue_finds_a_sky_lit_windscreen_on_a_black_car(yaw):
    # the windscreen mirrors the sky (lighter than the black paint), the rear window is as dark as
    # the paint: the dark-glass cue sees nothing to the front, the contrast cue does
    rgb, det = draw_car(yaw, BLACK, SKY_GLASS, (18, 20, 24))
    assert glass_evidence(rgb, det) <= 0.0
    assert glass_contrast(rgb, det) > 0.5
    back = replace(det, yaw_deg=float(wrap_deg(yaw + 180.0)))
    assert glass_contrast(rgb, back) < -0.5


def test_contrast_cue_sees_grey_glass_on_coloured_paint():
    # glass as light as the (red) paint: only the hue differs
    rgb, det = draw_car(20.0, (170, 40, 45), (85, 85, 90), (85, 85, 90))
    # windscreen 0.16 L, rear window 0.09 L: (0.16 - 0.09) / 0.25 = 0.28 of the glass lies ahead
    assert glass_contrast(rgb, det) > 0.2


def test_a_pickup_bed_does_not_turn_the_pickup_round():
    # the dark bed (0.32 L, at the rear) holds more dark samples than the windscreen: the contrast cue
    # must not read it as glass at the back; the dark-glass cue (beds left out) turns a wrong front round
    rgb, det = draw_car(75.0, (175, 178, 183), DARK_GLASS, None, length=52.0, width=19.0, bed=DARK_GLASS)
    assert glass_contrast(rgb, det) >= 0.0
    wrong = replace(det, yaw_deg=float(wrap_deg(255.0)), heading_known=False, heading_confidence=0.6)
    assert abs(wrap_deg(vehicle_fronts(rgb, [wrong])[0].yaw_deg - 75.0)) < 1e-6


def test_contrast_cue_needs_contrast_and_size():
    rgb, det = draw_car(75.0, BLACK, SKY_GLASS, BLACK)
    plain = np.full_like(rgb, 120)
    assert glass_contrast(plain, det) == 0.0
    small, tiny = draw_car(10.0, BLACK, SKY_GLASS, BLACK, size=(24, 24), length=8.0, width=3.5)
    assert glass_contrast(small, tiny) == 0.0


def test_vehicle_fronts_turns_a_black_car_round_by_its_windscreen():
    rgb, det = draw_car(30.0, BLACK, SKY_GLASS, (18, 20, 24))
    wrong = replace(det, yaw_deg=float(wrap_deg(210.0)), heading_known=True, heading_confidence=0.7)
    got = vehicle_fronts(rgb, [wrong])[0]
    assert abs(wrap_deg(got.yaw_deg - 30.0)) < 1e-6 and got.heading_confidence > 0.6


def test_cues_never_outweigh_a_sure_detector():
    # both cues at full strength against the detector: capped at FRONT_MAX_CUE in log-odds
    rgb, det = draw_car(-40.0, (230, 230, 232), DARK_GLASS, (200, 200, 205))
    assert glass_evidence(rgb, det) > 2.0 and glass_contrast(rgb, det) > 0.5
    sure_logit = FRONT_MAX_CUE / FRONT_W_NET + 0.5
    conf = float(1.0 / (1.0 + np.exp(-sure_logit)))
    flipped = replace(det, yaw_deg=float(wrap_deg(140.0)), heading_known=True, heading_confidence=conf)
    got = vehicle_fronts(rgb, [flipped])[0]
    assert abs(wrap_deg(got.yaw_deg - 140.0)) < 1e-6
    unsure = replace(flipped, heading_confidence=0.6)
    assert abs(wrap_deg(vehicle_fronts(rgb, [unsure])[0].yaw_deg + 40.0)) < 1e-6
