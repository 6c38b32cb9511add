"""coastforge synth: synthetic ground-truth levels (layouts, truth terrain, files, CLI)."""

from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest
import shapely
from click.testing import CliRunner
from shapely.geometry import Polygon

from coastforge import frames
from coastforge.classes import ASPHALT, ROCKS, SAND, SIDEWALK, WATER
from coastforge.errors import CoastforgeError, InputError, OutputExistsError
from coastforge.scene import dumps, load_scene, save_scene
from coastforge.synth import PRESETS, asset_catalog, parse_gsds, synth_to_dir, synthesize, synthesize_level

SMALL = dict(size_m=80.0, grid_m=0.4)  # fast variants of every level


def _at(scene, a, x, y):
    h, w = a.shape
    col, row = frames.scene_to_pixel(x, y, w, h, scene.gsd_m)
    return a[min(h - 1, max(0, int(math.floor(row)))), min(w - 1, max(0, int(math.floor(col))))]


def _box(o, shrink=0.0) -> Polygon:
    c = frames.box_corners_px(o.x_m, -o.y_m, o.length_m - shrink, o.width_m - shrink, o.yaw_deg)
    return Polygon([(x, -y) for x, y in c])  # box_corners_px works in image rows: flip y back


def check_level(scene) -> None:
    """Every invariant a truth level must hold (used on small and full-size levels)."""
    n = round(scene.extent_m[0] / scene.gsd_m)
    assert scene.classes.shape == (n, n) and scene.classes.dtype == np.uint8
    assert scene.height.shape == (n, n) and scene.height.dtype == np.float32
    water = scene.classes == WATER
    assert water.any() and (~water).any()
    assert (scene.height[water] < 0).all(), "a water pixel is at or above the water level"
    assert (scene.height[~water] > 0).all(), "a land pixel is at or below the water level"
    cat = asset_catalog()
    half = scene.extent_m[0] / 2
    ids = [o.id for o in scene.objects]
    assert len(set(ids)) == len(ids)
    boxes = {}
    for o in scene.objects:
        assert o.source == "synthetic" and o.score == 1.0
        assert -180.0 < o.yaw_deg <= 180.0
        assert o.asset_id in cat and cat[o.asset_id].category == o.category
        assert abs(o.x_m) < half and abs(o.y_m) < half
        d = cat[o.asset_id]
        if o.category != "pier":
            assert o.length_m == pytest.approx(d.length_m * o.scale[0], rel=1e-3)
            assert o.width_m == pytest.approx(d.width_m * o.scale[1], rel=1e-3)
        if o.category in ("boat", "buoy"):
            assert _at(scene, scene.classes, o.x_m, o.y_m) == WATER, f"{o.id} is not on water"
            assert _at(scene, scene.height, o.x_m, o.y_m) < 0
            assert o.z_m == 0.0
        if o.category == "vehicle":
            assert _at(scene, scene.classes, o.x_m, o.y_m) == ASPHALT, f"{o.id} is not on asphalt"
            assert o.z_m == pytest.approx(float(_at(scene, scene.height, o.x_m, o.y_m)), abs=1e-3)
        boxes[o.id] = _box(o, shrink=0.02)
    # no overlaps, except pier segments of one structure that are declared connected
    objs = list(scene.objects)
    polys = np.array([boxes[o.id] for o in objs], dtype=object)
    for i, o in enumerate(objs):
        hits = np.flatnonzero(shapely.intersects(polys, polys[i]))
        for j in hits:
            if j == i:
                continue
            p = objs[j]
            ok = (o.category == p.category == "pier" and o.attrs["structure"] == p.attrs["structure"]
                  and (p.id in o.attrs["connects_to"] or o.id in p.attrs["connects_to"]))
            assert ok, f"{o.id} overlaps {p.id}"
    # piers: symmetric links, one connected structure, anchored on land
    piers = {o.id: o for o in objs if o.category == "pier"}
    structures: dict[str, list] = {}
    for o in piers.values():
        assert o.asset_id in ("pier_walkway", "pier_finger")
        assert o.attrs["role"] == ("walkway" if o.asset_id == "pier_walkway" else "finger")
        for k in o.attrs["connects_to"]:
            assert k in piers and o.id in piers[k].attrs["connects_to"], f"{o.id} -> {k} is not mutual"
        structures.setdefault(o.attrs["structure"], []).append(o)
    for sid, segs in structures.items():
        roots = [s for s in segs if s.attrs["touches_land"]]
        assert len(roots) == 1, sid
        r = roots[0]
        end = (r.x_m - math.cos(math.radians(r.yaw_deg)) * r.length_m / 2,
               r.y_m - math.sin(math.radians(r.yaw_deg)) * r.length_m / 2)
        assert _at(scene, scene.classes, *end) != WATER, f"{sid} does not start on land"
        seen, todo = {r.id}, [r.id]
        while todo:
            for k in piers[todo.pop()].attrs["connects_to"]:
                if k not in seen:
                    seen.add(k)
                    todo.append(k)
        assert seen == {s.id for s in segs}, f"{sid} is not one connected structure"
    veg = scene.vegetation
    assert veg is not None and set(veg.category) <= {"vegetation", "rock"}
    for i in range(len(veg)):
        assert _at(scene, scene.classes, veg.x_m[i], veg.y_m[i]) != WATER


@pytest.mark.parametrize("preset", PRESETS)
def test_small_levels_hold_every_invariant(preset):
    scene = synthesize(preset, 1, **SMALL)
    assert scene.name == f"synth_{preset}" and scene.gsd_m == SMALL["grid_m"]
    assert scene.extent_m == (80.0, 80.0)
    assert len(scene.objects) > 0
    check_level(scene)


@pytest.mark.parametrize("preset,seed", [("marina", 2), ("pier_parking", 3), ("lake_harbor", 4)])
def test_full_size_levels_hold_every_invariant(preset, seed):
    scene = synthesize(preset, seed, grid_m=0.5)
    assert 120 <= scene.extent_m[0] <= 220
    check_level(scene)


def test_marina_is_dense_with_bow_habits():
    scene = synthesize("marina", 5, grid_m=0.5)
    boats = [o for o in scene.objects if o.category == "boat"]
    moored = [o for o in boats if o.attrs.get("state") == "moored"]
    fingers = [o for o in scene.objects if o.attrs.get("role") == "finger"]
    assert len(moored) >= 25 and len(fingers) >= 20
    assert len({o.asset_id for o in boats}) >= 3  # several boat types by slip size
    by_pier: dict[str, list[str]] = {}
    for o in moored:
        if o.attrs.get("bow") in ("in", "out"):
            by_pier.setdefault(o.attrs["structure"], []).append(o.attrs["bow"])
    assert by_pier
    for bows in by_pier.values():  # mostly consistent per pier, with exceptions allowed
        if len(bows) >= 6:
            assert max(bows.count("in"), bows.count("out")) / len(bows) >= 0.6
    # the boats of a finger pier are parallel to its fingers (bow in or out), up to a few degrees
    fyaw = {o.attrs["structure"]: o.yaw_deg for o in fingers}
    for o in moored:
        if o.attrs.get("bow") in ("in", "out"):
            assert abs(frames.wrap_half_deg(o.yaw_deg - fyaw[o.attrs["structure"]])) < 10


def test_cars_parked_in_rows_either_way():
    scene = synthesize("pier_parking", 3, grid_m=0.5)
    cars = [o for o in scene.objects if o.category == "vehicle" and "lot" in o.attrs]
    assert len(cars) >= 10
    noses = {o.attrs["nose"] for o in cars if "nose" in o.attrs}
    assert noses == {"in", "out"}
    # cars in a row share an orientation modulo 180 degrees
    yaws = np.array([o.yaw_deg for o in cars if o.asset_id != "bus"])
    dev = frames.wrap_half_deg(yaws - yaws[0])
    assert np.all(np.abs(dev) < 10)


def test_shore_profiles_follow_the_class_that_meets_the_water():
    from scipy import ndimage

    beach = synthesize("beach", 2, grid_m=0.5)
    marina = synthesize("marina", 2, grid_m=0.5)
    for scene, cls, lo, hi in ((beach, SAND, 0.0, 0.8), (marina, SIDEWALK, 1.5, 99.0)):
        water = scene.classes == WATER
        near = ndimage.binary_dilation(scene.classes == cls, iterations=2) & water
        assert near.sum() > 20
        depth = -scene.height[near]
        assert lo <= float(np.median(depth)) <= hi
    # the beach deepens gradually offshore (Dean profile), not in a step
    water = beach.classes == WATER
    dist = ndimage.distance_transform_edt(water) * beach.gsd_m
    for d0, d1 in ((2, 5), (10, 15), (30, 40)):
        band = water & (dist >= d0) & (dist < d1)
        if band.sum() > 50:
            assert float(np.median(-beach.height[band])) < 0.21 * 0.8 ** 0.48 * d1 ** (2 / 3) + 0.6
    rocky = synthesize("rocky_shore", 2, grid_m=0.5)
    assert (rocky.classes == ROCKS).any()


def test_determinism_and_seed_variety():
    a = synthesize_level("simple_pier_a", 7, **SMALL).scene
    b = synthesize_level("simple_pier_a", 7, **SMALL).scene
    c = synthesize("simple_pier_a", 8, **SMALL)
    assert dumps(a) == dumps(b)
    assert np.array_equal(a.classes, b.classes) and np.array_equal(a.height, b.height)
    assert dumps(a) != dumps(c)
    assert not np.array_equal(a.classes, c.classes)


def test_synth_to_dir_writes_a_round_tripping_truth(tmp_path):
    out = tmp_path / "lvl"
    r = synth_to_dir("lake_harbor", 3, out, gsds=(0.5, 1.0), **SMALL)
    assert r.truth_path == out / "truth.json" and r.gsds == (0.5, 1.0)
    assert json.loads((out / "inputs.json").read_text()) == {
        "images": [{"path": "image_0.50m.png", "gsd_m": 0.5}, {"path": "image_1.00m.png", "gsd_m": 1.0}]}
    from coastforge.fsio import read_png

    for p, g in zip(r.image_paths, r.gsds):
        img = read_png(p)
        assert img.shape == (round(80 / g), round(80 / g), 3)
        assert img.std() > 5  # a real picture, not a flat fill
    truth = load_scene(r.truth_path)
    assert all(o.source == "synthetic" for o in truth.objects)
    assert truth.provenance["preset"] == "lake_harbor"
    check_level(truth)
    again = tmp_path / "again"
    save_scene(truth, again, filename="truth.json")
    assert (again / "truth.json").read_text() == r.truth_path.read_text()
    assert (again / "vegetation.csv").read_text() == (out / "vegetation.csv").read_text()
    # the images of two GSDs show the same level: the coarse one is close to the fine one downsampled
    fine, coarse = read_png(r.image_paths[0]).astype(float), read_png(r.image_paths[1]).astype(float)
    down = fine.reshape(80, 2, 80, 2, 3).mean((1, 3))
    assert np.abs(down - coarse).mean() < 25
    with pytest.raises(OutputExistsError):
        synth_to_dir("lake_harbor", 3, out, gsds=(1.0,), **SMALL)
    synth_to_dir("lake_harbor", 4, out, gsds=(1.0,), overwrite=True, **SMALL)


def test_bad_inputs_raise_clear_errors(tmp_path):
    with pytest.raises(InputError, match="unknown synth preset 'harbour'"):
        synthesize("harbour", 0)
    with pytest.raises(InputError, match="abc"):
        parse_gsds("0.1,abc")
    with pytest.raises(InputError, match="between"):
        parse_gsds("0")
    with pytest.raises(InputError, match="size_m"):
        synthesize("beach", 0, size_m=5)
    if importlib.util.find_spec("coastforge.assets.library") is None:
        with pytest.raises(InputError, match="not available yet"):
            synthesize("beach", 0, library=tmp_path, **SMALL)
    else:  # a folder that is not a library: the library module's own clear error
        with pytest.raises(CoastforgeError, match="library"):
            synthesize("beach", 0, library=tmp_path, **SMALL)


def test_cli(tmp_path):
    from coastforge.cli import cli

    runner = CliRunner()
    res = runner.invoke(cli, ["synth", "--help"])
    assert res.exit_code == 0 and "--preset" in res.output
    out = tmp_path / "cli"
    args = ["synth", "--preset", "rocky_shore", "--seed", "2", "--out", str(out), "--gsd", "1.0"]
    res = runner.invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert (out / "truth.json").is_file() and (out / "image_1.00m.png").is_file()
    res = runner.invoke(cli, ["synth", "--preset", "rocky_shore", "--out", str(out), "--gsd", "1.0"])
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = runner.invoke(cli, ["synth", "--preset", "nope", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "unknown synth preset" in res.output and "Traceback" not in res.output


def test_library_assets_fill_the_layout_roles(monkeypatch, tmp_path):
    import dataclasses

    from coastforge.assets.kit import kit_assets, load_kit_mesh
    from coastforge.assets.library import Library

    class FakeLibrary:  # two boats and a car under new ids (meshes borrowed from the kit)
        def __init__(self):
            base = {a.id: a for a in kit_assets()}
            self.assets = tuple(dataclasses.replace(base[k], id=f"lib_{k}")
                                for k in ("yacht", "runabout", "sedan"))

        def __contains__(self, asset_id):
            return any(a.id == asset_id for a in self.assets)

        def mesh(self, asset_id):
            return load_kit_mesh(asset_id[4:])

    monkeypatch.setattr(Library, "load", classmethod(lambda cls, path, **kw: FakeLibrary()))
    r = synth_to_dir("pier_parking", 3, tmp_path / "lvl", gsds=(1.0,), library=tmp_path, **SMALL)
    truth = load_scene(r.truth_path)
    by_cat: dict[str, set] = {}
    for o in truth.objects:
        by_cat.setdefault(o.category, set()).add(o.asset_id)
    assert by_cat["boat"] <= {"lib_yacht", "lib_runabout"} and by_cat["boat"]
    assert by_cat["vehicle"] == {"lib_sedan"}
    assert by_cat["pier"] <= {"pier_walkway", "pier_finger"}  # roles the library cannot fill keep the kit
    assert truth.provenance["library"] == str(tmp_path)


def test_training_mix_shows_the_rare_types_and_leaves_benchmark_levels_alone():
    """The detector's training data draws buses, box trucks, hatchbacks and small boats often; the
    benchmark's levels (default mix) never get the types they did not have before."""
    from collections import Counter

    from coastforge.synth.layout import TRAINING_MIX

    bench, train = Counter(), Counter()
    for preset, seed in (("marina", 201), ("pier_parking", 202), ("marina", 203), ("lake_harbor", 204)):
        bench.update(o.asset_id for o in synthesize_level(preset, seed, size_m=110).scene.objects)
        level = synthesize_level(preset, seed, size_m=110, mix=TRAINING_MIX)
        train.update(o.asset_id for o in level.scene.objects)
    new = ("hatchback", "box_truck", "rowboat", "center_console")
    assert not any(bench[t] for t in new)
    assert train["hatchback"] >= 3 and train["bus"] + train["box_truck"] >= 1
    assert train["rowboat"] + train["center_console"] + train["dinghy"] + train["kayak"] >= 5


def test_rafted_mix_ties_boats_alongside_end_to_end_and_two_deep():
    """The detector's rafted training data: more boats alongside walkways, closer together, some rafted
    outboard of another; the benchmark's levels draw nothing of it."""
    from collections import Counter

    from coastforge.synth.layout import RAFTED_MIX, TRAINING_MIX

    def count(mix):
        c = Counter()
        for preset, seed in (("marina", 211), ("simple_pier_a", 212), ("pier_parking", 213), ("marina", 214)):
            for o in synthesize_level(preset, seed, size_m=110, mix=mix).scene.objects:
                if o.category == "boat":
                    c[o.attrs.get("bow")] += 1
                    c["rafted"] += bool(o.attrs.get("rafted"))
        return c

    train, rafted = count(TRAINING_MIX), count(RAFTED_MIX)
    assert rafted["alongside"] >= 2 * max(1, train["alongside"])
    assert rafted["rafted"] >= 1 and train["rafted"] == 0


def test_big_mix_adds_big_vessels_and_leaves_the_other_mixes_alone():
    """The detector's big-vessel training data: kit boats scaled to 20-50 m at anchor and alongside walkways
    (the kit's largest boat is 18 m, the real photos' reach 60 m); the training mix draws none."""
    from coastforge.synth.layout import BIG_LENGTH_M, BIG_MIX, TRAINING_MIX

    def boats(mix):
        out = []
        for preset, seed in (("beach", 221), ("simple_pier_a", 222), ("rocky_shore", 223), ("marina", 224)):
            out += [(o.asset_id, round(o.length_m, 3), round(o.x_m, 3), round(o.y_m, 3))
                    for o in synthesize_level(preset, seed, size_m=180, mix=mix).scene.objects if o.category == "boat"]
        return out

    big, train = boats(BIG_MIX), boats(TRAINING_MIX)
    long_ones = [b for b in big if b[1] >= BIG_LENGTH_M[0] - 1e-6]
    assert len(long_ones) >= 2 and max(b[1] for b in long_ones) <= BIG_LENGTH_M[1] + 1e-6
    assert not [b for b in train if b[1] >= BIG_LENGTH_M[0]]
