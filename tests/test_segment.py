"""Segmentation: classical backend, labels, onnx, gemini (fake client), outputs, cleaning, CLI."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

from coastforge.classes import ASPHALT, GRASS, PALETTE, SAND, TREES, WATER
from coastforge.config import Config, SegmentConfig
from coastforge.errors import BackendUnavailable, InputError, OutputExistsError
from coastforge.fsio import read_png, write_png
from coastforge.types import Detection, GeoImage, Grid

CLASSICAL = SegmentConfig(backend="classical")  # the default is the learned segmenter


def scene_image(seed: int = 0, size: int = 240, gsd: float = 0.5):
    """A tiny coast: blue water on the right (with a white boat), grass top-left, asphalt bottom-left,
    a dark textured tree clump in the grass. Returns the image and its truth ids."""
    rng = np.random.default_rng(seed)
    h = w = size
    truth = np.full((h, w), GRASS, np.uint8)
    yy, xx = np.mgrid[0:h, 0:w]
    shore = w * 0.55 + 6 * np.sin(yy / 17.0)
    truth[xx >= shore] = WATER
    truth[(xx < shore) & (yy > h * 0.6)] = ASPHALT
    tree = ((xx - 40) ** 2 + (yy - 50) ** 2) < 14**2
    truth[tree] = TREES
    rgb = np.zeros((h, w, 3), np.float32)
    base = {WATER: (38, 88, 128), GRASS: (95, 150, 60), ASPHALT: (85, 85, 88), TREES: (30, 62, 28)}
    noise = {WATER: 0.8, GRASS: 5.0, ASPHALT: 2.0, TREES: 16.0}
    for c, col in base.items():
        m = truth == c
        rgb[m] = np.asarray(col, np.float32) + rng.normal(0, noise[c], (m.sum(), 1))
    # a boat (transient object): its terrain is water
    boat = (xx > w * 0.75) & (xx < w * 0.75 + 20) & (yy > 100) & (yy < 108)
    rgb[boat] = (235, 235, 230)
    return GeoImage(rgb=np.clip(rgb, 0, 255).astype(np.uint8), grid=Grid(w, h, gsd)), truth, boat


def iou(a, b):
    return (a & b).sum() / max(1, (a | b).sum())


# ------------------------------------------------------------------------------------------- classical

def test_classical_water_land_and_boat():
    from coastforge.segmentation import segment

    image, truth, boat = scene_image()
    cm = segment(image, CLASSICAL)
    assert cm.ids.shape == truth.shape and cm.ids.dtype == np.uint8
    assert iou(cm.ids == WATER, truth == WATER) > 0.97
    assert (cm.ids[boat] == WATER).mean() > 0.95  # the boat is not land
    assert iou(cm.ids == GRASS, truth == GRASS) > 0.8
    assert iou(cm.ids == ASPHALT, truth == ASPHALT) > 0.8
    assert (cm.ids[truth == TREES] == TREES).mean() > 0.6


def test_classical_is_deterministic_and_handles_land_only():
    from coastforge.segmentation import segment

    image, _t, _b = scene_image(seed=3)
    a = segment(image, Config(seed=5, segment=CLASSICAL)).ids
    b = segment(image, Config(seed=5, segment=CLASSICAL)).ids
    assert np.array_equal(a, b)
    land = GeoImage(rgb=image.rgb[:, :100].copy(), grid=Grid(100, image.grid.height_px, 0.5))
    ids = segment(land, CLASSICAL).ids
    assert (ids == WATER).mean() < 0.02


@pytest.mark.parametrize("rgb", [(20, 60, 120), (0, 90, 160), (45, 62, 44)])
def test_classical_open_water_of_any_usual_colour(rgb):
    """Navy and saturated blues (a* > 0) and olive-green water, with a little noise, are all water."""
    from coastforge.segmentation import segment

    img = np.clip(np.asarray(rgb, np.float32) + np.random.default_rng(1).normal(0, 0.7, (160, 160, 1)), 0, 255)
    cm = segment(GeoImage(rgb=img.astype(np.uint8), grid=Grid(160, 160, 0.5)), CLASSICAL)
    assert (cm.ids == WATER).mean() > 0.99


def test_classical_rejects_options_and_bad_backend():
    from coastforge.errors import ConfigError
    from coastforge.segmentation import segment

    image, _t, _b = scene_image()
    with pytest.raises(InputError, match="takes no options"):
        segment(image, CLASSICAL, weights="x.onnx")
    with pytest.raises(ConfigError, match="valid backends"):
        segment(image, CLASSICAL, backend="nope")


# ---------------------------------------------------------------------------------------------- outputs

def test_write_segmentation_outputs(tmp_path):
    from coastforge.segmentation.outputs import BIOMES, biome_map, weight_maps, write_segmentation
    from coastforge.types import ClassMap

    image, truth, _b = scene_image()
    cm = ClassMap(ids=truth, grid=image.grid)
    res = write_segmentation(tmp_path, cm, image, SegmentConfig())
    assert np.array_equal(read_png(tmp_path / "classes.png"), truth)
    assert read_png(tmp_path / "classes_preview.png").shape == (*truth.shape, 3)
    total = sum(read_png(tmp_path / "weights" / f"{n}.png").astype(int) for n in
                ("water", "asphalt", "sidewalk", "grass", "trees", "dirt", "rocks", "sand"))
    assert (total == 255).all()
    wm = weight_maps(truth, image.grid.gsd_m, 2.0)
    # softened: a pixel at the shoreline carries both water and grass weight
    edge = (truth == GRASS) & np.roll(truth == WATER, -1, axis=1)
    assert (wm[edge][:, WATER] > 0).all() and (wm[edge][:, GRASS] > 0).all()
    legend = json.loads((tmp_path / "biome.json").read_text())
    assert [b["id"] for b in legend["legend"]] == [b[0] for b in BIOMES]
    bm = biome_map(truth, image.grid.gsd_m, shore_m=5.0, shallow_m=10.0)
    names = {b[1]: b[0] for b in BIOMES}
    assert bm[truth == TREES].max() == names["woodland"]
    assert set(np.unique(bm[truth == WATER])) == {names["deep_water"], names["shallow_water"]}
    assert res["class_fractions"]["water"] == pytest.approx((truth == WATER).mean())


# ----------------------------------------------------------------------------------------------- labels

def test_labels_values_and_colours(tmp_path):
    from coastforge.segmentation import segment

    image, truth, _b = scene_image()
    raw = np.choose(truth, [10, 20, 0, 30, 40, 0, 0, 0]).astype(np.uint8)[::2, ::2]  # half resolution
    write_png(tmp_path / "lab.png", raw)
    (tmp_path / "map.json").write_text(json.dumps({"classes": {"10": "water", "20": "asphalt", "30": "grass", "40": 4}}))
    cm = segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "lab.png", mapping=tmp_path / "map.json")
    assert cm.ids.shape == truth.shape
    assert (cm.ids == truth).mean() > 0.97

    col = PALETTE[truth][:, :, ::-1].copy()  # their own colours: BGR-swapped palette
    write_png(tmp_path / "col.png", col)
    table = {f"#{c[0]:02x}{c[1]:02x}{c[2]:02x}": name for c, name in
             zip(PALETTE[:, ::-1], ("water", "asphalt", "sidewalk", "grass", "trees", "dirt", "rocks", "sand"))}
    (tmp_path / "col.toml").write_text("[classes]\n" + "".join(f'"{k}" = "{v}"\n' for k, v in table.items()))
    cm2 = segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "col.png", mapping=tmp_path / "col.toml")
    assert np.array_equal(cm2.ids, truth)


def test_labels_errors(tmp_path):
    from coastforge.segmentation import segment

    image, truth, _b = scene_image()
    write_png(tmp_path / "lab.png", np.choose(truth, [10, 20, 0, 30, 40, 0, 0, 0]).astype(np.uint8))
    (tmp_path / "map.json").write_text(json.dumps({"classes": {"10": "water"}}))
    with pytest.raises(InputError, match=r"20, 30, 40"):
        segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "lab.png", mapping=tmp_path / "map.json")
    (tmp_path / "map2.json").write_text(json.dumps({"classes": {"10": "water"}, "default": "grass"}))
    cm = segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "lab.png", mapping=tmp_path / "map2.json")
    assert set(np.unique(cm.ids)) == {WATER, GRASS}
    (tmp_path / "bad.json").write_text(json.dumps({"classes": {"10": "lava"}}))
    with pytest.raises(InputError, match="lava"):
        segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "lab.png", mapping=tmp_path / "bad.json")
    write_png(tmp_path / "wide.png", np.zeros((10, 40), np.uint8))
    with pytest.raises(InputError, match="aspect"):
        segment(image, SegmentConfig(), backend="labels", labels=tmp_path / "wide.png", mapping=tmp_path / "map2.json")
    with pytest.raises(InputError, match="--labels"):
        segment(image, SegmentConfig(), backend="labels")


# ------------------------------------------------------------------------------------------------- onnx

def _tiny_onnx(path: Path, n_out: int = 3):
    """A 1x1 convolution whose logits are the R, G, B channels (plus zeros): argmax = dominant colour."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    w = np.zeros((n_out, 3, 1, 1), np.float32)
    for i in range(min(3, n_out)):
        w[i, i, 0, 0] = 1.0
    node = helper.make_node("Conv", ["x", "w"], ["y"])
    graph = helper.make_graph([node], "tiny", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 3, 16, 16])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, n_out, 16, 16])],
                              [numpy_helper.from_array(w, "w")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, str(path))


def test_onnx_backend(tmp_path):
    from coastforge.segmentation import segment

    _tiny_onnx(tmp_path / "m.onnx")
    rgb = np.zeros((64, 96, 3), np.uint8)
    rgb[:, :32] = (200, 20, 20)   # red → model class 0
    rgb[:, 32:64] = (20, 200, 20)  # green → 1
    rgb[:, 64:] = (20, 20, 200)   # blue → 2
    image = GeoImage(rgb=rgb, grid=Grid(96, 64, 1.0))
    (tmp_path / "map.json").write_text(json.dumps({"classes": {"0": "sand", "1": "grass", "2": "water"}}))
    cm = segment(image, SegmentConfig(), backend="onnx", weights=tmp_path / "m.onnx", mapping=tmp_path / "map.json")
    assert cm.ids.shape == (64, 96)
    assert (cm.ids[:, 4:28] == SAND).all() and (cm.ids[:, 36:60] == GRASS).all() and (cm.ids[:, 68:92] == WATER).all()
    with pytest.raises(InputError, match="outputs 3 classes"):
        segment(image, SegmentConfig(), backend="onnx", weights=tmp_path / "m.onnx")
    (tmp_path / "part.json").write_text(json.dumps({"classes": {"0": "sand"}}))
    with pytest.raises(InputError, match="1, 2"):
        segment(image, SegmentConfig(), backend="onnx", weights=tmp_path / "m.onnx", mapping=tmp_path / "part.json")
    with pytest.raises(InputError, match="does not exist"):
        segment(image, SegmentConfig(), backend="onnx", weights=tmp_path / "none.onnx")


# ----------------------------------------------------------------------------------------------- gemini

class _Obj:
    def __init__(self, **kw):
        self.__dict__.update(kw)


class FakeGemini:
    """Stands in for google.genai.Client: returns canned images, records the prompts."""

    def __init__(self, images):
        self.images = list(images)
        self.calls = []
        self.models = self

    def generate_content(self, model, contents, config=None):
        self.calls.append((model, contents))
        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.images.pop(0)).save(buf, format="PNG")
        part = _Obj(inline_data=_Obj(data=buf.getvalue(), mime_type="image/png"), text=None)
        return _Obj(candidates=[_Obj(content=_Obj(parts=[_Obj(inline_data=None, text="here you go"), part]))])


def test_gemini_with_fake_client():
    from coastforge.segmentation import segment

    image, truth, _b = scene_image()
    painted = PALETTE[truth].astype(np.int16)
    rng = np.random.default_rng(0)
    painted = np.clip(painted + rng.integers(-12, 13, painted.shape), 0, 255).astype(np.uint8)  # off-palette
    painted = np.asarray(__import__("PIL.Image", fromlist=["Image"]).fromarray(painted).resize((120, 120)))
    client = FakeGemini([image.rgb, painted])
    cm = segment(image, SegmentConfig(), backend="gemini", client=client)
    assert len(client.calls) == 2  # clean, then classes
    assert "Remove" in client.calls[0][1][0] and "#005aa0" in client.calls[1][1][0]
    assert cm.ids.shape == truth.shape
    assert (cm.ids == truth).mean() > 0.95


def test_gemini_errors(monkeypatch):
    from coastforge.segmentation import segment

    image, _t, _b = scene_image()
    monkeypatch.delenv("GEMINI_API_KEY", raising=False)
    monkeypatch.delenv("GOOGLE_API_KEY", raising=False)
    with pytest.raises(BackendUnavailable, match="GEMINI_API_KEY"):
        segment(image, SegmentConfig(), backend="gemini")

    class TextOnly(FakeGemini):
        def generate_content(self, model, contents, config=None):
            return _Obj(candidates=[_Obj(content=_Obj(parts=[_Obj(inline_data=None, text="I cannot")]))])

    with pytest.raises(BackendUnavailable, match=r"no image.*I cannot"):
        segment(image, SegmentConfig(), backend="gemini", client=TextOnly([]))


# ------------------------------------------------------------------------------------------------ clean

def test_clean_removes_boat_with_texture_fill():
    from coastforge.segmentation.clean import clean_image, detection_from_corners
    from coastforge.types import ClassMap

    image, truth, boat = scene_image()
    ys, xs = np.nonzero(boat)
    corners = [[xs.min(), ys.min()], [xs.max() + 1, ys.min()], [xs.max() + 1, ys.max() + 1], [xs.min(), ys.max() + 1]]
    det = detection_from_corners("boat", corners)
    assert det.length_px == pytest.approx(xs.max() + 1 - xs.min()) and det.width_px == pytest.approx(ys.max() + 1 - ys.min())
    out = clean_image(image, [det], ClassMap(ids=truth, grid=image.grid), seed=1)
    water = image.rgb[(truth == WATER) & ~boat].reshape(-1, 3).astype(float)
    filled = out[boat].reshape(-1, 3).astype(float)
    assert np.abs(filled.mean(0) - water.mean(0)).max() < 4
    assert filled.std(0).max() > 0.2  # texture, not a flat patch
    assert np.array_equal(out[~boat & (truth != WATER)], image.rgb[~boat & (truth != WATER)])
    # small objects go through OpenCV inpainting; piers are not transient and stay
    car = Detection("vehicle", 1.0, 60.0, 200.0, 6.0, 3.0, 0.0)
    pier = Detection("pier_walkway", 1.0, 200.0, 60.0, 30.0, 4.0, 90.0)
    img2 = image.rgb.copy()
    img2[198:202, 57:63] = 250
    out2 = clean_image(GeoImage(rgb=img2, grid=image.grid), [car, pier], None, seed=0)
    assert out2[199:201, 58:62].mean() < 150
    assert np.array_equal(out2[50:70, 195:205], img2[50:70, 195:205])


def test_clean_rafted_boats_take_open_water_not_their_shadows_and_piers_stay():
    """Boats moored side by side along a walkway: the ring right around them is shadow (dark) and deck
    (brown); the fill must look like the open water further out, and the walkway must stay."""
    from coastforge.segmentation.clean import clean_image
    from coastforge.types import ClassMap

    rng = np.random.default_rng(3)
    H = W = 240
    gsd = 0.2
    water_rgb = np.array([38.0, 62.0, 50.0])
    img = np.clip(water_rgb + rng.normal(0, 2.0, (H, W, 3)), 0, 255)
    ids = np.full((H, W), WATER, np.uint8)
    img[:, 114:126] = (120, 96, 70)  # the walkway deck (3.4 m), water in the class map (as after the fill)
    boats = []
    for k in range(8):  # two rows of boats, 3.6 m apart, each with a dark shadow band below it
        cy = 40.0 + 22.0 * k
        for cx in (80.0, 160.0):
            boats.append(Detection("boat", 0.9, cx, cy, 60.0, 14.0, 0.0))
            # the hull reaches past the box (boxes are never exact): its tips stay in the image
            img[int(cy) - 7:int(cy) + 7, int(cx) - 36:int(cx) + 36] = 235
            img[int(cy) + 7:int(cy) + 15, int(cx) - 30:int(cx) + 30] = (12, 18, 16)
    img = img.astype(np.uint8)
    walkway = Detection("pier_walkway", 0.9, 120.0, 120.0, 240.0, 12.0, 90.0)
    image = GeoImage(rgb=img, grid=Grid(W, H, gsd))
    out = clean_image(image, boats + [walkway], ClassMap(ids=ids, grid=image.grid), seed=0)
    under = np.zeros((H, W), bool)
    for b in boats:
        under[int(b.cy_px) - 5:int(b.cy_px) + 5, int(b.cx_px) - 28:int(b.cx_px) + 28] = True
    under[:, 108:132] = False
    filled = out[under].reshape(-1, 3).astype(float)
    assert np.abs(filled.mean(0) - water_rgb).max() < 6
    # ripples like the open water's, not specks copied from beside the hulls and shadows
    assert filled.std(0).max() < 3 * 2.0
    assert (np.abs(filled - water_rgb) > 25).any(axis=1).mean() < 0.005
    assert np.array_equal(out[:, 115:125], img[:, 115:125])  # the walkway stays


def test_load_detections(tmp_path):
    from coastforge.segmentation.clean import load_detections

    p = tmp_path / "d.json"
    p.write_text(json.dumps({"gsd_m": 0.2, "image_size": [100, 50],
                             "detections": [{"category": "boat", "corners_px": [[10, 10], [30, 10], [30, 16], [10, 16]]}]}))
    (d,) = load_detections(p, (200, 100))
    assert (d.cx_px, d.cy_px, d.length_px, d.width_px) == pytest.approx((40, 26, 40, 12))
    assert abs(d.yaw_deg) in (0.0, 180.0)
    with pytest.raises(InputError, match="aspect"):
        load_detections(p, (200, 200))
    p.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_detections(p)
    p.write_text(json.dumps({"detections": [{"category": "boat", "corners_px": [[0, 0]]}]}))
    with pytest.raises(InputError, match="4 finite"):
        load_detections(p)


# -------------------------------------------------------------------------------------------------- CLI

def test_cli_segment_and_clean(tmp_path):
    from click.testing import CliRunner

    from coastforge.cli import cli

    image, truth, boat = scene_image()
    write_png(tmp_path / "img.png", image.rgb)
    # the classical backend: this flat toy lawn at 0.5 m/px is one the learned network calls water
    r = CliRunner().invoke(cli, ["segment", str(tmp_path / "img.png"), "--gsd", "0.5", "--backend", "classical",
                                 "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    ids = read_png(tmp_path / "o" / "classes.png")
    assert iou(ids == WATER, truth == WATER) > 0.95
    r = CliRunner().invoke(cli, ["segment", str(tmp_path / "img.png"), "--gsd", "0.5", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--overwrite" in r.output
    r = CliRunner().invoke(cli, ["segment", str(tmp_path / "img.png"), "--out", str(tmp_path / "o2")])
    assert r.exit_code == 2 and "--gsd" in r.output

    ys, xs = np.nonzero(boat)
    dets = {"gsd_m": 0.5, "image_size": [240, 240], "detections": [
        {"category": "boat", "corners_px": [[int(xs.min()), int(ys.min())], [int(xs.max()) + 1, int(ys.min())],
                                            [int(xs.max()) + 1, int(ys.max()) + 1], [int(xs.min()), int(ys.max()) + 1]]}]}
    (tmp_path / "d.json").write_text(json.dumps(dets))
    args = ["clean", str(tmp_path / "img.png"), "--detections", str(tmp_path / "d.json"), "--out",
            str(tmp_path / "clean.png"), "--gsd", "0.5", "--classes", str(tmp_path / "o" / "classes.png")]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    cleaned = read_png(tmp_path / "clean.png")
    assert cleaned[boat].mean() < 140
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 2 and "--overwrite" in r.output


def test_output_dir_refused_without_overwrite(tmp_path):
    from coastforge.segmentation import segment_file

    image, _t, _b = scene_image()
    write_png(tmp_path / "img.png", image.rgb)
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "x").write_text("keep")
    with pytest.raises(OutputExistsError):
        segment_file(tmp_path / "img.png", tmp_path / "o", gsd_m=0.5)
    segment_file(tmp_path / "img.png", tmp_path / "o", gsd_m=0.5, overwrite=True)
    assert (tmp_path / "o" / "x").read_text() == "keep" and (tmp_path / "o" / "classes.png").exists()


# ---------------------------------------------------------------------------------------- real imagery

def test_marina_water_iou_and_miou_floor(shared_data):
    from coastforge.bench.segmentation import MARINA_TRUTH, class_ious, rasterize_polygons
    from coastforge.io import read_image
    from coastforge.segmentation import segment

    img = shared_data / "aerial" / "marina_p0861" / "image.jpg"
    if not img.exists():
        pytest.skip(f"{img} not found")
    spec = json.loads(MARINA_TRUTH.read_text())
    image = read_image(img, gsd_m=spec["gsd_m"])
    cm = segment(image, SegmentConfig())
    res = class_ious(cm.ids, rasterize_polygons(spec, cm.ids.shape))
    assert res["iou"]["water"] >= 0.95
    # the segmentation issue's target, on a real photo (measured 0.611, the same for every root seed;
    # 0.584 before car rows had a class of their own, 0.600 before crowns in pavement were kept)
    assert res["miou"] >= 0.60, res


# ----------------------------------------------------------------------- classical: cars, canopies, edges

def parking_image(seed: int = 0, gsd: float = 0.4):
    """Grey pavement (80 x 80 m at 0.4 m/px) with a row of parked cars (dark blue-grey and white
    rectangles with shadows) on the left and a textured green canopy on the right, under a yellow
    cast like the DOTA marina's. Returns the image, the car-row mask and the canopy mask."""
    rng = np.random.default_rng(seed)
    n = int(round(80 / gsd))
    yy, xx = np.mgrid[0:n, 0:n]
    rgb = np.empty((n, n, 3), np.float32)
    rgb[:] = (112, 112, 96)  # pavement, yellowish cast
    rgb += rng.normal(0, 1.5, (n, n, 1))
    cars = np.zeros((n, n), bool)
    cl, cw = int(4.5 / gsd), int(1.9 / gsd)  # a car: 4.5 x 1.9 m, one every 2.6 m
    for i, y0 in enumerate(range(int(10 / gsd), int(70 / gsd), int(2.6 / gsd))):
        x0 = int(12 / gsd)
        colour = (235, 235, 238) if i % 3 == 0 else (40, 44, 58)
        rgb[y0:y0 + cw, x0:x0 + cl] = colour
        rgb[y0 + cw:y0 + cw + 1, x0:x0 + cl] = (50, 52, 60)  # shadow on the pavement
        cars[y0:y0 + cw + 1, x0:x0 + cl] = True
    canopy = ((xx - int(55 / gsd)) ** 2 + (yy - int(40 / gsd)) ** 2) < int(8 / gsd) ** 2
    leaves = rng.normal(0, 1, canopy.sum())
    rgb[canopy] = np.stack([45 + 22 * leaves, 75 + 30 * leaves, 35 + 14 * leaves], 1)
    return GeoImage(rgb=np.clip(rgb, 0, 255).astype(np.uint8), grid=Grid(n, n, gsd)), cars, canopy


def test_greenness_tells_a_canopy_from_a_row_of_dark_cars():
    from coastforge.segmentation.features import compute_features
    from coastforge.segmentation.land import TREE_MIN_GREEN, greenness, pavement_exg

    image, cars, canopy = parking_image()
    F = compute_features(image.rgb, image.grid.gsd_m)
    water = np.zeros(cars.shape, bool)
    # the pavement's own excess green (the cast) is the reference, not zero
    assert pavement_exg(F, water) > 0.02
    g = greenness(F, water)
    assert np.median(g[canopy]) > 2 * TREE_MIN_GREEN
    assert np.median(g[cars]) < 0.0


def test_classical_car_row_is_pavement_and_canopy_stays_trees():
    from coastforge.segmentation import segment

    image, cars, canopy = parking_image(seed=1)
    ids = segment(image, CLASSICAL).ids
    assert (ids[cars] == TREES).mean() < 0.1  # dark cars are not crowns
    assert (ids[cars] == ASPHALT).mean() > 0.7  # the terrain under parked cars is pavement
    assert (ids[canopy] == TREES).mean() > 0.7


def test_parked_cars_mask_needs_pavement_texture_and_no_green():
    from coastforge.classes import ASPHALT as A
    from coastforge.segmentation.features import compute_features
    from coastforge.segmentation.land import greenness, land_seeds, parked_cars

    image, cars, canopy = parking_image(seed=2)
    F = compute_features(image.rgb, image.grid.gsd_m)
    water = np.zeros(cars.shape, bool)
    g = greenness(F, water)
    seeds = land_seeds(F, water, 0.0, g)
    m = parked_cars(F, g, seeds)
    assert m[cars].mean() > 0.5
    assert m[canopy].mean() < 0.05
    # without pavement the rules are sure of, nothing is a car row
    assert not parked_cars(F, g, np.where(seeds == A, -1, seeds).astype(np.int8)).any()


def test_refine_land_edges_moves_a_shifted_border_back():
    from coastforge.classes import GRASS as G
    from coastforge.segmentation.features import compute_features
    from coastforge.segmentation.land import refine_land_edges

    n, gsd = 120, 0.4
    rng = np.random.default_rng(0)
    rgb = np.empty((n, n, 3), np.float32)
    rgb[:, :60] = (95, 150, 60)  # grass left of column 60
    rgb[:, 60:] = (85, 85, 88)  # asphalt right of it
    rgb += rng.normal(0, 2.0, (n, n, 1))
    F = compute_features(np.clip(rgb, 0, 255).astype(np.uint8), gsd)
    ids = np.full((n, n), ASPHALT, np.uint8)
    ids[:, :63] = G  # the classifier's grass spilled 3 px (1.2 m) over the border
    land = np.ones((n, n), bool)
    out = refine_land_edges(ids, F, land, band_m=2.0)
    assert (out[:, 60:63] == ASPHALT).mean() > 0.9
    assert (out[:, :58] == G).all() and (out[:, 65:] == ASPHALT).all()
    # trees neither give nor take pixels (a crown's single pixels look like anything)
    ids_t = ids.copy()
    ids_t[:, :63] = TREES
    assert np.array_equal(refine_land_edges(ids_t, F, land, band_m=2.0), ids_t)


def test_land_seeds_pale_grass_is_not_asphalt_and_rough_bank_is_rocks():
    """Pale, dry grass (grey enough for the asphalt colour rule) is greener than the image's pavement,
    so it seeds no asphalt; rough grey ground on the bank seeds rocks, the same ground inland does not."""
    from coastforge.classes import ROCKS
    from coastforge.segmentation.features import compute_features
    from coastforge.segmentation.land import greenness, land_seeds

    n, gsd = 150, 0.4
    rng = np.random.default_rng(3)
    rgb = np.empty((n, n, 3), np.float32)
    rgb[:] = (100, 100, 98)  # pavement
    rgb[:, 40:70] = (102, 107, 96)  # pale dry grass: grey enough for the asphalt colour rule
    water = np.zeros((n, n), bool)
    water[:, 130:] = True
    rgb[water] = (40, 80, 110)
    rgb += rng.normal(0, 1.0, (n, n, 1))
    stones = np.zeros((n, n), bool)
    stones[:, 118:130] = True  # a 4.8 m revetment strip at the waterline
    stones[10:40, 80:92] = True  # the same rough grey ground 15 m inland
    rgb[stones] = (70, 69, 67) + rng.normal(0, 12.0, (stones.sum(), 1))  # dark, wet stones
    F = compute_features(np.clip(rgb, 0, 255).astype(np.uint8), gsd)
    g = greenness(F, water)
    seeds = land_seeds(F, water, 15.0, g)
    assert (seeds[5:-5, 45:65] == ASPHALT).mean() < 0.05
    assert (seeds[5:-5, 5:30] == ASPHALT).mean() > 0.9  # the pavement itself still seeds asphalt
    bank = seeds[5:-5, 120:128]
    assert (bank == ROCKS).mean() > 0.5
    inland = seeds[14:36, 82:90]
    assert (inland == ROCKS).mean() < (bank == ROCKS).mean() / 2



def test_cleaning_benchmark_restores_the_surface_under_removed_boats():
    """bench.cleaning on a small synthetic level with the true boxes: the cleaned image is far closer to
    the render without the objects than the input is (the fill is the surface, not a smear)."""
    pytest.importorskip("trimesh")
    from coastforge.bench.cleaning import clean_level

    r = clean_level("simple_pier_a", 1, 0.2, boxes="truth", size_m=80)
    assert r["pixels"] > 500
    assert r["mae"] < 0.5 * r["input_mae"]
    assert r["left"] < 0.5 * r["input_left"]


def test_fold_rows_gives_car_rows_to_pavement_only_where_rocks_would_win():
    from coastforge.classes import ROCKS
    from coastforge.segmentation.land import CAR_ROW, fold_rows

    classes = np.array([ASPHALT, 2, TREES, ROCKS, CAR_ROW])  # 2 = sidewalk
    proba = np.array([
        [0.10, 0.05, 0.05, 0.30, 0.50],  # a car row the terrain classes would call rocks -> asphalt
        [0.05, 0.10, 0.05, 0.30, 0.50],  # ... sidewalk where that is likelier than asphalt
        [0.05, 0.05, 0.30, 0.10, 0.50],  # a dark crown: the row's share is dropped, trees stay
        [0.00, 0.00, 0.00, 0.00, 1.00],  # only the row class explains it: left to its neighbours
    ], np.float32)
    kept, out = fold_rows(classes, proba)
    assert list(kept) == [ASPHALT, 2, TREES, ROCKS]
    assert np.allclose(out[:3].sum(axis=1), 1.0) and not out[3].any()
    assert out[0].argmax() == 0 and out[1].argmax() == 1 and out[2].argmax() == 2
    assert np.allclose(out[2], proba[2, :4] / proba[2, :4].sum())


def test_merge_small_keeps_a_fragmented_crown_in_pavement():
    from coastforge.classes import ROCKS
    from coastforge.segmentation.classical import merge_small

    ids = np.full((60, 60), ASPHALT, np.uint8)
    ids[20:24, 20:30] = TREES  # a crown read as three fragments, each below the minimum region
    ids[24:28, 20:30] = GRASS
    ids[28:30, 20:30] = ROCKS
    ids[24:26, 22:28] = TREES
    out = merge_small(ids, 60, fixed=np.zeros(ids.shape, bool))
    assert (out[20:30, 20:30] == TREES).all()
    # on a lawn the same fragments are noise and join the lawn
    lawn = np.where(ids == ASPHALT, GRASS, ids).astype(np.uint8)
    out = merge_small(lawn, 60, fixed=np.zeros(ids.shape, bool))
    assert (out == GRASS).all()


def test_hazy_asphalt_is_not_sidewalk():
    """Haze lifts a whole image: its asphalt at L* ~66 is above the fixed sidewalk threshold (60), its
    concrete paths at ~86. The paving split follows the image (synthetic marina seed 6 called its car
    park sidewalk)."""
    from coastforge.classes import SIDEWALK
    from coastforge.segmentation import segment
    from coastforge.segmentation.land import _paving_split

    rng = np.random.default_rng(0)
    n, gsd = 300, 0.4
    yy, xx = np.mgrid[0:n, 0:n]
    rgb = np.empty((n, n, 3), np.float32)
    rgb[:] = (150, 190, 110)  # hazy lawn
    car_park = (xx >= 40) & (xx < 200) & (yy >= 40) & (yy < 200)
    paths = ((yy >= 220) & (yy < 232)) | ((xx >= 220) & (xx < 232))
    rgb[car_park] = (160, 163, 168)  # asphalt under haze, L* ~66
    rgb[paths] = (214, 215, 216)  # concrete, L* ~86
    rgb += rng.normal(0, 1.5, (n, n, 1))
    image = GeoImage(rgb=np.clip(rgb, 0, 255).astype(np.uint8), grid=Grid(n, n, gsd))
    ids = segment(image, SegmentConfig(backend="classical")).ids
    assert (ids[car_park] == ASPHALT).mean() > 0.9
    assert (ids[paths] == SIDEWALK).mean() > 0.8
    # one kind of pavement only: the fixed thresholds stand
    L = np.r_[rng.normal(40, 3, 5000), rng.normal(42, 3, 5000)].astype(np.float32)
    zeros = np.zeros_like(L)
    assert _paving_split(L, zeros, zeros, zeros, np.zeros(L.shape, bool)) == (55.0, 60.0)
