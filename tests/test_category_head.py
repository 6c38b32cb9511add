"""The category head: the shipped ONNX model gives category posteriors of crops; ``Library.search`` weighs
its category vote by them; the trainer's export loads (a tiny model trained for two steps)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.assets.category_net import CATEGORIES, INPUT_PX, CategoryHead, shipped_head
from coastforge.errors import InputError

from test_embed_category import _library, _query


def test_shipped_head_tells_a_car_from_a_buoy_and_a_tuft():
    """Renders of the starter kit (a sedan on ground, a mooring buoy and a grass tuft on water): the shipped
    head puts each in its category, with probabilities that sum to one."""
    from coastforge.assets.library import default_library
    from coastforge.render import random_lighting, render_mesh_view
    from coastforge.rng import stage_rng

    lib = default_library()
    rng = stage_rng(7, "test-category-head")
    crops, gsds, want = [], [], []
    for aid, bg, gsd in (("sedan", "ground", 0.1), ("buoy", "water", 0.05), ("grass_clump", "ground", 0.05)):
        side = int(max(lib.asset(aid).dims_m[:2]) * 1.5 / gsd) + 4
        light = random_lighting(rng)
        crops.append(render_mesh_view(lib.mesh(aid), gsd, side, light, bg, yaw_deg=30.0, seed=1))
        gsds.append(gsd)
        want.append(lib.asset(aid).category)
    post = shipped_head().posteriors(crops, gsds)
    assert post.shape == (3, len(CATEGORIES)) and np.allclose(post.sum(1), 1.0, atol=1e-5)
    assert [CATEGORIES[i] for i in post.argmax(1)] == want


def test_the_prior_weighs_the_category_vote(monkeypatch):
    """A rock a hair above three boats loses the vote to the boats; a prior sure of rocks gives it back;
    without a prior nothing changes; a prior of the wrong shape is refused."""
    lib = _library(monkeypatch, ["rock", "boat", "boat", "boat"])
    q = _query([0.90, 0.89, 0.885, 0.88])
    assert lib.search(q, k=1)[0][0][0] == "a1"
    sure_rock = np.array([[0.02, 0.98]])  # over the library's categories, sorted: boat, rock
    assert lib.search(q, k=1, prior=sure_rock)[0][0][0] == "a0"
    assert lib.search(q, k=1, prior=np.array([[0.5, 0.5]]))[0][0][0] == "a1"
    with pytest.raises(Exception, match="prior of shape"):
        lib.search(q, k=1, prior=np.ones((1, 3)))


def test_prior_is_off_for_other_embedders(monkeypatch):
    lib = _library(monkeypatch, ["rock", "boat"])
    lib.doc = {"embedder": {"name": "dinov3"}}
    assert lib.category_prior([np.zeros((20, 20, 3), np.uint8)], [0.1]) is None


def test_missing_or_wrong_head_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        CategoryHead(tmp_path / "none.onnx")
    (tmp_path / "h.onnx").write_bytes(b"not onnx")
    (tmp_path / "h.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(InputError, match=r"is not a coastforge.category_head"):
        CategoryHead(tmp_path / "h.onnx")


def test_trained_head_exports_and_loads(tmp_path):
    """Two training steps on random crops, exported to ONNX: the head loads it and its posteriors match
    the torch network's."""
    torch = pytest.importorskip("torch")
    from coastforge.train.category_train import export, train

    rng = np.random.default_rng(0)
    n = 36
    np.savez(tmp_path / "crops.npz", x=rng.integers(0, 255, (n, INPUT_PX, INPUT_PX, 3), dtype=np.uint8),
             g=rng.uniform(0.05, 0.3, n).astype(np.float32), m=rng.uniform(1, 20, n).astype(np.float32),
             y=np.arange(n) % len(CATEGORIES))
    net, info = train(tmp_path, steps=2, batch=8, threads=1)
    path = export(net, tmp_path / "out", info)
    head = CategoryHead(path)
    crops = [rng.integers(0, 255, (s, s, 3), dtype=np.uint8) for s in (12, 48, 90)]
    post = head.posteriors(crops, [0.3, 0.1, 0.05])
    from coastforge.assets.category_net import net_batch, net_image, net_scalars

    with torch.no_grad():
        logits = net(torch.from_numpy(net_batch([net_image(c) for c in crops])),
                     torch.from_numpy(net_scalars([12 * 0.3, 48 * 0.1, 90 * 0.05], [0.3, 0.1, 0.05])))
    assert np.allclose(post, torch.softmax(logits, 1).numpy(), atol=1e-4)
