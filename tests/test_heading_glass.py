"""Vehicle fronts: the windscreen/glass cue (``heading.glass_evidence``) and its combination with a
detector's own heading (``heading.vehicle_fronts``), on cars drawn from above in numpy."""

from dataclasses import replace

import numpy as np
import pytest

from coastforge.detection.heading import box_coords, cabin_sign, glass_evidence, vehicle_fronts
from coastforge.frames import wrap_deg
from coastforge.types import Detection

PAINT, GLASS, GROUND = (225, 225, 230), (25, 30, 40), (110, 110, 105)


def draw_car(yaw: float, size=(96, 96), length=46.0, width=18.0, paint=PAINT, bed=False):
    """A car seen from above with its front at ``yaw``: painted body, a long windscreen band in front
    of the roof, a short rear window behind it (and, with ``bed``, a dark open bed at the rear end, as
    on a pickup). Returns (rgb, the car's Detection with the true front)."""
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
    if bed:
        rgb[glass & (un >= -0.48) & (un <= -0.16)] = GLASS
        rgb[glass & (un >= 0.08) & (un <= 0.19)] = GLASS
    else:
        rgb[glass & (un >= 0.04) & (un <= 0.20)] = GLASS  # windscreen, ~0.75 m of 4.6 m
        rgb[glass & (un >= -0.27) & (un <= -0.18)] = GLASS  # rear window, ~0.4 m
    return rgb, det


@pytest.mark.parametrize("yaw", [0.0, 37.0, 90.0, -150.0, 200.0])
def test_glass_cue_points_to_the_windscreen(yaw):
    rgb, det = draw_car(yaw)
    assert glass_evidence(rgb, det) > 1.0
    back = replace(det, yaw_deg=float(wrap_deg(yaw + 180.0)))
    assert glass_evidence(rgb, back) < -1.0
    assert cabin_sign(rgb, det)[0] == 1 and cabin_sign(rgb, back)[0] == -1


def test_pickup_bed_is_not_taken_for_glass():
    # the dark bed holds more dark pixels than the windscreen, at the rear: counted as glass it would
    # turn the car round
    rgb, det = draw_car(60.0, length=52.0, width=19.0, bed=True)
    assert glass_evidence(rgb, det) > 1.0


def test_no_contrast_and_tiny_boxes_give_no_evidence():
    rgb, det = draw_car(10.0, paint=GROUND)
    rgb[:] = GROUND  # nothing to see
    assert glass_evidence(rgb, det) == 0.0
    rgb, det = draw_car(10.0, size=(24, 24), length=8.0, width=3.5)
    assert glass_evidence(rgb, det) == 0.0


def test_vehicle_fronts_combines_prior_and_cue():
    rgb, det = draw_car(30.0)
    flipped = float(wrap_deg(30.0 + 180.0))
    # a detector unsure of its (wrong) front is turned round by the windscreen, and is then surer
    weak = replace(det, yaw_deg=flipped, heading_known=False, heading_confidence=0.55)
    got = vehicle_fronts(rgb, [weak])[0]
    assert abs(wrap_deg(got.yaw_deg - 30.0)) < 1e-6
    assert got.heading_known and got.heading_confidence > 0.65
    # a detector that is certain keeps its front (the cue weighs at most GLASS_WEIGHT in log-odds)
    sure = replace(det, yaw_deg=flipped, heading_known=True, heading_confidence=0.9999)
    got = vehicle_fronts(rgb, [sure])[0]
    assert abs(wrap_deg(got.yaw_deg - flipped)) < 1e-6
    # with no evidence either way, the ambiguity stays explicit
    plain = rgb.copy()
    plain[:] = GROUND
    unsure = replace(det, heading_known=False, heading_confidence=0.52)
    got = vehicle_fronts(plain, [unsure])[0]
    assert not got.heading_known and got.heading_confidence < 0.6
    assert abs(wrap_deg(got.yaw_deg - 30.0)) < 1e-6


def test_vehicle_fronts_leaves_other_categories_alone():
    rgb, det = draw_car(0.0)
    boat = replace(det, category="boat", yaw_deg=180.0, heading_confidence=0.51)
    assert vehicle_fronts(rgb, [boat]) == [boat]


def test_faint_shading_does_not_count_as_glass():
    # a van: white body, its only glass a windscreen far forward, and a grey roof vent behind the
    # middle (darker than the paint, far lighter than glass): the vent must not turn the van round
    rgb, det = draw_car(-70.0, length=52.0, width=20.0)
    rr, cc = np.mgrid[0:rgb.shape[0], 0:rgb.shape[1]]
    u, v = box_coords(det, cc, rr)
    un, vn = u / det.length_px, v / det.width_px
    body = (np.abs(un) <= 0.5) & (np.abs(vn) <= 0.5)
    rgb[body] = (240, 240, 238)
    rgb[body & (np.abs(vn) <= 0.42) & (un >= 0.28) & (un <= 0.42)] = GLASS
    rgb[body & (np.abs(vn) <= 0.3) & (un >= -0.34) & (un <= 0.0)] = (185, 185, 185)
    assert glass_evidence(rgb, det) > 0.5


def test_detect_turns_a_weak_backend_front_round(monkeypatch):
    from coastforge import registry
    from coastforge.config import DetectConfig
    from coastforge.detection import detect
    from coastforge.types import GeoImage, Grid

    rgb, det = draw_car(25.0)
    wrong = replace(det, yaw_deg=float(wrap_deg(25.0 + 180.0)), heading_known=False, heading_confidence=0.56)

    class Fixed:
        def __init__(self, config, **_):
            pass

        def detect(self, image, class_map, seed):
            return [wrong]

    monkeypatch.setattr(registry, "load", lambda stage, name: Fixed)
    img = GeoImage(rgb=rgb, grid=Grid(rgb.shape[1], rgb.shape[0], 0.1))
    got = detect(img, DetectConfig(), backend="fixed")
    assert len(got) == 1 and abs(wrap_deg(got[0].yaw_deg - 25.0)) < 15.0
    # the classical backend decided with the same cue already; refine=false is the backend's raw output
    assert abs(wrap_deg(detect(img, DetectConfig(), backend="classical")[0].yaw_deg - 205.0)) < 15.0
    assert detect(img, replace(DetectConfig(), refine=False), backend="fixed") == [wrong]
