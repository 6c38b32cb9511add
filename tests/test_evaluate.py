"""Evaluate against hand-computed cases (DESIGN.md §5)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from coastforge.evaluate import evaluate_scenes, object_metrics, pier_connectivity, pier_deck
from coastforge.scene import Scene, SceneObject


def obj(i, x, y, yaw, cat="boat", asset="runabout", length=6.0, width=2.0, source="synthetic"):
    return SceneObject(id=f"o{i}", category=cat, asset_id=asset, x_m=x, y_m=y, z_m=0.0, yaw_deg=yaw,
                       scale=(1.0, 1.0, 1.0), length_m=length, width_m=width, source=source, score=1.0)


def scene(objs, classes=None, height=None):
    return Scene(name="t", seed=0, gsd_m=1.0, extent_m=(100.0, 100.0), objects=tuple(objs), classes=classes,
                 height=height)


def test_perfect_match():
    t = [obj(0, 0, 0, 10), obj(1, 20, 5, -170, cat="vehicle", asset="sedan", length=4.6)]
    m = object_metrics(t, list(t))
    assert m.n_matched == 2 and m.recall == 1.0 and m.detection_precision == 1.0
    assert m.xy_rmse_m == 0.0 and m.rotation_rmse_deg == 0.0 and m.orientation_rmse_deg == 0.0
    assert m.match_precision == 1.0


def test_shifted_objects_rmse():
    t = [obj(0, 0, 0, 0), obj(1, 50, 0, 0)]
    p = [obj(0, 0.3, 0.4, 0), obj(1, 50, 1.0, 0)]  # shifts of 0.5 m and 1.0 m
    m = object_metrics(t, p)
    assert m.xy_rmse_m == pytest.approx(math.sqrt((0.25 + 1.0) / 2))


def test_heading_flip_is_rotation_180_orientation_0():
    m = object_metrics([obj(0, 0, 0, 30)], [obj(0, 0, 0, -150)])
    assert m.rotation_rmse_deg == pytest.approx(180.0)
    assert m.orientation_rmse_deg == pytest.approx(0.0)


def test_wraparound_at_180():
    # 179 vs -179 is 2 degrees apart, not 358
    m = object_metrics([obj(0, 0, 0, 179)], [obj(0, 0, 0, -179)])
    assert m.rotation_rmse_deg == pytest.approx(2.0)
    assert m.orientation_rmse_deg == pytest.approx(2.0)
    m = object_metrics([obj(0, 0, 0, 89)], [obj(0, 0, 0, -89)])  # 178 apart; as orientations 2 apart
    assert m.rotation_rmse_deg == pytest.approx(178.0)
    assert m.orientation_rmse_deg == pytest.approx(2.0)


def test_round_buoy_yaw_does_not_count_but_position_does():
    import dataclasses

    buoy = dataclasses.replace(obj(1, 30, 0, 40, cat="buoy", asset="buoy", length=1.0, width=1.0),
                               attrs={"symmetry": "rotational"})
    t = [obj(0, 0, 0, 10), buoy]
    p = [obj(0, 0, 0, 12), dataclasses.replace(buoy, x_m=30.3, y_m=0.4, yaw_deg=-95.0, attrs={})]
    m = object_metrics(t, p)
    assert m.n_matched == 2 and m.n_yaw == 1
    assert m.rotation_rmse_deg == pytest.approx(2.0) and m.orientation_rmse_deg == pytest.approx(2.0)
    assert m.xy_rmse_m == pytest.approx(math.sqrt(0.25 / 2))
    # the same buoy without the mark: its 135 degree error counts
    m = object_metrics([t[0], dataclasses.replace(buoy, attrs={})], p)
    assert m.n_yaw == 2 and m.rotation_rmse_deg == pytest.approx(math.sqrt((4 + 135 ** 2) / 2))


def test_missing_objects_and_false_positives():
    t = [obj(i, 10 * i, 0, 0) for i in range(4)]
    p = [obj(0, 0, 0, 0), obj(1, 10, 0, 0), obj(9, -40, -40, 0), obj(8, 40, 40, 0), obj(7, 30, 30, 0)]
    m = object_metrics(t, p)
    assert m.n_matched == 2 and m.recall == 0.5 and m.detection_precision == pytest.approx(2 / 5)


def test_gate_is_max_of_2m_and_half_length():
    # a 20 m boat: gate 10 m; a 3 m dinghy: gate 2 m
    assert object_metrics([obj(0, 0, 0, 0, length=20)], [obj(0, 9.0, 0, 0)]).n_matched == 1
    assert object_metrics([obj(0, 0, 0, 0, length=20)], [obj(0, 10.5, 0, 0)]).n_matched == 0
    assert object_metrics([obj(0, 0, 0, 0, length=3)], [obj(0, 1.9, 0, 0)]).n_matched == 1
    assert object_metrics([obj(0, 0, 0, 0, length=3)], [obj(0, 2.1, 0, 0)]).n_matched == 0


def test_hungarian_is_one_to_one_and_optimal():
    # greedy would give p0 to t0 (0.9 m) and leave t1 unmatched; the optimum matches both
    t = [obj(0, 0, 0, 0, length=3), obj(1, 1.5, 0, 0, length=3)]
    p = [obj(0, 0.9, 0, 0), obj(1, -1.0, 0, 0)]
    m = object_metrics(t, p)
    assert m.n_matched == 2
    assert m.xy_rmse_m == pytest.approx(math.sqrt((1.0 + 0.36) / 2))


def test_wrong_asset_strict_and_by_category():
    t = [obj(0, 0, 0, 0, asset="runabout"), obj(1, 30, 0, 0, asset="yacht"), obj(2, 60, 0, 0, cat="vehicle",
                                                                               asset="sedan")]
    p = [obj(0, 0, 0, 0, asset="runabout"), obj(1, 30, 0, 0, asset="sailboat"), obj(2, 60, 0, 0, cat="boat",
                                                                                  asset="kayak")]
    m = object_metrics(t, p)
    assert m.match_precision == pytest.approx(1 / 3)
    assert m.match_precision_category == pytest.approx(2 / 3)


def test_evaluate_scenes_keys_and_per_category_and_piers_ignored():
    t = [obj(0, 0, 0, 0), obj(1, 30, 0, 90, cat="vehicle", asset="sedan", length=4.6),
         obj(2, -30, 0, 0, cat="pier", asset="pier_walkway", length=10)]
    p = [obj(0, 0.5, 0, 0), obj(1, 30, 0, -90, cat="vehicle", asset="sedan", length=4.6)]
    r = evaluate_scenes(scene(t), scene(p))
    for k in ("n_truth", "n_pred", "n_matched", "xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "recall",
              "match_precision", "match_precision_category", "detection_precision", "per_category"):
        assert k in r
    assert r["n_truth"] == 2  # the pier segment does not count
    assert r["per_category"]["vehicle"]["rotation_rmse_deg"] == pytest.approx(180.0)
    assert r["per_category"]["boat"]["xy_rmse_m"] == pytest.approx(0.5)
    json.dumps(r)  # JSON-ready


def test_empty_prediction_gives_none_not_crash():
    r = evaluate_scenes(scene([obj(0, 0, 0, 0)]), scene([]))
    assert r["recall"] == 0.0 and r["xy_rmse_m"] is None and r["detection_precision"] is None


def test_terrain_metrics():
    classes = np.zeros((10, 10), np.uint8)
    classes[:, 5:] = 3
    pred = classes.copy()
    pred[:, 5] = 0  # one column of grass called water
    h = np.where(classes == 0, -2.0, 1.0).astype(np.float32)
    ph = h + 0.5
    r = evaluate_scenes(scene([], classes, h), scene([], pred, ph))["terrain"]
    assert r["class_iou"]["water"] == pytest.approx(50 / 60)
    assert r["class_iou"]["grass"] == pytest.approx(40 / 50)
    assert r["height_rmse_land_m"] == pytest.approx(0.5) and r["height_rmse_water_m"] == pytest.approx(0.5)


def test_pier_connectivity():
    classes = np.zeros((100, 100), np.uint8)
    classes[:, :20] = 3  # land on the west (x < -30)
    # walkway from x=-32 to -12 touching land; a finger attached to its end; a floating orphan
    walk = obj(0, -22, 0, 0, cat="pier", asset="pier_walkway", length=20, width=2.5)
    finger = obj(1, -12, -5, 90, cat="pier", asset="pier_finger", length=8, width=1.2)
    s = scene([walk, finger], classes)
    assert pier_connectivity(s)["all_connected"] is True
    orphan = obj(2, 20, 20, 0, cat="pier", asset="pier_finger", length=8, width=1.2)
    r = pier_connectivity(scene([walk, finger, orphan], classes))
    assert r["all_connected"] is False and r["disconnected_ids"] == ["o2"]


def test_pier_deck_counts_the_truth_deck_found_and_the_deck_built_over_open_water():
    walk = obj(0, 0, 0, 0, cat="pier", asset="pier_walkway", length=20, width=2.0)  # 40 m² of truth deck
    half = obj(1, -5, 0, 0, cat="pier", asset="pier_walkway", length=10, width=2.0)  # its western half
    stray = obj(2, 30, 30, 0, cat="pier", asset="pier_finger", length=10, width=2.0)  # 20 m² over open water
    boat = obj(3, 0, 10, 0)
    r = pier_deck(scene([walk, boat]), scene([half, stray, boat]))
    assert r["truth_m2"] == pytest.approx(40.0) and r["pred_m2"] == pytest.approx(40.0)
    # the half found, plus the 0.5 m tolerance beyond its east end (2 m wide): (10 + 0.5) x 2 of 40 m²
    assert r["recall"] == pytest.approx(21.0 / 40.0, abs=1e-6)
    assert r["precision"] == pytest.approx(0.5)  # the stray piece is no truth pier
    # offsets within the tolerance are forgiven; connectivity alone would call any connected deck fine
    shifted = obj(4, 0, 0.3, 0, cat="pier", asset="pier_walkway", length=20, width=2.0)
    assert pier_deck(scene([walk]), scene([shifted]))["recall"] == pytest.approx(1.0)
    none = pier_deck(scene([walk]), scene([boat]))
    assert none["recall"] == 0.0 and none["precision"] is None
    assert pier_deck(scene([boat]), scene([boat])) == {"truth_m2": 0.0, "pred_m2": 0.0, "recall": None,
                                                     "precision": None}
    assert "pier_deck" in evaluate_scenes(scene([walk]), scene([half]))


def test_benchmark_table_has_the_pier_deck_columns_on_every_line():
    from coastforge.bench.paper import PAPER, to_markdown

    row = {"level": "marina", "resolution": "high", "n_truth": 10, "gsd_m": 0.1, "xy_rmse_m": 0.1,
           "rotation_rmse_deg": 1.0, "orientation_rmse_deg": 0.5, "match_precision": 1.0,
           "match_precision_category": 1.0, "recall": 1.0, "detection_precision": 1.0, "miou": 0.9,
           "piers_connected": True, "pier_deck_recall": 0.812, "pier_deck_precision": 0.934, "generate_s": 3.0}
    avg = {k: v for k, v in row.items() if k not in ("level", "resolution", "gsd_m")}
    md = to_markdown({"rows": [row], "averages": {"high": avg}, "paper": PAPER}).splitlines()
    assert "pier deck recall" in md[0] and "0.812" in md[2] and "0.934" in md[3]
    assert len({line.count("|") for line in md}) == 1  # header, rule, rows, averages and paper rows line up
