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


def test_grey_parts_of_an_object_on_grey_ground_are_not_shadow():
    """A white deck crossed by dark neutral-grey stripes on light grey ground: the stripes look like a
    shadow by colour, but they lie inside the object's outline; the cast shadow beside it stays out."""
    rng = stage_rng(0, "test-embed-stripes")
    yy, xx = np.mgrid[0:64, 0:64]
    truth = (abs(yy - 32) < 8) & (abs(xx - 32) < 20)
    img = np.clip(np.array((190, 188, 184)) + rng.normal(0, 3, (64, 64, 3)), 0, 255)
    shadow = (abs(yy - 40) < 8) & (abs(xx - 40) < 20) & ~truth
    img[shadow] = img[shadow] * np.array([0.55, 0.57, 0.66])
    img[truth] = (246, 246, 243)
    stripes = truth & ((xx - 15) % 8 < 3) & (abs(xx - 32) < 16)  # inside a white rim
    img[stripes] = (118, 117, 115)
    m = object_mask(img.astype(np.uint8))
    assert _iou(m, truth) > 0.9
    assert (m & shadow).sum() < 0.05 * shadow.sum()


def test_integrated_contrast_is_kept_when_pixels_are_averaged():
    """A 0.6 m tuft seen at 0.02 m/px and area-averaged to 0.2 m/px (3 px) has the same integrated contrast;
    a fainter tuft of the same size has a clearly different one."""
    import cv2

    from coastforge.assets.embed import integrated_contrast

    light = standard_view_lightings()[1]
    out = {}
    for name, colour in (("bright", (60, 170, 50)), ("faint", (30, 75, 40))):
        fine = render_mesh_view(_box((0.6, 0.6, 0.05), colour), 0.02, 120, light, "ground", seed=3)
        coarse = cv2.resize(fine, (12, 12), interpolation=cv2.INTER_AREA)
        c_fine = integrated_contrast(fine, object_mask(fine), 0.02)
        c_coarse = integrated_contrast(coarse, object_mask(coarse), 0.2)
        # Lab units x m^2: within 25 % per channel, or 5 % of the strongest channel (L of a green tuft on
        # grey ground is near 0 and shifts a little as pixels mix)
        np.testing.assert_allclose(c_coarse, c_fine, rtol=0.25, atol=0.05 * float(np.abs(c_fine).max()))
        out[name] = c_fine
    diff = np.abs(out["bright"] - out["faint"]).max()
    assert diff > 0.25 * max(np.abs(out["bright"]).max(), np.abs(out["faint"]).max())


def test_size_code_of_a_few_pixels_is_wide():
    """A 3 px object measured 4 px long still shares size code with its 3 px self; at 30 vs 40 px it does not."""
    import math

    from coastforge.assets.embed import SIZE_PX_UNCERTAINTY, rbf

    def code(px, gsd=0.2):
        return rbf(math.log(px * gsd), math.log(0.1), math.log(400.0), 96, SIZE_PX_UNCERTAINTY / px)

    def cos(a, b):
        return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))

    assert cos(code(3), code(4)) > 0.5
    assert cos(code(30), code(40)) < 0.2


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
