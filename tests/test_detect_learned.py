"""The learned detector: decoding, training targets ↔ decoding, errors, and the shipped ONNX model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coastforge import frames
from coastforge.config import DetectConfig
from coastforge.errors import InputError
from coastforge.types import GeoImage, Grid

pytest.importorskip("onnxruntime")

from coastforge.detection.learned import LearnedDetector, decode, default_weights


def _maps(n=16, c=3):
    return np.zeros((c, n, n), np.float32), np.zeros((8, n, n), np.float32)


def _put(peaks, reg, cls, i, j, score, off, L, W, axis_deg, head_deg):
    peaks[cls, i, j] = score
    a, h = math.radians(axis_deg), math.radians(head_deg)
    reg[:, i, j] = [off[0], off[1], math.log(L / 4), math.log(W / 4), math.cos(2 * a), math.sin(2 * a),
                    math.cos(h), math.sin(h)]


def test_decode_peak_to_box_and_heading():
    peaks, reg = _maps()
    _put(peaks, reg, 0, 5, 7, 0.9, (0.25, 0.75), 40.0, 12.0, 30.0, 30.0)  # front along the axis
    _put(peaks, reg, 1, 10, 2, 0.8, (0.5, 0.5), 20.0, 8.0, 30.0, -150.0)  # front opposite: yaw = axis+180
    _put(peaks, reg, 2, 12, 12, 0.2, (0.5, 0.5), 4.0, 4.0, 0.0, 0.0)  # below threshold
    rows = decode(peaks, reg, threshold=0.3)
    assert len(rows) == 2
    rows = rows[np.argsort(-rows[:, 1])]
    c, s, cx, cy, L, W, yaw, conf = rows[0]
    assert (c, round(s, 3)) == (0, 0.9)
    assert (cx, cy) == pytest.approx(((7 + 0.25) * 4, (5 + 0.75) * 4), abs=1e-4)
    assert (L, W) == pytest.approx((40.0, 12.0), rel=1e-4)
    assert yaw == pytest.approx(30.0, abs=1e-3) and conf == pytest.approx(1.0, abs=1e-4)
    assert rows[1][6] == pytest.approx(-150.0, abs=1e-3)


def test_decode_swaps_a_wide_box_and_checks_shapes():
    peaks, reg = _maps()
    _put(peaks, reg, 0, 3, 3, 0.9, (0.5, 0.5), 8.0, 20.0, 10.0, 10.0)
    (_c, _s, _cx, _cy, L, W, yaw, conf), = decode(peaks, reg, 0.3)
    assert (L, W) == pytest.approx((20.0, 8.0)) and yaw == pytest.approx(100.0, abs=1e-3)
    assert conf == 0.5  # the front of a swapped box is unknown
    with pytest.raises(InputError, match="expected"):
        decode(peaks, reg[:5], 0.3)


def test_axis_aligned_real_labels_teach_centres_only():
    """A real label (axis-aligned box, 7th column 0) supervises the heatmap and the offset, not the size
    nor the axis: its box is not the object's oriented extent."""
    from coastforge.train.train_detector import make_targets

    box = np.array([[0, 80.0, 80.0, 40.0, 20.0, 0.0, 0.0]])
    heat, _reg, wmask, amask, smask = make_targets(box, 160)
    assert heat[0].max() == 1.0 and wmask.sum() >= 1
    assert amask.sum() == 0 and smask.sum() == 0
    r, c = np.unravel_index(heat[0].argmax(), heat[0].shape)
    assert heat[0, r, c + 2] == pytest.approx(heat[0, r + 2, c], rel=1e-6)  # round, not along the box


def test_objects_the_crop_cuts_are_background_as_the_real_labels_have_them():
    """``train_detector --min-inside``: a boat under 70 % inside the training crop teaches no centre (the real
    sets leave it to the next picture); one 80 % inside does, and so does a ship longer than half the crop."""
    from coastforge.train.train_detector import drop_cut_boxes, make_targets

    boxes = np.array([[0, 5.0, 100.0, 40.0, 14.0, 0.0, 1.0],  # x -15 .. 25: 62 % inside
                      [0, 12.0, 100.0, 40.0, 14.0, 0.0, 1.0],  # x -8 .. 32: 80 % inside
                      [0, 100.0, 220.0, 40.0, 14.0, 90.0, 1.0],  # y 200 .. 240: 60 % inside, turned
                      [0, 180.0, 40.0, 160.0, 40.0, 0.0, 1.0]])  # x 100 .. 260: a big ship, 75 % inside
    kept = drop_cut_boxes(boxes, 224, 0.7)
    assert kept[:, 1].tolist() == [12.0, 180.0]
    assert len(drop_cut_boxes(boxes, 224, 0.0)) == 4  # off: every object whose centre is inside
    heat = make_targets(kept, 224)[0]
    assert heat[0, 25, 1] < 0.5 and heat[0, 25, 3] == 1.0  # no peak at the cut boat's centre (x 5)


def test_coarse_source_softens_a_crop_as_a_coarser_photo_would():
    """``train_detector --coarse-p``: a crop brought down 1.5-5 times and back up keeps its size and mean but
    loses its sharp edges (a one-pixel line is spread out), differently for each draw."""
    from coastforge.train.train_detector import coarse_source

    img = np.full((64, 64, 3), 40, np.uint8)
    img[:, 32] = 240  # a one-pixel white line, as a pier's edge or a hull's rim at 0.2 m/px
    a = coarse_source(img, np.random.default_rng(0))
    b = coarse_source(img, np.random.default_rng(1))
    assert a.shape == img.shape and a.dtype == np.uint8
    assert abs(float(a.mean()) - float(img.mean())) < 6.0
    assert a[:, 32].mean() < 200 and a[:, 31].mean() > 45  # the line spread over its neighbours
    assert not np.array_equal(a, b)


def test_weather_draws_each_of_its_four_looks():
    """``train_detector --weather-p``: each draw is haze (contrast shrunk alike in every channel), hard exposure (mean moved), heavy
    noise (a flat patch gets texture) or no colour (equal channels); the size and type stay."""
    from coastforge.train.train_detector import weather

    img = np.full((48, 48, 3), (40, 90, 120), np.uint8)  # flat dark water
    img[:, 24:] = (200, 200, 190)  # a white hull
    seen = {"haze": 0, "exposure": 0, "noise": 0, "grey": 0}
    for seed in range(40):
        out = weather(img, np.random.default_rng(seed))
        assert out.shape == img.shape and out.dtype == np.uint8
        o = out.astype(int)
        if o[:, :24].std(axis=(0, 1)).max() > 3:
            seen["noise"] += 1
        elif (o[..., 0] == o[..., 1]).all() and (o[..., 1] == o[..., 2]).all():
            seen["grey"] += 1
        elif np.ptp(slope := (o[0, 30] - o[0, 0]) / (img[0, 30].astype(int) - img[0, 0])) < 0.05 and slope[0] < 0.95:
            seen["haze"] += 1  # a blend towards one light colour: every channel's contrast shrinks alike
        else:
            assert abs(o.mean() - img.mean()) > 3  # exposure: the mean moved
            seen["exposure"] += 1
    assert all(n > 3 for n in seen.values()), seen


def test_a_flat_margin_keeps_objects_the_picture_cuts_whole():
    """``train_detector --blank-p``: a strip along one side of the crop is painted flat; a boat still 30 % or
    more visible keeps its whole box (centre under the strip, a peak there), one hidden more goes; the rest
    of the crop is untouched."""
    from coastforge.train.train_detector import blank_margin, make_targets

    img = np.random.default_rng(3).integers(0, 255, (224, 224, 3), dtype=np.uint8)
    boxes = np.array([[0, 20.0, 100.0, 60.0, 14.0, 0.0, 1.0],  # x -10 .. 50
                      [0, 8.0, 160.0, 30.0, 10.0, 0.0, 1.0],  # x -7 .. 23
                      [0, 150.0, 150.0, 40.0, 14.0, 30.0, 1.0]])  # far from the strip
    for seed in range(40):  # find a draw that blanks the left side
        out, kept = blank_margin(img, boxes, np.random.default_rng(seed))
        flat = (out[:, :1] == out[0, 0]).all()
        if flat and not (out[:, -1:] == out[0, -1]).all():
            break
    width = int(np.argmax(~(out == out[0, 0]).all(axis=(0, 2))))  # first column not flat
    assert 0.08 * 224 - 1 <= width <= 0.3 * 224 + 1
    assert np.array_equal(out[:, width + 1:], img[:, width + 1:])
    visible = [(b[1] + b[3] / 2 - width) / b[3] for b in boxes[:2]]
    expect = [b[1] for b, v in zip(boxes[:2], visible) if v >= 0.3] + [150.0]
    assert kept[:, 1].tolist() == expect and kept[:, 3].tolist() == [b[3] for b in boxes if b[1] in expect]
    if 20.0 in expect and width > 20:  # the centre lies under the strip and still teaches a peak
        assert make_targets(kept, 224)[0][0, 25, 5] == 1.0


def test_an_edge_margin_places_a_cut_object_in_the_pictures_frame(monkeypatch):
    """A card's ``edge_margin_px`` pads the picture with flat colour before the network runs; boxes come
    back in the picture's pixels, and one centred in the margin (under half inside) is left out."""
    det = LearnedDetector(DetectConfig(flip_tta=False, axis_tta=False, refine=False, row_context=0.0, big_pass=0.0))
    det.meta = {**det.meta, "edge_margin_px": 32}
    seen = []

    def fake_session_run(names, feeds):
        x = feeds["image"]
        seen.append(x.shape)
        n = x.shape[2] // 4, x.shape[3] // 4
        peaks, reg = np.zeros((1, 3, *n), np.float32), np.zeros((1, 8, *n), np.float32)
        for i, j in ((10, 12), (10, 4)):  # (4, 12) in the padded frame: x 16 + 32 - 32 px; (4, 4) in the margin
            peaks[0, 0, i, j] = 0.9
            reg[0, :, i, j] = [0.5, 0.5, math.log(40 / 4), math.log(12 / 4), 1, 0, 1, 0]
        return [peaks, reg]

    monkeypatch.setattr(det.session, "run", fake_session_run)
    image = GeoImage(np.full((96, 128, 3), 90, np.uint8), Grid(128, 96, det.meta["work_gsd_m"]))
    out = det.detect(image)
    assert seen and seen[0][2:] == (96 + 64, 128 + 64)
    assert len(out) == 1
    assert (out[0].cx_px, out[0].cy_px) == pytest.approx((12 * 4 + 2 - 32, 10 * 4 + 2 - 32))


def test_unlabelled_classes_are_not_taught_as_background():
    """``ships_aerial`` labels boats only: its parked cars must not teach the vehicle heatmap that cars
    are background, so that class's loss is left out for such images."""
    torch = pytest.importorskip("torch")
    from coastforge.train.detector_model import N_CLASSES, N_OUT
    from coastforge.train.train_detector import losses

    out = torch.zeros(1, N_OUT, 8, 8)
    out[:, 1] = 4.0  # the network is sure of a vehicle everywhere
    heat = torch.zeros(1, N_CLASSES, 8, 8)
    reg, m = torch.zeros(1, 8, 8, 8), torch.zeros(1, 8, 8)
    all_lab = torch.ones(1, N_CLASSES, dtype=torch.bool)
    boats_only = torch.tensor([[True, False, False]])
    l_all = float(losses(torch, out, heat, reg, m, m, m, all_lab)[1]["heat"])
    l_boats = float(losses(torch, out, heat, reg, m, m, m, boats_only)[1]["heat"])
    assert l_all > 10 * max(l_boats, 1e-3)


def test_training_targets_decode_back():
    """What training asks the network for at a box decodes to that box (targets and decoder agree),
    also after the rotation used as augmentation."""
    import cv2

    from coastforge.train.train_detector import affine_boxes, make_targets

    box = np.array([[0, 61.3, 70.9, 36.0, 11.0, 57.0]])
    M = cv2.getRotationMatrix2D((80.0, 80.0), 40.0, 1.1)
    moved = affine_boxes(box, M, 1.1, 40.0)
    # the rotated front direction is the image direction of the new yaw
    fx, fy = frames.direction_px(57.0)
    assert frames.yaw_from_direction_px(*(M[:, :2] @ [fx, fy])) == pytest.approx(moved[0, 5], abs=1e-6)
    heat, reg, wmask, amask, smask = make_targets(moved, 160)
    pooled = cv2.dilate(heat.transpose(1, 2, 0), np.ones((3, 3), np.uint8)).transpose(2, 0, 1)
    peaks = np.where(heat >= pooled, heat, 0)
    rows = decode(peaks, reg, 0.99)
    assert len(rows) == 1 and wmask.sum() >= 1 and amask.sum() == wmask.sum() == smask.sum()
    _c, _s, cx, cy, L, W, yaw, _conf = rows[0]
    assert (cx, cy) == pytest.approx(tuple(moved[0, 1:3]), abs=1e-3)
    assert (L, W) == pytest.approx((36.0 * 1.1, 11.0 * 1.1), rel=1e-3)
    assert yaw == pytest.approx(moved[0, 5], abs=1e-3)


def test_missing_and_corrupt_weights(tmp_path):
    with pytest.raises(InputError, match="do not exist"):
        LearnedDetector(DetectConfig(), weights=tmp_path / "nope.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"this is not an onnx model")
    with pytest.raises(InputError, match=r"bad.onnx"):
        LearnedDetector(DetectConfig(), weights=bad)


def test_foreign_onnx_is_refused(tmp_path):
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    g = helper.make_graph([helper.make_node("Identity", ["image"], ["out"])], "g",
                          [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, None, None])],
                          [helper.make_tensor_value_info("out", TensorProto.FLOAT, [1, 3, None, None])])
    p = tmp_path / "other.onnx"
    onnx.save(helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)], ir_version=9), p)
    with pytest.raises(InputError, match="backend onnx"):
        LearnedDetector(DetectConfig(), weights=p)


def test_shipped_model_is_small_and_documented():
    import json

    p = default_weights()
    assert p.is_file() and p.stat().st_size < 5e6
    meta = json.loads(p.with_suffix(".json").read_text())
    assert meta["classes"] == ["boat", "vehicle", "buoy"] and meta["work_gsd_m"] > 0
    assert meta["training"]["steps"] > 0 and min(meta["training"]["seeds"]) >= 100  # never the val seed 0


@pytest.fixture(scope="module")
def tiny_level():
    from coastforge.synth import synthesize_level
    from coastforge.synth.render import mesh_source, render_level

    level = synthesize_level("simple_pier_a", 7, size_m=60)
    rgb = render_level(level, mesh_source(None), 0.2, 7)
    n = rgb.shape[0]
    g = level.scene.extent_m[0] / n
    return GeoImage(rgb=rgb, grid=Grid(n, n, g)), level.scene


def test_shipped_model_finds_boats_on_a_generated_level(tiny_level):
    from coastforge.detection import detect

    img, scene = tiny_level
    dets = detect(img, DetectConfig(), backend="learned")
    boats = [o for o in scene.objects if o.category == "boat"]
    assert boats
    found, axis_err, front_ok = 0, [], 0
    for o in boats:
        col, row = img.grid.to_pixel(o.x_m, o.y_m)
        near = [d for d in dets if d.category == "boat"
                and math.hypot(d.cx_px - col, d.cy_px - row) < 0.5 * o.length_m / img.grid.gsd_m]
        if near:
            d = near[0]
            found += 1
            axis_err.append(abs(float(frames.wrap_half_deg(d.yaw_deg - o.yaw_deg))))
            front_ok += abs(float(frames.wrap_deg(d.yaw_deg - o.yaw_deg))) < 90.0
            assert 0.6 < d.length_px * img.grid.gsd_m / o.length_m < 1.6
    assert found >= 0.75 * len(boats)
    assert np.median(axis_err) < 10.0
    assert front_ok >= 0.7 * found  # bow vs stern is learned
    assert sum(d.category == "boat" for d in dets) <= len(boats) + 2  # few false boats


def test_flip_tta_is_mirror_symmetric(tiny_level):
    """With ``flip_tta`` the network's pass and its mirrored pass are averaged after mapping the mirrored
    maps back, so mirroring the image mirrors every box exactly: a wrong sign or offset in the mapping
    (centre offset ``1 - r``, reflected angles) moves them. One tile (side a multiple of 32) keeps the tiling
    itself symmetric."""
    img, _ = tiny_level
    n = min(img.rgb.shape[:2]) // 32 * 32
    rgb = np.ascontiguousarray(img.rgb[:n, :n])
    det = LearnedDetector(DetectConfig(flip_tta=True))
    a = det.run(rgb, 0.3)
    b = det.run(np.ascontiguousarray(rgb[:, ::-1]), 0.3)
    assert len(a) >= 3 and len(a) == len(b)
    b[:, 2] = n - b[:, 2]  # mirrored back: column, and the yaw reflected about the image's vertical
    b[:, 6] = [frames.wrap_deg(180.0 - y) for y in b[:, 6]]
    a, b = a[np.lexsort((a[:, 3], a[:, 2]))], b[np.lexsort((b[:, 3], b[:, 2]))]
    assert np.allclose(a[:, :6], b[:, :6], atol=1e-3)
    assert np.allclose([frames.wrap_half_deg(d) for d in a[:, 6] - b[:, 6]], 0.0, atol=1e-2)  # axes
    known = a[:, 7] > 0.6  # fronts, where the network has one (a buoy's is a coin toss at 0)
    assert np.allclose([frames.wrap_deg(d) for d in a[known, 6] - b[known, 6]], 0.0, atol=1e-2)
    plain = LearnedDetector(DetectConfig(flip_tta=False)).run(rgb, 0.3)
    assert not np.array_equal(plain[:, 1], a[:, 1][:len(plain)])  # the option does change the scores


def test_bad_gsd_is_refused(tiny_level):
    img, _ = tiny_level
    det = LearnedDetector(DetectConfig())
    with pytest.raises(InputError, match="m/px"):
        det.detect(GeoImage(rgb=img.rgb, grid=Grid(img.grid.width_px, img.grid.height_px, 8.0)), None, 0)


def test_floor_adds_weaker_boxes_after_the_same_confident_ones(tiny_level):
    img, _ = tiny_level
    det = LearnedDetector(DetectConfig())
    strong = det.detect(img, None, 0)
    both = det.detect(img, None, 0, floor=0.05)
    def key(dets):
        return [(d.category, round(d.score, 6), round(d.cx_px, 3), round(d.cy_px, 3), round(d.yaw_deg, 3))
                for d in dets]

    assert key([d for d in both if det.is_confident(d)]) == key(strong)  # the confident boxes are unchanged
    weak = [d for d in both if not det.is_confident(d)]
    assert weak and all(0.05 <= d.score < det.class_threshold[d.category] for d in weak)
    assert key(det.detect(img, None, 0)) == key(strong)  # the floor does not stick


def test_training_starts_exactly_from_an_exported_onnx(tmp_path):
    """``train_detector --init detector.onnx``: the BatchNorms the export folded away are rebuilt so that
    the torch network computes what the ONNX model does, and a model of another shape is refused."""
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    import onnxruntime as ort

    from coastforge.train.detector_model import build_model
    from coastforge.train.train_detector import export_onnx, init_from_onnx

    torch.manual_seed(0)
    src = build_model(8)
    src.train()
    with torch.no_grad():  # non-trivial BatchNorm statistics, so that the folding matters
        for _ in range(3):
            src(torch.rand(2, 3, 64, 64) * 2.0)
    path = export_onnx(src, tmp_path / "detector.onnx")

    class Crops:
        rng = np.random.default_rng(0)

        def sample(self):
            return self.rng.integers(0, 256, (48, 48, 3), dtype=np.uint8), np.zeros((0, 6))

    net = build_model(8)
    assert init_from_onnx(torch, net, path, Crops(), batches=2) < 1e-3
    x = np.random.default_rng(1).integers(0, 256, (1, 3, 64, 64)).astype(np.float32)
    heat, _peaks, reg = ort.InferenceSession(str(path)).run(None, {"image": x})
    net.eval()
    with torch.no_grad():
        y = net(torch.from_numpy(x) / 255.0).numpy()
    np.testing.assert_allclose(1.0 / (1.0 + np.exp(-y[:, :3])), heat, atol=1e-4)
    np.testing.assert_allclose(y[:, 3:], reg, atol=1e-3)
    with pytest.raises(InputError, match="expected"):
        init_from_onnx(torch, build_model(16), path, Crops(), batches=1)


def test_training_samples_levels_from_several_data_folders(tmp_path):
    """``train_detector --data A --data B``: the levels of both folders, in that order, even where both have
    an image of the same name; a folder without an index is a clear error."""
    import json

    import cv2

    from coastforge.train.train_detector import Sampler

    for name, seed in (("A", 1000), ("B", 2000)):
        d = tmp_path / name
        d.mkdir()
        cv2.imwrite(str(d / "lvl.png"), np.full((64, 64, 3), seed // 1000 * 50, np.uint8))
        item = {"image": "lvl.png", "preset": "beach", "seed": seed,
                "boxes": [[0, 32.0, 32.0, 20.0, 8.0, 0.0]]}
        (d / "index.json").write_text(json.dumps({"work_gsd_m": 0.2, "items": [item]}))
    s = Sampler([tmp_path / "A", tmp_path / "B"], 48, np.random.default_rng(0))
    assert [it["seed"] for it in s.items] == [1000, 2000]
    assert sorted(int(v[0, 0, 0]) for v in s.images.values()) == [50, 100]
    crop, boxes = s.sample()
    assert crop.shape == (48, 48, 3) and boxes.shape[1] == 7 and (boxes[:, 6] == 1).all()  # oriented synthetic boxes
    with pytest.raises(InputError, match="no training index"):
        Sampler([tmp_path / "A", tmp_path / "C"], 48, np.random.default_rng(0))


def test_tta_axes_average_the_turned_crops_axes_and_keep_the_front(monkeypatch):
    """``tta_axes``: the network is run on the boat's crop turned by 90, 180 and 270°; each turned pass's box
    is found where the boat's centre lands and its yaw turned back, then averaged (as 2θ, by score) with the
    tile's own pass. Here a stand-in network reads a bright bar's axis from its image moments, so every
    turned pass sees the true axis (30°), while the tile's pass said 162° (12° off, the front at the other
    end)."""
    import cv2

    work = np.zeros((200, 200, 3), np.uint8)
    box = cv2.boxPoints(((90.0, 110.0), (40.0, 10.0), -30.0))  # cv2's angle is clockwise on screen
    cv2.fillConvexPoly(work, box.astype(np.int32), (255, 255, 255))
    det = LearnedDetector(DetectConfig())
    seen = []

    def fake_run(crop, threshold=None):
        m = cv2.moments((crop[:, :, 0] > 128).astype(np.uint8), binaryImage=True)
        cx, cy = m["m10"] / m["m00"], m["m01"] / m["m00"]
        theta = 0.5 * math.degrees(math.atan2(2 * m["mu11"], m["mu20"] - m["mu02"]))  # rows point down
        seen.append(crop.shape[:2])
        far = [1, 0.9, cx + 30, cy, 40.0, 10.0, 0.0, 0.9]  # another class, elsewhere: ignored
        return np.array([[0, 0.9, cx, cy, 40.0, 10.0, -theta, 0.9], far])

    monkeypatch.setattr(det, "run", fake_run)
    from coastforge.types import Detection

    # detections at half the scale, the box centre 7 px off the bar's (it must be followed through the turns)
    boat = Detection("boat", 0.9, 48.0, 53.0, 20.0, 5.0, 162.0, True, 0.9)
    car = Detection("vehicle", 0.9, 20.0, 20.0, 10.0, 4.0, 5.0, True, 0.9)
    out = det.tta_axes(work, [boat, car], 2.0, 2.0)
    assert len(seen) == 3 and seen[0] == (64, 64)  # three turned passes of a 64-px crop, for the boat only
    assert out[1] is car
    # the mean of 2θ over 162° once and 30° three times, equal scores: an axis of 20.5°; the front stays at
    # the end the detector chose (162°), so 200.5° = -159.5°
    mean = np.exp(2j * np.radians(162.0)) + 3 * np.exp(2j * np.radians(30.0))
    assert np.degrees(np.angle(mean)) / 2 == pytest.approx(20.5, abs=0.1)
    assert out[0].yaw_deg == pytest.approx(-159.5, abs=1.0)
    assert (out[0].cx_px, out[0].length_px, out[0].heading_known) == (48.0, 20.0, True)


def test_label_mask_teaches_unlabelled_classes_only_near_labelled_objects():
    from coastforge.train.detector_model import N_CLASSES
    from coastforge.train.train_detector import label_mask

    boats_only = np.array([True, False, False])
    boxes = np.array([[0, 80.0, 80.0, 20.0, 8.0, 0.0, 0.0]])
    m = label_mask(boxes, boats_only, 160)
    assert m.shape == (N_CLASSES, 40, 40)
    assert (m[0] == 1).all()  # boats: everywhere
    assert m[1, 20, 20] == 1 and m[1, 5, 5] == 0  # vehicles: on the boat, not far from it
    assert (label_mask(boxes, np.ones(3, bool), 160) == 1).all()


def test_row_context_raises_a_weak_boat_in_a_gap_of_a_moored_row(monkeypatch):
    """``detect.row_context``: a weak boat peak abreast of confident boats (parallel, side by side) gains score
    per neighbour and is kept; the same weak peak alone, across the row, or at the row's bow end is not.
    The stand-in network returns rows in working pixels (the image is at the working GSD)."""
    thr = LearnedDetector(DetectConfig()).class_threshold["boat"]
    weak = thr - 0.06  # two neighbours (2 x 0.05) lift it over the threshold, none do not
    # three boats 40 x 12 px, bows pointing right (yaw 0), moored side by side 16 px apart, a gap at y = 132
    row = [[0, 0.8, 100.0, y, 40.0, 12.0, 0.0, 0.9] for y in (100.0, 116.0, 148.0)]
    gap = [0, weak, 101.0, 132.0, 38.0, 12.0, 2.0, 0.9]
    alone = [0, weak, 300.0, 300.0, 40.0, 12.0, 0.0, 0.9]
    across = [0, weak, 100.0, 164.0, 40.0, 12.0, 90.0, 0.9]  # abreast but turned 90°: a pier finger's way
    ahead = [0, weak, 150.0, 116.0, 40.0, 12.0, 0.0, 0.9]  # in line with a boat's bow, not beside it
    rows = np.array([*row, gap, alone, across, ahead], np.float64)
    img = GeoImage(rgb=np.zeros((400, 400, 3), np.uint8), grid=Grid(400, 400, 0.2))

    def found(boost):
        det = LearnedDetector(DetectConfig(axis_tta=False, row_context=boost, big_pass=0.0))
        monkeypatch.setattr(det, "run", lambda work, threshold=None, margin=0: rows[rows[:, 1] >= threshold])
        return sorted((round(d.cx_px), round(d.cy_px)) for d in det.detect(img, None, 0))

    assert found(0.0) == [(100, 100), (100, 116), (100, 148)]
    assert found(0.05) == [(100, 100), (100, 116), (100, 148), (101, 132)]


def test_big_vessel_pass_replaces_the_parts_of_a_big_hull_and_leaves_rows_of_boats(monkeypatch):
    """``detect.big_pass``: a 40 m vessel the normal pass sees only a part of is found whole on the image
    shrunk three times and replaces that part; where the shrunk view merges boats moored end to end or
    abreast, or a car park, into one long "boat", the normal pass's boxes stay. The stand-in network
    answers by the size of what it is given (working pixels, 0.2 m)."""
    full = {  # the normal pass, on the 600 x 600 px image
        "part": [0, 0.6, 160.0, 150.0, 50.0, 18.0, 2.0, 0.9],  # a part of the big hull at (150, 150)
        "row": [[0, 0.8, x, 450.0, 60.0, 20.0, 0.0, 0.9] for x in (100.0, 165.0, 230.0)],  # end to end
        "abreast": [[0, 0.8, 450.0, y, 50.0, 16.0, 0.0, 0.9] for y in (370.0, 390.0, 410.0, 430.0)],
        "car": [1, 0.8, 480.0, 120.0, 22.0, 10.0, 90.0, 0.9],
    }
    shrunk = np.array([  # the shrunk pass (x 1/3): each group seen as one long boat
        [0, 0.8, 50.0, 50.0, 200 / 3, 20.0, 0.0, 0.9],
        [0, 0.7, 55.0, 150.0, 200 / 3, 20.0, 0.0, 0.9],
        [0, 0.7, 150.0, 400 / 3, 40.0, 18.0, 90.0, 0.9],
        [0, 0.7, 160.0, 40.0, 40.0, 15.0, 90.0, 0.9],
    ])
    normal = np.array([full["part"], *full["row"], *full["abreast"], full["car"]], np.float64)
    img = GeoImage(rgb=np.zeros((600, 600, 3), np.uint8), grid=Grid(600, 600, 0.2))

    def boats(factor):
        det = LearnedDetector(DetectConfig(axis_tta=False, row_context=0.0, big_pass=factor))

        def run(work, threshold=None, margin=0):
            rows = normal if work.shape[0] == 600 else shrunk
            return rows[rows[:, 1] >= (threshold or 0.0)]

        monkeypatch.setattr(det, "run", run)
        return sorted((round(d.cx_px), round(d.cy_px), round(d.length_px)) for d in det.detect(img, None, 0)
                      if d.category == "boat")

    rest = [(100, 450, 60), (165, 450, 60), (230, 450, 60), (450, 370, 50), (450, 390, 50), (450, 410, 50),
            (450, 430, 50)]
    assert boats(0.0) == sorted([(160, 150, 50), *rest])
    assert boats(3.0) == sorted([(150, 150, 200), *rest])
