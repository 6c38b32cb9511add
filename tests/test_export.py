"""Exporters (issue 8): every format checked by a real reader, and round trips of a known pose.

Readers: the Khronos glTF validator (npm ``gltf-validator``, installed with
``npm install --prefix tests/js --no-audit --no-fund``),
pxr (usd-core) with its validators, libsdformat (Debian ``libsdformat-dev``, through a tiny C++ checker
compiled on first use), and a recording stand-in for Unreal's ``unreal`` module that accepts only
documented UE 5.3 names. Tests that need a missing reader skip and say how to install it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from coastforge.config import ExportConfig
from coastforge.errors import InputError, OutputExistsError
from coastforge.export import export_scene, parse_formats
from coastforge.export.glb import read_glb
from coastforge.export.gltf import from_gltf, yaw_from_quaternion
from coastforge.export.terrain_mesh import resample_height, sample_class, sample_height
from coastforge.export.ue5 import LANDSCAPE_SIZES, decode_heights, encode_heights, landscape_size
from coastforge.scene import Scene, SceneObject, Vegetation

HERE = Path(__file__).resolve().parent
JS_DIR = HERE / "js"
ALL = ("ue5", "holoocean", "gltf", "usd", "sdf")

# ---------------------------------------------------------------- a small synthetic harbour


def make_scene(name: str = "Test Harbor") -> Scene:
    """64 x 48 m: water in the west deepening to 6.6 m, a sand strip, grass rising to the east, asphalt."""
    h, w = 48, 64
    cols = np.arange(w)[None, :].repeat(h, 0)
    classes = np.where(cols < 32, 0, 3).astype(np.uint8)
    classes[:, 32:36] = 7
    classes[:10, 50:] = 1
    height = np.where(cols < 32, -0.2 - (32 - cols) * 0.2, 0.3 + (cols - 32) * 0.08).astype(np.float32)
    objs = (
        SceneObject("boat_1", "boat", "kit_boat", -15.0, 5.0, 0.0, 30.0, (1.0, 1.0, 1.0), 6.0, 2.2, "detection", 0.9),
        SceneObject('car "1"\nx', "vehicle", "kit_car", 20.0, -10.0, 2.0, -120.0, (1.1, 1.0, 1.0), 4.5, 1.8,
                    "detection", 0.8),
        SceneObject("pier_1", "pier", "kit_pier", -2.0, 0.0, 0.6, 90.0, (2.0, 1.0, 1.0), 10.0, 2.0, "pier", 1.0),
        SceneObject("big_boat", "boat", "kit_boat", -22.0, -12.0, 0.0, 179.0, (2.0, 2.0, 2.0), 12.0, 4.0,
                    "detection", 0.7),
    )
    veg = Vegetation(np.array(["kit_tree", "kit_tree"], dtype=object), np.array(["tree", "tree"], dtype=object),
                     np.array([25.0, 28.0]), np.array([15.0, 18.0]), np.array([2.5, 2.7]), np.array([10.0, 50.0]),
                     np.array([1.0, 1.2]))
    return Scene(name=name, seed=1, gsd_m=1.0, extent_m=(64.0, 48.0), height=height, classes=classes,
                 objects=objs, vegetation=veg)


DIMS = {"kit_boat": (6.0, 2.2, 1.5), "kit_car": (4.5, 1.8, 1.5), "kit_pier": (5.0, 2.0, 0.3), "kit_tree": (2.0, 2.0, 5.0)}


class PrimResolver:
    """Boxes in the scene frame (footprint centred, lowest point at z = 0) with face colours."""

    def __init__(self, ue_paths=None):
        self.ue_paths = ue_paths if ue_paths is not None else {"kit_boat": "/Game/Boats/SM_Boat"}

    def mesh(self, aid):
        d = DIMS[aid]
        m = trimesh.creation.box(d)
        m.apply_translation([0.0, 0.0, d[2] / 2.0])
        m.visual.face_colors = np.tile([200, 60, 40, 255], (len(m.faces), 1))
        m.visual.face_colors[:4] = [250, 250, 250, 255]
        return m

    def mesh_path(self, aid):
        return None

    def ue_path(self, aid):
        return self.ue_paths.get(aid)

    def category(self, aid):
        return None


CFG = ExportConfig(gltf_max_vertices=3000)


@pytest.fixture(scope="module")
def scene() -> Scene:
    return make_scene()


@pytest.fixture(scope="module")
def out(tmp_path_factory, scene) -> Path:
    d = tmp_path_factory.mktemp("export")
    export_scene(scene, ALL, out_dir=d, mesh_lookup=PrimResolver(), config=CFG)
    return d


# ---------------------------------------------------------------- writer


def test_writer_layout_refuses_overwrite_and_bad_formats(out, scene):
    for fmt in ALL:
        assert (out / fmt).is_dir() and any((out / fmt).rglob("*")), fmt
    glb = out / "gltf" / "Test_Harbor.glb"
    before = glb.read_bytes()
    with pytest.raises(OutputExistsError, match="--overwrite"):
        export_scene(scene, ["gltf"], out_dir=out, mesh_lookup=PrimResolver(), config=CFG)
    assert glb.read_bytes() == before
    export_scene(scene, "gltf", out_dir=out, overwrite=True, mesh_lookup=PrimResolver(), config=CFG)
    assert not list(out.rglob(".*.tmp")) and not [p for p in out.rglob(".*") if p.is_file()]
    with pytest.raises(InputError, match="fbx"):
        parse_formats("gltf,fbx")
    with pytest.raises(InputError, match="out_dir"):
        export_scene(scene, ["gltf"], mesh_lookup=PrimResolver())


def test_export_from_scene_folder_uses_cleaned_image(tmp_path):
    from coastforge.fsio import write_png
    from coastforge.scene import save_scene

    s = make_scene()
    save_scene(s, tmp_path)
    img = np.zeros((48, 64, 3), np.uint8)
    img[:, :, 0] = 255  # a pure red "cleaned" image
    write_png(tmp_path / "cleaned.png", img)
    res = PrimResolver()
    written = export_scene(tmp_path, ["gltf"], mesh_lookup=lambda aid: res.mesh(aid), config=CFG)
    glb = tmp_path / "gltf" / "Test_Harbor.glb"
    assert written["gltf"] == [glb]
    doc, binary = read_glb(glb.read_bytes())
    bv = doc["bufferViews"][doc["images"][0]["bufferView"]]
    import cv2

    tex = cv2.imdecode(np.frombuffer(binary[bv["byteOffset"]: bv["byteOffset"] + bv["byteLength"]], np.uint8),
                       cv2.IMREAD_COLOR)
    assert tex.shape[:2] == (48, 64) and (tex[:, :, 2] == 255).all() and (tex[:, :, :2] == 0).all()


# ---------------------------------------------------------------- ue5


def test_landscape_size_rule():
    assert landscape_size(64) == 127 and landscape_size(127) == 127 and landscape_size(128) == 253
    assert landscape_size(3000) == 4033 and landscape_size(20000) == 8129
    assert landscape_size(3000, cap=2017) == 2017
    with pytest.raises(InputError, match="ue_max_size"):
        landscape_size(100, cap=100)
    for n in LANDSCAPE_SIZES:  # components x sections x quads + 1
        from coastforge.export.ue5 import landscape_layout

        q, s, c = landscape_layout(n)
        assert q in (7, 15, 31, 63, 127, 255) and c * s * q + 1 == n and c * c <= 1024


def test_ue5_heightmap_decodes_within_one_step(out, scene):
    import cv2

    ue = out / "ue5"
    spec = json.loads((ue / "level.json").read_text())
    ls = spec["landscape"]
    n = ls["size"]
    assert n in LANDSCAPE_SIZES and n >= max(scene.height.shape)
    png = cv2.imread(str(ue / ls["heightmap_png"]), cv2.IMREAD_UNCHANGED)
    assert png.dtype == np.uint16 and png.shape == (n, n)
    raw = np.frombuffer((ue / ls["heightmap_r16"]).read_bytes(), "<u2").reshape(n, n)
    assert (raw == png).all()
    rg = cv2.imread(str(ue / ls["heightmap_rg8"]), cv2.IMREAD_UNCHANGED)[:, :, [2, 1, 0, 3]]
    assert ((rg[..., 0].astype(np.uint32) << 8 | rg[..., 1]) == png).all()
    for f in [ls["heightmap_png"], ls["heightmap_r16"], ls["heightmap_rg8"]] + [w["file"] for w in spec["weightmaps"]]:
        assert not re.search(r"\d+\s*[xX]\s*\d+", Path(f).name), f  # UE reads NxN names as tiles
    sx, sy, sz = ls["scale"]
    ew, eh = scene.extent_m
    assert sx == pytest.approx(ew * 100 / (n - 1)) and sy == pytest.approx(eh * 100 / (n - 1))
    assert sz >= np.abs(scene.height).max() * 100 / 256
    assert ls["location"] == pytest.approx([-ew * 50, -eh * 50, 0.0])
    assert encode_heights(np.array([0.0]), sz)[0] == 32768
    # decode exactly as Unreal: Z = (H - 32768)/128 * ScaleZ + LocationZ, at every vertex
    z_ue = decode_heights(png, sz, ls["location"][2])
    step_m = sz / 128.0 / 100.0
    want = resample_height(scene, n, n)
    assert np.abs(z_ue - want).max() <= step_m
    # vertex (col i, row j) sits at X = LocX + i*ScaleX, Y = LocY + j*ScaleY: check one against the raster
    i, j = 100, 30
    x_m, y_m = (ls["location"][0] + i * sx) / 100.0, -(ls["location"][1] + j * sy) / 100.0
    assert z_ue[j, i] == pytest.approx(float(sample_height(scene, x_m, y_m)), abs=step_m)


def test_ue5_weightmaps_and_masks(out):
    import cv2

    ue = out / "ue5"
    spec = json.loads((ue / "level.json").read_text())
    n = spec["landscape"]["size"]
    maps = [cv2.imread(str(ue / w["file"]), cv2.IMREAD_UNCHANGED) for w in spec["weightmaps"]]
    assert len(maps) == 8 and all(m.dtype == np.uint8 and m.shape == (n, n) for m in maps)
    assert (np.sum(maps, axis=0, dtype=np.int32) == 255).all()
    water = maps[0]
    assert water[:, :20].min() == 255 and water[:, -20:].max() == 0  # west is water, east is land
    for m in spec["pcg"]["masks"]:
        a = cv2.imread(str(ue / m["file"]), cv2.IMREAD_UNCHANGED)
        assert a.dtype == np.uint8 and a.shape == (n, n)


def _run_build_level(bundle: Path, unreal_mod, argv, capsys):
    spec = importlib.util.spec_from_file_location("cf_build_level", bundle / "build_level.py")
    mod = importlib.util.module_from_spec(spec)
    saved = sys.modules.get("unreal")
    if unreal_mod is None:
        sys.modules.pop("unreal", None)
        sys.modules["unreal"] = None  # makes `import unreal` fail, as outside the editor
    else:
        sys.modules["unreal"] = unreal_mod
    try:
        spec.loader.exec_module(mod)
        rc = mod.main(argv)
    finally:
        if saved is not None:
            sys.modules["unreal"] = saved
        else:
            sys.modules.pop("unreal", None)
    return rc, capsys.readouterr().out


def test_build_level_against_recording_unreal(out, scene, capsys):
    import cv2
    import unreal_stub

    ue = out / "ue5"
    spec = json.loads((ue / "level.json").read_text())
    mod, rec = unreal_stub.make_unreal(assets={"/Game/Boats/SM_Boat"})
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0, text
    assert rec.violations == []
    assert rec.named("LevelEditorSubsystem.new_level_from_template")[0][0][1:] == (
        "/Game/Coastforge/Maps/Test_Harbor", CFG.template_level)
    # landscape: transform and the heights that arrived through the RGBA8 render target
    land = next(a for a in rec.world_actors if isinstance(a, unreal_stub.Landscape))
    ls = spec["landscape"]
    assert (land.location.x, land.location.y, land.location.z) == pytest.approx(tuple(ls["location"]))
    assert (land.scale.x, land.scale.y, land.scale.z) == pytest.approx(tuple(ls["scale"]))
    png = cv2.imread(str(ue / ls["heightmap_png"]), cv2.IMREAD_UNCHANGED)
    assert land.heights is not None and (land.heights == png).all()
    for w in spec["weightmaps"]:
        assert (land.weights[w["layer"]] == cv2.imread(str(ue / w["file"]), cv2.IMREAD_UNCHANGED)).all()
    # actors: centimetres, Y flipped (left-handed), yaw sign flipped, Tagger folders, labels kept verbatim
    spawned = {a.label: a for a in rec.world_actors if isinstance(a, unreal_stub.StaticMeshActor) and a.asset}
    assert len(spawned) == len(scene.objects) + len(scene.vegetation)
    folders = {"boat_1": "float/small_float", 'car "1"\nx': "Car", "pier_1": "Pier", "big_boat": "float/big_float"}
    for o in scene.objects:
        a = spawned[o.id]
        assert (a.location.x, a.location.y, a.location.z) == pytest.approx((o.x_m * 100, -o.y_m * 100, o.z_m * 100))
        assert a.rotation.yaw == pytest.approx(-o.yaw_deg) and a.rotation.roll == 0 and a.rotation.pitch == 0
        assert (a.scale.x, a.scale.y, a.scale.z) == pytest.approx(o.scale)
        assert a.folder == folders[o.id]
        assert spec["run_tag"] in a._props["tags"]
    # HoloOcean's Tagger reads the FIRST actor tag; floating boats also carry Float (the tide moves them)
    labels = {"boat_1": ["Boat", "Float"], 'car "1"\nx': ["Car"], "pier_1": ["Pier"], "big_boat": ["Boat", "Float"]}
    for oid, want in labels.items():
        tags = spawned[oid]._props["tags"]
        assert tags[:len(want)] == want and tags[len(want)] == spec["run_tag"]
    assert spawned["boat_1"].asset.path == "/Game/Boats/SM_Boat"  # a library Unreal path is used as is
    # GLB imported into <level>/<Label>/Meshes: the Tagger's Content-folder fallback names the label too
    assert spawned["pier_1"].asset.path == "/Game/Coastforge/Test_Harbor/Pier/Meshes/SM_kit_pier"
    assert spawned["veg_tree_1"].folder == "Tree" and spawned["veg_tree_1"].scale.z == pytest.approx(1.2)
    assert spawned["veg_tree_1"]._props["tags"][0] == "Tree"
    assert len(rec.named("AssetTools.import_asset_tasks")) == 3  # car, pier, tree: once each
    assert rec.saved == 1 and "WARNING" not in text
    assert "height check at" in text and "max error 0.000 cm" in text  # the landscape read back after import

    # re-run: the level is loaded, earlier actors replaced (no duplicates), imported meshes re-used
    n_actors = len(rec.world_actors)
    rec.calls.clear()
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0, text
    assert rec.violations == [] and rec.named("LevelEditorSubsystem.load_level")
    assert len(rec.named("EditorActorSubsystem.destroy_actor")) == len(scene.objects) + len(scene.vegetation)
    assert len(rec.world_actors) == n_actors and rec.named("AssetTools.import_asset_tasks") == []


def test_build_level_under_interchange_reuses_imports(out, capsys):
    """UE 5.3's Interchange glTF importer ignores destination_name and lists no imported paths: the script
    still finds the meshes it imported (by the source's name, in the destination folder) and re-uses them."""
    import unreal_stub

    ue = out / "ue5"
    mod, rec = unreal_stub.make_unreal(assets={"/Game/Boats/SM_Boat"}, interchange=True)
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0, text
    assert rec.violations == [] and len(rec.named("AssetTools.import_asset_tasks")) == 3
    spawned = {a.label: a for a in rec.world_actors if isinstance(a, unreal_stub.StaticMeshActor) and a.asset}
    assert spawned["pier_1"].asset.path == "/Game/Coastforge/Test_Harbor/Pier/Meshes/SM_kit_pier"
    rec.calls.clear()
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0, text
    assert rec.named("AssetTools.import_asset_tasks") == [] and rec.violations == []


def test_build_level_stops_when_the_landscape_heights_differ(out, capsys):
    import unreal_stub

    ue = out / "ue5"
    mod, rec = unreal_stub.make_unreal(assets={"/Game/Boats/SM_Boat"})
    rec.height_drift = 400  # Unreal would hold every height 400 raw steps (about 8 cm here) off the file
    rc, text = _run_build_level(ue, mod, [], capsys)
    spec = json.loads((ue / "level.json").read_text())
    want_cm = 400 * spec["landscape"]["height_step_cm"]
    assert rc == 1 and "STOPPED" in text and "differ from the heightmap" in text
    assert f"max error {want_cm:.3f} cm" in text and "Resolution:" in text
    assert rec.violations == [] and rec.named("EditorActorSubsystem.spawn_actor_from_object") == []
    # a landscape imported by hand (--skip-landscape) is checked too
    land = next(a for a in rec.world_actors if isinstance(a, unreal_stub.Landscape))
    rc, text = _run_build_level(ue, mod, ["--skip-landscape"], capsys)
    assert land.heights is not None and rc == 1 and "differ from the heightmap" in text
    rec.height_drift = 0
    rc, text = _run_build_level(ue, mod, ["--skip-landscape"], capsys)
    assert rc == 0 and "max error 0.000 cm" in text and rec.violations == []


def test_build_level_checks_the_holoocean_water_actors(out, capsys):
    import unreal_stub

    ue = out / "ue5"
    mod, rec = unreal_stub.make_unreal(assets={"/Game/Boats/SM_Boat"})
    plane = next(a for a in rec.world_actors if "WaterSurface" in a._props["tags"])
    plane._props["root_component"]._props["mobility"] = unreal_stub.EnumValue("ComponentMobility.STATIC")
    fog = next(a for a in rec.world_actors if a.label == "PostProcessFog")
    rec.world_actors.remove(fog)
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0 and rec.violations == []
    assert "is not Movable" in text and "one post-process volume tagged WaterPPV" in text


def test_build_level_dry_run_stop_and_documented_names(out, capsys):
    import unreal_stub

    ue = out / "ue5"
    rc, text = _run_build_level(ue, None, ["--dry-run"], capsys)
    assert rc == 0
    assert "[dry-run] create the level" in text and "[dry-run] spawn 'boat_1'" in text
    assert "'car \"1\"\\nx'" in text  # a name with quotes/newline is printed as data
    rc, text = _run_build_level(ue, None, [], capsys)
    assert rc == 2 and "inside the Unreal Editor" in text
    # a template without a landscape: stop and print the exact manual import settings
    mod, rec = unreal_stub.make_unreal(landscape=False, water=False)
    rc, text = _run_build_level(ue, mod, [], capsys)
    spec = json.loads((ue / "level.json").read_text())
    n = spec["landscape"]["size"]
    assert rc == 1 and "STOPPED" in text and f"Resolution:                {n} x {n}" in text
    assert "WARNING: no actor tagged WaterSurface" in text and "WARNING: no actor tagged WaterPPV" in text
    assert "terrain_height.png" in text and "--skip-landscape" in text
    assert rec.named("EditorActorSubsystem.spawn_actor_from_object") == [] and rec.saved == 0
    # the stand-in really refuses undocumented names
    with pytest.raises(AttributeError):
        mod.EditorLevelLibrary  # noqa: B018  (deprecated in 5.3, not in the documented list)
    with pytest.raises(AttributeError):
        mod.get_editor_subsystem(mod.EditorActorSubsystem).spawn_actor  # noqa: B018
    assert rec.violations == ["EditorLevelLibrary", "EditorActorSubsystem.spawn_actor"]


def test_build_level_script_holds_no_scene_values(tmp_path, out):
    other = make_scene("Completely Different Name")
    export_scene(other, ["ue5"], out_dir=tmp_path, mesh_lookup=PrimResolver(ue_paths={}), config=CFG)
    a = (out / "ue5" / "build_level.py").read_bytes()
    b = (tmp_path / "ue5" / "build_level.py").read_bytes()
    assert a == b
    for needle in (b"Test_Harbor", b"boat_1", b"kit_", b"/Game/Boats"):
        assert needle not in a
    assert "(over export.max_vegetation_actors)" not in (out / "ue5" / "README.md").read_text()
    text = (out / "ue5" / "README.md").read_text()
    assert "5.3" in text and "WaterSurface" in text and "--dry-run" in text


# ---------------------------------------------------------------- holoocean

SCENARIO_KEYS = ("name", "world", "package_name", "agents")
AGENT_KEYS = ("agent_name", "agent_type", "sensors", "control_scheme", "location", "rotation")


def test_holoocean_scenario_rules(out, scene):
    from coastforge.export.holoocean import AGENT_SOCKETS, AGENT_TYPES, SENSOR_TYPES

    ho = out / "holoocean"
    files = sorted(p.name for p in ho.iterdir())
    assert "Test_Harbor-Survey.json" in files and "config_world_entry.json" in files
    sc = json.loads((ho / "Test_Harbor-Survey.json").read_text())
    for k in SCENARIO_KEYS:
        assert k in sc
    assert f"{sc['world']}-{sc['name']}.json" == "Test_Harbor-Survey.json"
    ticks = sc["ticks_per_sec"]
    lo, hi = np.array(sc["env_min"]), np.array(sc["env_max"])
    ew, eh = scene.extent_m
    assert (lo[:2] <= [-ew / 2, -eh / 2]).all() and (hi[:2] >= [ew / 2, eh / 2]).all()
    assert lo[2] <= scene.height.min() and hi[2] >= scene.height.max()
    types = {}
    for ag in sc["agents"]:
        for k in AGENT_KEYS:
            assert k in ag, k
        assert ag["agent_type"] in AGENT_TYPES and len(ag["rotation"]) == 3
        loc = np.array(ag["location"])
        assert (lo <= loc).all() and (loc <= hi).all()
        for s in ag["sensors"]:
            assert s["sensor_type"] in SENSOR_TYPES and 0 < s["Hz"] <= ticks
            assert "socket" in s and "socket" not in s.get("configuration", {})
            assert s["socket"] in AGENT_SOCKETS[ag["agent_type"]], (ag["agent_type"], s["socket"])
        types[ag["agent_type"]] = (loc, {s["sensor_type"] for s in ag["sensors"]})
    assert sc["main_agent"] in [a["agent_name"] for a in sc["agents"]]
    auv, auv_sensors = types["HoveringAUV"]
    assert {"ImagingSonar", "DVLSensor", "IMUSensor", "DepthSensor", "RGBCamera", "PoseSensor"} <= auv_sensors
    seabed = float(sample_height(scene, auv[0], auv[1]))
    assert int(sample_class(scene, auv[0], auv[1])) == 0
    assert auv[2] <= -1.0 and auv[2] >= seabed + 1.0
    vessel, v_sensors = types["SurfaceVessel"]
    assert {"GPSSensor", "IMUSensor", "RaycastSemanticLidar", "RGBCamera"} <= v_sensors
    assert int(sample_class(scene, vessel[0], vessel[1])) == 0 and vessel[2] == 0.0
    for o in scene.objects:
        r = 0.5 * math.hypot(o.length_m * o.scale[0], o.width_m * o.scale[1])
        assert math.hypot(auv[0] - o.x_m, auv[1] - o.y_m) > r and math.hypot(vessel[0] - o.x_m, vessel[1] - o.y_m) > r
    entry = json.loads((ho / "config_world_entry.json").read_text())
    assert entry["name"] == sc["world"] and entry["env_min"] == sc["env_min"] and entry["env_max"] == sc["env_max"]


def test_holoocean_refuses_a_dry_scene():
    from coastforge.export.holoocean import export_holoocean

    s = make_scene()
    dry = Scene(name="dry", seed=0, gsd_m=1.0, extent_m=s.extent_m, height=np.full_like(s.height, 2.0),
                classes=np.full_like(s.classes, 3))
    with pytest.raises(InputError, match="AUV"):
        export_holoocean(dry, PrimResolver(), CFG)


# ---------------------------------------------------------------- glTF


def _validator():
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed: apt-get install nodejs npm, then "
                    "npm install --prefix tests/js --no-audit --no-fund")
    if not (JS_DIR / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("the Khronos glTF validator is not installed: "
                    "run `npm install --prefix tests/js --no-audit --no-fund`")
    return node


def test_gltf_passes_khronos_validator(out):
    node = _validator()
    glb = out / "gltf" / "Test_Harbor.glb"
    r = subprocess.run([node, str(JS_DIR / "validate_gltf.mjs"), str(glb)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    # the validator does find errors: break an accessor's bounds
    doc, binary = read_glb(glb.read_bytes())
    doc["accessors"][0]["max"] = [0.0, 0.0, 0.0]
    from coastforge.export.glb import GlbBuilder

    b = GlbBuilder()
    b.doc, b.bin = doc, bytearray(binary)
    bad = out / "bad.glb"
    bad.write_bytes(b.to_bytes())
    r = subprocess.run([node, str(JS_DIR / "validate_gltf.mjs"), str(bad)], capture_output=True, text=True, timeout=120)
    assert json.loads(r.stdout)["issues"]["numErrors"] > 0


def test_gltf_round_trip_y_up(out, scene):
    doc, _binary = read_glb((out / "gltf" / "Test_Harbor.glb").read_bytes())
    nodes = {n["name"]: n for n in doc["nodes"]}
    for o in scene.objects:
        n = nodes[o.id]
        assert from_gltf(np.array(n["translation"])) == pytest.approx([o.x_m, o.y_m, o.z_m])
        assert yaw_from_quaternion(n["rotation"]) == pytest.approx(o.yaw_deg, abs=1e-6)
        assert n["scale"] == pytest.approx([o.scale[0], o.scale[2], o.scale[1]])
        assert n["extras"]["asset_id"] == o.asset_id
    meshes = {m["name"] for m in doc["meshes"]}
    assert meshes == {"terrain", "water", "kit_boat", "kit_car", "kit_pier", "kit_tree"}  # one mesh per asset
    assert nodes["boat_1"]["mesh"] == nodes["big_boat"]["mesh"]
    terrain = doc["meshes"][nodes["terrain"]["mesh"]]["primitives"][0]
    pos = doc["accessors"][terrain["attributes"]["POSITION"]]
    assert pos["count"] <= CFG.gltf_max_vertices
    # y-up: glTF y spans the terrain heights; -z is north
    assert pos["min"][1] == pytest.approx(scene.height.min(), abs=0.05)
    assert pos["max"][1] == pytest.approx(scene.height.max(), abs=0.05)
    assert pos["min"][2] == pytest.approx(-24.0) and pos["max"][0] == pytest.approx(32.0)
    water = doc["accessors"][doc["meshes"][nodes["water"]["mesh"]]["primitives"][0]["attributes"]["POSITION"]]
    assert water["min"][1] == 0.0 and water["max"][1] == 0.0
    # an asset's vertex: the boat's bow (+x, local) points along yaw 30° in the scene
    yaw = math.radians(30.0)
    q = nodes["boat_1"]["rotation"]
    v = np.array([1.0, 0.0, 0.0])  # glTF +x = scene +x
    x, y, z, w = q
    u = np.array([x, y, z])
    v_rot = 2 * np.dot(u, v) * u + (w * w - np.dot(u, u)) * v + 2 * w * np.cross(u, v)
    assert from_gltf(v_rot) == pytest.approx([math.cos(yaw), math.sin(yaw), 0.0], abs=1e-9)


# ---------------------------------------------------------------- USD


def _usd_errors(path: Path) -> list[str]:
    from pxr import Usd, UsdUtils

    if hasattr(UsdUtils, "ComplianceChecker"):  # usd-core < 25
        checker = UsdUtils.ComplianceChecker(arkit=False, skipARKitRootLayerCheck=False, rootPackageOnly=False,
                                             skipVariants=False, verbose=False)
        checker.CheckCompliance(str(path))
        return list(checker.GetErrors()) + list(checker.GetFailedChecks())
    from pxr import UsdValidation  # its successor: the same rules as registered validators

    stage = Usd.Stage.Open(str(path))
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errs = UsdValidation.ValidationContext(validators).Validate(stage)
    return [e.GetMessage() for e in errs if e.GetType() == UsdValidation.ValidationErrorType.Error]


def test_usd_opens_passes_checks_and_round_trips(out, scene):
    pytest.importorskip("pxr", reason="usd-core is not installed: pip install 'coastforge[usd]'")
    from pxr import Gf, Usd, UsdGeom

    path = out / "usd" / "Test_Harbor.usdc"
    assert _usd_errors(path) == []
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    objs = stage.GetPrimAtPath("/World/Objects")
    by_id = {p.GetCustomDataByKey("coastforge:id"): p for p in objs.GetChildren()}
    assert set(by_id) == {o.id for o in scene.objects}
    cache = UsdGeom.XformCache()
    for o in scene.objects:
        p = by_id[o.id]
        assert p.IsInstanceable() and p.IsInstance()
        m = cache.GetLocalToWorldTransform(p)
        assert list(m.ExtractTranslation()) == pytest.approx([o.x_m, o.y_m, o.z_m])
        fwd = m.TransformDir(Gf.Vec3d(1, 0, 0))
        assert math.degrees(math.atan2(fwd[1], fwd[0])) == pytest.approx(o.yaw_deg, abs=1e-4)
        assert fwd.GetLength() == pytest.approx(o.scale[0])
        # the referenced asset arrived: the instance has a mesh with the asset's size
        proto = p.GetPrototype()
        mesh = UsdGeom.Mesh(proto.GetChild("mesh"))
        ext = np.array(mesh.GetExtentAttr().Get())
        assert (ext[1] - ext[0]) == pytest.approx(DIMS[o.asset_id], abs=1e-5)
    pi = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Vegetation"))
    assert len(pi.GetPositionsAttr().Get()) == len(scene.vegetation)
    assert list(pi.GetPositionsAttr().Get()[1]) == pytest.approx([28.0, 18.0, 2.7])
    terrain = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Terrain"))
    assert len(terrain.GetPointsAttr().Get()) <= CFG.gltf_max_vertices


def test_usd_checker_catches_a_broken_stage(tmp_path):
    pytest.importorskip("pxr", reason="usd-core is not installed: pip install 'coastforge[usd]'")
    bad = tmp_path / "bad.usda"
    bad.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n)\ndef Xform "World"\n{\n'
                   '    def Xform "x" ( prepend references = @./missing.usda@ )\n    {\n    }\n}\n')
    assert _usd_errors(bad) != []


# ---------------------------------------------------------------- SDF

SDFCHECK_CC = r"""
// Load an SDF file with libsdformat and print what it parsed.
#include <iostream>
#include <sdf/sdf.hh>
int main(int argc, char** argv) {
  if (argc != 2) { std::cerr << "usage: sdfcheck FILE\n"; return 2; }
  sdf::Root root;
  sdf::Errors errors = root.Load(argv[1]);
  for (const auto& e : errors) std::cout << "ERROR " << e.Message() << "\n";
  if (!errors.empty()) return 1;
  std::cout.precision(10);
  for (uint64_t w = 0; w < root.WorldCount(); ++w) {
    const sdf::World* world = root.WorldByIndex(w);
    std::cout << "WORLD " << world->Name() << "\n";
    for (uint64_t m = 0; m < world->ModelCount(); ++m) {
      const sdf::Model* model = world->ModelByIndex(m);
      auto p = model->RawPose();
      std::cout << "MODEL " << model->Name() << " " << p.Pos().X() << " " << p.Pos().Y() << " " << p.Pos().Z()
                << " " << p.Rot().Euler().X() << " " << p.Rot().Euler().Y() << " " << p.Rot().Euler().Z() << "\n";
      for (uint64_t l = 0; l < model->LinkCount(); ++l) {
        const sdf::Link* link = model->LinkByIndex(l);
        for (uint64_t v = 0; v < link->VisualCount(); ++v) {
          const sdf::Geometry* g = link->VisualByIndex(v)->Geom();
          if (g->MeshShape()) {
            auto s = g->MeshShape()->Scale();
            std::cout << "MESH " << model->Name() << " " << g->MeshShape()->Uri() << " " << s.X() << " " << s.Y()
                      << " " << s.Z() << "\n";
          }
          if (g->HeightmapShape()) {
            auto h = g->HeightmapShape();
            std::cout << "HEIGHTMAP " << h->Uri() << " " << h->Size().X() << " " << h->Size().Y() << " "
                      << h->Size().Z() << " " << h->Position().X() << " " << h->Position().Y() << " "
                      << h->Position().Z() << "\n";
          }
        }
      }
    }
  }
  std::cout << "OK\n";
  return 0;
}
"""


@pytest.fixture(scope="session")
def sdfcheck() -> Path:
    return build_sdfcheck()


def build_sdfcheck() -> Path:
    """The libsdformat checker, compiled once per machine (cached by source hash)."""
    gxx, pkg = shutil.which("g++"), shutil.which("pkg-config")
    if gxx is None or pkg is None:
        pytest.skip("g++/pkg-config missing: apt-get install g++ pkg-config libsdformat-dev")
    for lib in ("sdformat12", "sdformat13", "sdformat14"):
        if subprocess.run([pkg, "--exists", lib]).returncode == 0:
            break
    else:
        pytest.skip("libsdformat is not installed: apt-get install libsdformat-dev")
    key = hashlib.sha256((SDFCHECK_CC + lib).encode()).hexdigest()[:12]
    exe = Path(tempfile.gettempdir()) / f"coastforge-sdfcheck-{key}"
    if not exe.exists():
        src = exe.with_suffix(".cc")
        src.write_text(SDFCHECK_CC)
        flags = subprocess.run([pkg, "--cflags", "--libs", lib], capture_output=True, text=True, check=True).stdout
        tmp = exe.with_suffix(".tmp")
        subprocess.run([gxx, "-std=c++17", "-O0", str(src), "-o", str(tmp), *flags.split()], check=True, timeout=300)
        tmp.replace(exe)
    return exe


def test_sdf_parses_with_libsdformat_and_round_trips(out, scene, sdfcheck):
    import cv2

    sdf = out / "sdf"
    r = subprocess.run([str(sdfcheck), str(sdf / "Test_Harbor.world")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "OK" in r.stdout, r.stdout + r.stderr
    models = {}
    meshes = {}
    hm = None
    for line in r.stdout.splitlines():
        kind, *rest = line.split(" ")
        if kind == "MODEL":
            models[rest[0]] = [float(v) for v in rest[1:]]
        elif kind == "MESH":
            meshes[rest[0]] = (rest[1], [float(v) for v in rest[2:]])
        elif kind == "HEIGHTMAP":
            hm = (rest[0], [float(v) for v in rest[1:]])
    from coastforge.export import unique_names

    names = unique_names([o.id for o in scene.objects])
    for o in scene.objects:
        x, y, z, roll, pitch, yaw = models[names[o.id]]
        assert (x, y, z) == pytest.approx((o.x_m, o.y_m, o.z_m), abs=1e-5)
        assert (roll, pitch) == pytest.approx((0.0, 0.0), abs=1e-9)
        assert math.degrees(yaw) == pytest.approx(o.yaw_deg, abs=1e-4)
        uri, sc = meshes[names[o.id]]
        assert sc == pytest.approx(list(o.scale)) and (sdf / uri).is_file() and uri.endswith(".obj")
        loaded = trimesh.load(sdf / uri, force="mesh")
        assert loaded.extents == pytest.approx(DIMS[o.asset_id], abs=1e-5)
    assert "water_surface" in models and models["water_surface"][2] == 0.0
    uri, (sx, sy, sz, px, py, pz) = hm
    img = cv2.imread(str(sdf / uri), cv2.IMREAD_UNCHANGED)
    n = img.shape[0]
    assert img.dtype == np.uint16 and img.shape == (n, n) and ((n - 1) & (n - 2)) == 0 and n >= 65
    assert (sx, sy) == pytest.approx(scene.extent_m) and (px, py) == (0.0, 0.0)
    assert pz == pytest.approx(scene.height.min(), abs=0.01) and pz + sz == pytest.approx(scene.height.max(), abs=0.01)
    z = pz + img.astype(np.float64) / 65535.0 * sz
    assert np.abs(z - resample_height(scene, n, n)).max() <= sz / 65535.0


def test_sdf_checker_reports_errors(tmp_path, sdfcheck):
    bad = tmp_path / "bad.world"
    bad.write_text('<?xml version="1.0"?><sdf version="1.9"><world name="w"><model name="m"><pose>1 2</pose>'
                   "</model></world></sdf>")
    r = subprocess.run([str(sdfcheck), str(bad)], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "ERROR" in r.stdout


# ---------------------------------------------------------------- CLI with the starter kit


def test_cli_export_with_starter_kit(tmp_path):
    from click.testing import CliRunner

    from coastforge.cli import cli

    try:
        from coastforge.assets.kit import kit_assets

        kit = kit_assets()
    except Exception as exc:  # noqa: BLE001 - the kit is built by another module; skip until it is installed
        pytest.skip(f"starter kit not available: {exc}")
    from coastforge.scene import save_scene

    by_cat = {}
    for a in kit:
        by_cat.setdefault(a.category, a.id)
    s = make_scene()
    objs = tuple(SceneObject(o.id, o.category, by_cat.get(o.category, kit[0].id), o.x_m, o.y_m, o.z_m, o.yaw_deg,
                             o.scale, o.length_m, o.width_m, o.source, o.score) for o in s.objects)
    s2 = Scene(name=s.name, seed=0, gsd_m=1.0, extent_m=s.extent_m, height=s.height, classes=s.classes, objects=objs)
    save_scene(s2, tmp_path / "scene")
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "scene"), "--format", "gltf,holoocean",
                                 "--out", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "out" / "gltf" / "Test_Harbor.glb").is_file() and "gltf: 1 files" in r.output
    r = CliRunner().invoke(cli, ["export", str(tmp_path / "scene"), "--format", "gltf", "--out", str(tmp_path / "out")])
    assert r.exit_code == 2 and "--overwrite" in r.output


def test_build_level_pcg_volume_and_vegetation_cap(tmp_path, scene, capsys):
    import dataclasses

    import unreal_stub

    cfg = dataclasses.replace(CFG, pcg_graph="/Game/PCG/CoastBiomes", max_vegetation_actors=1)
    export_scene(scene, ["ue5"], out_dir=tmp_path, mesh_lookup=PrimResolver(), config=cfg)
    ue = tmp_path / "ue5"
    spec = json.loads((ue / "level.json").read_text())
    assert spec["vegetation_left_to_pcg"] == 2 and not any(a["id"].startswith("veg_") for a in spec["actors"])
    mod, rec = unreal_stub.make_unreal(assets={"/Game/Boats/SM_Boat", "/Game/PCG/CoastBiomes"})
    rc, text = _run_build_level(ue, mod, [], capsys)
    assert rc == 0, text
    assert rec.violations == []
    vols = [a for a in rec.world_actors if isinstance(a, unreal_stub.PCGVolume)]
    assert len(vols) == 1
    comp = vols[0].components[0]
    assert comp.graph.path == "/Game/PCG/CoastBiomes" and comp.generated
    ew, eh = scene.extent_m
    assert (vols[0].scale.x * 200, vols[0].scale.y * 200) == pytest.approx((ew * 100, eh * 100))
    assert len(rec.named("AssetTools.import_asset_tasks")) == 2 + len(spec["pcg"]["masks"])  # car, pier + masks
    assert "2 instances left to the PCG masks" in text


def test_default_resolver_library_then_kit_then_error():
    from coastforge.errors import LibraryError
    from coastforge.export import DefaultResolver

    class FakeRecord:
        ue_path = "/Game/Lib/SM_X"
        mesh_path = "/lib/x.glb"
        category = "boat"

    class FakeLibrary:
        def asset(self, aid):
            if aid != "lib_x":
                raise LibraryError(f"asset {aid!r} is not in the library")
            return FakeRecord()

        def mesh(self, aid):
            return PrimResolver().mesh("kit_boat")

    r = DefaultResolver(library=FakeLibrary())
    assert r.ue_path("lib_x") == "/Game/Lib/SM_X" and r.category("lib_x") == "boat"
    assert r.mesh_path("lib_x") == Path("/lib/x.glb")
    assert r.mesh("lib_x").extents == pytest.approx(DIMS["kit_boat"])
    with pytest.raises(LibraryError, match=r"no_such_asset.*--library"):
        r.mesh("no_such_asset")
    try:
        from coastforge.assets.kit import kit_assets

        kit_id = kit_assets()[0].id
    except Exception as exc:  # noqa: BLE001 - the kit is another module's; skip until installed
        pytest.skip(f"starter kit not available: {exc}")
    assert r.ue_path(kit_id) is None and r.mesh_path(kit_id).suffix == ".glb"
    assert len(r.mesh(kit_id).faces) > 0


def test_grid_resampling_matches_scipy_and_weight_maps_sum():
    from scipy.ndimage import map_coordinates

    from coastforge.export.terrain_mesh import (class_weight_maps_u8, class_weights, grid_bilinear, vertex_grid,
                                                weights_to_u8)

    rng = np.random.default_rng(3)
    src = rng.normal(size=(37, 53)).astype(np.float32)
    rows = np.linspace(-0.5, 36.5, 300)
    cols = np.linspace(-0.5, 52.5, 123)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    want = map_coordinates(src.astype(np.float64), [rr, cc], order=1, mode="nearest")
    assert np.abs(grid_bilinear(src, rows, cols, block=7) - want).max() < 1e-9
    s = make_scene()
    cls = s.classes.copy()
    cls[20:30, 40:50] = rng.integers(0, 8, size=(10, 10))
    s = Scene(name="w", seed=0, gsd_m=1.0, extent_m=s.extent_m, height=s.height, classes=cls)
    w = class_weights(s, 90, 70)
    gx, gy = vertex_grid(s.extent_m, 90, 70)
    assert np.abs(w.sum(0) - 1).max() < 1e-5 and w[0][sample_class(s, gx, gy) == 0].max() > 0.99
    maps, kept = class_weight_maps_u8(s, 90, 70, keep=(0, 3))
    assert (maps.sum(0, dtype=np.int32) == 255).all()
    assert np.abs(maps.astype(int) - weights_to_u8(w).astype(int)).max() <= 8  # same rule, float32 ties aside
    assert kept[3].dtype == np.uint8 and np.abs(kept[3].astype(int) - np.round(w[3] * 255)).max() <= 1
