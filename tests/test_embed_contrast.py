"""Default embedder: Lab integrated contrast on dark water and its direction; foam at the crop's edge is not
the object; the edge extent measures a hull the colour mask misses; sun glints are not the object."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coastforge.assets import embed as E
from coastforge.assets.embed import integrated_contrast, object_mask
from coastforge.rng import stage_rng


def _water(n=60, colour=(20, 70, 110), seed=0):
    rng = stage_rng(seed, "test-embed-h24")
    img = np.empty((n, n, 3), np.float32)
    img[:] = colour
    img += rng.normal(0.0, 2.0, img.shape)
    return img


def _tuft(img, colour, half=3):
    n = img.shape[0]
    c = n // 2
    img[c - half:c + half, c - half:c + half] = colour
    truth = np.zeros(img.shape[:2], bool)
    truth[c - half:c + half, c - half:c + half] = True
    return truth


@pytest.mark.parametrize("drop_edge_parts, ok", [(True, True), (False, False)])
def test_foam_at_the_crop_edge_is_not_the_object(monkeypatch, drop_edge_parts, ok):
    """A whitecap across the top of a crop (bigger than the tuft, away from the centre, running out of the
    crop) is dropped; without the rule it is kept, as the biggest part, and the tuft is measured as foam."""
    monkeypatch.setattr(E, "DROP_EDGE_PARTS", drop_edge_parts)
    img = _water()
    truth = _tuft(img, (60, 140, 50), half=2)
    img[4:12, :] = (240, 245, 245)  # a foam streak, 8 x 60 px (wider than a glint): a minority of the ring
    m = object_mask(np.clip(img, 0, 255).astype(np.uint8))
    on_foam = m[4:12].sum()
    hit = (m & truth).sum() / truth.sum()
    assert (on_foam == 0 and hit > 0.8) == ok


def test_lab_contrast_tells_green_from_dark_tufts_on_dark_water():
    """On dark water the red channel is near 0, so a per-RGB ratio to the background explodes for any tuft;
    in Lab a bright green tuft (a* < 0, L up) and a dark olive one (L down) of the same size stay apart, and
    the same tuft on two water colours keeps the sign of its a* and L contrast."""
    codes = {}
    for water in ((20, 70, 110), (10, 40, 50)):
        for name, colour in (("green", (70, 150, 60)), ("dark", (25, 35, 20))):
            img = _water(colour=water, seed=len(codes))
            _tuft(img, colour, half=2)
            rgb = np.clip(img, 0, 255).astype(np.uint8)
            codes[(water, name)] = integrated_contrast(rgb, object_mask(rgb), 0.1)
    for water in ((20, 70, 110), (10, 40, 50)):
        g, d = codes[(water, "green")], codes[(water, "dark")]
        assert g[0] > 0 > d[0]  # L: the green tuft is lighter than the water, the olive one darker
        assert g[1] < 0  # a*: green
        assert abs(g[0] - d[0]) > 0.25 * max(np.abs(g).max(), np.abs(d).max())


def test_library_benchmark_reports_category_confusion_by_pixels():
    """bench.library's retrieval figures: a category confusion matrix and category accuracy per length band."""
    from types import SimpleNamespace

    from coastforge.bench.library import pixel_band, retrieval

    assets = {"grass": SimpleNamespace(category="grass", dims_m=(0.5, 0.5, 0.5)),
              "kelp": SimpleNamespace(category="seaweed", dims_m=(0.5, 0.5, 0.8)),
              "car": SimpleNamespace(category="vehicle", dims_m=(4.5, 1.8, 1.4))}
    answers = iter([[("kelp", 0.9)], [("grass", 0.9)], [("car", 0.9)]])  # top-1 per query, in order

    class Lib:
        def asset(self, aid):
            return assets[aid]

        def embed(self, images, gsds):
            return np.zeros((len(images), 4), np.float32)

        def category_prior(self, images, gsds):
            return None  # no category head for this stand-in library

        def search(self, vecs, k=1, category=None, prior=None):
            if category is not None:  # the within-category search of the matched categories
                return [[("car", 0.9)]]
            return [next(answers) for _ in range(len(vecs))]

    img = np.zeros((12, 12, 3), np.uint8)
    queries = [(img, 0.25, "grass", "grass"), (img, 0.05, "grass", "grass"), (img, 0.1, "car", "vehicle")]
    r = retrieval(Lib(), queries)
    assert r["category_confusion"] == {"grass": {"grass": 1, "seaweed": 1}, "vehicle": {"vehicle": 1}}
    assert r["category_by_pixels"]["grass"] == {"<3 px": "0/1", "8-16 px": "1/1"}
    assert r["by_object_pixels"][">=32 px"] == {"n": 1, "asset": 1.0, "category": 1.0}
    assert [pixel_band(x) for x in (2.9, 3.0, 7.99, 32.0)] == ["<3 px", "3-5 px", "5-8 px", ">=32 px"]


def test_contrast_direction_is_the_colour_whatever_the_coverage():
    """A tuft covering its pixels fully and one covering them by half (its colour mixed with the water's)
    differ in integrated contrast by about 2x, but not in its direction; a dark olive tuft differs in both."""
    from coastforge.assets.embed import DefaultEmbedder

    def code(colour, cover):
        img = _water(colour=(20, 70, 110), seed=3)
        c = img.shape[0] // 2
        patch = img[c - 2:c + 2, c - 2:c + 2]
        img[c - 2:c + 2, c - 2:c + 2] = cover * np.asarray(colour, np.float32) + (1 - cover) * patch
        rgb = np.clip(img, 0, 255).astype(np.uint8)
        return integrated_contrast(rgb, object_mask(rgb), 0.1)

    full, half, olive = code((70, 150, 60), 1.0), code((70, 150, 60), 0.5), code((25, 35, 20), 1.0)
    assert 1.5 < np.linalg.norm(full) / np.linalg.norm(half) < 2.5
    d = DefaultEmbedder._contrast_dir
    cos = lambda a, b: float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))  # noqa: E731
    assert cos(d(full), d(half)) > 0.9
    assert cos(d(full), d(olive)) < 0.5
    # the magnitude's code differs
    assert cos(DefaultEmbedder._contrast(full), DefaultEmbedder._contrast(half)) < 0.9
    assert not d(np.zeros(3)).any()


def _ground(n, seed):
    """Light concrete with the renderer's kind of grain: blotches and per-pixel noise of a few levels."""
    import cv2

    rng = stage_rng(seed, "test-edge-extent")
    blotch = cv2.GaussianBlur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), (0, 0), n / 12)
    blotch *= 4.0 / max(float(blotch.std()), 1e-6)
    img = np.empty((n, n, 3), np.float32)
    img[:] = (188, 184, 172)
    img += blotch[:, :, None] + rng.normal(0.0, 2.5, (n, n, 1))
    return img


@pytest.mark.parametrize("gsd", [0.05, 0.1])
def test_edge_extent_measures_a_white_hull_on_light_ground(gsd):
    """A white 12 x 6 m hull on light concrete is so faint that the colour mask finds about half of it, but
    its outline holds the gradient energy above the ground's grain: the radius holding 85 % of it is about the
    hull's half-diagonal in metres, at any GSD, and a 5 m hull gives a clearly smaller one. (Without the
    grain's share taken off, the radius grows by a quarter.)"""
    from coastforge.assets.embed import EDGE_BINS, DefaultEmbedder, _centres, rgb_to_lab

    def r85(length_m, width_m):
        n = int(round(1.5 * length_m / gsd)) + 4
        img = _ground(n, seed=int(length_m))
        c, hl, hw = (n - 1) / 2.0, length_m / gsd / 2.0, width_m / gsd / 2.0
        rows = slice(int(round(c - hw)), int(round(c + hw)))
        cols = slice(int(round(c - hl)), int(round(c + hl)))
        img[rows, cols] += 14.0  # a white hull, 14 levels lighter
        lab = rgb_to_lab(np.clip(img, 0, 255).astype(np.uint8))
        code = DefaultEmbedder._edge_extent(lab, gsd)[EDGE_BINS:]
        return float(np.exp(_centres(math.log(0.05), math.log(200.0), EDGE_BINS)[int(np.argmax(code))]))

    big, small = r85(12.0, 6.0), r85(5.0, 2.0)
    assert 0.85 * math.hypot(6.0, 3.0) < big < 1.15 * math.hypot(6.0, 3.0)
    assert big > 1.8 * small
    flat = rgb_to_lab(np.full((20, 20, 3), 128, np.uint8))
    assert not DefaultEmbedder._edge_extent(flat, gsd).any()  # nothing there


def test_a_mask_lost_at_the_work_size_falls_back_to_the_centre():
    """A 2 px speck in an 88 px crop is found at the 72 px work size but lost when its mask is scaled back up:
    the blocks then use the central disc, not an empty mask (the radial spectrum took the mean of nothing)."""
    import warnings

    from coastforge.assets.embed import DefaultEmbedder

    img = np.full((88, 88, 3), 110.0) + stage_rng(0, "test-lost-mask").normal(0.0, 2.0, (88, 88, 3))
    img[45:47, 46:48] += 36.0
    img = np.clip(img, 0, 255).astype(np.uint8)
    assert not object_mask(img).any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v = DefaultEmbedder().embed([img], [0.1])
    assert np.isfinite(v).all() and abs(float(np.linalg.norm(v)) - 1.0) < 1e-5


def test_ring_clutter_tells_a_car_in_a_row_from_a_lone_one():
    """The ring clutter is the share of the crop's ring unlike its median colour: about 0 for a lone car on
    asphalt (grain, no neighbours), well above it when the neighbours of a parking row cut the ring; the
    code peaks at that share. The background's colour counts only in a crowded crop."""
    from coastforge.assets.embed import CLUTTER_BINS, DefaultEmbedder, _centres, rgb_to_lab

    n = 70  # a 4.5 m car at 0.1 m/px, cropped 1.5 x its length + 4 px
    asphalt = _water(n, colour=(105, 105, 108))
    lone = asphalt.copy()
    lone[26:44, 12:58] = (200, 40, 40)
    row = lone.copy()
    for dy in (-26, 26):  # neighbours 2.6 m to either side, running out of the crop
        row[26 + dy:44 + dy, 12:58] = (230, 230, 225) if dy < 0 else (25, 25, 30)

    def context(img):
        code, colour = DefaultEmbedder._ring_context(rgb_to_lab(np.clip(img, 0, 255).astype(np.uint8)))
        assert code.shape == (CLUTTER_BINS,) and np.linalg.norm(code) == pytest.approx(1.0)
        return float(_centres(0.0, 1.0, CLUTTER_BINS)[int(np.argmax(code))]), colour

    (s_asphalt, _), (s_lone, c_lone), (s_row, c_row) = context(asphalt), context(lone), context(row)
    assert s_asphalt == 0.0 and s_lone == 0.0 and s_row >= 0.15
    assert not c_lone.any() and np.linalg.norm(c_row) > 0.7
    # the row on water instead of asphalt: another background code; on slightly lighter asphalt: about the same
    ground = np.abs(row - 105).sum(-1, keepdims=True) < 25

    def cos(img):
        s, c = context(img)
        assert s >= 0.15
        return float(c @ c_row) / (np.linalg.norm(c) * np.linalg.norm(c_row))

    assert cos(row + (np.asarray((20, 70, 110), np.float32) - 105.0) * ground) < 0.6
    assert cos(row + 4.0 * ground) > 0.9


def _glitter(img, seed, n=40, avoid=None):
    """Sun glints: white specks of 2 x 3 px scattered over the crop (some touch the object)."""
    rng = stage_rng(seed, "test-embed-glints")
    h, w = img.shape[:2]
    for _ in range(n):
        y, x = int(rng.integers(0, h - 3)), int(rng.integers(0, w - 4))
        if avoid is not None and avoid[y:y + 2, x:x + 3].any():
            continue
        img[y:y + 2, x:x + 3] = (235, 240, 240)


@pytest.mark.parametrize("glints, ok", [(True, True), (False, False)])
def test_sun_glints_around_a_pier_are_not_the_object(monkeypatch, glints, ok):
    """A wooden pier on glittering water: specks that touch its outline or lie beside it are glints, so the
    mask is the pier alone; without the glint rule they join it and widen it."""
    monkeypatch.setattr(E, "GLINTS", glints)
    img = _water(n=90, colour=(25, 75, 115))
    truth = np.zeros((90, 90), bool)
    truth[39:51, 15:75] = True
    img[truth] = (120, 80, 50)
    _glitter(img, 0, n=120, avoid=truth)
    m = object_mask(np.clip(img, 0, 255).astype(np.uint8))
    near = np.zeros_like(truth)
    near[38:52, 14:76] = True  # a pixel's slack round the pier
    hit = (m & truth).sum() / truth.sum()
    extra = (m & ~near).sum() / truth.sum()
    assert (hit > 0.95 and extra < 0.02) == ok


def test_a_white_buoy_among_glints_is_kept():
    """A speck on the crop's very centre is the object, however glint-like (a small white buoy)."""
    img = _water(n=40, colour=(25, 75, 115))
    buoy = np.zeros((40, 40), bool)
    buoy[18:22, 18:22] = True
    img[buoy] = (240, 240, 235)
    zone = np.zeros_like(buoy)
    zone[15:25, 15:25] = True  # glints round it, not on it
    _glitter(img, 1, n=25, avoid=zone)
    m = object_mask(np.clip(img, 0, 255).astype(np.uint8))
    assert (m & buoy).sum() == buoy.sum() and m.sum() < 2 * buoy.sum()
