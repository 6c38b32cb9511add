"""Matching, heading: the shape fit's heading evidence does not depend on which way the detector's box
points (each heading is fitted at its own best place), a fairly sure but wrong detector is overruled, the
detector's prior counts more on objects of few pixels, and the grey-level cue adds to the evidence."""

from __future__ import annotations

import math

import pytest

from coastforge.config import MatchConfig
from coastforge.matching import ShapeMatcher, heading_prior, match_detections
from coastforge.types import Detection

from test_matching import KINDS, _det, _scene, car_library  # noqa: F401  (fixture)


def _yaw_err(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("kind", KINDS)
def test_heading_evidence_does_not_follow_the_box_heading(car_library, kind):
    """The same car, boxed front-first and back-first: both fits find the true heading with the same NCC at
    it (before, the template was placed at the box heading's best fit, which favoured that heading)."""
    img = _scene(kind, (30, 32, 36), 30.0, 1.0)  # a near-black car: hardly any paint contrast
    sm = ShapeMatcher(car_library)
    right = _det(img, 4.6, 1.9, 30.0)
    back = _det(img, 4.6, 1.9, 210.0)
    a = sm.score(img.rgb, right, img.grid.gsd_m, list(KINDS), "ground")[kind]
    b = sm.score(img.rgb, back, img.grid.gsd_m, list(KINDS), "ground")[kind]
    assert not a.flipped and b.flipped
    assert abs(a.ncc - b.ncc) < 0.03 and abs(a.ncc_other_heading - b.ncc_other_heading) < 0.03, (a, b)
    # the fitted centre is the same point in the image: the offsets along the box's axes are mirrored
    assert abs(a.offset_m[0] + b.offset_m[0]) < 0.1 and abs(a.offset_m[1] + b.offset_m[1]) < 0.1, (a, b)


@pytest.mark.parametrize("kind,paint,conf", [("sedan", (30, 32, 36), 0.65), ("pickup", (30, 32, 36), 0.65),
                                             ("sedan", (96, 99, 104), 0.8), ("hatch", (96, 99, 104), 0.8),
                                             ("pickup", (96, 99, 104), 0.8)])
def test_wrong_detector_heading_is_corrected_by_the_fit(car_library, kind, paint, conf):
    """The detector fairly sure of the wrong front: the fit's evidence outweighs it, also on a near-black car
    (whose weak evidence the old box-heading placement turned toward the detector's heading)."""
    for yaw in (-60.0, 30.0):
        img = _scene(kind, paint, yaw, 1.0)
        det = _det(img, 4.6, 1.9, yaw + 180.0, known=True, conf=conf)
        dec = match_detections(img, [det], car_library, MatchConfig(), seed=0)[0]
        assert dec.asset_id == kind
        assert _yaw_err(dec.yaw_deg, yaw) < 1e-6 and dec.heading_source == "library", dec


def test_heading_prior_counts_more_on_small_objects():
    cfg = MatchConfig()
    big = Detection("vehicle", 0.9, 50, 50, 45.0, 18.0, 0.0, True, 0.8)
    small = Detection("vehicle", 0.9, 50, 50, 22.5, 9.0, 0.0, True, 0.8)
    huge = Detection("boat", 0.9, 50, 50, 300.0, 90.0, 0.0, True, 0.8)
    logit = math.log(0.8 / 0.2)
    assert heading_prior(cfg, big) == pytest.approx(cfg.heading_prior_weight * logit)
    assert heading_prior(cfg, small) == pytest.approx(2.0 * heading_prior(cfg, big))
    # long objects are compared at most MAX_LEN_PX long: their evidence is no finer than that
    assert heading_prior(cfg, huge) == pytest.approx(
        cfg.heading_prior_weight * logit * cfg.heading_prior_ref_px / ShapeMatcher.MAX_LEN_PX)
    flat = MatchConfig(heading_prior_ref_px=0.0)
    assert heading_prior(flat, small) == pytest.approx(flat.heading_prior_weight * logit)


def test_grey_cue_adds_to_the_library_evidence(car_library):
    """The grey-level cue (crop against the asset's mean view) points the right way on a painted car and is
    added, weighted and pixel-scaled, to the shape fit's heading evidence."""
    from coastforge.matching import _pixel_scaling, detection_crop, heading_evidence, mean_view

    img = _scene("sedan", (96, 99, 104), 30.0, 1.0)
    det = _det(img, 4.6, 1.9, 30.0, known=True, conf=0.8)
    view, view_gsd = mean_view(car_library, "sedan", "ground")
    assert view.shape == car_library.views_on("sedan", "ground")[0].shape
    crop, crop_gsd = detection_crop(img, det)
    grey = heading_evidence(crop, crop_gsd, view, view_gsd, 4.6, 1.9)
    assert grey > 0.05  # the windscreen and rear window where the mean view has them
    off = match_detections(img, [det], car_library, MatchConfig(heading_appearance_weight=0.0), seed=0)[0]
    on = match_detections(img, [det], car_library, MatchConfig(heading_appearance_weight=0.3), seed=0)[0]
    assert off.asset_id == on.asset_id == "sedan" and _yaw_err(on.yaw_deg, 30.0) < 1e-6
    expected = 0.3 * _pixel_scaling(MatchConfig(), det) * grey
    assert on.flip_evidence - off.flip_evidence == pytest.approx(expected, rel=1e-4, abs=1e-6)
