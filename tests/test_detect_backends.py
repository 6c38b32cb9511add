"""The yolo (ultralytics YOLO-OBB) and onnx detector backends: slicing, class mapping, NMS, plumbing."""

from __future__ import annotations

import importlib.util
import itertools
import os
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import pytest

from coastforge.config import DetectConfig
from coastforge.detection import detect
from coastforge.detection.onnx_backend import OnnxDetector, decode_output
from coastforge.detection.yolo import (YoloDetector, box_from_xywhr, results_to_detections, slice_windows)
from coastforge.errors import BackendUnavailable, InputError
from coastforge.frames import wrap_half_deg
from coastforge.types import GeoImage, Grid
from onnx_models import constant_detector


def _image(w=300, h=200):
    rgb = np.full((h, w, 3), (45, 62, 44), np.uint8)
    return GeoImage(rgb=rgb, grid=Grid(w, h, 0.2))


def test_slice_windows_cover_with_overlap():
    wins = slice_windows(2500, 1000, 1024, 128)
    cols = sorted({w[0] for w in wins})
    assert cols[0] == 0 and wins[-1][2] == 2500 and all(c1 - c0 <= 1024 for c0, _r0, c1, _r1 in wins)
    assert all(b - a <= 1024 - 128 for a, b in itertools.pairwise(cols))
    assert slice_windows(500, 400, 1024, 128) == [(0, 0, 500, 400)]
    with pytest.raises(InputError, match="slice_px"):
        slice_windows(100, 100, 64, 64)


def test_box_from_xywhr_long_side_is_length():
    # ultralytics: side w along image direction (cos r, sin r), rows down
    _cx, _cy, length, width, yaw = box_from_xywhr(10, 20, 40, 10, np.deg2rad(30))
    assert (length, width) == (40, 10) and yaw == pytest.approx(-30.0)  # 30 deg clockwise on screen
    _c, _r, length, width, yaw = box_from_xywhr(10, 20, 10, 40, np.deg2rad(30))
    assert (length, width) == (40, 10) and abs(wrap_half_deg(yaw - 60.0)) < 1e-9


class _Obb:
    def __init__(self, rows):
        a = np.asarray(rows, float).reshape(-1, 7)
        self.xywhr, self.conf, self.cls = a[:, :5], a[:, 5], a[:, 6]

    def __len__(self):
        return len(self.conf)


class _StubModel:
    """Stands in for ultralytics.YOLO: same ``names`` and ``predict(...) -> [Results with .obb]``."""

    names: ClassVar[dict[int, str]] = {0: "plane", 1: "ship", 2: "small vehicle", 3: "harbor"}

    def __init__(self):
        self.calls = []

    def predict(self, tile, imgsz, conf, verbose):
        self.calls.append(tile.shape)
        h, w = tile.shape[:2]
        # the same ship seen whole in every tile that holds its centre (image col 250, row 100)
        rows = [[40, 40, 30, 8, 0.0, 0.9, 0], [w / 2, h / 2, 10, 24, 0.2, 0.2, 2]]
        return [SimpleNamespace(obb=_Obb(rows))]


def test_results_mapping_and_offsets():
    r = SimpleNamespace(obb=_Obb([[10, 10, 30, 8, 0.0, 0.9, 1], [5, 5, 8, 4, 0.0, 0.8, 0],
                                  [20, 30, 6, 14, 0.0, 0.7, 2], [1, 1, 50, 5, 0.0, 0.1, 3]]))
    dets = results_to_detections(r, _StubModel.names, {"ship": "boat", "small vehicle": "vehicle",
                                                        "harbor": "pier_walkway"}, (100, 50), 0.3)
    assert [d.category for d in dets] == ["boat", "vehicle"]  # plane unmapped, harbor below min score
    assert dets[0].cx_px == 110 and dets[0].cy_px == 60
    assert dets[1].length_px == 14 and abs(wrap_half_deg(dets[1].yaw_deg - 90)) < 1e-9


def test_yolo_sliced_with_stub_model_and_nms():
    class Ship(_StubModel):
        def predict(self, tile, imgsz, conf, verbose):
            self.calls.append(tile.shape)
            return [SimpleNamespace(obb=_Obb(self.rows.pop(0)))]

    m = Ship()
    cfg = DetectConfig(slice_px=200, slice_overlap_px=100, min_score=0.3)
    # two windows (cols 0-200, 100-300); the ship at image col 150 is seen in both
    m.rows = [[[150, 100, 40, 10, 0.0, 0.9, 1]], [[50, 100, 40, 10, 0.0, 0.8, 1], [60, 30, 10, 4, 0.0, 0.5, 0]]]
    det = YoloDetector(cfg, model=m)
    out = det.detect(_image(), None, 0)
    assert len(m.calls) == 2 and all(c == (200, 200, 3) for c in m.calls)
    assert len(out) == 1 and out[0].category == "boat" and out[0].score == pytest.approx(0.9)
    assert out[0].cx_px == pytest.approx(150)


def test_yolo_needs_local_weights(tmp_path):
    with pytest.raises(BackendUnavailable, match="--weights"):
        YoloDetector(DetectConfig())
    with pytest.raises(InputError, match=r"nope.pt"):
        YoloDetector(DetectConfig(), weights=tmp_path / "nope.pt")


@pytest.mark.skipif(importlib.util.find_spec("ultralytics") is None or importlib.util.find_spec("torch") is None,
                    reason="ultralytics/torch not installed (pip install 'coastforge[yolo]')")
@pytest.mark.slow
def test_yolo_random_weights_end_to_end(tmp_path, monkeypatch):
    """yolo11n-obb.yaml with random weights (nothing downloaded), saved and loaded through the backend."""
    monkeypatch.setenv("YOLO_OFFLINE", "1")
    monkeypatch.setenv("YOLO_CONFIG_DIR", str(tmp_path / "ycfg"))
    from ultralytics import YOLO

    model = YOLO("yolo11n-obb.yaml")
    pt = tmp_path / "tiny.pt"
    model.save(pt)
    assert pt.is_file()
    names = model.names
    cmap = {str(names[0]): "boat", str(names[1]): "vehicle"}
    dets = detect(_image(160, 96), DetectConfig(min_score=0.0, slice_px=128, slice_overlap_px=32),
                  backend="yolo", weights=pt, names_map=cmap, imgsz=128)
    assert isinstance(dets, list)
    assert all(d.category in ("boat", "vehicle") and d.length_px >= d.width_px for d in dets)
    assert not any(p.name.endswith(".pt") and p != pt for p in tmp_path.rglob("*.pt"))  # nothing fetched


# ------------------------------------------------------------------------------------------- onnx

def _tiny_onnx(path, rows=None, raw_nc=None, fixed=(64, 64)):
    """An ONNX graph that ignores its image and returns constant detections."""
    return constant_detector(path, rows, raw_nc=raw_nc, fixed=fixed)


def test_onnx_rows_letterboxed_and_mapped(tmp_path):
    pytest.importorskip("onnx")
    # a 64x64 model on a 128x96 slice: letterbox scale 0.5 -> boxes double
    p = _tiny_onnx(tmp_path / "rows.onnx", [[10, 20, 16, 4, 0.0, 0.9, 0], [30, 30, 4, 10, 0.0, 0.8, 1],
                                            [5, 5, 4, 4, 0.0, 0.9, 2], [40, 40, 6, 2, 0.0, 0.1, 0]])
    cfg = DetectConfig(slice_px=1024, min_score=0.3)
    dets = OnnxDetector(cfg, weights=p).detect(_image(128, 96), None, 0)
    cats = sorted(d.category for d in dets)
    assert cats == ["boat", "vehicle"]
    boat = next(d for d in dets if d.category == "boat")
    assert (boat.cx_px, boat.cy_px, boat.length_px, boat.width_px) == pytest.approx((20, 40, 32, 8))
    veh = next(d for d in dets if d.category == "vehicle")
    assert veh.length_px == pytest.approx(20) and abs(wrap_half_deg(veh.yaw_deg - 90)) < 1e-6


def test_onnx_ultralytics_raw_layout(tmp_path):
    pytest.importorskip("onnx")
    # (1, 4 + nc + 1, A) with nc = 3: two overlapping anchors for one ship, one weak anchor
    a = np.array([[10, 11, 30], [10, 10, 30], [20, 20, 6], [6, 6, 4],  # cx, cy, w, h
                  [0.9, 0.7, 0.05], [0.0, 0.1, 0.1], [0.0, 0.0, 0.1],  # class scores
                  [0.0, 0.0, 0.0]], np.float32)[None]  # angle
    rows = decode_output(a, 3)
    assert rows.shape == (3, 7) and rows[0, 6] == 0 and rows[0, 5] == pytest.approx(0.9)
    p = _tiny_onnx(tmp_path / "raw.onnx", a, raw_nc=3, fixed=(64, 64))
    dets = OnnxDetector(DetectConfig(min_score=0.3), weights=p).detect(_image(64, 64), None, 0)
    assert len(dets) == 1 and dets[0].category == "boat" and dets[0].score == pytest.approx(0.9)


def test_onnx_errors(tmp_path):
    with pytest.raises(BackendUnavailable, match="--weights"):
        OnnxDetector(DetectConfig())
    with pytest.raises(InputError, match=r"missing.onnx"):
        OnnxDetector(DetectConfig(), weights=tmp_path / "missing.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(InputError, match="cannot load"):
        OnnxDetector(DetectConfig(), weights=bad)
    with pytest.raises(InputError, match="expected"):
        decode_output(np.zeros((2, 3, 4, 5)))
    assert os.environ.get("YOLO_OFFLINE") in (None, "1")
