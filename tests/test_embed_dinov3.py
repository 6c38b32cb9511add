"""DINOv3 embedder from a tiny, randomly initialised local model (nothing is downloaded)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.errors import BackendUnavailable, InputError, LibraryError

pytest.importorskip("torch")
transformers = pytest.importorskip("transformers")


@pytest.fixture(scope="module")
def tiny_dinov3(tmp_path_factory):
    if not hasattr(transformers, "DINOv3ViTModel"):
        pytest.skip("this transformers has no DINOv3ViTModel")
    cfg = transformers.DINOv3ViTConfig(hidden_size=32, intermediate_size=64, num_hidden_layers=1,
                                       num_attention_heads=2, image_size=32, patch_size=8)
    folder = tmp_path_factory.mktemp("dinov3")
    transformers.DINOv3ViTModel(cfg).save_pretrained(str(folder))
    return folder


def test_embeds_unit_vectors(tiny_dinov3):
    from coastforge.assets.embed_dinov3 import Dinov3Embedder

    emb = Dinov3Embedder(weights=tiny_dinov3)
    rng = np.random.default_rng(0)
    img = np.full((48, 48, 3), (20, 90, 130), np.uint8)
    img[18:30, 8:40] = (230, 60, 40)
    v = emb.embed([img, np.rot90(img).copy(), rng.integers(0, 255, (40, 40, 3), dtype=np.uint8)], [0.1, 0.1, 0.1])
    assert v.shape == (3, emb.dim) == (3, 32 + Dinov3Embedder.SIZE_DIM)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-5)
    assert float(v[0] @ v[1]) > 0.99  # pose normalisation: a rotated crop embeds the same
    assert emb.settings["model_type"] == "dinov3_vit" and emb.settings["hidden_size"] == 32


def test_missing_or_wrong_weights(tmp_path, tiny_dinov3):
    from coastforge.assets.embed_dinov3 import Dinov3Embedder

    with pytest.raises(BackendUnavailable, match="needs --weights"):
        Dinov3Embedder()
    with pytest.raises(BackendUnavailable, match=r"no config.json"):
        Dinov3Embedder(weights=tmp_path)
    (tmp_path / "config.json").write_text(json.dumps({"model_type": "vit"}))
    with pytest.raises(InputError, match="dinov3_vit"):
        Dinov3Embedder(weights=tmp_path)


def test_library_with_dinov3_refuses_default_queries(tiny_dinov3, tmp_path):
    import trimesh

    from coastforge.assets.library import Library, build_library
    from coastforge.config import LibraryConfig

    src = tmp_path / "src"
    src.mkdir()
    for name, ext, col in (("boat", (6, 2, 1), (200, 40, 40)), ("van", (5, 2, 2), (40, 40, 200))):
        m = trimesh.creation.box(extents=ext)
        m.visual.face_colors = np.array([*col, 255], np.uint8)
        (src / f"{name}.ply").write_bytes(m.export(file_type="ply"))
    (src / "m.toml").write_text('[[assets]]\nid = "boat"\ncategory = "boat"\nmesh = "boat.ply"\n'
                                '[[assets]]\nid = "van"\ncategory = "vehicle"\nmesh = "van.ply"\n')
    cfg = LibraryConfig(lightings=1, backgrounds=("water",), embed_scales=(1.0,), view_size_px=48)
    lib = build_library(src / "m.toml", tmp_path / "lib", embedder="dinov3", weights=tiny_dinov3, config=cfg,
                        workers=1)
    img, gsd = lib.view("van", 0, "water")
    loaded = Library.load(tmp_path / "lib")
    assert loaded.embedder_name == "dinov3"
    assert loaded.query(img, gsd, k=1)[0][0] == "van"
    with pytest.raises(LibraryError, match="not 'default'"):
        Library.load(tmp_path / "lib", embedder="default")
    with pytest.raises(LibraryError, match="another embedder"):
        from coastforge.assets.embed import DefaultEmbedder

        loaded.search(DefaultEmbedder().embed([img], [gsd]), 1)
