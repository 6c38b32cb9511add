"""Default embedder: segmentation on water/ground, rotation invariance, metric size, bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from coastforge.assets.embed import DefaultEmbedder, object_mask
from coastforge.errors import InputError
from coastforge.render import Lighting, render_mesh_view, standard_view_lightings
from coastforge.rng import stage_rng


def _hull(length=6.0, beam=2.2, colour=(210, 60, 40)):
    from shapely.geometry import Polygon

    ring = [(-length / 2, -beam / 2), (length / 4, -beam / 2), (length / 2, 0), (length / 4, beam / 2),
            (-length / 2, beam / 2)]
    m = trimesh.creation.extrude_polygon(Polygon(ring), 1.0)
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def _box(extents, colour):
    m = trimesh.creation.box(extents=extents)
    m.apply_translation([0, 0, extents[2] / 2])
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def _iou(a, b):
    return (a & b).sum() / max((a | b).sum(), 1)


def test_mask_on_water_and_ground_ignores_shadow():
    rng = stage_rng(0, "test-embed")
    yy, xx = np.mgrid[0:80, 0:80]
    truth = (abs(yy - 40) < 10) & (abs(xx - 40) < 22)
    for bg in ((20, 90, 130), (190, 185, 172)):
        img = np.clip(np.array(bg) + rng.normal(0, 4, (80, 80, 3)), 0, 255)
        shadow = (abs(yy - 52) < 10) & (abs(xx - 52) < 22) & ~truth  # darker, bluish copy of the background
        img[shadow] = img[shadow] * np.array([0.5, 0.52, 0.62])
        img[truth] = (240, 240, 235)
        m = object_mask(img.astype(np.uint8))
        assert _iou(m, truth) > 0.9


def test_rendered_mask_matches_the_footprint():
    mesh = _hull()
    for bg in ("water", "ground"):
        img = render_mesh_view(mesh, 0.1, 96, standard_view_lightings()[0], bg)
        m = object_mask(img)
        area_m2 = m.sum() * 0.01
        assert 0.85 * 11.55 < area_m2 < 1.15 * 11.55, (bg, area_m2)  # 4.5 x 2.2 + the bow triangle 1.65 m2


def test_embeddings_are_unit_rotation_invariant_and_discriminative():
    emb = DefaultEmbedder()
    boat, box = _hull(), _box((6.0, 2.2, 1.0), (40, 70, 200))
    light = Lighting(sun_elevation_deg=60)
    imgs = [render_mesh_view(boat, 0.1, 96, light, "water", yaw_deg=y, seed=i) for i, y in enumerate((0, 37, 121, -75))]
    other = render_mesh_view(box, 0.1, 96, light, "water", yaw_deg=37)
    small = render_mesh_view(_hull(3.0, 1.1), 0.1, 96, light, "water", yaw_deg=37)
    v = emb.embed(imgs + [other, small], [0.1] * 6)
    assert v.shape == (6, emb.dim) and v.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-5)
    same = v[:4] @ v[:4].T
    assert same.min() > 0.9
    assert (v[:4] @ v[4]).max() < same[0, 1:].min()  # another colour and shape
    assert (v[:4] @ v[5]).max() < same[0, 1:].min()  # same shape at half the size: metric footprint
    # deterministic, and the same object at another ground resolution stays close
    np.testing.assert_array_equal(emb.embed(imgs[:1], [0.1]), v[:1])
    coarse = render_mesh_view(boat, 0.25, 40, light, "water", yaw_deg=200)
    assert float(emb.embed([coarse], [0.25])[0] @ v[0]) > float(v[4] @ v[0])


def test_bad_input():
    emb = DefaultEmbedder()
    img = np.zeros((32, 32, 3), np.uint8)
    with pytest.raises(InputError, match="one gsd per image"):
        emb.embed([img], [0.1, 0.2])
    with pytest.raises(InputError, match="positive number"):
        emb.embed([img], [0.0])
    with pytest.raises(InputError, match="RGB"):
        emb.embed([np.zeros((8, 8, 5), np.uint8)], [0.1])
    with pytest.raises(InputError, match="at least 4x4"):
        emb.embed([np.zeros((2, 9, 3), np.uint8)], [0.1])
    with pytest.raises(InputError, match="uses no weights"):
        DefaultEmbedder(weights="/some/folder")
    # a crop with no contrast still embeds (fallback mask), to a unit vector
    v = emb.embed([np.full((20, 20, 3), 128, np.uint8)], [0.1])
    assert abs(float(np.linalg.norm(v)) - 1.0) < 1e-5


def test_registry_names_the_embedders():
    from coastforge import registry

    assert registry.load("embed", "default") is DefaultEmbedder
    assert registry.default_name("embed") == "default"
