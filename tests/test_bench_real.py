"""coastforge.bench.real: the grown-box matching rule, the coarse land-cover mapping, and one quick run on the
real sets (skipped without ../shared/data)."""

from __future__ import annotations

import numpy as np
import pytest

from coastforge import realdata
from coastforge.bench.real import (coarse_confusion, coarse_scores, coarser, cut_by_edge, default_config,
                                   det_gsd_sweep, det_munich, match_centres_in_boxes, match_centres_in_quads,
                                   seg_dubai)
from coastforge.classes import ASPHALT, GRASS, ROCKS, SAND, WATER

BOX = np.array([[100.0, 100.0, 140.0, 120.0]])  # 40 x 20, centre (120, 110); grown: x 95..145, y 97.5..122.5


def test_centre_just_inside_grown_box_matches():
    assert match_centres_in_boxes(np.array([[144.9, 110.0]]), BOX) == [(0, 0)]
    assert match_centres_in_boxes(np.array([[120.0, 97.6]]), BOX) == [(0, 0)]


def test_centre_just_outside_grown_box_does_not_match():
    assert match_centres_in_boxes(np.array([[145.1, 110.0]]), BOX) == []
    assert match_centres_in_boxes(np.array([[120.0, 122.6]]), BOX) == []
    # inside the grown box along x but not along y: both sides must hold
    assert match_centres_in_boxes(np.array([[144.0, 123.0]]), BOX) == []


def test_oriented_label_box_is_grown_along_its_own_axes():
    # a 40 x 20 box turned 45 degrees about (0, 0): along its long axis the grown box reaches 25 px, across 12.5
    u, v = np.array([1.0, 1.0]) / np.sqrt(2.0), np.array([-1.0, 1.0]) / np.sqrt(2.0)
    quad = np.array([-20 * u - 10 * v, 20 * u - 10 * v, 20 * u + 10 * v, -20 * u + 10 * v])[None]
    assert match_centres_in_quads(24.9 * u[None], quad) == [(0, 0)]
    assert match_centres_in_quads(25.1 * u[None], quad) == []
    assert match_centres_in_quads(12.4 * v[None], quad) == [(0, 0)]
    assert match_centres_in_quads(12.6 * v[None], quad) == []
    # (20, 0) lies in the axis-aligned hull of the turned box but 14.1 px across its axis: no match
    assert match_centres_in_quads(np.array([[20.0, 0.0]]), quad) == []


def test_one_to_one_when_two_predictions_share_a_label():
    pairs = match_centres_in_boxes(np.array([[121.0, 110.0], [118.0, 111.0]]), BOX)
    assert len(pairs) == 1
    assert pairs == [(0, 0)]  # the closer centre wins


def test_hungarian_picks_the_globally_best_pairing():
    # label boxes A (x 0..40, grown -5..45) and B (x 40..60, grown 37.5..62.5). Pred 0 lies in both,
    # nearest to B's centre; pred 1 lies in B only. Nearest-first greedy (pred 0 -> B) leaves one label
    # unmatched; the best assignment matches both.
    boxes = np.array([[0.0, 0.0, 40.0, 20.0], [40.0, 0.0, 60.0, 20.0]])
    preds = np.array([[44.0, 10.0], [60.0, 10.0]])
    assert sorted(match_centres_in_boxes(preds, boxes)) == [(0, 0), (1, 1)]
    # both pairings allowed: the smaller total distance wins
    boxes = np.array([[0.0, 0.0, 20.0, 20.0], [10.0, 0.0, 30.0, 20.0]])  # centres x 10 and 20
    preds = np.array([[19.0, 10.0], [11.0, 10.0]])
    assert sorted(match_centres_in_boxes(preds, boxes)) == [(0, 1), (1, 0)]


def test_empty_inputs_match_nothing():
    assert match_centres_in_boxes(np.zeros((0, 2)), BOX) == []
    assert match_centres_in_boxes(np.array([[120.0, 110.0]]), np.zeros((0, 4))) == []


def test_a_box_reaching_past_the_image_edge_is_cut_by_it():
    from coastforge.types import Detection

    assert not cut_by_edge(Detection("boat", 0.5, 100.0, 50.0, 40.0, 10.0, 0.0), 120, 100)  # x 80..120
    assert cut_by_edge(Detection("boat", 0.5, 101.0, 50.0, 40.0, 10.0, 0.0), 120, 100)
    assert cut_by_edge(Detection("boat", 0.5, 50.0, 19.0, 40.0, 10.0, 90.0), 120, 100)  # turned: y -1..39
    assert cut_by_edge(Detection("boat", 0.5, 50.0, 4.0, 40.0, 10.0, 0.0), 120, 100)  # y -1..9


def test_coarse_mapping_rocks_wrong_building_ignored():
    truth = np.array([[0, 0, 1, 2, 3, realdata.BUILDING, realdata.COARSE_IGNORE]], np.uint8)
    pred = np.array([[WATER, ROCKS, ASPHALT, GRASS, SAND, ROCKS, ROCKS]], np.uint8)
    cm = coarse_confusion(pred, truth)
    assert cm.shape == (4, 5)
    assert cm.sum() == 5  # building and unlabeled left out
    assert cm[0, 4] == 1  # rocks on water: the separate "other" column
    s = coarse_scores(cm)
    assert s["water_iou"] == pytest.approx(0.5)  # 1 right of 2 water pixels, rocks is not water
    assert s["iou"]["paved"] == s["iou"]["vegetation"] == s["iou"]["bare"] == 1.0
    assert s["miou"] == pytest.approx((0.5 + 3.0) / 4)


def test_coarse_mapping_merges_our_classes():
    truth = np.array([[1, 1, 2, 2, 3, 3]], np.uint8)
    pred = np.array([[1, 2, 3, 4, 5, 7]], np.uint8)  # asphalt, sidewalk, grass, trees, dirt, sand
    s = coarse_scores(coarse_confusion(pred, truth))
    assert s["present"] == ["paved", "vegetation", "bare"]
    assert s["miou"] == 1.0 and np.isnan(s["water_iou"])


@pytest.mark.shared_data
def test_quick_real_runs():
    if not realdata.SHARED.is_dir():
        pytest.skip(f"../shared/data not found at {realdata.SHARED}: "
                    "real-imagery tests need it beside the repo")
    # the default learned segmenter runs the net and then falls back to classical on these photos (~20 s on a
    # busy 2-core machine): the test checks the benchmark's bookkeeping, so the classical backend suffices
    seg = seg_dubai(default_config(segment_backend="classical"), split="val", limit=1)
    assert "skipped" not in seg
    assert seg["val"]["images"] == 1 and seg["train"]["images"] == 0
    assert len(seg["images"]) == 1 and seg["images"][0]["name"].split("/")[0] in realdata.DUBAI_VAL_TILES
    assert 0.0 <= seg["val"]["miou"] <= 1.0 and 0.0 <= seg["val"]["water_iou"] <= 1.0
    assert seg["backend"] == "classical" and len(seg["worst"]) == 1
    assert seg["val"]["pixels"] > 0 and np.asarray(seg["val"]["confusion"]).sum() == seg["val"]["pixels"]

    det = det_munich(limit=1)
    assert "skipped" not in det
    rows = det["images"]
    assert len(rows) == 1 and not rows[0].get("na")
    assert det["train"]["images"] + det["val"]["images"] == 1
    r = rows[0]
    assert r["labels"] > 0 and r["gsd_m"] == pytest.approx(realdata.MUNICH_GSD_M)
    assert 0 <= r["matched"] <= min(r["labels"], r["preds"])
    assert 0.0 <= r["recall"] <= 1.0
    assert r["preds"] == 0 or 0.0 <= r["precision"] <= 1.0


def test_coarser_averages_the_image_down_and_scales_its_gsd():
    from coastforge.types import GeoImage, Grid

    rgb = np.zeros((40, 60, 3), np.uint8)
    rgb[:, 30:] = 200  # a sharp edge between two 2 x 2 blocks stays sharp; blocks are averaged
    rgb[0, 0] = 40
    img = GeoImage(rgb, Grid(60, 40, 0.13))
    small = coarser(img, 2.0)
    assert small.rgb.shape == (20, 30, 3) and small.grid.gsd_m == pytest.approx(0.26)
    assert (small.grid.width_px, small.grid.height_px) == (30, 20)
    assert small.rgb[0, 0, 0] == 10 and small.rgb[5, 14, 0] == 0 and small.rgb[5, 15, 0] == 200
    assert coarser(img, 1.0) is img


@pytest.mark.shared_data
def test_gsd_sweep_runs_on_one_photo():
    if not realdata.SHARED.is_dir():
        pytest.skip(f"../shared/data not found at {realdata.SHARED}: "
                    "real-imagery tests need it beside the repo")
    r = det_gsd_sweep(split="train", limit=1, factors=(4.0,))
    assert "marina_p0861" not in r  # evaluation-only: not measured with the training split
    rows = r["cars_munich"]["rows"]
    assert [x["factor"] for x in rows] == [1.0, 4.0]
    assert rows[1]["gsd_m"] == pytest.approx(4 * realdata.MUNICH_GSD_M, abs=1e-3)
    assert rows[0]["objects"] == rows[1]["objects"] > 0
    for x in rows:
        assert 0 <= x["matched"] <= min(x["objects"], x["preds"])
    # the same cars seen from 4 times higher (0.52 m/px) are still mostly found
    assert rows[1]["recall"] >= 0.5 * rows[0]["recall"]


def test_weathered_keeps_size_and_gsd_and_changes_the_look():
    from coastforge.bench.real import WEATHER, weathered
    from coastforge.types import GeoImage, Grid

    rng = np.random.default_rng(3)
    rgb = rng.integers(40, 200, (32, 48, 3)).astype(np.uint8)
    rgb[:, :24] = (30, 60, 90)  # a dark blue half
    img = GeoImage(rgb, Grid(48, 32, 0.3))
    out = {k: weathered(img, k) for k in WEATHER}
    for k, o in out.items():
        assert o.rgb.shape == rgb.shape and o.rgb.dtype == np.uint8 and o.grid == img.grid, k
        assert not np.array_equal(o.rgb, rgb), k
    assert out["haze"].rgb.std() < rgb.std() and out["haze"].rgb.mean() > rgb.mean()  # flatter and lighter
    assert out["dark"].rgb.mean() < rgb.mean() < out["bright"].rgb.mean()
    g = out["grey"].rgb.astype(int)
    assert (g[..., 0] == g[..., 1]).all() and (g[..., 1] == g[..., 2]).all()
    assert np.abs(np.diff(out["blur"].rgb.astype(int), axis=1)).mean() < np.abs(np.diff(rgb.astype(int), axis=1)).mean()
    assert np.array_equal(weathered(img, "noise").rgb, out["noise"].rgb)  # seeded: runs compare
    with pytest.raises(ValueError, match="unknown weather"):
        weathered(img, "fog")


@pytest.mark.shared_data
def test_weather_sweep_runs_on_one_photo_per_set():
    from coastforge.bench.real import det_weather_sweep

    if not realdata.SHARED.is_dir():
        pytest.skip(f"../shared/data not found at {realdata.SHARED}: "
                    "real-imagery tests need it beside the repo")
    r = det_weather_sweep(split="train", limit=1, kinds=("haze", "grey"))
    assert "marina_p0861" not in r  # evaluation-only: not measured with the training split
    assert r["kinds"] == ["none", "haze", "grey"]
    for name in ("ships_aerial", "cars_munich"):
        rows = r[name]["rows"]
        assert [x["kind"] for x in rows] == ["none", "haze", "grey"]
        assert rows[0]["objects"] == rows[1]["objects"] == rows[2]["objects"] > 0
        for x in rows:
            assert 0 <= x["matched"] <= min(x["objects"], x["preds"])
        assert rows[0]["recall"] > 0.5  # the photo as it is: most objects found
    with pytest.raises(ValueError, match="unknown weather"):
        det_weather_sweep(split="train", limit=1, kinds=("fog",))
