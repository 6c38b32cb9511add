"""The onnx terrain backend, with tiny models built with the onnx helper API and run by onnxruntime."""

from __future__ import annotations

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

from coastforge.bench.terrain import synthetic_class_map  # noqa: E402
from coastforge.classes import WATER  # noqa: E402
from coastforge.config import TerrainConfig  # noqa: E402
from coastforge.errors import BackendUnavailable, InputError  # noqa: E402
from coastforge.terrain import estimate_terrain  # noqa: E402
from coastforge.types import ClassMap, GeoImage, Grid  # noqa: E402

PER_CLASS = np.array([-3.0, 1.2, 1.1, 2.0, 2.5, 1.8, 1.5, 0.6], np.float32)


def _conv_model(path, channels: int, weights: np.ndarray, hw=("H", "W"), name="x"):
    """A 1x1 convolution: height = sum_c weights[c] * input[c]."""
    w = numpy_helper.from_array(weights.reshape(1, channels, 1, 1).astype(np.float32), "w")
    node = helper.make_node("Conv", [name, "w"], ["z"], kernel_shape=[1, 1])
    graph = helper.make_graph(
        [node], "terrain",
        [helper.make_tensor_value_info(name, TensorProto.FLOAT, [1, channels, *hw])],
        [helper.make_tensor_value_info("z", TensorProto.FLOAT, [1, 1, *hw])], [w])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def _cm(n=48, m=64):
    ids = synthetic_class_map("mixed", 64, 1.0)[:n, :m].copy()
    return ClassMap(ids, Grid(m, n, 1.0))


def test_one_hot_class_model(tmp_path):
    path = _conv_model(tmp_path / "m.onnx", 8, PER_CLASS)
    cm = _cm()
    res = estimate_terrain(cm, TerrainConfig(), backend="onnx", backend_opts={"weights": str(path)})
    assert res.diagnostics.backend == "onnx"
    assert np.allclose(res.height.z_m, PER_CLASS[cm.ids], atol=1e-5)


def test_fixed_size_model_runs_tiled(tmp_path):
    path = _conv_model(tmp_path / "m.onnx", 8, PER_CLASS, hw=(16, 16))
    cm = _cm(45, 61)
    res = estimate_terrain(cm, TerrainConfig(), backend="onnx", backend_opts={"weights": str(path)})
    assert np.allclose(res.height.z_m, PER_CLASS[cm.ids], atol=1e-5)


def test_rgb_model_and_class_consistency(tmp_path):
    # height = 4 * blue - 2: positive on some water pixels, so the class map must pull them under water
    path = _conv_model(tmp_path / "rgb.onnx", 3, np.array([0.0, 0.0, 4.0], np.float32))
    cm = _cm()
    rgb = np.zeros((48, 64, 3), np.uint8)
    rgb[..., 2] = np.linspace(0, 255, 64).astype(np.uint8)[None]
    img = GeoImage(rgb, cm.grid)
    res = estimate_terrain(cm, TerrainConfig(), image=img, backend="onnx",
                           backend_opts={"weights": str(path)})
    z = res.height.z_m
    water = cm.ids == WATER
    assert (z[water] < 0).all() and (z[~water] > 0).all()
    raw = estimate_terrain(cm, TerrainConfig(), image=img, backend="onnx",
                           backend_opts={"weights": str(path), "enforce_classes": False}).height.z_m
    assert np.allclose(raw, 4.0 * rgb[..., 2] / 255.0, atol=1e-5)
    with pytest.raises(BackendUnavailable, match="RGB"):
        estimate_terrain(cm, TerrainConfig(), backend="onnx", backend_opts={"weights": str(path)})


def test_bad_weights(tmp_path):
    cm = _cm()
    with pytest.raises(InputError, match="--weights"):
        estimate_terrain(cm, TerrainConfig(), backend="onnx")
    with pytest.raises(InputError, match="does not exist"):
        estimate_terrain(cm, TerrainConfig(), backend="onnx",
                         backend_opts={"weights": str(tmp_path / "no.onnx")})
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(InputError, match="not a loadable ONNX model"):
        estimate_terrain(cm, TerrainConfig(), backend="onnx", backend_opts={"weights": str(junk)})
    bad = _conv_model(tmp_path / "c5.onnx", 5, np.ones(5, np.float32))
    with pytest.raises(InputError, match="channels"):
        estimate_terrain(cm, TerrainConfig(), backend="onnx", backend_opts={"weights": str(bad)})
