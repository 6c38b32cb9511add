"""Issue 27: exports that simulators use fully. One label table per scene (instances.json) carried into every
engine, HoloOcean sensor rates and floating props, USD materials, pier decks and scores, and the Unreal
script's robustness (Interchange imports, landscape heights read back).

Conventions under test, with where they were looked up (see also ``coastforge/export/labels.py``):
- HoloOcean labels and stencil values: Tagger.cpp ``ATagger::GetLabelByFolderName`` / ``TagActor`` and
  ObjectLabel.h of the HoloOcean engine; the table in byu-holoocean/holoocean-docs
  ``develop/_sources/develop/env-docs/custom-semantics.rst.txt``.
- ``Float`` tag, ``WaterSurface`` / ``WaterPPV``: byu-holoocean/holoocean-docs
  ``develop/_sources/develop/env-docs/create-env.rst.txt``.
- Scenario loading (``load_like_holoocean`` below): ``holoocean.make`` (client/src/holoocean/holoocean.py) and
  ``HoloOceanEnvironment._load_scenario`` (client/src/holoocean/environments.py) of the HoloOcean client
  (read in github.com/wellscrosby/MRGHoloOcean and github.com/Wrm2002/HoloOcean_code, same code).
"""

from __future__ import annotations

import json
import math
import re
from typing import ClassVar
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from coastforge.config import Config, ExportConfig, MatchConfig, PierConfig
from coastforge.errors import InputError
from coastforge.export import export_scene, export_summary, unique_names
from coastforge.export.glb import read_glb
from coastforge.export.gltf import from_gltf, yaw_from_quaternion
from coastforge.export.labels import HOLOOCEAN_LABELS, instances_table
from coastforge.scene import Scene, SceneObject, load_scene

ALL = ("ue5", "holoocean", "gltf", "usd", "sdf")

# the label table of HoloOcean's docs (custom-semantics.rst.txt), the stencil values coastforge relies on
DOCS_STENCILS = {"GroundGrass": 5, "GroundRock": 6, "Ground": 7, "WaterPlane": 9, "Boat": 10, "Yacht": 11,
                 "Rock": 17, "Seaweed": 18, "Pier": 22, "Buoy": 23, "Grass": 25, "Asphalt": 26, "Bus": 30,
                 "Bush": 31, "Car": 32, "SemiTruck": 46, "Sidewalk": 47, "Tree": 52, "Unlabeled": 54}


# ---------------------------------------------------------------- the label table


def test_holoocean_label_list_is_the_taggers():
    assert len(HOLOOCEAN_LABELS) == 54 and "Landscape" in HOLOOCEAN_LABELS
    for name, stencil in DOCS_STENCILS.items():
        assert HOLOOCEAN_LABELS[name] == stencil, name


def _scene(objects, classes=None) -> Scene:
    h, w = 40, 40
    cls = np.zeros((h, w), np.uint8) if classes is None else classes
    cls[:, 30:] = 1  # a quay (asphalt) in the east
    height = np.where(cls == 0, -3.0, 1.2).astype(np.float32)
    return Scene(name="t", seed=0, gsd_m=1.0, extent_m=(40.0, 40.0), height=height, classes=cls, objects=objects)


def _obj(oid, cat, asset, x=-5.0, y=0.0, z=0.0, **attrs):
    return SceneObject(oid, cat, asset, x, y, z, 0.0, (1.0, 1.0, 1.0), 5.0, 2.0, "detection", 0.9, attrs)


def test_instances_table_labels_ids_and_floating():
    objs = (_obj("b", "boat", "runabout"), _obj("bus", "vehicle", "bus", x=15, z=1.2),
            _obj("truck", "vehicle", "box_truck", x=15, z=1.2), _obj("pick", "vehicle", "pickup", x=15, z=1.2),
            _obj("buoy", "buoy", "buoy_channel"), _obj("ashore", "boat", "dinghy", x=15, z=1.4, ashore=True),
            _obj("p", "pier", "pier_walkway", z=0.6))
    t = instances_table(_scene(objs))
    assert t["format"] == "coastforge.instances/1"
    rows = {r["id"]: r for r in t["objects"]}
    assert [r["instance_id"] for r in t["objects"]] == list(range(1, len(objs) + 1))  # 1..N, scene order
    assert {k: r["holoocean"] for k, r in rows.items()} == {
        "b": "Boat", "bus": "Bus", "truck": "SemiTruck", "pick": "Car", "buoy": "Buoy", "ashore": "Boat", "p": "Pier"}
    assert {k for k, r in rows.items() if r["floating"]} == {"b", "buoy"}
    for r in t["objects"]:
        assert r["holoocean_id"] == HOLOOCEAN_LABELS[r["holoocean"]]
    classes = {(c["kind"], c["name"]): c for c in t["classes"]}
    assert len({c["id"] for c in t["classes"]}) == len(t["classes"])  # ids are unique
    assert classes[("terrain", "water")]["holoocean"] == "WaterPlane" and classes[("terrain", "water")]["id"] == 0
    assert classes[("terrain", "rocks")]["holoocean"] == "GroundRock"
    assert classes[("terrain", "sand")]["holoocean"] == "Ground"  # HoloOcean has no sand label
    assert all(c["holoocean"] in HOLOOCEAN_LABELS for c in t["classes"])
    from coastforge.export.ue5 import LAYER_NAMES

    assert [c["ue_layer"] for c in t["classes"] if c["kind"] == "terrain"] == list(LAYER_NAMES)


# ---------------------------------------------------------------- generate -> every engine


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """``generate --export ue5,holoocean,gltf,usd,sdf`` (the default pipeline) on 100 m of a synthetic
    harbour with boats, a buoy, parked cars and piers, all of which it finds."""
    from coastforge.pipeline import GenerateRequest, run_generate
    from coastforge.synth import synth_to_dir

    d = tmp_path_factory.mktemp("level")
    synth_to_dir("pier_parking", 1, d, gsds=(0.25,), size_m=100, overwrite=True)
    out = tmp_path_factory.mktemp("gen")
    res = run_generate(GenerateRequest(image=str(d / "image_0.25m.png"), out=str(out), gsd_m=0.25, report=False,
                                       overwrite=True, exports=ALL), Config())
    return out, res


def _table(out: Path) -> dict:
    return json.loads((out / "instances.json").read_text())


def test_generate_writes_one_label_table(generated):
    out, _res = generated
    scene = load_scene(out)
    t = _table(out)
    assert [r["id"] for r in t["objects"]] == [o.id for o in scene.objects]
    assert t == instances_table(scene)  # generate's table and the export's are the same table
    cats = {o.category for o in scene.objects}
    assert {"boat", "pier", "vehicle", "buoy"} <= cats


def test_every_engine_carries_the_same_label_and_id(generated):
    """instances.json, level.json (first tag), glTF extras, USD semantics and the SDF label plugins agree for
    every object, and the positions and yaws agree to 1e-5 between them."""
    from pxr import Usd, UsdGeom, UsdSemantics

    out, _ = generated
    scene = load_scene(out)
    rows = {r["id"]: r for r in _table(out)["objects"]}
    objs = {o.id: o for o in scene.objects}

    # UE / HoloOcean: the label first, Float on floating objects, float folders for them
    spec = json.loads((out / "ue5" / "level.json").read_text())
    actors = {a["id"]: a for a in spec["actors"] if not a["id"].startswith("veg_")}
    assert set(actors) == set(rows)
    for oid, a in actors.items():
        r = rows[oid]
        assert a["tags"][0] == r["holoocean"] and a["instance_id"] == r["instance_id"]
        assert ("Float" in a["tags"]) == r["floating"] and a["tags"].index(spec["run_tag"]) >= 1
        assert a["folder"].startswith("float/") == r["floating"]
        assert f"coastforge:instance={r['instance_id']}" in a["tags"]
        o = objs[oid]
        assert np.allclose(a["location"], [o.x_m * 100, -o.y_m * 100, o.z_m * 100], atol=1e-3)  # 1e-5 m
        assert a["rotation"]["yaw"] == pytest.approx(-o.yaw_deg, abs=1e-5)
    assert any(r["floating"] for r in rows.values())
    buoys = [a for a in actors.values() if a["category"] == "buoy"]
    assert buoys and all(a["folder"] in ("float/small_float", "float/big_float") for a in buoys)
    veg = [a for a in spec["actors"] if a["id"].startswith("veg_")]
    kinds = {"tree": "Tree", "bush": "Bush", "grass": "Grass", "rock": "Rock", "seaweed": "Seaweed"}
    for a in veg:  # per-type folders (the vegetation table says 'vegetation': the asset tells the kind)
        kind = next(k for k in kinds if k in a["asset_id"])
        assert a["folder"] == a["tags"][0] == kinds[kind]
    assert {a["folder"] for a in veg} >= {"Tree", "Grass", "Bush"}

    # glTF: node extras
    (glb,) = (out / "gltf").glob("*.glb")
    doc, _ = read_glb(glb.read_bytes())
    nodes = {n["name"]: n for n in doc["nodes"] if n.get("extras", {}).get("id")}
    assert set(nodes) == set(rows)
    for oid, n in nodes.items():
        r, o = rows[oid], objs[oid]
        ex = n["extras"]
        assert (ex["label"], ex["instance_id"], ex["label_id"], ex["class"]) == (
            r["holoocean"], r["instance_id"], r["holoocean_id"], r["class"])
        assert from_gltf(np.array(n["translation"])) == pytest.approx([o.x_m, o.y_m, o.z_m], abs=1e-5)
        assert yaw_from_quaternion(n["rotation"]) == pytest.approx(o.yaw_deg, abs=1e-4)

    # USD: UsdSemantics LabelsAPI (class + instance taxonomies) and Isaac's legacy Semantics attributes
    (usdc,) = (out / "usd").glob("*.usdc")
    stage = Usd.Stage.Open(str(usdc))
    prims = {p.GetCustomDataByKey("coastforge:id"): p for p in stage.GetPrimAtPath("/World/Objects").GetChildren()}
    assert set(prims) == set(rows)
    cache = UsdGeom.XformCache()
    for oid, p in prims.items():
        r, o = rows[oid], objs[oid]
        assert list(UsdSemantics.LabelsAPI(p, "class").GetLabelsAttr().Get()) == [r["holoocean"]]
        assert list(UsdSemantics.LabelsAPI(p, "coastforge_instance").GetLabelsAttr().Get()) == [str(r["instance_id"])]
        # authored in apiSchemas (GetAppliedSchemas lists registered schemas only; usd-core lacks Isaac's)
        assert "SemanticsAPI:Semantics" in p.GetMetadata("apiSchemas").GetAddedOrExplicitItems()
        assert p.GetAttribute("semantic:Semantics:params:semanticType").Get() == "class"
        assert p.GetAttribute("semantic:Semantics:params:semanticData").Get() == r["holoocean"]
        m = cache.GetLocalToWorldTransform(p)
        assert list(m.ExtractTranslation()) == pytest.approx([o.x_m, o.y_m, o.z_m], abs=1e-5)

    # SDF: Gazebo's Label system with the label's stencil value, and the instance id in coastforge's element
    (world,) = (out / "sdf").glob("*.world")
    root = ET.parse(world).getroot()
    ns = {"coastforge": "https://coastforge.invalid/sdf"}
    models = {m.get("name"): m for m in root.iter("model")}
    names = unique_names(list(rows))
    for oid, r in rows.items():
        m = models[names[oid]]
        (plugin,) = m.findall("plugin")
        assert plugin.get("filename") == "gz-sim-label-system" and plugin.get("name") == "gz::sim::systems::Label"
        assert int(plugin.find("label").text) == r["holoocean_id"]
        inst = m.find("coastforge:instance", ns)
        assert inst.get("id") == oid and int(inst.get("instance_id")) == r["instance_id"]
        o = objs[oid]
        pose = [float(v) for v in m.find("pose").text.split()]
        assert pose[:3] == pytest.approx([o.x_m, o.y_m, o.z_m], abs=1e-5)
        assert math.degrees(pose[5]) == pytest.approx(o.yaw_deg, abs=1e-4)
    assert int(models["water_surface"].find("plugin/label").text) == HOLOOCEAN_LABELS["WaterPlane"]


def test_generated_sdf_parses_with_libsdformat(generated, sdfcheck):
    import subprocess

    out, _ = generated
    (world,) = (out / "sdf").glob("*.world")
    r = subprocess.run([str(sdfcheck), str(world)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "OK" in r.stdout, r.stdout + r.stderr


def test_generated_glb_passes_the_khronos_validator(generated):
    import subprocess

    from test_export import JS_DIR, _validator

    node = _validator()
    out, _ = generated
    (glb,) = (out / "gltf").glob("*.glb")
    r = subprocess.run([node, str(JS_DIR / "validate_gltf.mjs"), str(glb)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    issues = json.loads(r.stdout)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]


@pytest.fixture(scope="session")
def sdfcheck():
    from test_export import build_sdfcheck  # the libsdformat checker test_export compiles

    return build_sdfcheck()


# ---------------------------------------------------------------- HoloOcean


def load_like_holoocean(scenario: dict, world_entry: dict) -> list[str]:
    """What ``holoocean.make(scenario_cfg=...)`` does with a scenario before it starts the engine, as the
    client's code does it: ``make`` looks the world up in the package's config.json ``worlds`` (its
    ``pre_start_steps``, ``env_min``/``env_max``); ``_load_scenario`` requires ``agents`` with ``agent_name``,
    ``agent_type``, ``sensors`` and ``control_scheme``, ``sensor_type`` per sensor, raises ValueError for a
    sensor faster than ``ticks_per_sec`` and rounds (with a printed message) a rate that does not divide it.
    Returns those rounding messages."""
    package_config = {"worlds": [world_entry]}
    world = next(w for w in package_config["worlds"] if w["name"] == scenario["world"])  # StopIteration: not listed
    _ = world["pre_start_steps"]
    assert "env_min" in scenario or "env_min" in world
    ticks = scenario.get("ticks_per_sec", 30)
    messages = []
    for agent in scenario["agents"]:
        _ = agent["agent_name"], agent["agent_type"], agent["control_scheme"]
        for sensor in agent["sensors"]:
            if "sensor_type" not in sensor:
                raise ValueError(f"sensor of {agent['agent_name']} lacks sensor_type")
            cfg = {"location": [0, 0, 0], "rotation": [0, 0, 0], "socket": "", "configuration": None,
                   "sensor_name": sensor["sensor_type"], "Hz": ticks}
            cfg.update(sensor)
            if ticks < cfg["Hz"]:
                raise ValueError(f"{cfg['sensor_name']} is sampled at {cfg['Hz']} which is greater than ticks_per_sec")
            tick_every = ticks / cfg["Hz"]
            if int(tick_every) != tick_every:
                messages.append(f"{cfg['sensor_name']} rate {cfg['Hz']} is not a factor of ticks_per_sec {ticks}, "
                                f"rounding to {ticks // int(tick_every)}")
            assert len(cfg["location"]) == 3 and len(cfg["rotation"]) == 3
        assert len(agent["location"]) == 3 and len(agent["rotation"]) == 3
    return messages


def test_scenario_loads_like_holoocean_with_exact_rates(generated):
    out, _ = generated
    ho = out / "holoocean"
    entry = json.loads((ho / "config_world_entry.json").read_text())
    (path,) = [p for p in ho.glob("*.json") if p.name != "config_world_entry.json"]
    sc = json.loads(path.read_text())
    assert load_like_holoocean(sc, entry) == []  # no sensor rounded
    ticks = sc["ticks_per_sec"]
    hz = {s["sensor_name"]: s["Hz"] for a in sc["agents"] for s in a["sensors"]}
    assert all(ticks % v == 0 for v in hz.values())
    assert hz["DVLSensor"] == 15  # 20 Hz asked at 30 ticks per second: the nearest divisor, not a silent 30
    types = {s["sensor_type"] for a in sc["agents"] for s in a["sensors"]}
    assert {"SemanticSegmentationCamera", "RaycastSemanticLidar"} <= types
    # the check really catches a rate HoloOcean would round
    bad = json.loads(json.dumps(sc))
    bad["agents"][0]["sensors"][0]["Hz"] = 20
    assert load_like_holoocean(bad, entry) and "not a factor" in load_like_holoocean(bad, entry)[0]


@pytest.mark.parametrize("ticks", [30, 25, 60, 7])
def test_sensor_rates_divide_any_ticks_per_sec(ticks):
    from coastforge.export.holoocean import build_scenario, check_rates, sensor_hz
    from test_export import make_scene

    sc, entry = build_scenario(make_scene(), ExportConfig(ticks_per_sec=ticks))
    assert sc["ticks_per_sec"] == ticks and load_like_holoocean(sc, entry) == []
    assert sensor_hz(20, 30) == 15 and sensor_hz(10, 30) == 10 and sensor_hz(100, 30) == 30 and sensor_hz(5, 7) == 7
    sc["agents"][1]["sensors"][0]["Hz"] = ticks + 1
    with pytest.raises(InputError, match="ticks_per_sec"):
        check_rates(sc)


# ---------------------------------------------------------------- USD materials


def test_usd_textured_terrain_translucent_water_and_clean_checks(generated):
    from pxr import Usd, UsdGeom, UsdSemantics, UsdShade
    from test_export import _usd_errors

    out, _ = generated
    (usdc,) = (out / "usd").glob("*.usdc")
    assert _usd_errors(usdc) == []
    stage = Usd.Stage.Open(str(usdc))
    terrain = stage.GetPrimAtPath("/World/Terrain")
    mat, _ = UsdShade.MaterialBindingAPI(terrain).ComputeBoundMaterial()
    surf = mat.ComputeSurfaceSource()[0]
    assert surf.GetIdAttr().Get() == "UsdPreviewSurface"
    tex = surf.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    tex = UsdShade.Shader(tex.GetPrim())
    assert tex.GetIdAttr().Get() == "UsdUVTexture"
    f = tex.GetInput("file").Get()
    assert (usdc.parent / f.path).is_file() and f.path.endswith(".png")
    reader = UsdShade.Shader(tex.GetInput("st").GetConnectedSources()[0][0].source.GetPrim())
    assert reader.GetIdAttr().Get() == "UsdPrimvarReader_float2" and reader.GetInput("varname").Get() == "st"
    assert UsdGeom.PrimvarsAPI(terrain).GetPrimvar("st").IsDefined()
    # one GeomSubset per terrain class present, a partition of the faces, labelled
    subsets = UsdGeom.Subset.GetGeomSubsets(UsdGeom.Imageable(terrain), UsdGeom.Tokens.face, "terrainClass")
    assert subsets and sum(len(s.GetIndicesAttr().Get()) for s in subsets) == len(
        UsdGeom.Mesh(terrain).GetFaceVertexCountsAttr().Get())
    water_sub = [s for s in subsets if s.GetPrim().GetName() == "water"]
    assert water_sub and list(UsdSemantics.LabelsAPI(water_sub[0].GetPrim(), "class").GetLabelsAttr().Get()) == [
        "WaterPlane"]
    # translucent water
    water = stage.GetPrimAtPath("/World/Water")
    wmat, _ = UsdShade.MaterialBindingAPI(water).ComputeBoundMaterial()
    assert 0.0 < wmat.ComputeSurfaceSource()[0].GetInput("opacity").Get() < 1.0
    # asset colours as materials: every asset mesh (or its parts) is bound to a UsdPreviewSurface
    for layer in (out / "usd" / "assets").glob("*.usda"):
        st = Usd.Stage.Open(str(layer))
        mesh = st.GetPrimAtPath("/Asset/mesh")
        parts = [s.GetPrim() for s in UsdGeom.Subset.GetGeomSubsets(UsdGeom.Imageable(mesh))] or [mesh]
        for part in parts:
            m, _ = UsdShade.MaterialBindingAPI(part).ComputeBoundMaterial()
            assert m and m.ComputeSurfaceSource()[0].GetInput("diffuseColor").Get() is not None, layer.name


# ---------------------------------------------------------------- physical truths


def test_pier_decks_above_water_and_scores_in_unit_interval(generated):
    out, _ = generated
    scene = load_scene(out)
    piers = [o for o in scene.objects if o.category == "pier"]
    assert piers
    deck = PierConfig().deck_height_m
    for o in piers:
        assert 0.0 < o.z_m <= Config().terrain.quay_height_m and o.z_m + deck > 0.5  # not at the water surface
    assert all(0.0 <= o.score <= 1.0 for o in scene.objects)
    assert all(o.z_m == 0.0 for o in scene.objects if o.category == "boat" and not o.attrs.get("ashore"))


def test_deck_height_follows_the_quay():
    from coastforge.pier_chains import set_deck_heights
    from coastforge.types import HeightMap

    cls = np.zeros((40, 40), np.uint8)
    cls[:, :10] = 1  # quay in the west: x < -10
    height = np.where(cls == 0, -3.0, 1.5).astype(np.float32)
    scene = Scene(name="t", seed=0, gsd_m=1.0, extent_m=(40.0, 40.0), height=height, classes=cls)
    walk = SceneObject("w", "pier", "pier_walkway", -5.0, 0.0, 0.0, 0.0, (1, 1, 1), 11.0, 2.5, "pier", 0.8,
                       {"structure": "pier0"})  # from x = -10.5 (on the quay) to x = 0.5
    finger = SceneObject("f", "pier", "pier_finger", 0.0, 4.0, 0.0, 90.0, (1, 1, 1), 8.0, 1.2, "pier", 0.6,
                         {"structure": "pier0"})
    lone = SceneObject("l", "pier", "pier_walkway", 10.0, 10.0, 0.0, 0.0, (1, 1, 1), 6.0, 2.5, "pier", 0.8,
                       {"structure": "pier1"})
    boat = SceneObject("b", "boat", "runabout", 10.0, -10.0, 0.0, 0.0, (1, 1, 1), 6.0, 2.4)
    got = {o.id: o.z_m for o in set_deck_heights([walk, finger, lone, boat], cls, HeightMap(height, scene.grid),
                                                  PierConfig(deck_height_m=0.6), quay_height_m=1.2)}
    assert got["w"] == pytest.approx(0.9) and got["f"] == pytest.approx(0.9)  # deck top flush with the 1.5 m quay
    assert got["l"] == pytest.approx(0.6)  # no land near it: the quay height as its deck
    assert got["b"] == 0.0


def test_match_confidence_is_a_score_in_unit_interval():
    from coastforge.matching import Candidate, match_confidence

    cfg = MatchConfig()
    top = 1.0 + cfg.shape_appearance_weight
    assert match_confidence(Candidate("a", 0.9, 0.8, 1.15, shape=0.95, fit_scale=1.0), cfg) == pytest.approx(1.15 / top)
    assert match_confidence(Candidate("a", 1.0, 1.0, top, shape=1.0, fit_scale=1.0), cfg) == 1.0
    assert match_confidence(Candidate("a", -0.5, 0.1, -0.3, shape=-0.2, fit_scale=1.0), cfg) == 0.0
    assert match_confidence(Candidate("a", 0.7, 0.5, 0.6), cfg) == pytest.approx(0.6)
    a, b = (match_confidence(Candidate("a", 0.9, 0.8, s, shape=0.9, fit_scale=1.0), cfg) for s in (1.05, 1.15))
    assert a < b  # normalised, not clipped: the ranking survives


# ---------------------------------------------------------------- summaries print plain paths


def test_export_summaries_print_plain_paths(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from coastforge.cli import cli
    from test_export import CFG, PrimResolver, make_scene

    written = export_scene(make_scene(), ["gltf", "sdf"], out_dir=tmp_path / "o", mesh_lookup=PrimResolver(),
                           config=CFG)
    lines = export_summary(written)
    assert lines[0].startswith("gltf: 1 files under ") and not any("PosixPath" in x or "[" in x for x in lines)
    assert (tmp_path / "o" / "instances.json").is_file()

    # generate's summary (run_generate replaced: only the printing is under test)
    import coastforge.pipeline as pipeline

    class R:
        scene_path = tmp_path / "o" / "scene.json"
        n_objects: ClassVar[dict[str, int]] = {"boat": 1}
        timings_s: ClassVar[dict[str, float]] = {"total": 1.0}
        exports = written
        report_path = None
        warnings = ()
        notes = ()

    monkeypatch.setattr(pipeline, "run_generate", lambda *a, **k: R())
    img = tmp_path / "i.png"
    from coastforge.fsio import write_png

    write_png(img, np.zeros((8, 8, 3), np.uint8))
    r = CliRunner().invoke(cli, ["generate", str(img), "--gsd", "0.5", "--out", str(tmp_path / "g"),
                                 "--export", "gltf,sdf", "--no-report"])
    assert r.exit_code == 0, r.output
    assert "PosixPath" not in r.output and re.search(r"export\s+gltf: 1 files under", r.output)
