"""The learned segmenter (shipped ONNX U-Net) and its training helpers (no torch needed here)."""

from __future__ import annotations

import itertools
import json

import cv2
import numpy as np
import pytest

from coastforge.classes import GRASS, N_CLASSES, WATER
from coastforge.config import SegmentConfig
from coastforge.errors import InputError
from coastforge.types import GeoImage, Grid

pytest.importorskip("onnxruntime")

from coastforge.segmentation import learned


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
        assert all(a[3] == b[2] for a, b in itertools.pairwise(t))
        assert all(s <= kf < kt <= e and e - s <= max(768, 0) for s, e, kf, kt in t)


def test_tiles_are_even_and_keep_their_context():
    # 1707: a 2560 px window at 0.2 m/px on the 0.3 m/px grid; 1365: 2048 px
    for n, count in ((1365, 2), (1707, 3), (2731, 4), (5001, 8)):
        t = learned._tiles(n, 768, 48, 16)
        assert len(t) == count
        assert len({e - s for s, e, _, _ in t}) == 1 and (t[0][1] - t[0][0]) % 16 == 0
        assert all(kf - s >= 48 for s, _, kf, _ in t[1:]) and all(e - kt >= 48 for _, e, _, kt in t[:-1])


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
    seg.meta = {**seg.meta, "overlap_px": 32}  # the card's overlap (deeper networks ask for more)
    tiled = seg.proba_small(rgb)
    assert np.allclose(whole.sum(2), 1.0, atol=1e-4)
    assert (whole.argmax(2) == tiled.argmax(2)).mean() > 0.95


@pytest.mark.parametrize("arch,mult", [("unet4", 16), ("unet5", 32)])
def test_segmenter_architectures(arch, mult):
    torch = pytest.importorskip("torch")
    from coastforge.train.seg_model import build_segmenter
    from coastforge.train.seg_train import ARCH_MULTIPLE

    assert ARCH_MULTIPLE[arch] == mult
    net = build_segmenter(8, 8, arch).eval()
    with torch.no_grad():
        out = net(torch.zeros(1, 3, 2 * mult, 3 * mult))
    assert tuple(out.shape) == (1, 8, 2 * mult, 3 * mult)
    with pytest.raises(ValueError, match="arch"):
        build_segmenter(8, 8, "unet9")


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
    (tmp_path / "m.json").write_text(json.dumps({"format": learned.FORMAT, "classes": [
        "water", "asphalt", "sidewalk", "grass", "trees", "dirt", "rocks", "sand"], "work_gsd_m": 0.3}))
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


def test_wide_looks_make_land_dark_and_base_is_the_default():
    """``--looks wide`` lets a land class turn dark (so dark alone never means water) and casts shadows;
    ``base`` is the default."""
    from coastforge.rng import stage_rng
    from coastforge.train import seg_train

    ids = np.full((64, 64), 3, np.uint8)  # grass
    ids[:, :32] = 0  # and water
    rgb = np.full((64, 64, 3), 150, np.uint8)

    def grass_means(looks):
        rng = stage_rng(5, "looks")
        return np.array([seg_train.augment(rgb, ids, rng, looks)[:, 32:].mean() for _ in range(300)])

    base, wide = grass_means("base"), grass_means("wide")
    assert np.percentile(wide, 10) < np.percentile(base, 10) - 10  # darker land is drawn more often
    rng_a, rng_b = stage_rng(5, "same"), stage_rng(5, "same")
    assert np.array_equal(seg_train.augment(rgb, ids, rng_a), seg_train.augment(rgb, ids, rng_b, "base"))


def test_coarse_images_fall_back_to_classical_and_bad_mode():
    from coastforge.segmentation.classical import ClassicalSegmenter

    img = GeoImage(rgb=_scene(96), grid=Grid(96, 96, 2.0))  # 2 m/px: far outside the training GSDs
    cm = learned.LearnedSegmenter(SegmentConfig()).segment(img, 3)
    assert np.array_equal(cm.ids, ClassicalSegmenter(SegmentConfig()).segment(img, 3).ids)
    assert (cm.source == learned.SOURCE_CLASSICAL).all()
    with pytest.raises(InputError, match="learned_water"):
        learned.LearnedSegmenter(SegmentConfig(learned_water="both")).segment(
            GeoImage(rgb=_scene(64), grid=Grid(64, 64, 0.2)), 0)


def _proba(water: float) -> np.ndarray:
    """One pixel's probabilities: ``water`` for water, the rest 3:1 between asphalt and grass."""
    p = np.zeros((1, 1, N_CLASSES), np.float32)
    p[..., WATER] = water
    p[..., 1] = 0.75 * (1 - water)
    p[..., GRASS] = 0.25 * (1 - water)
    return p


def _votes(cls: int) -> np.ndarray:
    v = np.zeros((1, 1, N_CLASSES), np.float32)
    v[..., cls] = 1.0
    return v


def test_classical_water_votes_but_does_not_veto():
    """A sure network keeps its water call against the classical water model; an unsure one follows it;
    the probabilities still sum to 1."""
    vote = learned.CLASSICAL_WATER_VOTE
    sure_land = _proba(0.02)
    learned.fuse_votes(sure_land, _votes(WATER), vote, 0.0)  # the rules say water
    assert sure_land[0, 0].argmax() != WATER
    sure_water = _proba(0.98)
    learned.fuse_votes(sure_water, _votes(GRASS), vote, 0.0)  # the rules say lawn
    assert sure_water[0, 0].argmax() == WATER
    for cls, want in ((WATER, True), (GRASS, False)):
        unsure = _proba(0.45)
        learned.fuse_votes(unsure, _votes(cls), vote, 0.0)
        assert bool(unsure[0, 0].argmax() == WATER) is want
        assert unsure.sum() == pytest.approx(1.0, abs=1e-5)


def test_land_classes_mix_by_gsd():
    """Among land classes the classical classifier decides at fine GSDs, the network at coarse ones."""
    assert learned.classical_weight(0.1) == 1.0 and learned.classical_weight(1.0) == 0.0
    assert 0.0 < learned.classical_weight(0.45) < 1.0
    fine, coarse = _proba(0.1), _proba(0.1)  # the network: asphalt 3:1 over grass
    learned.fuse_votes(fine, _votes(GRASS), 3.0, learned.classical_weight(0.2))
    learned.fuse_votes(coarse, _votes(GRASS), 3.0, learned.classical_weight(0.8))
    assert fine[0, 0].argmax() == GRASS and coarse[0, 0].argmax() == 1
    where_rules_see_water = _proba(0.3)
    learned.fuse_votes(where_rules_see_water, _votes(WATER), 3.0, 1.0)  # no land class to mix in
    assert where_rules_see_water[0, 0, 1] / where_rules_see_water[0, 0, GRASS] == pytest.approx(3.0, rel=1e-3)


def test_source_map_says_who_decided():
    net = np.array([[WATER, WATER, GRASS, GRASS]], np.uint8)
    final = np.array([[WATER, GRASS, GRASS, WATER]], np.uint8)
    classical = np.zeros((1, 4, N_CLASSES), np.float32)
    classical[0, [0, 2, 3], WATER] = 1.0
    classical[0, 1, GRASS] = 1.0
    src = learned.source_map(net, final, classical)
    assert src.tolist() == [[learned.SOURCE_BOTH, learned.SOURCE_CLASSICAL, learned.SOURCE_NETWORK,
                             learned.SOURCE_CLASSICAL]]
    assert (learned.source_map(net, net, None) == learned.SOURCE_NETWORK).all()


def test_segment_gives_confidence_and_source():
    """The class map carries a confidence and who decided each pixel, consistent with the classes: where
    the final class is not the network's own, the classical rules decided. (This flat, saturated green
    toy lawn is one the network calls water, p ~ 0.96, and the rules' vote does not outweigh it: real
    lawns are measured by bench.real.)"""
    img = GeoImage(rgb=_scene(256, seed=2), grid=Grid(256, 256, 0.2))
    seg = learned.LearnedSegmenter(SegmentConfig())
    cm = seg.segment(img, 0)
    net = learned.LearnedSegmenter(SegmentConfig(learned_water="net")).segment(img, 0)
    assert cm.confidence.shape == cm.source.shape == (256, 256)
    assert cm.confidence.dtype == np.uint8 and cm.confidence.mean() > 128
    assert set(np.unique(cm.source)) <= {learned.SOURCE_BOTH, learned.SOURCE_NETWORK, learned.SOURCE_CLASSICAL}
    differs = cm.ids != net.ids
    assert (cm.source[differs] == learned.SOURCE_CLASSICAL).mean() > 0.9
    assert (cm.ids[:, :100] == WATER).mean() > 0.9


# ------------------------------------------------------------- network water when the rules find none


def _have_weights() -> bool:
    return learned.default_weights().is_file()


def test_network_water_outvotes_rules_that_find_none(tmp_path, monkeypatch):
    """A silty olive-brown river (synthetic simple_pier_a, seed 3) whose colour the classical water
    rules do not know (here: their murky-water rule switched off; the hue is that of yellow-cast
    pavement): they find no water at all. The network sees the river and is sure of it: its water
    stands against their vote."""
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
    cm = seg.segment(image)
    w = cm.ids == WATER
    assert (w & t).sum() / (w | t).sum() > 0.85  # measured 0.88 (the network's river banks are a little wide)
    assert (cm.source[w & t] == learned.SOURCE_NETWORK).mean() > 0.8  # the network outvoted the rules there


def test_no_water_on_a_real_car_park():
    """A real car park crop (DOTA, 0.125 m/px) has no water: neither the network nor the rules may
    invent any."""
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


def test_false_water_weighs_pixels_wrongly_called_water():
    """``seg_train --false-water W``: a pixel the network calls water where its label forbids water weighs W
    times as much in the loss; right pixels and wrong pixels of other classes keep their weight."""
    torch = pytest.importorskip("torch")
    from coastforge.train import seg_train

    sets = torch.from_numpy(seg_train.label_sets())
    weights = torch.ones(seg_train.N_CODES)
    logits = torch.zeros(1, N_CLASSES, 1, 3)
    logits[0, WATER, 0, 0] = 3.0  # called water, labelled grass: a false water pixel
    logits[0, WATER, 0, 1] = 3.0  # called water, labelled water: right
    logits[0, 1, 0, 2] = 3.0  # called asphalt, labelled grass: wrong, but not water
    y = torch.tensor([[[GRASS, WATER, GRASS]]])
    nll = [float(seg_train.set_loss(torch, logits[..., i:i + 1], y[..., i:i + 1], sets, weights)) for i in range(3)]
    plain = float(seg_train.set_loss(torch, logits, y, sets, weights))
    heavy = float(seg_train.set_loss(torch, logits, y, sets, weights, false_water=4.0))
    assert plain == pytest.approx(sum(nll) / 3, rel=1e-5)
    assert heavy == pytest.approx((4 * nll[0] + nll[1] + nll[2]) / 6, rel=1e-5)


def test_dubai_tiles_can_be_held_out_for_an_inner_check():
    """``seg_train --hold tile_4`` leaves a training tile out (so a recipe can be judged on unseen tiles
    without looking at the validation tiles); a tile that is not a training tile is a clear error."""
    from coastforge import realdata
    from coastforge.train import seg_train

    items = realdata.dubai_items()
    if not items:
        pytest.skip(f"../shared/data/real/landcover_dubai not found under {realdata.SHARED}")
    train_tiles = sorted({n.split("/")[0] for n, _i, _m, v in items if not v})
    held = train_tiles[0]
    n_all = sum(not v for _n, _i, _m, v in items)
    n_held = sum(not v and n.startswith(held + "/") for n, _i, _m, v in items)
    kept = seg_train.load_dubai(1.2, hold=(held,))
    assert len(kept) == n_all - n_held > 0
    assert all(lab.dtype == np.uint8 and rgb.shape[:2] == lab.shape for rgb, lab in kept)
    with pytest.raises(InputError, match="not a Dubai training tile"):
        seg_train.load_dubai(1.2, hold=(realdata.DUBAI_VAL_TILES[0],))


def test_ships_self_training_labels(monkeypatch):
    """``--real shipsself``: on harbour photos the teacher's sure water and every labelled boat are water, its
    sure land is land, the rest is left out; a missing teacher is a clear error."""
    from coastforge import realdata
    from coastforge.train import seg_train

    items = [it for it in realdata.ships_items() if not it.val and len(it.boxes) >= 3][:2]
    if not items:
        pytest.skip(f"../shared/data/real/ships_aerial not found under {realdata.SHARED}")
    monkeypatch.setattr(realdata, "ships_items", lambda: items)
    out = seg_train.load_ships_self(learned.default_weights(), 0.3)
    assert len(out) == 2
    for (rgb, lab), it in zip(out, items):
        assert rgb.shape[:2] == lab.shape
        assert set(np.unique(lab)) <= {seg_train.IGNORE, seg_train.REAL_WATER, seg_train.SET_LAND}
        s = lab.shape[1] / realdata.read_rgb(it.path).shape[1]
        x0, y0, x1, y1 = it.boxes[0] * s
        assert np.all(lab[int(round(y0)):int(round(y1)), int(round(x0)):int(round(x1))] == seg_train.REAL_WATER)
        assert (lab == seg_train.SET_LAND).any() or (lab == seg_train.REAL_WATER).mean() > 0.5
    with pytest.raises(InputError, match="teacher"):
        seg_train.load_ships_self("no/such/model.onnx")
