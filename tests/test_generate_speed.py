"""The rewrites that made `generate` faster give what the code they replaced gave: the library's stored
footprints, the pier probes along a ray, the connectivity metric's quick rejection, the report's render
from a terrain layer rendered ahead, and the smaller windows of the cleaning fill."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.types import ClassMap, Detection, GeoImage, Grid


@pytest.fixture(scope="module")
def car_lib(tmp_path_factory):
    import trimesh

    from coastforge.assets.library import build_library
    from coastforge.config import LibraryConfig

    tmp = tmp_path_factory.mktemp("lib")
    src = tmp / "src"
    src.mkdir()
    body = trimesh.creation.box(extents=(4.4, 1.8, 0.8))
    body.apply_translation([0, 0, 0.4])
    cabin = trimesh.creation.box(extents=(2.0, 1.6, 0.6))
    cabin.apply_translation([-0.4, 0, 1.1])
    car = trimesh.util.concatenate([body, cabin])
    car.visual.face_colors = np.array([200, 40, 40, 255], np.uint8)
    (src / "car.glb").write_bytes(car.export(file_type="glb"))
    (src / "manifest.json").write_text(json.dumps({"assets": [
        {"id": "car", "category": "vehicle", "mesh": "car.glb", "up_axis": "+z", "forward_axis": "+x"}]}))
    cfg = LibraryConfig(view_size_px=96, paint_variants=False, query_view_gsds_m=())
    return build_library(src / "manifest.json", tmp / "lib", config=cfg, workers=1)


def test_library_stores_the_footprint_the_matcher_would_rasterise(car_lib):
    from coastforge.assets.meshes import footprint_mask
    from coastforge.matching import ShapeMatcher, _silhouette

    a = car_lib.asset("car")
    stored = car_lib.silhouette("car")
    n = stored.shape[0]
    assert a.silhouette_path is not None and a.silhouette_path.is_file()
    from_mesh = footprint_mask(car_lib.mesh("car"), n, a.view_gsd_m).astype(np.float32)
    assert stored.dtype == np.float32 and 0.03 < stored.mean() < 0.9 and stored.max() == 1.0
    assert np.abs(stored - from_mesh).mean() < 0.002  # the GLB round trip may move an edge pixel
    # the matcher takes the stored footprint: no mesh (and no trimesh) needed at match time
    car_lib.mesh = lambda aid: (_ for _ in ()).throw(AssertionError("mesh loaded at match time"))
    try:
        view = car_lib.views_on("car", "ground")[0]
        assert np.array_equal(_silhouette(car_lib, "car", n, a.view_gsd_m, view), stored)
        _views, gsd, sil = ShapeMatcher(car_lib)._asset_views("car", "ground")
        assert sil.any() and gsd == a.view_gsd_m
    finally:
        del car_lib.mesh


def test_pier_probe_along_a_ray_matches_one_probe_per_step():
    from coastforge.pier_chains import LandProbe, PierBox

    rng = np.random.default_rng(4)
    ids = np.zeros((200, 240), np.uint8)  # water
    ids[:, 180:] = 3  # land on the right
    ids[rng.integers(0, 200, 40), rng.integers(0, 180, 40)] = 3  # stray land pixels
    grid = Grid(240, 200, 0.2)
    box = PierBox("walkway", -5.0, 1.0, 8.0, 2.0, 10.0, 0.9)
    probe = LandProbe(ClassMap(ids, grid), [box])
    end = box.ends()[1]
    qs = end[None, :] + box.axis[None, :] * (np.arange(1, 120) * 0.25)[:, None]
    many = probe.ends_touch(box, qs, 0.5)
    one = np.array([any(probe.land_within(q, 0.5) for q in (p, p + s, p - s))
                    for p in qs for s in [np.array([-box.axis[1], box.axis[0]]) * box.width_m / 2]])
    assert many.dtype == bool and np.array_equal(many, one) and many.any() and not many.all()


def test_pier_connectivity_quick_rejection_changes_nothing(monkeypatch):
    from coastforge import evaluate
    from coastforge.scene import Scene, SceneObject

    ids = np.zeros((100, 100), np.uint8)
    ids[:, 70:] = 3
    objs = []
    for k, x in enumerate(np.arange(-8.0, 6.0, 2.0)):  # a walkway from open water onto the land
        objs.append(SceneObject(f"w{k}", "pier", "walk", float(x), 0.0, 0.0, 0.0, (1.0, 1.0, 1.0), 2.0, 1.5))
    objs.append(SceneObject("lone", "pier", "walk", -5.0, 6.0, 0.0, 90.0, (1.0, 1.0, 1.0), 2.0, 1.5))
    scene = Scene(name="t", seed=0, gsd_m=0.2, extent_m=(20.0, 20.0), water_level_m=0.0, crs=None, transform=None,
                  height=np.where(ids == 0, -2.0, 1.0).astype(np.float32), classes=ids, objects=tuple(objs))
    fast = evaluate.pier_connectivity(scene)
    monkeypatch.setattr(evaluate, "_box_pixels", lambda *a: None)
    assert evaluate.pier_connectivity(scene) == fast
    assert fast["n_structures"] == 2 and fast["disconnected_ids"] == ["lone"]


def test_render_from_a_terrain_layer_rendered_ahead_is_the_same_picture():
    import trimesh

    from coastforge.render import MeshInstance, render_terrain_layer, render_topdown

    ids = np.zeros((80, 100), np.uint8)
    ids[:, 60:] = 3
    z = np.where(ids == 0, -1.5, 0.8).astype(np.float32)
    box = trimesh.creation.box(extents=(4.0, 1.6, 1.0))
    box.visual.face_colors = np.array([230, 230, 230, 255], np.uint8)
    inst = [MeshInstance(box, -3.0, 1.0, 0.0, 30.0, (1.0, 1.0, 1.0), None)]
    plain = render_topdown(ids, z, (20.0, 16.0), inst, 0.25, seed=5)
    layer = render_terrain_layer(ids, z, (20.0, 16.0), 0.25, seed=5)
    ahead = render_topdown(ids, z, (20.0, 16.0), inst, 0.25, seed=5, terrain=layer)
    assert np.array_equal(plain, ahead)
    # a layer of other settings is not used by mistake
    other = render_terrain_layer(ids, z, (20.0, 16.0), 0.25, seed=6)
    assert np.array_equal(render_topdown(ids, z, (20.0, 16.0), inst, 0.25, seed=5, terrain=other), plain)


def test_cleaning_fill_in_small_windows_comes_from_the_ring():
    from coastforge.segmentation import clean

    rng = np.random.default_rng(2)
    rgb = np.clip(rng.normal(90, 12, (160, 200, 3)), 0, 255).astype(np.uint8)
    rgb[:, 140:] = np.clip(rng.normal(170, 10, (160, 60, 3)), 0, 255).astype(np.uint8)
    ids = np.zeros((160, 200), np.uint8)
    ids[:, 140:] = 3
    grid = Grid(200, 160, 0.25)
    dets = [Detection("boat", 0.9, 60.0, 70.0, 40.0, 14.0, 20.0, True, 0.9),
            Detection("vehicle", 0.9, 170.0, 40.0, 18.0, 8.0, 90.0, True, 0.9)]
    out = clean.clean_image(GeoImage(rgb, grid), dets, ClassMap(ids, grid), seed=1)
    assert out.shape == rgb.shape and not np.array_equal(out, rgb)
    # the fill reads only the ring around each hole: its colour is the ring's, not the boat's
    hole = clean.transient_mask(rgb.shape[:2], dets[:1], ("boat",), 0.6 / 0.25)
    assert abs(float(out[hole].mean()) - 90.0) < 6.0
