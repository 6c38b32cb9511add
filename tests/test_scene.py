from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.errors import SceneFormatError
from coastforge.scene import Scene, SceneObject, Vegetation, dumps, load_scene, save_scene


def make_scene(**kw):
    rng = np.random.default_rng(0)
    h = rng.normal(0, 2, (40, 60)).astype(np.float32)
    c = rng.integers(0, 8, (40, 60)).astype(np.uint8)
    objs = (SceneObject("b1", "boat", "runabout", 1.5, -2.25, 0.0, 179.9, (1.0, 1.0, 1.0), 6.0, 2.2, "synthetic", 1.0),
            SceneObject("p1", "pier", "pier_walkway", -3.0, 4.0, 0.6, -90.0, (1.2, 1.0, 1.0), 12.0, 2.5, "pier", 0.8,
                        {"structure": "s0", "connects_to": ["land"]}))
    veg = Vegetation.from_rows([{"asset_id": "tree_conifer", "category": "vegetation", "x_m": 0.1, "y_m": 0.2,
                                 "z_m": 1.0, "yaw_deg": 33.3, "scale": 1.1}])
    d = dict(name="test \"quoted\"\nname", seed=7, gsd_m=0.5, extent_m=(30.0, 20.0), height=h, classes=c,
             objects=objs, vegetation=veg, provenance={"tool": "coastforge", "timings_s": {"segment": 0.1}},
             crs=None, transform=None)
    d.update(kw)
    return Scene(**d)


def test_round_trip_identical(tmp_path):
    s = make_scene()
    save_scene(s, tmp_path / "a")
    loaded = load_scene(tmp_path / "a")
    save_scene(loaded, tmp_path / "b")
    assert (tmp_path / "a/scene.json").read_bytes() == (tmp_path / "b/scene.json").read_bytes()
    assert (tmp_path / "a/vegetation.csv").read_bytes() == (tmp_path / "b/vegetation.csv").read_bytes()
    assert np.array_equal(loaded.height, s.height) and loaded.height.dtype == np.float32
    assert np.array_equal(loaded.classes, s.classes)
    assert loaded.objects == s.objects and loaded.objects[1].attrs["structure"] == "s0"
    assert loaded.vegetation.rows() == s.vegetation.rows()
    assert loaded.grid.width_px == 60 and loaded.grid.gsd_m == 0.5


def test_georeferenced_round_trip(tmp_path):
    s = make_scene(crs="EPSG:32633", transform=(0.5, 0.0, 500000.0, 0.0, -0.5, 4000000.0))
    save_scene(s, tmp_path)
    import rasterio

    with rasterio.open(tmp_path / "terrain/height.tif") as src:
        assert src.crs.to_epsg() == 32633 and src.transform.c == 500000.0
    assert load_scene(tmp_path / "scene.json").transform == s.transform


def test_unknown_top_level_keys_kept(tmp_path):
    save_scene(make_scene(), tmp_path)
    d = json.loads((tmp_path / "scene.json").read_text())
    d["future_field"] = {"x": 1}
    (tmp_path / "scene.json").write_text(json.dumps(d))
    assert json.loads(dumps(load_scene(tmp_path)))["future_field"] == {"x": 1}


@pytest.mark.parametrize("path,value,msg", [
    (("objects", 0, "yaw_deg"), 200.0, "yaw_deg = 200.0"),
    (("objects", 0, "category"), "submarine", "category = 'submarine'"),
    (("objects", 0, "scale"), [1, 0, 1], "scale"),
    (("objects", 0, "length_m"), -1, "length_m = -1"),
    (("objects", 0, "source"), "magic", "source = 'magic'"),
    (("gsd_m",), 0, "gsd_m = 0"),
    (("format",), "other/2", "format"),
    (("seed",), "x", "seed"),
    (("terrain", "height"), "../../etc/passwd", "inside the scene folder"),
])
def test_validation_names_field_and_value(tmp_path, path, value, msg):
    save_scene(make_scene(), tmp_path)
    d = json.loads((tmp_path / "scene.json").read_text())
    cur = d
    for p in path[:-1]:
        cur = cur[p]
    cur[path[-1]] = value
    (tmp_path / "scene.json").write_text(json.dumps(d))
    with pytest.raises(SceneFormatError, match=msg.replace("[", r"\[").replace("(", r"\(")):
        load_scene(tmp_path)


def test_duplicate_ids_and_bad_json(tmp_path):
    s = make_scene()
    s2 = s.with_objects(s.objects + (s.objects[0],))
    with pytest.raises(SceneFormatError, match="duplicate object id"):
        save_scene(s2, tmp_path)
    (tmp_path / "scene.json").write_text("{not json")
    with pytest.raises(SceneFormatError, match="not valid JSON"):
        load_scene(tmp_path)
    with pytest.raises(SceneFormatError, match="no scene file"):
        load_scene(tmp_path / "nowhere")


def test_nan_is_refused(tmp_path):
    s = make_scene()
    bad = s.with_objects([SceneObject("x", "boat", "a", float("nan"), 0, 0, 0, (1, 1, 1), 1, 1, "manual", 1)])
    with pytest.raises((SceneFormatError, ValueError)):
        save_scene(bad, tmp_path)
    assert not (tmp_path / "scene.json").exists()


def test_inline_vegetation_round_trip(tmp_path):
    s = make_scene(vegetation_ref=None)
    save_scene(s, tmp_path)
    assert isinstance(json.loads((tmp_path / "scene.json").read_text())["vegetation"], list)
    assert load_scene(tmp_path).vegetation.rows() == s.vegetation.rows()


def test_atomic_write_leaves_no_temp_files(tmp_path):
    save_scene(make_scene(), tmp_path)
    leftovers = [p for p in tmp_path.rglob(".*") if p.is_file()]
    assert leftovers == []


def test_outputs_have_normal_permissions(tmp_path):
    import os
    import stat

    save_scene(make_scene(), tmp_path)
    mode = stat.S_IMODE(os.stat(tmp_path / "scene.json").st_mode)
    assert mode & stat.S_IRGRP and mode & stat.S_IROTH  # not 0600 like mkstemp's temporary file


def test_a_synthetic_levels_folder_loads_by_its_truth_json(tmp_path):
    # `coastforge synth` writes truth.json; `evaluate --truth FOLDER` takes the folder
    s = make_scene()
    save_scene(s, tmp_path)
    (tmp_path / "scene.json").rename(tmp_path / "truth.json")
    assert [o.id for o in load_scene(tmp_path).objects] == [o.id for o in s.objects]
