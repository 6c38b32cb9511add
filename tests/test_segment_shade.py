"""Classical segmenter on the real marina's hard cases (issue #4): deep shade under a canopy called
pavement (``shaded_crowns``), a tree's shade on a beach and speckled sand called riprap
(``shaded_continuation``, ``_sandy``)."""

from __future__ import annotations

import numpy as np

from coastforge.classes import ASPHALT, ROCKS, SAND, TREES
from coastforge.segmentation.features import compute_features
from coastforge.segmentation.land import _sandy, shaded_continuation, shaded_crowns

GSD = 0.25


def _lab_image(h: int, w: int, rgb: tuple, seed: int = 0, noise: float = 1.5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float32)
    img[:] = rgb
    return img + rng.normal(0, noise, (h, w, 1))


def test_deep_shade_beside_a_crown_becomes_trees_but_cars_and_far_shadows_stay():
    h, w = 160, 200
    img = _lab_image(h, w, (110, 110, 112))  # pavement
    ids = np.full((h, w), ASPHALT, np.uint8)
    crown = np.zeros((h, w), bool)
    crown[20:60, 20:60] = True  # 10 x 10 m canopy
    shade = np.zeros((h, w), bool)
    shade[60:85, 25:60] = True  # its shade, 6 m deep: wider than a car
    car = np.zeros((h, w), bool)
    car[30:48, 60:67] = True  # a dark car parked against the crown: 1.75 m wide
    far = np.zeros((h, w), bool)
    far[100:140, 120:180] = True  # a building's shadow far from any tree
    img[crown] = (40, 80, 35)
    img[shade | car | far] = (22, 24, 30)
    ids[crown] = TREES
    F = compute_features(np.clip(img, 0, 255).astype(np.uint8), GSD)
    land = np.ones((h, w), bool)
    out = shaded_crowns(ids, F, land)
    inner = np.zeros_like(shade)
    inner[62:83, 27:58] = True
    assert (out[inner] == TREES).mean() > 0.9
    assert (out[car] == ASPHALT).mean() > 0.9
    assert (out[far] == ASPHALT).all()
    assert (out[crown] == TREES).all()


def test_no_crown_no_change():
    h, w = 80, 80
    img = _lab_image(h, w, (110, 110, 112))
    img[20:60, 20:60] = (22, 24, 30)
    ids = np.full((h, w), ASPHALT, np.uint8)
    F = compute_features(np.clip(img, 0, 255).astype(np.uint8), GSD)
    assert (shaded_crowns(ids, F, np.ones((h, w), bool)) == ids).all()


def test_a_trees_shade_on_sand_is_sand_and_grey_riprap_stays_rocks():
    h, w = 120, 200
    img = _lab_image(h, w, (215, 195, 150))  # sand
    ids = np.full((h, w), SAND, np.uint8)
    shade = np.zeros((h, w), bool)
    shade[40:64, 30:54] = True  # 6 m across: all of it within reach of the lit sand
    img[shade] = np.array((215, 195, 150), np.float32) * 0.55  # dimmed, same hue
    riprap = np.zeros((h, w), bool)
    riprap[40:80, 130:170] = True
    rng = np.random.default_rng(1)
    img[riprap] = (120, 120, 118) + rng.normal(0, 12, (int(riprap.sum()), 1))  # grey stones
    ids[shade | riprap] = ROCKS
    F = compute_features(np.clip(img, 0, 255).astype(np.uint8), GSD)
    out = shaded_continuation(ids, F, np.ones((h, w), bool), SAND, into=(ROCKS,))
    assert (out[shade] == SAND).mean() > 0.9
    assert (out[riprap] == ROCKS).mean() > 0.95


def test_speckled_sand_is_sandy_and_riprap_is_not():
    h, w = 100, 200
    rng = np.random.default_rng(2)
    img = _lab_image(h, w, (215, 195, 150))
    specks = (rng.random((h, w)) < 0.2) & (np.arange(w)[None, :] < 100)
    img[specks] = (90, 80, 60)  # dark debris and footprints on the left half
    img[:, 100:] = (120, 120, 118) + rng.normal(0, 12, (h, 100, 1))  # riprap on the right half
    F = compute_features(np.clip(img, 0, 255).astype(np.uint8), GSD)
    sandy = _sandy(F)
    assert sandy[10:90, 10:90].mean() > 0.8
    assert sandy[10:90, 110:190].mean() < 0.02
