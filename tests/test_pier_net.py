"""The pier-deck network: its training data (deck masks), its ONNX inference (a small randomly initialised
model built here), and the classical detector finding a deck the colour thresholds miss once it marks it."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from pier_scenes import StandNet

from coastforge.config import DetectConfig
from coastforge.detection.classical import ClassicalDetector
from coastforge.detection.pier_net import FORMAT, PierNet
from coastforge.errors import InputError
from coastforge.types import GeoImage, Grid


def test_deck_mask_covers_the_pier_footprints_on_the_scene_grid():
    from coastforge.synth import synthesize_level
    from coastforge.train.pier_data import deck_mask

    level = synthesize_level("simple_pier_a", 101, size_m=100, grid_m=0.2)
    mask = deck_mask(level.scene)
    assert mask.shape == level.scene.classes.shape and mask.dtype == np.uint8
    piers = [o for o in level.scene.objects if o.category == "pier"]
    assert piers
    # the masked area is the decks' (union) area within a pixel rim
    from shapely import unary_union
    from shapely.geometry import Polygon

    area = unary_union([Polygon(o.footprint_m()) for o in piers]).area
    assert abs(mask.sum() * 0.04 - area) < 0.15 * area
    o = piers[0]
    cx, cy = np.asarray(o.footprint_m()).mean(0)
    col, row = level.scene.grid.to_pixel(np.array([cx]), np.array([cy]))
    assert mask[int(row[0]), int(col[0])] == 1


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from coastforge.train.seg_train import export_onnx
    from coastforge.train.seg_model import build_segmenter

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("piernet") / "piers.onnx"
    export_onnx(build_segmenter(1, 4, "unet4"), path)
    path.with_suffix(".json").write_text(json.dumps({"format": FORMAT, "work_gsd_m": 0.2, "multiple": 16}))
    return path


def test_pier_net_runs_tiled_at_its_working_gsd(tiny_model):
    net = PierNet(tiny_model)
    rgb = np.random.default_rng(0).integers(0, 255, (300, 1700, 3), np.uint8)  # three tiles across
    p = net.probability_small(rgb)
    assert p.shape == (300, 1700) and p.dtype == np.float32 and 0 <= p.min() and p.max() <= 1
    # the image at 0.1 m/px: run on it halved, the answer brought back to the asked grid
    q = net.probability(rgb, 0.1, (150, 850))
    assert q.shape == (150, 850) and np.isfinite(q).all()


def test_pier_net_refuses_a_missing_model_or_another_card(tiny_model, tmp_path):
    with pytest.raises(InputError, match="pier_train"):
        PierNet(tmp_path / "none.onnx")
    other = tmp_path / "piers.onnx"
    other.write_bytes(tiny_model.read_bytes())
    other.with_suffix(".json").write_text(json.dumps({"format": "coastforge.segmenter/1"}))
    with pytest.raises(InputError, match="not a pier-deck card"):
        PierNet(other)
    other.with_suffix(".json").write_text(json.dumps({"format": FORMAT, "max_gsd_m": "coarse"}))
    with pytest.raises(InputError, match="max_gsd_m"):
        PierNet(other)


def test_the_card_says_how_coarse_an_image_the_network_is_for(tiny_model, tmp_path):
    assert PierNet(tiny_model).max_gsd_m == 0.4  # a card without it: the renders' range
    other = tmp_path / "piers.onnx"
    other.write_bytes(tiny_model.read_bytes())
    other.with_suffix(".json").write_text(json.dumps({"format": FORMAT, "max_gsd_m": 1.2}))
    assert PierNet(other).max_gsd_m == 1.2


def test_training_crops_are_turned_jittered_and_keep_their_masks():
    from coastforge.train.pier_train import CROP, sample

    rng = np.random.default_rng(0)
    rgb = np.full((300, 300, 3), (40, 90, 110), np.uint8)
    mask = np.zeros((300, 300), np.uint8)
    mask[100:110, 50:250] = 1
    rgb[mask > 0] = (120, 100, 80)
    x, m = sample([(0, rgb, mask)], rng, deck_share=1.0)
    assert x.shape == (3, CROP, CROP) and m.shape == (CROP, CROP) and 0 <= x.min() and x.max() <= 1
    assert m.any()  # centred on the deck


def _faint_pier_scene():
    """Water with a walkway (40 m x 2 m, from the west edge) and two fingers coloured almost like it (4 L
    brighter): under the colour thresholds of the structure mask."""
    gsd = 0.2
    rgb = np.zeros((400, 400, 3), np.uint8)
    rgb[:] = (40, 90, 110)
    deck = np.zeros((400, 400), bool)
    deck[190:200, 0:200] = True  # the walkway
    deck[140:190, 100:105] = True  # fingers
    deck[200:250, 150:155] = True
    rgb[deck] = (44, 94, 112)
    return GeoImage(rgb=rgb, grid=Grid(400, 400, gsd)), deck


def test_the_classical_detector_finds_a_deck_only_the_network_sees(monkeypatch):
    image, deck = _faint_pier_scene()
    piers = lambda dets: [d for d in dets if d.category.startswith("pier")]  # noqa: E731
    assert not piers(ClassicalDetector(DetectConfig(pier_net=False, vehicles=False)).detect(image))

    det = ClassicalDetector(DetectConfig(pier_net=True, vehicles=False))
    monkeypatch.setattr(det, "pier_net", lambda: StandNet(deck))
    found = piers(det.detect(image))
    walk = [d for d in found if d.category == "pier_walkway"]
    assert walk and max(d.length_px for d in walk) * 0.2 > 30


def test_a_boat_moored_alongside_no_longer_cuts_the_walkway(monkeypatch):
    """A bright 24 m walkway with a 10 m hull moored alongside its middle: in the colour mask the two make a blob
    too wide for a deck, which cut the walkway into runs shorter than a walkway; the network's decks leave the
    hull out of the pier search, and the walkway is found whole."""
    rgb = np.zeros((300, 400, 3), np.uint8)
    rgb[:] = (40, 90, 110)
    deck = np.zeros((300, 400), bool)
    deck[150:160, 0:120] = True  # 2 m x 24 m at 0.2 m/px, from the west edge
    rgb[deck] = (170, 160, 140)
    rgb[160:178, 35:85] = (235, 235, 235)  # the hull, 3.6 m x 10 m, touching the deck
    image = GeoImage(rgb=rgb, grid=Grid(400, 300, 0.2))
    walks = lambda dets: [d for d in dets if d.category == "pier_walkway"]  # noqa: E731
    assert not walks(ClassicalDetector(DetectConfig(pier_net=False, vehicles=False)).detect(image))
    det = ClassicalDetector(DetectConfig(pier_net=True, vehicles=False))
    monkeypatch.setattr(det, "pier_net", lambda: StandNet(deck))
    found = walks(det.detect(image))
    assert found and max(d.length_px for d in found) * 0.2 > 20


def test_component_axes_give_each_elongated_part_its_direction():
    import cv2

    from coastforge.detection.piers import component_axes

    m = np.zeros((200, 200), np.uint8)
    cv2.line(m, (20, 100), (180, 100 - int(round(160 * np.tan(np.radians(5))))), 1, 5)  # 5° up to the right
    cv2.circle(m, (60, 160), 12, 1, -1)  # a round blob: no direction
    m[10:14, 10:24] = 1  # too short
    angles = component_axes(m.astype(bool), 40)
    assert len(angles) == 2 and min(abs(a - 5.0) for a in angles) < 1.0 and min(abs(a - 95.0) for a in angles) < 1.0


def test_the_shipped_network_marks_a_rendered_pier_and_little_else():
    from coastforge.train.pier_data import level_sample

    rgb, deck = level_sample("lake_harbor", 7004, 0.2, 120)  # dark timber; a seed it never trained on (6000-6599)
    p = PierNet().probability_small(rgb) >= 0.5
    t = deck > 0
    assert t.any()
    assert (p & t).sum() >= 0.6 * t.sum()
    assert (p & ~t).sum() <= 0.01 * (~t).sum()


def test_a_walkway_crossed_by_many_long_fingers_stays_the_walkway():
    """Six parallel 24 m fingers (more deck than the 60 m walkway they cross) must not take the crossings from
    it: with ``longest_run`` (the network's decks) the direction with the longest straight run wins them."""
    from coastforge.detection.piers import detect_piers

    gsd = 0.2
    m = np.zeros((400, 400), bool)
    m[195:205, 50:350] = True  # walkway: 60 m x 2 m, west-east
    for x in range(70, 340, 50):
        m[140:260, x:x + 5] = True  # fingers: 24 m x 1 m, crossing it
    water = ~m
    dets, _ = detect_piers(m, gsd, angles=[0.0, 90.0], water=water, longest_run=True)
    walks = [d for d in dets if d.category == "pier_walkway"]
    assert walks and max(d.length_px for d in walks) * gsd > 50
    assert all(abs(abs(((d.yaw_deg + 90) % 180) - 90)) < 5 for d in walks if d.length_px * gsd > 50)


def test_a_curved_walkway_is_chained_from_pieces_along_its_deck(monkeypatch):
    """The straight line openings find no 18 m run in a walkway bent through a quarter circle; the deck's
    spine (``detect.deck_spines``) gives it as short straight pieces along the curve."""
    from pier_scenes import curved_pier_scene

    image, deck = curved_pier_scene()

    def walkway_cover(spines: bool) -> float:
        det = ClassicalDetector(DetectConfig(pier_net=True, deck_spines=spines, vehicles=False))
        monkeypatch.setattr(det, "pier_net", lambda: StandNet(deck))
        drawn = np.zeros(deck.shape, np.uint8)
        for d in det.detect(image):
            if d.category == "pier_walkway":
                cv2.fillPoly(drawn, [np.round(d.corners_px()).astype(np.int32)], 1)
        return float(drawn[deck].mean())

    assert walkway_cover(False) < 0.3
    assert walkway_cover(True) > 0.7
