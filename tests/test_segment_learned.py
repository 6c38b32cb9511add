"""The learned segmenter (shipped ONNX U-Net) and its training helpers (no torch needed here)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from coastforge.classes import GRASS, N_CLASSES, WATER
from coastforge.config import SegmentConfig
from coastforge.errors import InputError
from coastforge.types import GeoImage, Grid

pytest.importorskip("onnxruntime")

from coastforge.segmentation import learned  # noqa: E402


def _scene(n: int = 256, seed: int = 0) -> np.ndarray:
    """Left half open water (blue-green, faint ripples), right half a lawn (textured green)."""
    rng = np.random.default_rng(seed)
    rgb = np.empty((n, n, 3), np.float32)
    rgb[:, : n // 2] = (38, 72, 88)
    rgb[:, n // 2:] = (88, 128, 58)
    rgb += rng.normal(0, 2, rgb.shape)
    rgb[:, n // 2:] += rng.normal(0, 9, (n, n - n // 2, 1))
    return np.clip(rgb, 0, 255).astype(np.uint8)


def test_tiles_cover_exactly_once():
    for n in (5, 768, 769, 2000, 5001):
        t = learned._tiles(n, 768, 48)
        assert t[0][2] == 0 and t[-1][3] == n
        assert all(a[3] == b[2] for a, b in zip(t, t[1:]))
        assert all(s <= kf < kt <= e and e - s <= max(768, 0) for s, e, kf, kt in t)


@pytest.fixture(scope="module")
def render():
    """A small level of a seed never trained on (training used 2000-2239), rendered like the benchmark."""
    pytest.importorskip("trimesh")
    from coastforge.train.seg_data import level_sample

    return level_sample("simple_pier_a", 4242, 0.2, 60.0)


def test_shipped_model_on_a_fresh_render(render):
    rgb, truth = render
    seg = learned.LearnedSegmenter(SegmentConfig(learned_water="net"))
    ids = seg.segment(GeoImage(rgb=rgb, grid=Grid(rgb.shape[1], rgb.shape[0], 0.2)), 0).ids
    assert ids.shape == truth.shape and ids.dtype == np.uint8 and int(ids.max()) < N_CLASSES
    assert (ids == truth).mean() > 0.9
    for c in (WATER, GRASS):
        inter = ((ids == c) & (truth == c)).sum()
        assert inter / ((ids == c) | (truth == c)).sum() > 0.8


def test_tiled_inference_matches_whole(render, monkeypatch):
    seg = learned.LearnedSegmenter(SegmentConfig())
    rgb = cv2.resize(render[0], (200, 200), interpolation=cv2.INTER_AREA)  # 60 m at 0.3 m/px
    whole = seg.proba_small(rgb)
    monkeypatch.setattr(learned, "TILE_PX", 128)
    monkeypatch.setattr(learned, "OVERLAP_PX", 32)
    tiled = seg.proba_small(rgb)
    assert np.allclose(whole.sum(2), 1.0, atol=1e-4)
    assert (whole.argmax(2) == tiled.argmax(2)).mean() > 0.95


def test_learned_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        learned.LearnedSegmenter(SegmentConfig(), weights=tmp_path / "missing.onnx")
    with pytest.raises(InputError, match="takes weights="):
        learned.LearnedSegmenter(SegmentConfig(), bogus=1)
    fake = tmp_path / "m.onnx"
    fake.write_bytes(b"not onnx")
    (tmp_path / "m.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(InputError, match="format"):
        learned.LearnedSegmenter(SegmentConfig(), weights=fake)
    (tmp_path / "m.json").write_text(json.dumps({"format": learned.FORMAT, "classes": list(
        ("water", "asphalt", "sidewalk", "grass", "trees", "dirt", "rocks", "sand")), "work_gsd_m": 0.3}))
    seg = learned.LearnedSegmenter(SegmentConfig(), weights=fake)
    with pytest.raises(InputError, match="not a loadable ONNX"):
        seg.segment(GeoImage(rgb=_scene(64), grid=Grid(64, 64, 0.2)), 0)
    with pytest.raises(InputError, match="uint8 RGB"):
        learned.LearnedSegmenter(SegmentConfig()).segment(
            GeoImage(rgb=np.zeros((8, 8), np.uint8), grid=Grid(8, 8, 0.2)), 0)


def test_registry_and_segment_entry_point():
    from coastforge.segmentation import segment

    img = GeoImage(rgb=_scene(128), grid=Grid(128, 128, 0.3))
    cm = segment(img, SegmentConfig(backend="learned"))
    assert cm.ids.shape == (128, 128)


def test_training_batches_are_balanced_and_augmented():
    from coastforge.rng import stage_rng
    from coastforge.train import seg_train

    rng = stage_rng(3, "test")
    ids = np.zeros((200, 200), np.uint8)
    ids[150:, 150:] = 7  # a rare class (sand) in one corner
    rgb = np.full((200, 200, 3), 90, np.uint8)
    levels = [(rgb, ids)]
    centres = seg_train.class_centres(levels, rng)
    assert len(centres) == 2
    x, y = seg_train.sample_batch(levels, 16, 64, rng, centres)
    assert x.shape == (16, 3, 64, 64) and y.shape == (16, 64, 64)
    assert -0.5 <= x.min() and x.max() <= 0.5 and x.std() > 0.01  # appearance changed
    assert (y == 7).any(axis=(1, 2)).sum() >= 6  # about half the crops are centred on the rare class
    w = seg_train.class_weights(levels)
    assert w[7] > w[0]


def test_coarse_images_fall_back_to_classical_and_bad_mode():
    from coastforge.segmentation.classical import ClassicalSegmenter

    img = GeoImage(rgb=_scene(96), grid=Grid(96, 96, 2.0))  # 2 m/px: far outside the training GSDs
    got = learned.LearnedSegmenter(SegmentConfig()).segment(img, 3).ids
    assert np.array_equal(got, ClassicalSegmenter(SegmentConfig()).segment(img, 3).ids)
    with pytest.raises(InputError, match="learned_water"):
        learned.LearnedSegmenter(SegmentConfig(learned_water="both")).segment(
            GeoImage(rgb=_scene(64), grid=Grid(64, 64, 0.2)), 0)


def test_agreement_gate_picks_network_or_classical():
    from coastforge.segmentation.classical import ClassicalSegmenter

    img = GeoImage(rgb=_scene(256, seed=2), grid=Grid(256, 256, 0.4))
    never = learned.LearnedSegmenter(SegmentConfig(learned_min_agreement=1.01))
    assert np.array_equal(never.segment(img, 0).ids, ClassicalSegmenter(SegmentConfig()).segment(img, 0).ids)
    assert never.last_choice.startswith("classical") and 0.0 <= never.last_agreement <= 1.0
    always = learned.LearnedSegmenter(SegmentConfig(learned_min_agreement=0.0))
    ids = always.segment(img, 0).ids
    assert always.last_choice.startswith("network")
    assert (ids[:, :100] == WATER).mean() > 0.9 and (ids[:, 150:] == WATER).mean() < 0.05


# ------------------------------------------------------------- network water when the rules find none


def _have_weights() -> bool:
    return learned.default_weights().is_file()


def test_network_water_replaces_none_from_the_classical_rules(tmp_path, monkeypatch):
    """A silty olive-brown river (synthetic simple_pier_a, seed 3) whose colour the classical water
    rules do not know (here: their murky-water rule switched off; the hue is that of yellow-cast
    pavement): they find no water at all, and their land seeds on the river make the self-check
    reject the network. The network sees the river, is sure of it, and agrees with the rules off it:
    its water is used."""
    if not _have_weights():
        pytest.skip("learned segmenter weights are not shipped in this checkout")
    synth = pytest.importorskip("coastforge.synth")
    from coastforge.fsio import read_png
    from coastforge.io import read_image
    from coastforge.segmentation import segment

    synth.synth_to_dir("simple_pier_a", 3, tmp_path, gsds=(0.3,), overwrite=True)
    truth_scene = json.loads((tmp_path / "truth.json").read_text(encoding="utf-8"))
    truth = read_png(tmp_path / truth_scene["terrain"]["classes"])
    image = read_image(tmp_path / "image_0.30m.png", gsd_m=0.3)
    t = cv2.resize(truth, (image.rgb.shape[1], image.rgb.shape[0]), interpolation=cv2.INTER_NEAREST) == WATER
    found = segment(image, SegmentConfig(backend="classical")).ids == WATER
    assert (found & t).sum() / (found | t).sum() > 0.9  # the murky-water rule finds it ...
    from coastforge.segmentation import classical as classical_mod

    monkeypatch.setattr(classical_mod, "MURKY_MAX_L", -1.0)
    monkeypatch.setattr(classical_mod, "MURKY_GREEN_MAX_L", -1.0)
    classical = segment(image, SegmentConfig(backend="classical")).ids == WATER
    assert classical.mean() < 0.01  # ... without it, the rules miss this river entirely
    seg = learned.LearnedSegmenter(SegmentConfig())
    w = seg.segment(image).ids == WATER
    assert (w & t).sum() / (w | t).sum() > 0.9
    assert "network water" in seg.last_choice


def test_network_water_not_trusted_on_a_photo_without_water():
    """On a real car park crop the network calls much of the asphalt water, unsure (~0.7): the
    classical result (no water) stands."""
    from pathlib import Path

    if not _have_weights():
        pytest.skip("learned segmenter weights are not shipped in this checkout")
    shared = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    path = shared / "aerial" / "vehicles_p1053" / "image.jpg"
    if not path.is_file():
        pytest.skip(f"real test image {path} not found (../shared/data is not part of the repository)")
    from coastforge.io import read_image

    seg = learned.LearnedSegmenter(SegmentConfig())
    ids = seg.segment(read_image(path, gsd_m=0.125)).ids
    assert (ids == WATER).mean() < 0.01
    assert seg.last_choice.startswith("classical")
