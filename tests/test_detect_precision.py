"""False-positive checks after detection (issue #6): wakes, pier pieces, car specks (``coastforge.detection.refine``) and duplicate car boxes (``coastforge.detection.learned``),
on small drawn scenes."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from coastforge.detection.refine import align_with_neighbours, refine_boxes
from coastforge.detection.verify import drop_wakes, is_structure_piece
from coastforge.frames import box_corners_px
from coastforge.types import Detection, GeoImage, Grid

SS = 8  # drawn at 8x and area-averaged down
WATER = (50, 105, 115)


def _canvas(w: int, h: int, colour=WATER) -> np.ndarray:
    big = np.zeros((h * SS, w * SS, 3), np.uint8)
    big[:] = colour
    return big


def _box(big: np.ndarray, cx, cy, length, width, yaw, colour) -> None:
    cv2.fillPoly(big, [np.round(box_corners_px(cx, cy, length, width, yaw) * SS).astype(np.int32)], colour)


def _down(big: np.ndarray) -> np.ndarray:
    h, w = big.shape[0] // SS, big.shape[1] // SS
    return cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)


def _hull(big, cx, cy, length, width, yaw=0.0) -> None:
    """A white hull with a darker cabin and a cast shadow (yaw 0: bow toward +x)."""
    _box(big, cx + 1.5, cy + 1.5, length, width, yaw, tuple(int(c * 0.5) for c in WATER))
    _box(big, cx, cy, length, width, yaw, (228, 228, 222))
    f = np.array([np.cos(np.radians(yaw)), -np.sin(np.radians(yaw))])  # forward in (col, row)
    _box(big, cx - 0.1 * length * f[0], cy - 0.1 * length * f[1], 0.3 * length, 0.55 * width, yaw, (120, 125, 135))


def _wake_scene(trail: bool) -> np.ndarray:
    """A 10 m boat at 0.2 m/px heading +x, and behind it either a foam trail (white speckles over
    water) or a second boat moored stern to stern."""
    big = _canvas(240, 100)
    _hull(big, 170, 50, 50, 17)
    if trail:
        rng = np.random.default_rng(0)
        for _ in range(90):  # foam: small white blobs with water between them
            x, y = rng.uniform(60, 140), rng.uniform(42, 58)
            cv2.circle(big, (int(x * SS), int(y * SS)), int(rng.uniform(0.8, 1.6) * SS), (200, 215, 215), -1)
    else:
        _hull(big, 85, 50, 50, 17, 180.0)
    return _down(big)


def test_a_wake_behind_a_boat_is_dropped_a_boat_stern_to_stern_is_not():
    boat = Detection("boat", 0.85, 170.0, 50.0, 50.0, 17.0, 0.0, heading_known=True, heading_confidence=0.9)
    behind = Detection("boat", 0.47, 100.0, 50.0, 48.0, 16.0, 0.0)
    rgb = _wake_scene(trail=True)
    assert drop_wakes(rgb, [boat, behind], 0.2) == [boat]
    rgb = _wake_scene(trail=False)
    second = Detection("boat", 0.8, 85.0, 50.0, 50.0, 17.0, 180.0, heading_known=True, heading_confidence=0.9)
    assert drop_wakes(rgb, [boat, second], 0.2) == [boat, second]
    # a foam trail in front of a boat is not its wake (boats do not push their wake ahead)
    ahead = Detection("boat", 0.85, 170.0, 50.0, 50.0, 17.0, 180.0, heading_known=True, heading_confidence=0.9)
    assert len(drop_wakes(_wake_scene(trail=True), [ahead, behind], 0.2)) == 2


def test_a_pier_piece_is_dropped_a_moored_boat_is_not():
    # 0.1 m/px: a plank finger (uniform brown) running out from a walkway; a box on its outer part is
    # a pier piece. A white boat moored bow-on to the walkway is not (the walkway is another colour).
    big = _canvas(300, 200)
    deck = (150, 120, 80)
    _box(big, 150, 20, 300, 24, 0.0, deck)  # walkway along the top
    _box(big, 60, 95, 24, 150, 0.0, deck)  # a finger going down from it (150 px = 15 m)
    _hull(big, 200, 82, 90, 30, 90.0)  # a 9 m boat, bow at the walkway
    rgb = _down(big)
    piece = Detection("boat", 0.6, 60.0, 130.0, 75.0, 24.0, 90.0)  # the finger's outer half
    boat = Detection("boat", 0.8, 200.0, 82.0, 90.0, 30.0, 90.0)
    assert is_structure_piece(rgb, piece, 0.1)
    assert not is_structure_piece(rgb, boat, 0.1)
    assert [d.cx_px for d in refine_boxes(rgb, [piece, boat], 0.1)] == [pytest.approx(200.0, abs=3.0)]


def test_a_car_sized_speck_is_no_vehicle():
    # 0.1 m/px: a 1.4 m dark speck on pavement is no car; a 4.5 m car is kept
    big = _canvas(200, 100, (120, 120, 118))
    _box(big, 40, 50, 14, 9, 30.0, (40, 40, 42))
    _box(big, 130, 50, 45, 18, 0.0, (200, 40, 40))
    rgb = _down(big)
    speck = Detection("vehicle", 0.45, 40.0, 50.0, 14.0, 9.0, 30.0)
    car = Detection("vehicle", 0.9, 130.0, 50.0, 45.0, 18.0, 0.0)
    out = refine_boxes(rgb, [speck, car], 0.1)
    assert len(out) == 1 and out[0].cx_px == pytest.approx(130.0, abs=3.0)


def test_learned_duplicate_car_boxes_are_merged(monkeypatch):
    pytest.importorskip("onnxruntime")
    from coastforge.detection.learned import LearnedDetector

    det = LearnedDetector()
    # rows at the working GSD (0.2 m/px): class, score, cx, cy, length, width, yaw, heading confidence;
    # a car, the same car's box shifted onto the empty bay beside it (overlapping ~35 %), and a
    # neighbour parked side by side (touching, not overlapping)
    rows = np.array([
        [1, 0.80, 100.0, 100.0, 23.0, 9.0, 0.0, 0.9],
        [1, 0.55, 100.0, 106.0, 23.0, 9.0, 3.0, 0.9],
        [1, 0.75, 100.0, 87.0, 23.0, 9.0, 0.0, 0.9],
    ])
    monkeypatch.setattr(det, "run", lambda work, threshold=None, margin=0: rows.copy())
    img = GeoImage(rgb=np.zeros((200, 200, 3), np.uint8), grid=Grid(200, 200, 0.2))
    out = det.detect(img)
    assert sorted(round(d.score, 2) for d in out) == [0.75, 0.8]


def test_an_unclear_boat_in_a_row_takes_its_clear_neighbours_axis():
    # boats moored side by side: the middle one's own axis was unclear (mirror contrast 1.05) and 12°
    # off its neighbours'; a clear boat keeps its own axis, and a lone unclear boat is left alone
    row = [Detection("boat", 0.8, 100.0 + 20.0 * k, 100.0, 40.0, 14.0, 90.0 + off, heading_known=True,
                     heading_confidence=0.9) for k, off in enumerate((1.0, -12.0, -1.0))]
    out = align_with_neighbours(row, [1.6, 1.05, 1.5])
    assert out[0] is row[0] and out[2] is row[2]
    assert out[1].yaw_deg == pytest.approx(90.0, abs=0.01)  # the mean of its neighbours' axes
    assert (out[1].cx_px, out[1].cy_px, out[1].heading_known) == (120.0, 100.0, True)
    # ... its front stays on its side (an axis, not a heading, is taken from the neighbours)
    flipped = [row[0], Detection("boat", 0.8, 120.0, 100.0, 40.0, 14.0, -102.0), row[2]]
    assert align_with_neighbours(flipped, [1.6, 1.05, 1.5])[1].yaw_deg == pytest.approx(-90.0, abs=0.01)
    assert align_with_neighbours(row, [1.6, 1.3, 1.5]) == row  # clear enough itself
    far = [row[0], replace(row[1], cx_px=400.0), row[2]]  # no neighbour within reach
    assert align_with_neighbours(far, [1.6, 1.05, 1.5]) == far
    # neighbours that disagree with each other say nothing
    split = [replace(row[0], yaw_deg=86.0), row[1], replace(row[2], yaw_deg=96.0)]  # 8° and 18° off it
    assert align_with_neighbours(split, [1.6, 1.05, 1.5]) == split
    # a small unclear boat 60 px from a long clear one is not moored beside it: its reach is set by the
    # shorter of the two (3 x 18 px), not the yacht's 3 x 45 px
    dinghy = Detection("boat", 0.8, 160.0, 100.0, 18.0, 7.0, 80.0)
    yacht = Detection("boat", 0.8, 100.0, 100.0, 45.0, 14.0, 90.0)
    assert align_with_neighbours([yacht, dinghy], [1.6, 1.05]) == [yacht, dinghy]
    near = replace(dinghy, cx_px=130.0)
    assert align_with_neighbours([yacht, near], [1.6, 1.05])[1].yaw_deg == pytest.approx(90.0, abs=0.01)
