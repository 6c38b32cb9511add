from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coastforge import frames

finite = st.floats(-1e4, 1e4, allow_nan=False)


@pytest.mark.parametrize("a,w", [(180, 180), (-180, 180), (190, -170), (-190, 170), (360, 0), (540, 180),
                                 (0, 0), (179.5, 179.5), (-179.5, -179.5)])
def test_wrap_deg(a, w):
    assert frames.wrap_deg(a) == pytest.approx(w)


@pytest.mark.parametrize("a,w", [(90, 90), (-90, 90), (100, -80), (180, 0), (-135, 45), (270, 90)])
def test_wrap_half_deg(a, w):
    assert frames.wrap_half_deg(a) == pytest.approx(w)


@given(finite)
def test_wrap_range(a):
    w = frames.wrap_deg(a)
    assert -180 < w <= 180
    assert np.isclose(np.cos(np.deg2rad(w)), np.cos(np.deg2rad(a)), atol=1e-6)


def test_pixel_scene_convention():
    # a 200 x 100 image at 0.5 m/px covers x in [-50, 50], y in [-25, 25]
    x, y = frames.pixel_to_scene(0, 0, 200, 100, 0.5)
    assert (x, y) == (-50.0, 25.0)  # top-left corner is north-west
    x, y = frames.pixel_to_scene(200, 100, 200, 100, 0.5)
    assert (x, y) == (50.0, -25.0)
    x, y = frames.pixel_to_scene(100, 50, 200, 100, 0.5)
    assert (x, y) == (0.0, 0.0)


@given(finite, finite)
def test_pixel_scene_round_trip(c, r):
    x, y = frames.pixel_to_scene(c, r, 640, 480, 0.13)
    c2, r2 = frames.scene_to_pixel(x, y, 640, 480, 0.13)
    assert c2 == pytest.approx(c, abs=1e-6) and r2 == pytest.approx(r, abs=1e-6)


def test_unreal_is_cm_left_handed():
    assert tuple(map(float, frames.scene_to_unreal(1.0, 2.0, -3.0))) == (100.0, -200.0, -300.0)
    assert frames.yaw_to_unreal(30.0) == -30.0
    assert frames.yaw_to_unreal(180.0) == 180.0  # -180 wraps to 180


@given(finite, finite, finite, st.floats(-720, 720))
def test_unreal_round_trip(x, y, z, yaw):
    back = frames.unreal_to_scene(*frames.scene_to_unreal(x, y, z))
    assert np.allclose(back, (x, y, z), atol=1e-6)
    assert frames.yaw_from_unreal(frames.yaw_to_unreal(yaw)) == pytest.approx(frames.wrap_deg(yaw), abs=1e-9) or \
        abs(abs(frames.wrap_deg(yaw)) - 180) < 1e-9


def test_unreal_yaw_points_the_same_way():
    # a boat facing north (+y, yaw 90) faces -Y in Unreal, i.e. yaw_ue = -90
    yaw = 90.0
    dx, dy = np.cos(np.deg2rad(yaw)), np.sin(np.deg2rad(yaw))
    ux, uy, _ = frames.scene_to_unreal(dx, dy, 0)
    yaw_ue = frames.yaw_to_unreal(yaw)
    assert np.allclose([ux / 100, uy / 100], [np.cos(np.deg2rad(yaw_ue)), np.sin(np.deg2rad(yaw_ue))])


def test_holoocean_is_scene_frame():
    assert tuple(map(float, frames.scene_to_holoocean(1, 2, 3))) == (1.0, 2.0, 3.0)
    assert frames.yaw_to_holoocean(370) == pytest.approx(10)


def test_image_direction_row_points_down():
    dc, dr = frames.direction_px(90.0)  # north = up in the image = decreasing row
    assert dc == pytest.approx(0, abs=1e-12) and dr == pytest.approx(-1)
    assert frames.yaw_from_direction_px(0.0, -1.0) == pytest.approx(90.0)
    assert frames.yaw_from_direction_px(-1.0, 0.0) == pytest.approx(180.0)


def test_box_corners():
    c = frames.box_corners_px(10, 10, 4, 2, 0)  # facing image-right
    assert np.allclose(c[0], [12, 9])  # front-left is up (north) of the front
    assert np.allclose(c.mean(0), [10, 10])
