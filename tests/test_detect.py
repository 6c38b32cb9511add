"""Detection: classical backend on a drawn harbour, heading, rotated NMS, JSON, overlay and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.config import DetectConfig
from coastforge.detection import (detect, detections_from_json, detections_to_json, draw_overlay)
from coastforge.detection.heading import resolve_heading, silhouette_sign
from coastforge.detection.nms import polygon_iou, rotated_nms
from coastforge.detection.piers import dominant_angles, line_open
from coastforge.errors import InputError
from coastforge.frames import direction_px, wrap_deg, wrap_half_deg
from coastforge.rng import stage_rng
from coastforge.types import Detection, GeoImage, Grid

GSD = 0.2
WATER = (45, 62, 44)
CLASSICAL = DetectConfig(backend="classical")  # the default is the hybrid detector


def boat_polygon(cx, cy, yaw, length, width):
    """A boat outline in image pixels: square stern, pointed bow toward ``yaw``."""
    f = np.array(direction_px(yaw))
    lft = np.array(direction_px(yaw + 90.0))
    local = [(-0.5, 0.5), (0.2, 0.5), (0.5, 0.0), (0.2, -0.5), (-0.5, -0.5)]
    return np.array([[cx, cy] + u * length * f + v * width * lft for u, v in local])


def draw_scene(seed=0):
    """600x600 px at 0.2 m/px: water with a walkway, fingers, 6 boats; land strip with 3 cars."""
    import cv2

    rng = stage_rng(seed, "test", "detect-scene")
    h = w = 600
    img = np.empty((h, w, 3), np.float32)
    img[:] = WATER
    land_top = 480
    img[land_top:] = (105, 107, 100)  # asphalt
    # walkway from the land up into the water, fingers to the right
    cv2.rectangle(img, (100, 60), (111, land_top), (150, 145, 135), -1)
    for y in (120, 220, 320):
        cv2.rectangle(img, (112, y), (170, y + 4), (150, 145, 135), -1)
    boats = [(145, 170, 0.0), (145, 270, 0.0), (145, 370, 180.0 - 180.0),
             (330, 150, 35.0), (420, 300, -120.0), (300, 400, 100.0)]
    truth = []
    for i, (cx, cy, yaw) in enumerate(boats):
        length, width = 50.0 + 4 * i, 17.0
        if i == 2:
            yaw = 180.0
            cx = 150
        poly = boat_polygon(cx, cy, yaw, length, width)
        cv2.fillPoly(img, [np.round(poly * 16).astype(np.int32)], (235, 235, 230), cv2.LINE_AA, shift=4)
        truth.append((cx, cy, yaw, length))
    cars = [(200, 540, 0.0, (200, 30, 30)), (300, 540, 90.0, (230, 230, 235)), (420, 530, 0.0, (20, 20, 25))]
    for cx, cy, yaw, col in cars:
        f = np.array(direction_px(yaw))
        lft = np.array(direction_px(yaw + 90.0))
        c = np.array([cx, cy])
        pts = np.array([c + f * 11 + lft * 4.5, c - f * 11 + lft * 4.5, c - f * 11 - lft * 4.5, c + f * 11 - lft * 4.5])
        cv2.fillPoly(img, [np.round(pts).astype(np.int32)], col)
    img += rng.normal(0, 1.5, img.shape)
    rgb = np.clip(img, 0, 255).astype(np.uint8)
    return GeoImage(rgb=rgb, grid=Grid(w, h, GSD)), truth, cars


@pytest.fixture(scope="module")
def scene():
    return draw_scene()


@pytest.fixture(scope="module")
def dets(scene):
    image, _t, _c = scene
    return detect(image, CLASSICAL)


def test_classical_finds_boats_with_axis_and_heading(scene, dets):
    _image, truth, _cars = scene
    boats = [d for d in dets if d.category == "boat"]
    found = 0
    for cx, cy, yaw, length in truth:
        near = [d for d in boats if np.hypot(d.cx_px - cx, d.cy_px - cy) < length / 2]
        assert len(near) == 1, f"boat at ({cx}, {cy}) matched {len(near)} detections"
        d = near[0]
        assert abs(wrap_half_deg(d.yaw_deg - yaw)) < 4.0
        assert abs(d.length_px - length) < 0.2 * length
        if d.heading_known:
            found += abs(wrap_deg(d.yaw_deg - yaw)) < 90
    assert found >= 5, "the pointed bow should give the heading of most drawn boats"
    assert len(boats) == len(truth), [(round(d.cx_px), round(d.cy_px)) for d in boats]


def test_classical_finds_walkway_and_cars(scene, dets):
    _image, _truth, cars = scene
    walks = [d for d in dets if d.category == "pier_walkway"]
    assert any(abs(wrap_half_deg(d.yaw_deg - 90.0)) < 3 and d.length_px > 200 for d in walks)
    vehicles = [d for d in dets if d.category == "vehicle"]
    for cx, cy, yaw, _col in cars:
        near = [d for d in vehicles if np.hypot(d.cx_px - cx, d.cy_px - cy) < 8]
        assert near, f"car at ({cx}, {cy}) not found"
        assert abs(wrap_half_deg(near[0].yaw_deg - yaw)) < 8


def test_empty_water_gives_nothing():
    rgb = np.empty((300, 300, 3), np.uint8)
    rgb[:] = WATER
    assert detect(GeoImage(rgb=rgb, grid=Grid(300, 300, 0.2)), DetectConfig()) == []


def test_detect_rejects_bad_input():
    with pytest.raises(InputError, match="uint8"):
        detect(GeoImage(rgb=np.zeros((10, 10, 3), np.float32), grid=Grid(10, 10, 0.2)))


def test_silhouette_sign_points_to_the_taper():
    import cv2

    for yaw in (0.0, 37.0, 90.0, -150.0):
        m = np.zeros((200, 200), np.uint8)
        cv2.fillPoly(m, [np.round(boat_polygon(100, 100, yaw, 80, 26)).astype(np.int32)], 1)
        axis = Detection("boat", 1, 100, 100, 80, 26, wrap_deg(yaw + 180))  # deliberately backwards
        s, conf = silhouette_sign(m.astype(bool), (0, 0), axis)
        assert s == -1 and conf > 0.8
        d = resolve_heading(np.dstack([m * 230] * 3).astype(np.uint8), axis)
        assert d.heading_known and abs(wrap_deg(d.yaw_deg - yaw)) < 1e-6


def test_rectangle_heading_stays_unknown():
    m = np.zeros((100, 100), bool)
    m[40:60, 20:80] = True
    _s, conf = silhouette_sign(m, (0, 0), Detection("boat", 1, 50, 50, 60, 20, 0.0))
    assert conf < 0.62


def test_rotated_nms_and_iou():
    a = Detection("boat", 0.9, 50, 50, 40, 10, 30.0)
    b = Detection("boat", 0.8, 51, 50, 40, 10, 32.0)
    c = Detection("boat", 0.7, 150, 50, 40, 10, 30.0)
    d = Detection("vehicle", 0.95, 50, 50, 40, 10, 30.0)
    assert polygon_iou(a.corners_px(), a.corners_px()) == pytest.approx(1.0)
    assert polygon_iou(a.corners_px(), c.corners_px()) == 0.0
    kept = rotated_nms([b, c, a, d], 0.3)
    assert kept == [d, a, c]
    assert rotated_nms([b, a, d], 0.3, class_aware=False) == [d]
    half = Detection("boat", 0.95, 40, 50, 20, 10, 0.0)
    whole = Detection("boat", 0.9, 50, 50, 40, 10, 0.0)
    assert rotated_nms([half, whole], 0.6, ioa_threshold=0.8) == [half]


def test_line_open_and_dominant_angles():
    import cv2

    m = np.zeros((300, 300), np.uint8)
    end = (260, int(round(260 - 220 * np.tan(np.deg2rad(30)))))
    cv2.line(m, (40, 260), end, 1, 5)
    cv2.rectangle(m, (150, 200), (220, 260), 1, -1)  # a wide blob is not a pier
    assert any(abs(wrap_half_deg(a - 30)) < 3 for a in dominant_angles(m.astype(bool)))
    thin = line_open(m.astype(bool), 30.0, 100, 8)
    assert thin.sum() > 0.5 * 5 * 220 / np.cos(np.deg2rad(30))
    assert not thin[210:250, 160:210].any()
    assert not line_open(m.astype(bool), 120.0, 100, 8).any()


def test_json_round_trip(dets):
    text = detections_to_json(dets, 0.2, (600, 600), {"backend": "classical"})
    doc = json.loads(text)
    assert doc["gsd_m"] == 0.2 and doc["image_size"] == [600, 600]
    first = doc["detections"][0]
    assert set(first) >= {"category", "score", "corners_px", "cx_px", "cy_px", "length_px", "width_px", "yaw_deg",
                          "heading_known", "heading_confidence"}
    back, header = detections_from_json(text)
    assert header["image_size"] == [600, 600]
    assert len(back) == len(dets)
    for a, b in zip(dets, back):
        assert a.category == b.category and abs(a.cx_px - b.cx_px) < 1e-2 and abs(a.yaw_deg - b.yaw_deg) < 1e-2
        np.testing.assert_allclose(a.corners_px(), b.corners_px(), atol=0.05)


@pytest.mark.parametrize("bad,msg", [
    ("[1, 2]", "detections"),
    ('{"detections": [{"category": "whale", "score": 1}]}', "whale"),
    ('{"detections": [{"category": "boat", "score": 1, "cx_px": 1, "cy_px": 1, "length_px": -1, "width_px": 1,'
     ' "yaw_deg": 0}]}', "non-positive"),
    ('{"detections": [{"category": "boat", "score": "x", "cx_px": 1, "cy_px": 1, "length_px": 2, "width_px": 1,'
     ' "yaw_deg": 0}]}', "score"),
    ("not json", "JSON"),
])
def test_json_errors(bad, msg):
    with pytest.raises(InputError, match=msg):
        detections_from_json(bad)


def test_overlay_draws_boxes(scene, dets):
    image, _t, _c = scene
    out = draw_overlay(image.rgb, dets)
    assert out.shape == image.rgb.shape and (out != image.rgb).any()
    assert (image.rgb == draw_scene()[0].rgb).all()  # the input is not modified


def test_cli_detect(tmp_path, scene):
    from click.testing import CliRunner

    from coastforge.cli import cli
    from coastforge.fsio import write_png

    image, _t, _c = scene
    src = tmp_path / "harbour.png"
    write_png(src, image.rgb)
    out = tmp_path / "dets.json"
    ov = tmp_path / "ov.png"
    r = CliRunner().invoke(cli, ["detect", str(src), "--gsd", "0.2", "--out", str(out), "--overlay", str(ov),
                                 "--backend", "classical"])
    assert r.exit_code == 0, r.output
    assert "boat" in r.output and out.is_file() and ov.is_file()
    dets, header = detections_from_json(out)
    assert header["gsd_m"] == 0.2 and sum(d.category == "boat" for d in dets) == 6
    r = CliRunner().invoke(cli, ["detect", str(src), "--gsd", "0.2", "--out", str(out)])
    assert r.exit_code == 2 and "--overwrite" in r.output
    r = CliRunner().invoke(cli, ["detect", str(src), "--out", str(tmp_path / "x.json")])
    assert r.exit_code == 2 and "--gsd" in r.output
    r = CliRunner().invoke(cli, ["detect", str(src), "--gsd", "0.2", "--out", str(tmp_path / "y.json"),
                                 "--backend", "nope"])
    assert r.exit_code == 2 and "nope" in r.output
    r = CliRunner().invoke(cli, ["detect", str(src), "--gsd", "0.2", "--out", str(tmp_path / "z.json"),
                                 "--backend", "onnx", "--weights", str(tmp_path / "missing.onnx")])
    assert r.exit_code == 2 and "missing.onnx" in r.output


@pytest.mark.shared_data
@pytest.mark.slow
def test_real_marina_smoke(shared_data):
    """The real DOTA marina crop: most labelled ships are found (the benchmark prints the full figures)."""
    from coastforge.bench.detection import Score, match, read_dota_yolo
    from coastforge.io import read_image

    d = shared_data / "aerial" / "marina_p0861"
    img = read_image(d / "image.jpg", gsd_m=0.2)
    dets = detect(img, DetectConfig())
    ships = [t for c, t in read_dota_yolo(d / "labels_yolo_obb.txt", 1024, 1024) if c == "ship"]
    s = Score("marina")
    match(ships, [x for x in dets if x.category == "boat"], s)
    assert s.recall >= 0.8 and s.precision >= 0.65 and s.orient_rmse < 8.0


def test_class_map_water_is_used(scene):
    """Classical: with a class map the water comes from it: marking everything land leaves no boats or piers."""
    from coastforge.classes import ASPHALT, WATER as WATER_ID
    from coastforge.types import ClassMap

    image, truth, _cars = scene
    ids = np.full(image.rgb.shape[:2], WATER_ID, np.uint8)
    ids[480:] = ASPHALT
    with_map = detect(image, CLASSICAL, class_map=ClassMap(ids=ids, grid=image.grid))
    assert sum(d.category == "boat" for d in with_map) == len(truth)
    land = ClassMap(ids=np.full_like(ids, ASPHALT), grid=image.grid)
    assert not any(d.category in ("boat", "pier_walkway") for d in detect(image, CLASSICAL, class_map=land))
    with pytest.raises(InputError, match="class map shape"):
        detect(image, CLASSICAL, class_map=ClassMap(ids=ids[:10], grid=image.grid))


def test_detection_bench_reports_images_a_backend_cannot_run_as_na(tmp_path, capsys):
    """The learned detector refuses 8 m/px satellite images: the bench prints a n/a row and goes on."""
    import json

    from coastforge.bench.detection import bench_real, print_scores
    from coastforge.fsio import write_png

    s2 = tmp_path / "sen2ships"
    for city in ("a", "b"):
        (s2 / city).mkdir(parents=True)
        rgb = np.full((64, 64, 3), (20, 60, 90), np.uint8)
        rgb[30:32, 20:26] = 230  # a ship
        write_png(s2 / city / "image.png", rgb)
        (s2 / city / "labels.txt").write_text("20 30 26 30 26 32 20 32 ship 0\n")
    entries = [{"city": c, "image": f"{c}/image.png", "ground_gsd_m": 8.0, "obb_dota": f"{c}/labels.txt"}
               for c in ("a", "b")]
    (s2 / "MANIFEST.json").write_text(json.dumps(entries))
    rows = bench_real(tmp_path, "learned", DetectConfig(), None)
    assert [r.name for r in rows] == ["sen2ships a", "sen2ships b"]
    assert all(r.na and "m/px" in r.na for r in rows)
    print_scores(rows)
    out = capsys.readouterr().out
    assert out.count("n/a (") == 2
    rows = bench_real(tmp_path, "classical", DetectConfig(), None)
    assert [r.na for r in rows] == [None, None] and rows[0].n_truth == 1
