"""Classical segmenter: footpath seeds, narrow light paving between lawns and banks (segmentation
issue #4: concrete paths on the real marina came out as asphalt, grass or rocks)."""

from __future__ import annotations

import numpy as np

from coastforge.classes import ASPHALT, SIDEWALK
from coastforge.segmentation.features import compute_features
from coastforge.segmentation.land import footpaths, land_seeds


def _park(gsd: float = 0.4, seed: int = 0):
    """A lawn with a 2.4 m light concrete path across it, a wide dark car park, a light strip along
    the car park's edge, and a wide light plaza. Returns rgb and the masks of path, edge strip, plaza."""
    rng = np.random.default_rng(seed)
    h, w = 200, 240
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:] = (85, 135, 55)  # lawn
    path = np.zeros((h, w), bool)
    path[60:66, 10:230] = True  # 6 px = 2.4 m wide, 88 m long
    lot = np.zeros((h, w), bool)
    lot[120:190, 10:110] = True
    edge = np.zeros((h, w), bool)
    edge[114:120, 10:110] = True  # light strip along the lot: pavement borders it
    plaza = np.zeros((h, w), bool)
    plaza[120:190, 140:230] = True
    rgb[path | edge | plaza] = (122, 122, 118)  # L* ~ 51: concrete no lighter than a bleached lot
    rgb[lot] = (88, 88, 90)
    rgb += rng.normal(0, 1.5, (h, w, 1))
    return np.clip(rgb, 0, 255).astype(np.uint8), path, edge, plaza


def test_footpath_seeds_are_narrow_light_strips_between_unpaved_ground():
    rgb, path, edge, plaza = _park()
    F = compute_features(rgb, 0.4)
    water = np.zeros(path.shape, bool)
    seeds = land_seeds(F, water)
    core = np.zeros_like(path)
    core[61:65, 20:220] = True  # away from the blurred borders of the 1.2 m texture window
    assert (seeds[core] == SIDEWALK).mean() > 0.8
    # a strip along the car park and the wide plaza are not footpaths
    fp = footpaths(F, water, seeds, np.hypot(F.a, F.b), F.a)
    assert fp[core].mean() > 0.8
    assert fp[edge].mean() < 0.1
    assert fp[plaza].mean() < 0.05


def test_footpaths_need_asphalt_to_compare_with():
    rgb, path, _edge, _plaza = _park()
    F = compute_features(rgb, 0.4)
    water = np.zeros(path.shape, bool)
    no_asphalt = np.full(path.shape, -1, np.int8)
    assert not footpaths(F, water, no_asphalt, np.zeros(path.shape, np.float32), F.a).any()


def test_classical_labels_a_grey_path_across_a_lawn_sidewalk():
    from coastforge.segmentation import segment
    from coastforge.types import GeoImage, Grid

    rgb, path, _edge, _plaza = _park()
    h, w = path.shape
    cm = segment(GeoImage(rgb=rgb, grid=Grid(w, h, 0.4)), backend="classical")
    core = np.zeros_like(path)
    core[61:65, 20:220] = True
    assert (cm.ids[core] == SIDEWALK).mean() > 0.8
    lot = np.zeros_like(path)
    lot[130:180, 20:100] = True
    assert (cm.ids[lot] == ASPHALT).mean() > 0.9


def _pavement_and_stones(seed: int = 0):
    """At 0.1 m/px: light smooth paving (left) beside light riprap (right), stones ~0.2-0.3 m across
    that average out on the classical segmenter's ~0.4 m working raster. Returns rgb and both masks."""
    import cv2

    rng = np.random.default_rng(seed)
    h, w = 320, 480
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:] = (176, 176, 172)  # L* ~ 71
    stones = np.zeros((h, w), bool)
    stones[:, w // 2:] = True
    # a stone field: blurred noise on a 2 px (0.2 m) lattice
    field = cv2.resize(rng.normal(0.0, 1.0, (h // 2, w // 2)).astype(np.float32), (w, h),
                       interpolation=cv2.INTER_NEAREST)
    field = cv2.GaussianBlur(field, (0, 0), 0.7)
    rgb[stones] += 30.0 * field[stones, None]
    rgb += rng.normal(0, 1.0, (h, w, 1))
    return np.clip(rgb, 0, 255).astype(np.uint8), ~stones, stones


def test_riprap_that_averages_out_on_the_working_raster_is_not_sidewalk():
    """Fine texture, measured on the image itself, keeps light riprap out of the sidewalk seeds: on the
    0.4 m working raster its small stones are as smooth as paving (the real marina's riprap was
    segmented as path)."""
    import cv2

    from coastforge.segmentation.features import fine_texture

    full, _paving, _stones = _pavement_and_stones()
    small = cv2.resize(full, (120, 80), interpolation=cv2.INTER_AREA)
    water = np.zeros((80, 120), bool)
    core_p = np.zeros((80, 120), bool)
    core_p[10:70, 8:50] = True
    core_s = np.zeros((80, 120), bool)
    core_s[10:70, 70:112] = True
    coarse = land_seeds(compute_features(small, 0.4), water)
    # the working raster alone cannot tell them apart: both are light, neutral and smooth there
    assert (coarse[core_p] == SIDEWALK).mean() > 0.9 and (coarse[core_s] == SIDEWALK).mean() > 0.5
    F = compute_features(small, 0.4, fine=fine_texture(full, 0.1, (80, 120)))
    seeds = land_seeds(F, water)
    assert (seeds[core_p] == SIDEWALK).mean() > 0.9
    assert (seeds[core_s] == SIDEWALK).mean() < 0.05
    assert F.stack().shape[1] == compute_features(small, 0.4).stack().shape[1] + 1  # and a classifier feature
