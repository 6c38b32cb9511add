"""Default embedder v5 and the category vote: calibrated shadow test, speckle removed by area
(thin rims stay), per-asset scores of the index, and the category vote of ``Library.search``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from coastforge.assets import embed as E
from coastforge.assets.embed import object_mask
from coastforge.assets.index import VectorIndex
from coastforge.rng import stage_rng


def _ground(n, colour, seed=0, sd=1.5):
    rng = stage_rng(seed, "test-embed-category")
    img = np.empty((n, n, 3), np.float32)
    img[:] = colour
    img += rng.normal(0.0, sd, img.shape)
    return img


def _u8(img):
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("blue_max, ok", [(E.SHADOW_BLUE_MAX, True), (1.6, False)])
def test_navy_car_on_dark_ground_is_not_a_shadow(monkeypatch, blue_max, ok):
    """A navy car on dark green ground is darker than the ground and bluer than it by ~1.5 x, far
    bluer than a cast shadow (renders: at most ~1.13 x): it is the object. The cast shadow beside it (a
    darker copy of the ground, a little bluer) is still dropped. With the old, loose bound (1.6) the car
    was a 'shadow' and the mask went wrong."""
    monkeypatch.setattr(E, "SHADOW_BLUE_MAX", blue_max)
    ground = np.array([72.0, 93.0, 82.0])
    img = _ground(56, ground)
    img[24:33, 10:30] = ground * np.array([0.45, 0.45, 0.50])  # cast shadow (blue ratio 1.11 x)
    img[20:29, 14:42] = (36, 41, 61)  # the car, 28 x 9 px (blue ratio 1.56 x)
    car = np.zeros((56, 56), bool)
    car[20:29, 14:42] = True
    shadow_only = np.zeros((56, 56), bool)
    shadow_only[29:33, 10:30] = True
    m = object_mask(_u8(img))
    covered = (m & car).sum() / car.sum()
    shadow_dropped = (m & shadow_only).sum() <= 0.2 * shadow_only.sum()
    assert (covered > 0.8 and shadow_dropped) == ok


@pytest.mark.parametrize("speckle_by_area, ok", [(True, True), (False, False)])
def test_thin_white_rim_on_light_ground_keeps_the_hull_length(monkeypatch, speckle_by_area, ok):
    """A white hull on light ground shows only a 1 px rim brighter than the ground around a dark console:
    removing speckle by area keeps the rim, so the mask spans the hull; an opening (the old way) erased the
    rim and left the console (a third of the length) as the object."""
    import cv2

    if not speckle_by_area:  # the old speckle removal: an opening with a 3x3 cross
        real = cv2.connectedComponentsWithStats

        def opening_instead(fg8, connectivity=8):
            cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
            opened = cv2.morphologyEx(fg8, cv2.MORPH_OPEN, cross)
            n, lbl, st, c = real(opened, connectivity=connectivity)
            st = st.copy()
            st[1:, cv2.CC_STAT_AREA] = np.maximum(st[1:, cv2.CC_STAT_AREA], E.SPECKLE_PX)
            return n, lbl, st, c

        calls = {"n": 0}

        def patched(img, connectivity=8):
            calls["n"] += 1
            if calls["n"] == 1:  # the speckle step is the first labelling in object_mask
                return opening_instead(img, connectivity)
            return real(img, connectivity=connectivity)

        monkeypatch.setattr(cv2, "connectedComponentsWithStats", patched)
    ground = np.array([205.0, 205.0, 200.0])
    img = _ground(64, ground, sd=1.0)
    hull = np.zeros((64, 64), np.uint8)
    cv2.rectangle(hull, (12, 26), (51, 37), 1, 1)  # 40 x 12 px outline, 1 px wide
    img[hull > 0] = (250, 250, 250)
    img[29:35, 26:36] = (30, 35, 60)  # the console
    m = object_mask(_u8(img))
    xs = np.nonzero(m.any(0))[0]
    length = xs.max() - xs.min() + 1 if len(xs) else 0
    assert (length >= 36) == ok


def test_index_asset_scores_are_the_best_row_of_each_asset():
    rng = stage_rng(3, "test-index-asset-scores")
    v = rng.normal(size=(9, 6)).astype(np.float32)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    row_asset = [2, 0, 0, 2, 1, 1, 0, 2, 1]  # not grouped: the index must not assume contiguous rows
    idx = VectorIndex(v, row_asset)
    q = rng.normal(size=(4, 6)).astype(np.float32)
    got = idx.asset_scores(q, 4)
    want = np.stack([(q @ v[np.array(row_asset) == a].T).max(1) for a in range(3)], 1)
    assert np.allclose(got[:, :3], want, atol=1e-5)
    assert np.all(np.isneginf(got[:, 3]))  # an asset without rows
    top = idx.search(q, k=3)
    assert [[a for a, _ in row] for row in top] == [list(np.argsort(-want[i])) for i in range(4)]


def _library(monkeypatch, cats, t=0.03):
    from coastforge.assets.library import Library

    n = len(cats)
    v = np.eye(n, dtype=np.float32)  # one row per asset: a query's cosine to asset i is its i-th component
    assets = tuple(SimpleNamespace(id=f"a{i}", category=c) for i, c in enumerate(cats))
    lib = Library.__new__(Library)
    lib.assets, lib.index = assets, VectorIndex(v, list(range(n)))
    lib.doc = {"embedder": {"name": "default"}}
    lib._by_id = {a.id: i for i, a in enumerate(assets)}
    monkeypatch.setattr(Library, "CATEGORY_VOTE_T", t)
    return lib


def _query(scores):
    return np.asarray(scores, np.float32)[None]


def test_category_vote_prefers_the_category_with_more_evidence(monkeypatch):
    """A lone rock a hair above three boats loses the first place to the best boat; the other hits follow by
    cosine, with their own cosines; a clear winner keeps it; within a category nothing is voted."""
    lib = _library(monkeypatch, ["rock", "boat", "boat", "boat"])
    hits = lib.search(_query([0.90, 0.89, 0.885, 0.88]), k=3)[0]
    assert [a for a, _ in hits] == ["a1", "a0", "a2"]
    assert hits[0][1] == pytest.approx(0.89) and hits[1][1] == pytest.approx(0.90)
    assert lib.search(_query([0.99, 0.80, 0.79, 0.78]), k=1)[0][0][0] == "a0"  # far ahead: stays first
    assert lib.search(_query([0.90, 0.89, 0.885, 0.88]), k=1, category="rock")[0][0][0] == "a0"
    assert lib.search(_query([0.90, 0.89, 0.885, 0.88]), k=2, category="boat")[0] == [
        ("a1", pytest.approx(0.89)), ("a2", pytest.approx(0.885))]


def test_category_vote_off_is_the_plain_ranking(monkeypatch):
    """T = 0, or a library of an embedder T was not calibrated for: the plain ranking by cosine."""
    lib = _library(monkeypatch, ["rock", "boat", "boat", "boat"], t=0.0)
    assert [a for a, _ in lib.search(_query([0.90, 0.89, 0.885, 0.88]), k=2)[0]] == ["a0", "a1"]
    lib = _library(monkeypatch, ["rock", "boat", "boat", "boat"])
    lib.doc = {"embedder": {"name": "dinov3"}}
    assert [a for a, _ in lib.search(_query([0.90, 0.89, 0.885, 0.88]), k=2)[0]] == ["a0", "a1"]
    with pytest.raises(Exception, match="k = 0"):
        _library(monkeypatch, ["rock", "boat"]).search(_query([0.5, 0.4]), k=0)


@pytest.mark.parametrize("centre_frac, ok", [(E.CENTRE_FRAC, True), (0.0, False)])
def test_parked_neighbours_leaving_the_crop_are_not_the_object(monkeypatch, centre_frac, ok):
    """A crop centred on a parked car also shows its neighbours, bigger than it in the crop and reaching its
    central half, but running out of the crop: the car covering the crop's centre is the object."""
    monkeypatch.setattr(E, "CENTRE_FRAC", centre_frac)  # 0: the old rule, without the centre
    img = _ground(60, (95.0, 95.0, 98.0))
    img[14:24, :] = (220, 40, 40)  # neighbour above, across the whole crop
    img[26:34, 12:48] = (40, 60, 180)  # the car at the centre
    img[36:46, :] = (230, 230, 230)  # neighbour below
    m = object_mask(_u8(img))
    rows = np.nonzero(m.any(1))[0]
    assert len(rows) and ((rows.min() >= 25 and rows.max() <= 34) == ok)
