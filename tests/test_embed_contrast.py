"""Default embedder (v4): Lab integrated contrast on dark water; foam at the crop's edge is not the object."""

from __future__ import annotations

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
    img[6:10, :] = (240, 245, 245)  # a thin foam streak, 4 x 60 px: a minority of the crop's ring
    m = object_mask(np.clip(img, 0, 255).astype(np.uint8))
    on_foam = m[6:10].sum()
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

        def search(self, vecs, k=1, category=None):
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
