"""Tiny ONNX models built in the tests (no downloaded weights): the real loading and inference code runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

THREE_NAMES = "{0: 'ship', 1: 'small vehicle', 2: 'plane'}"


def constant_detector(path: str | Path, rows, raw_nc: int | None = None, fixed: tuple[int, int] = (64, 64),
                      names: str = THREE_NAMES) -> Path:
    """An ONNX detector that ignores its image and returns the constant detections ``rows`` (one image's
    rows; with ``raw_nc``, ``rows`` is already the raw (1, 5 + nc, A) output); ``names`` is its class map."""
    import onnx
    from onnx import TensorProto, helper

    out = np.asarray(rows, np.float32) if raw_nc is not None else np.asarray(rows, np.float32)[None]
    h, w = fixed
    inp = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, h, w])
    res = helper.make_tensor_value_info("out", TensorProto.FLOAT, list(out.shape))
    const = helper.make_node("Constant", [], ["c"], value=helper.make_tensor("v", TensorProto.FLOAT, out.shape,
                                                                             out.ravel().tolist()))
    # out = c + 0 * sum(images): keeps the input wired into the graph
    red = helper.make_node("ReduceSum", ["images"], ["s"], keepdims=0)
    zero = helper.make_node("Constant", [], ["z"], value=helper.make_tensor("zv", TensorProto.FLOAT, [], [0.0]))
    mul = helper.make_node("Mul", ["s", "z"], ["sz"])
    add = helper.make_node("Add", ["c", "sz"], ["out"])
    g = helper.make_graph([const, red, zero, mul, add], "tiny", [inp], [res])
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)])
    m.ir_version = 8
    helper.set_model_props(m, {"names": names})
    onnx.save(m, str(path))
    return Path(path)
