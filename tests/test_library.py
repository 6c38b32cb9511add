"""Asset library: manifests, normalisation of real models, views, FAISS index, rebuilds, bad input, CLI."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from coastforge.assets.library import (AssetRecord, Library, build_library, default_library, guess_category,
                                       read_manifest)
from coastforge.assets.meshes import load_mesh, normalise_mesh
from coastforge.config import LibraryConfig
from coastforge.errors import LibraryError, OutputExistsError
from coastforge.fsio import read_png

# one lighting on water, no extra scales: keeps these tests fast (the full 3 x 2 runs in one test)
SMALL = LibraryConfig(lightings=1, backgrounds=("water",), embed_scales=(1.0,), view_size_px=64, paint_variants=False)

QUAT = {  # file stem -> (id, category, real size field, value)
    "Ship_pack__Boat": ("boat", "boat", "length_m", 5.0),
    "Ship_pack__Lifeboat": ("lifeboat", "boat", "length_m", 7.0),
    "Ship_pack__CruiseShip": ("cruise_ship", "boat", "length_m", 250.0),
    "Basic_Car_Pack__Taxi": ("taxi", "vehicle", "length_m", 4.6),
    "Basic_Car_Pack__RaceCar": ("race_car", "vehicle", "length_m", 4.4),
    "Nature_Pack_Essentials_vol.3__Tree1": ("tree1", "tree", "height_m", 8.0),
    "Nature_Pack_Essentials_vol.3__Rock1": ("rock1", "rock", "length_m", 2.0),
}


def _boat_mesh(length=6.0, beam=2.0, height=1.0, colour=(200, 40, 40)) -> trimesh.Trimesh:
    """A pointed hull (bow at +x), z up, metres."""
    ring = np.array([[-length / 2, -beam / 2], [length / 4, -beam / 2], [length / 2, 0.0], [length / 4, beam / 2],
                     [-length / 2, beam / 2]])
    poly = __import__("shapely.geometry", fromlist=["Polygon"]).Polygon(ring)
    m = trimesh.creation.extrude_polygon(poly, height)
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def _car_mesh(colour=(40, 60, 200)) -> trimesh.Trimesh:
    body = trimesh.creation.box(extents=(4.5, 1.9, 0.9))
    body.apply_translation([0, 0, 0.45])
    cabin = trimesh.creation.box(extents=(2.0, 1.7, 0.6))
    cabin.apply_translation([-0.5, 0, 1.2])
    m = trimesh.util.concatenate([body, cabin])
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def _write(mesh: trimesh.Trimesh, path: Path, y_up: bool = False) -> Path:
    m = mesh.copy()
    if y_up:  # glTF convention: scene (x, y, z) -> (x, z, -y)
        m.apply_transform(np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], float))
    path.write_bytes(m.export(file_type=path.suffix[1:]))
    return path


def _manifest(tmp: Path, entries: list[dict], name: str = "manifest.json") -> Path:
    p = tmp / name
    p.write_text(json.dumps({"assets": entries}))
    return p


@pytest.fixture()
def two_assets(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    _write(_boat_mesh(), src / "boat.glb", y_up=True)
    _write(_car_mesh(), src / "car.glb", y_up=True)
    man = _manifest(src, [
        {"id": "red_boat", "category": "boat", "mesh": "boat.glb", "length_m": 6.0, "ue_path": "/Game/B/SM_Boat"},
        {"id": "blue_car", "category": "vehicle", "mesh": "car.glb", "up_axis": "+y", "forward_axis": "+x"},
    ])
    return man


# --------------------------------------------------------------------------- real models


@pytest.mark.shared_data
def test_quaternius_models_normalised_upright_forward(shared_data, tmp_path):
    qdir = shared_data / "models" / "quaternius"
    if not qdir.is_dir():
        pytest.skip(f"{qdir} not found")
    src = tmp_path / "src"
    src.mkdir()
    entries = []
    for stem, (aid, cat, key, val) in QUAT.items():
        shutil.copyfile(qdir / f"{stem}.glb", src / f"{stem}.glb")  # links to outside the folder are refused
        entries.append({"id": aid, "category": cat, "mesh": f"{stem}.glb", key: val})
    # a car without a real size: its unit (cm) must be guessed
    shutil.copyfile(qdir / "Basic_Car_Pack__BasicCar.glb", src / "Basic_Car_Pack__BasicCar.glb")
    entries.append({"id": "basic_car", "category": "vehicle", "mesh": "Basic_Car_Pack__BasicCar.glb"})
    lib = build_library(_manifest(src, entries), tmp_path / "lib", config=SMALL, workers=1)
    assert not lib.build_report.skipped
    assert len(lib.assets) == len(entries)
    for aid, _cat, key, val in QUAT.values():
        a = lib.asset(aid)
        got = a.dims_m[2] if key == "height_m" else max(a.dims_m[:2])
        assert abs(got - val) <= 0.05 * val, (aid, a.dims_m, val)
        mesh = lib.mesh(aid)
        v = mesh.vertices
        if cat in ("boat", "vehicle"):
            # upright (lower than long) and forward along +x (the long horizontal axis is x)
            assert a.dims_m[2] < a.dims_m[0] and a.dims_m[1] < a.dims_m[0], (aid, a.dims_m)
            # the widest part is near the top (deck / body), not the keel or the wheels' contact points
            h = a.dims_m[2]
            assert np.ptp(v[v[:, 2] < v[:, 2].min() + 0.1 * h][:, 1]) < np.ptp(v[:, 1])
        if cat == "boat":
            # bow (narrower end) towards +x
            L = a.dims_m[0]
            front = v[v[:, 0] > 0.35 * L][:, 1]
            back = v[v[:, 0] < -0.35 * L][:, 1]
            assert np.ptp(front) < np.ptp(back), aid
            # floating: z = 0 at the waterline, hull below it by the draft
            assert a.floating and a.draft_m > 0
            assert v[:, 2].min() == pytest.approx(-a.draft_m, abs=1e-3)
        if cat == "tree":
            # upright tree: the trunk (bottom) is narrow, the canopy (top) wide
            h = a.dims_m[2]
            low, high = v[v[:, 2] < 0.1 * h], v[v[:, 2] > 0.5 * h]
            assert np.ptp(low[:, 0]) < 0.5 * np.ptp(high[:, 0])
    basic = lib.asset("basic_car")
    assert 4.0 <= basic.dims_m[0] <= 5.0  # README: cars 4-5 m; the model is in centimetres
    assert any("unit guessed as cm" in n for n in lib.build_report.notes["basic_car"])
    # views: top-down, the boat's bow to the right of the image: the hull colour is further right than left
    img, gsd = lib.view("boat", 0, "water")
    assert img.shape == (64, 64, 3) and gsd == lib.asset("boat").view_gsd_m


def test_detects_z_up_and_forward_of_a_rotated_boat(tmp_path):
    boat = _boat_mesh(length=8.0, beam=2.5, height=1.5)
    # z-up file with the bow along -y: nothing in the manifest says so
    rot = trimesh.transformations.rotation_matrix(-np.pi / 2, [0, 0, 1])
    boat.apply_transform(rot)
    _write(boat, tmp_path / "boat.glb")
    raw = load_mesh(tmp_path / "boat.glb")
    m, norm = normalise_mesh(raw, "boat", suffix=".glb")
    assert norm.up_axis == "+z"  # against the glTF y-up convention, from the boat's flat shape
    assert norm.forward_axis == "-y"
    assert m.extents[0] == pytest.approx(8.0, rel=1e-3)
    v = m.vertices
    assert np.ptp(v[v[:, 0] > 3.0][:, 1]) < np.ptp(v[v[:, 0] < -3.0][:, 1])
    assert any("up axis" in n for n in norm.notes) and any("bow" in n for n in norm.notes)


# --------------------------------------------------------------------------- build, views, index, query


def test_build_full_views_query_and_library_json(two_assets, tmp_path):
    cfg = LibraryConfig(view_size_px=64, embed_scales=(1.0, 2.0))
    lib = build_library(two_assets, tmp_path / "lib", config=cfg, workers=1)
    doc = json.loads((tmp_path / "lib" / "library.json").read_text())
    assert doc["format"] == "coastforge.library/1"
    assert doc["embedder"]["name"] == "default" and doc["index"]["kind"] == "faiss.IndexFlatIP"
    a = lib.asset("red_boat")
    assert isinstance(a, AssetRecord) and a.ue_path == "/Game/B/SM_Boat" and a.category == "boat"
    assert len(a.views) == 6 and {c.split("_")[1] for c in a.view_conditions} == {"water", "ground"}
    for p in a.views:
        assert p.is_file() and read_png(p).shape == (64, 64, 3)
    rec = doc["assets"][0]
    assert {"id", "category", "dims_m", "ue_path", "mesh", "views", "draft_m", "floating", "hashes"} <= set(rec)
    assert lib.asset("blue_car").dims_m == pytest.approx((4.5, 1.9, 1.5), rel=1e-3)
    # the boat keeps its given length; the car was in metres already
    assert a.dims_m[0] == pytest.approx(6.0, rel=1e-3)
    # a view of each asset finds itself, and the category filter works
    for aid in ("red_boat", "blue_car"):
        img, gsd = lib.view(aid, 2, "ground")
        assert lib.query(img, gsd, k=2)[0][0] == aid
    img, gsd = lib.view("red_boat", 0, "water")
    assert [h[0] for h in lib.query(img, gsd, k=5, category="vehicle")] == ["blue_car"]
    # paintable assets (vehicles, small boats) are also embedded repainted: a red car still finds the car
    rec = {r["id"]: r for r in doc["assets"]}
    assert len(rec["blue_car"]["paint_views"]) == 7 and len(rec["red_boat"]["paint_views"]) == 7
    # query-like views: the 4.5 m car (views at 0.2 m/px) is under 40 px long at 0.28 and 0.4 m/px; those
    # stand in for the 2x downsampled copies (0.4 m/px), which are left out. Per GSD: the 3 lightings x 2
    # backgrounds, and 2 random lightings per background; then 2 crowded views (in a parking row) at 0.1 and
    # 0.2 m/px each
    qv = rec["blue_car"]["query_views"]
    solo = [q for q in qv if not q.get("crowded")]
    assert sorted({q["gsd_m"] for q in solo}) == [0.28, 0.4] and len(solo) == 2 * (6 + 4)
    assert sum(q["lighting"] == "random" for q in solo) == 2 * 4
    crowded = [(q["gsd_m"], q["background"]) for q in qv if q.get("crowded")]
    assert crowded == [(0.1, "ground")] * 2 + [(0.2, "ground")] * 2
    assert (tmp_path / "lib" / rec["blue_car"]["query_views_file"]).is_file()
    assert rec["blue_car"]["index_rows"][1] == (6 + 7) + len(qv)
    from coastforge.assets.library import repaint
    from coastforge.render import render_mesh_view, standard_view_lightings

    red_car = render_mesh_view(repaint(lib.mesh("blue_car"), (200, 30, 30)), 0.1, 80,
                               standard_view_lightings()[0], "ground", yaw_deg=33)
    assert lib.query(red_car, 0.1, k=1)[0][0] == "blue_car"
    with pytest.raises(LibraryError, match="unknown category"):
        lib.search(lib.embed([img], [gsd]), 1, category="spaceship")
    # reload from disk gives the same search results
    again = Library.load(tmp_path / "lib")
    v = again.embed([img], [gsd])
    assert again.search(v, 2) == lib.search(v, 2)


def test_rebuild_rerenders_only_changed_assets(two_assets, tmp_path):
    out = tmp_path / "lib"
    first = build_library(two_assets, out, config=SMALL, workers=1)
    assert set(first.build_report.rendered) == {"red_boat", "blue_car"}
    view = first.asset("blue_car").views[0]
    mtime = view.stat().st_mtime_ns
    second = build_library(two_assets, out, config=SMALL, workers=1)
    assert second.build_report.rendered == () and set(second.build_report.reused) == {"red_boat", "blue_car"}
    assert second.build_report.embedded == ()
    assert view.stat().st_mtime_ns == mtime
    # change one asset's settings: only it is re-rendered
    doc = json.loads(two_assets.read_text())
    doc["assets"][0]["length_m"] = 7.0
    two_assets.write_text(json.dumps(doc))
    third = build_library(two_assets, out, config=SMALL, workers=1)
    assert third.build_report.rendered == ("red_boat",)
    assert third.asset("red_boat").dims_m[0] == pytest.approx(7.0, rel=1e-3)
    assert view.stat().st_mtime_ns == mtime
    # change a mesh file: only it is re-rendered
    _write(_car_mesh(colour=(250, 250, 0)), two_assets.parent / "car.glb", y_up=True)
    fourth = build_library(two_assets, out, config=SMALL, workers=1)
    assert fourth.build_report.rendered == ("blue_car",)


def test_parallel_build_matches_serial(two_assets, tmp_path):
    a = build_library(two_assets, tmp_path / "a", config=SMALL, workers=1)
    b = build_library(two_assets, tmp_path / "b", config=SMALL, workers=2)
    assert [x.id for x in a.assets] == [x.id for x in b.assets]
    np.testing.assert_allclose(a.index.vectors(), b.index.vectors(), atol=1e-5)


def test_no_fork_after_a_ray_cast():
    """After a render (embree ray casts), embree's TBB pool has native threads: build workers must not be
    forked then (a child forked while one held a lock hung in its first ray cast). Before one, a plain script
    still forks (so it needs no ``if __name__ == "__main__"`` guard). Checked in fresh interpreters."""
    import subprocess
    import sys

    head = ("import threading, trimesh; from coastforge.assets.library.build import _start_method; "
            "from coastforge.render import render_mesh_view, standard_view_lightings; ")
    render = "render_mesh_view(trimesh.creation.box(), 0.1, 32, standard_view_lightings()[0], 'water'); "
    for body, want in (("", "fork"), (render, "spawn")):
        code = head + body + "print(threading.active_count(), _start_method())"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert out.stdout.split() == ["1", want]


def test_parallel_build_from_a_background_thread_does_not_fork(two_assets, tmp_path):
    """generate builds the starter kit in a worker thread; forking there deadlocked on a held import lock."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    from coastforge.assets.library.build import _start_method

    assert threading.active_count() >= 1
    with ThreadPoolExecutor(1) as ex:
        assert ex.submit(_start_method).result() == "spawn"
        lib = ex.submit(build_library, two_assets, tmp_path / "c", config=SMALL, workers=2).result(timeout=300)
    ref = build_library(two_assets, tmp_path / "d", config=SMALL, workers=1)
    np.testing.assert_allclose(lib.index.vectors(), ref.index.vectors(), atol=1e-5)


# --------------------------------------------------------------------------- bad input


def test_bad_assets_are_reported_and_skipped_or_strict(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    _write(_boat_mesh(), src / "boat.glb")
    (src / "broken.glb").write_bytes(b"not a glb at all")
    (src / "empty.obj").write_text("# nothing\n")
    (tmp_path / "outside.glb").write_bytes((src / "boat.glb").read_bytes())
    entries = [
        {"id": "good", "category": "boat", "mesh": "boat.glb", "up_axis": "+z"},
        {"id": "good", "category": "boat", "mesh": "boat.glb"},
        {"id": "ufo", "category": "spaceship", "mesh": "boat.glb"},
        {"id": "escape", "category": "boat", "mesh": "../outside.glb"},
        {"id": "absolute", "category": "boat", "mesh": str(src / "boat.glb")},
        {"id": "broken", "category": "boat", "mesh": "broken.glb"},
        {"id": "empty", "category": "rock", "mesh": "empty.obj"},
        {"id": "missing", "category": "rock", "mesh": "nope.glb"},
        {"id": "bad id!", "category": "rock", "mesh": "boat.glb"},
        {"id": "typo", "category": "rock", "mesh": "boat.glb", "lenght_m": 3},
    ]
    man = _manifest(src, entries)
    lib = build_library(man, tmp_path / "lib", config=SMALL, workers=1)
    assert [a.id for a in lib.assets] == ["good"]
    errors = {s.id: s.error for s in lib.build_report.skipped}
    assert "duplicate id" in errors["good"]
    assert "unknown category 'spaceship'" in errors["ufo"]
    assert "escapes the manifest folder" in errors["escape"]
    assert "absolute" in errors["absolute"]
    assert "broken" in errors["broken"] and "cannot read mesh" in errors["broken"]
    assert "'empty'" in errors["empty"] and ("no triangles" in errors["empty"] or "cannot read" in errors["empty"])
    assert "does not exist" in errors["missing"]
    assert "invalid" in errors["bad id!"]
    assert "lenght_m" in errors["typo"]
    with pytest.raises(LibraryError, match="strict"):
        build_library(man, tmp_path / "lib2", config=SMALL, workers=1, strict=True)
    assert not (tmp_path / "lib2" / "library.json").exists()
    with pytest.raises(LibraryError, match="no usable assets"):
        build_library(_manifest(src, entries[2:4], "bad.json"), tmp_path / "lib3", config=SMALL, workers=1)
    bad = src / "x.json"
    bad.write_text("{}")
    with pytest.raises(LibraryError, match="top-level 'assets'"):
        read_manifest(bad)


def test_corrupted_and_mismatched_library(two_assets, tmp_path):
    out = tmp_path / "lib"
    build_library(two_assets, out, config=SMALL, workers=1)
    idx = out / "index.faiss"
    good = idx.read_bytes()
    idx.write_bytes(good[:-16] + b"\0" * 16)
    with pytest.raises(LibraryError, match="does not match the hash"):
        Library.load(out)
    idx.write_bytes(b"garbage")
    doc = json.loads((out / "library.json").read_text())
    doc["index"].pop("sha256")
    (out / "library.json").write_text(json.dumps(doc))
    with pytest.raises(LibraryError, match="unreadable"):
        Library.load(out)
    idx.write_bytes(good)
    doc["assets"][0]["index_rows"][1] += 1
    doc["index"]["rows"] += 1
    (out / "library.json").write_text(json.dumps(doc))
    with pytest.raises(LibraryError, match="rebuild"):
        Library.load(out)
    (out / "library.json").write_text("{ not json")
    with pytest.raises(LibraryError, match="not readable JSON"):
        Library.load(out)
    with pytest.raises(LibraryError, match="not an asset library"):
        Library.load(tmp_path)
    # a non-empty folder that is not a library is not overwritten silently
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "notes.txt").write_text("mine")
    with pytest.raises(OutputExistsError):
        build_library(two_assets, junk, config=SMALL, workers=1)


def test_refuses_another_embedder(two_assets, tmp_path):
    lib = build_library(two_assets, tmp_path / "lib", config=SMALL, workers=1)
    with pytest.raises(LibraryError, match="built with the 'default' embedder, not 'dinov3'"):
        Library.load(tmp_path / "lib", embedder="dinov3")

    class Other:
        name, settings, dim = "default", {"version": 99}, lib.index.dim

    with pytest.raises(LibraryError, match="embedded with"):
        lib.check_embedder(Other())
    with pytest.raises(LibraryError, match="another embedder"):
        lib.search(np.ones((1, 7), np.float32), 1)


def test_library_of_an_older_embedder_version_asks_for_a_rebuild(two_assets, tmp_path):
    out = tmp_path / "lib"
    build_library(two_assets, out, config=SMALL, workers=1)
    doc = json.loads((out / "library.json").read_text())
    doc["embedder"]["settings"]["version"] -= 1  # what a library built before the embedder changed holds
    for a in doc["assets"]:
        a["hashes"]["embedding"] = "0" * 64
    (out / "library.json").write_text(json.dumps(doc))
    old = Library.load(out)
    img, gsd = old.view("red_boat", 0, "water")
    with pytest.raises(LibraryError, match=r"version \d+ of the 'default' embedder.*rebuild it"):
        old.query(img, gsd)
    # building again over it re-embeds the stored views (no re-render) and the library answers again
    again = build_library(two_assets, out, config=SMALL, workers=1)
    assert again.build_report.rendered == () and set(again.build_report.embedded) == {"red_boat", "blue_car"}
    assert again.query(img, gsd, k=1)[0][0] == "red_boat"


def _buoy_mesh(diameter=0.6, height=0.8, colour=(220, 40, 30)) -> trimesh.Trimesh:
    m = trimesh.creation.cylinder(radius=diameter / 2, height=height, sections=24)
    m.apply_translation([0, 0, height / 2])
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def test_query_views_of_small_assets(tmp_path, monkeypatch):
    """Assets a few pixels long at a configured GSD are also rendered there (random yaw, cropped like the
    matcher's crops), stored in one file, reused on rebuilds and re-embedded from disk."""
    from coastforge.assets import embed as E
    from coastforge.assets.library import query_view_plan, read_query_views
    from coastforge.render import render_mesh_view, standard_view_lightings

    src = tmp_path / "src"
    src.mkdir()
    _write(_buoy_mesh(), src / "buoy.glb", y_up=True)
    _write(_boat_mesh(), src / "boat.glb", y_up=True)
    man = _manifest(src, [{"id": "buoy", "category": "buoy", "mesh": "buoy.glb"},
                          {"id": "red_boat", "category": "boat", "mesh": "boat.glb", "length_m": 6.0}])
    cfg = LibraryConfig(lightings=1, backgrounds=("water",), embed_scales=(1.0, 2.0), view_size_px=64,
                        paint_variants=False, query_view_gsds_m=(0.1, 0.2, 0.4), query_view_max_px=20,
                        query_view_random_lightings=0, crowded_views=0)
    out = tmp_path / "lib"
    lib = build_library(man, out, config=cfg, workers=1)
    doc = {a["id"]: a for a in json.loads((out / "library.json").read_text())["assets"]}
    buoy, boat = doc["buoy"], doc["red_boat"]
    # the 0.6 m buoy is under 20 px at every configured GSD; the 6 m boat only at 0.4 m/px (15 px)
    assert [q["gsd_m"] for q in buoy["query_views"]] == [0.1, 0.2, 0.4]
    assert [q["gsd_m"] for q in boat["query_views"]] == [0.4]
    plan = query_view_plan(lib.asset("buoy").dims_m, buoy["view_gsd_m"], cfg)
    assert [g for g, _ in plan] == [0.1, 0.2, 0.4]
    assert [side for _, side in plan] == [13, 12, 12]  # 1.5 x the size + 4 px, at least 12 px
    imgs = read_query_views(out / buoy["query_views_file"], 3)
    assert [i.shape for i in imgs] == [(side, side, 3) for _, side in plan]
    assert len({q["yaw_deg"] for q in buoy["query_views"]}) == 3  # random yaws
    # rows: the view and its 2x copy (finer than the query-like views), then the three query-like views
    assert buoy["index_rows"][1] == 2 + 3
    # the boat's 2x copy (0.4 m/px) is left out: its query-like view stands for that scale
    assert boat["index_rows"][1] == 1 + 1
    # a 2 px buoy in a query finds the buoy
    q = render_mesh_view(lib.mesh("buoy"), 0.3, 12, standard_view_lightings()[2], "water", yaw_deg=40, seed=5)
    assert lib.query(q, 0.3, k=1)[0][0] == "buoy"
    # rebuilt unchanged: nothing re-rendered; the file gone: that asset is re-rendered
    assert build_library(man, out, config=cfg, workers=1).build_report.rendered == ()
    (out / buoy["query_views_file"]).unlink()
    assert build_library(man, out, config=cfg, workers=1).build_report.rendered == ("buoy",)
    # another embedder setting: the stored views (query-like ones included) are re-embedded, not re-rendered
    monkeypatch.setattr(E.DefaultEmbedder, "WEIGHTS", {**E.DefaultEmbedder.WEIGHTS, "lbp": 0.5})
    again = build_library(man, out, config=cfg, workers=1)
    assert again.build_report.rendered == () and set(again.build_report.embedded) == {"buoy", "red_boat"}
    fresh = build_library(man, tmp_path / "fresh", config=cfg, workers=1)
    np.testing.assert_allclose(again.index.vectors(), fresh.index.vectors(), atol=1e-5)
    # bad configuration names the field
    with pytest.raises(LibraryError, match="query_view_gsds_m"):
        query_view_plan((1.0, 1.0, 1.0), 0.05, LibraryConfig(query_view_gsds_m=(0.1, -0.2)))


def test_query_views_under_random_lightings():
    """Each GSD also gets randomly lit query-like views (water colour, sun, haze) per background, the same on
    every build; a negative count is refused by name."""
    from coastforge.assets.library import render_query_views

    mesh = _buoy_mesh()
    cfg = LibraryConfig(lightings=1, query_view_gsds_m=(0.2,), query_view_random_lightings=3)
    views = render_query_views(mesh, "buoy", (0.6, 0.6, 1.0), 0.05, cfg)
    meta = [m for _, m in views]
    assert [(m["lighting"], m["background"]) for m in meta] == \
        [(0, "water"), (0, "ground")] + [("random", "water")] * 3 + [("random", "ground")] * 3
    water = [img for img, m in views if m["background"] == "water"]
    # the random lightings change the water's colour: the views' backgrounds differ
    rings = [np.concatenate([i[0], i[-1]]).reshape(-1, 3).mean(0) for i in water]
    assert max(np.abs(r - rings[0]).max() for r in rings[1:]) > 10
    again = render_query_views(mesh, "buoy", (0.6, 0.6, 1.0), 0.05, cfg)
    assert all(np.array_equal(a[0], b[0]) and a[1] == b[1] for a, b in zip(views, again))
    with pytest.raises(LibraryError, match="query_view_random_lightings"):
        render_query_views(mesh, "buoy", (0.6, 0.6, 1.0), 0.05, LibraryConfig(query_view_random_lightings=-1))


def test_crowded_views_show_the_asset_between_copies_of_itself():
    """Vehicles and boats (up to 25 m) also get views between copies of themselves, as parked or berthed,
    centred on the middle one; other categories and huge boats do not; bad settings are refused by name."""
    from coastforge.assets.library import crowd_mesh, render_query_views
    from coastforge.render import render_mesh_view, standard_view_lightings
    from coastforge.rng import stage_rng

    car = _boat_mesh(length=4.5, beam=1.8, height=1.4, colour=(30, 60, 160))
    b = car.bounds
    centre = (0.5 * (b[0, 0] + b[1, 0]), 0.5 * (b[0, 1] + b[1, 1]))
    rng = stage_rng(0, "test-crowd")
    lateral = []
    for _ in range(20):
        crowd, c = crowd_mesh(car, "vehicle", (4.5, 1.8, 1.4), rng)
        assert c == pytest.approx(centre)
        n = len(crowd.faces) // len(car.faces)
        assert 1 <= n <= 4 and len(crowd.faces) == n * len(car.faces)
        lateral.append(crowd.bounds[1, 1] - crowd.bounds[0, 1])
    # neighbours stand beside it with a gap (wider than the car by more than its width), at least once
    assert max(lateral) > 2 * 1.8 + 0.4
    cfg = LibraryConfig(lightings=1, query_view_gsds_m=(), crowded_views=2, crowded_gsds_m=(0.1, 0.2))
    views = render_query_views(car, "car", (4.5, 1.8, 1.4), 0.05, cfg, "vehicle")
    assert [(m["gsd_m"], m["background"], m.get("crowded")) for _, m in views] == \
        [(0.1, "ground", True)] * 2 + [(0.2, "ground", True)] * 2
    img, meta = views[0]
    assert img.shape == (72, 72, 3)  # cropped like a query: 1.5 x the length + 4 px
    # the middle car is at the centre: its blue body is there, as in a lone render at that yaw
    lone = render_mesh_view(car, 0.1, 72, standard_view_lightings()[1], "ground", yaw_deg=meta["yaw_deg"])
    assert img[36, 36, 2] > img[36, 36, 0] + 40 and lone[36, 36, 2] > lone[36, 36, 0] + 40
    # the same views on every build
    again = render_query_views(car, "car", (4.5, 1.8, 1.4), 0.05, cfg, "vehicle")
    assert all(np.array_equal(a[0], b[0]) and a[1] == b[1] for a, b in zip(views, again))
    assert render_query_views(car, "bush", (4.5, 1.8, 1.4), 0.05, cfg, "tree") == []
    assert render_query_views(car, "ship", (40.0, 8.0, 6.0), 0.4, cfg, "boat") == []
    with pytest.raises(LibraryError, match="crowded_views"):
        render_query_views(car, "car", (4.5, 1.8, 1.4), 0.05, LibraryConfig(crowded_views=-1), "vehicle")
    with pytest.raises(LibraryError, match="crowded_gsds_m"):
        render_query_views(car, "car", (4.5, 1.8, 1.4), 0.05, LibraryConfig(crowded_gsds_m=(0.1, 0.0)),
                           "vehicle")


# --------------------------------------------------------------------------- folders, thumbnails, CLI, kit


def test_folder_scan_guesses_categories(tmp_path):
    src = tmp_path / "models"
    (src / "Vehicles").mkdir(parents=True)
    _write(_boat_mesh(), src / "Ship_pack__Boat.glb", y_up=True)
    _write(_car_mesh(), src / "Vehicles" / "thing_01.glb", y_up=True)
    _write(_car_mesh(), src / "mystery.glb", y_up=True)
    lib = build_library(src, tmp_path / "lib", config=SMALL, workers=1)
    cats = {a.id: a.category for a in lib.assets}
    assert cats == {"Ship_pack__Boat": "boat", "thing_01": "vehicle"}
    (skip,) = lib.build_report.skipped
    assert skip.id == "mystery" and "cannot guess its category" in skip.error
    assert any("folder word 'vehicles'" in n for n in lib.build_report.notes["thing_01"])
    assert guess_category("Nature_Pack__Grass3")[0] == "grass"
    assert guess_category("CruiseShip")[0] == "boat"
    assert guess_category("SM_CopCar")[0] == "vehicle"


def test_from_thumbnails(tmp_path):
    from coastforge.fsio import write_png
    from coastforge.render import render_mesh_view, standard_view_lightings

    thumbs = tmp_path / "thumbs"
    entries = []
    for name, mesh, cat in (("SM_Speedboat", _boat_mesh(), None), ("SM_Thing", _car_mesh(), "vehicle")):
        views = []
        for k, light in enumerate(standard_view_lightings()[:1]):
            for bg in ("water", "ground"):
                rel = f"{name}/l{k}_{bg}.png"
                write_png(thumbs / rel, render_mesh_view(mesh, 0.1, 96, light, bg))
                views.append({"file": rel, "lighting": k, "background": bg})
        ext = (mesh.extents * 50.0).tolist()  # half extents in cm, Unreal X forward
        entries.append({"name": name, "asset_path": f"/Game/Props/{name}.{name}", "category": cat, "tags": [],
                        "bounds_cm": {"origin": [0, 0, ext[2]], "box_extent": ext}, "gsd_m": 0.1, "views": views})
    (thumbs / "thumbnails.json").write_text(json.dumps({"format": "coastforge.thumbnails/1", "assets": entries}))
    lib = build_library(None, tmp_path / "lib", from_thumbnails=thumbs, config=SMALL, workers=1)
    boat = lib.asset("SM_Speedboat")
    assert boat.category == "boat" and boat.ue_path == "/Game/Props/SM_Speedboat.SM_Speedboat"
    assert boat.dims_m == pytest.approx((6.0, 2.0, 1.0), rel=1e-3) and boat.mesh_path is None
    assert lib.mesh("SM_Thing").extents == pytest.approx(lib.asset("SM_Thing").dims_m, rel=1e-6)
    img = read_png(thumbs / "SM_Thing" / "l0_ground.png")
    assert lib.query(img, 0.1, k=1)[0][0] == "SM_Thing"
    with pytest.raises(LibraryError, match=r"no thumbnails.json"):
        build_library(None, tmp_path / "lib2", from_thumbnails=tmp_path, config=SMALL)


def test_unreal_capture_script_is_shipped():
    from coastforge.assets.unreal import CAPTURE_SCRIPT

    text = CAPTURE_SCRIPT.read_text()
    compile(text, str(CAPTURE_SCRIPT), "exec")  # valid Python (it runs only inside Unreal)
    for name in ("SceneCapture2D", "CameraProjectionMode.ORTHOGRAPHIC", "ortho_width", "capture_scene",
                 "export_render_target", "get_selected_assets", "thumbnails.json", "coastforge.thumbnails/1"):
        assert name in text


def test_cli_build_and_query_json(two_assets, tmp_path):
    from click.testing import CliRunner

    from coastforge.cli import cli
    from coastforge.fsio import write_png

    out = tmp_path / "lib"
    r = CliRunner().invoke(cli, ["library", "build", str(two_assets), "--out", str(out), "--workers", "1",
                                 "--set", "library.lightings=1", "--set", 'library.backgrounds=["water"]',
                                 "--set", "library.view_size_px=64", "--json"])
    assert r.exit_code == 0, r.output
    rep = json.loads(r.output)
    assert set(rep["rendered"]) == {"red_boat", "blue_car"}
    lib = Library.load(out)
    img, gsd = lib.view("blue_car", 0, "water")
    write_png(tmp_path / "crop.png", img)
    r = CliRunner().invoke(cli, ["library", "query", str(out), str(tmp_path / "crop.png"), "--gsd", str(gsd),
                                 "--k", "2", "--json"])
    assert r.exit_code == 0, r.output
    res = json.loads(r.output)["results"]
    assert res[0]["asset_id"] == "blue_car" and res[0]["category"] == "vehicle"
    assert len(res) == 2 and res[0]["score"] >= res[1]["score"]
    r = CliRunner().invoke(cli, ["library", "query", str(out), str(tmp_path / "crop.png"), "--gsd", "0.1",
                                 "--embedder", "dinov3"])
    assert r.exit_code == 2 and "built with the 'default' embedder" in r.output
    r = CliRunner().invoke(cli, ["library", "build", str(tmp_path / "nothing.json"), "--out", str(tmp_path / "x")])
    assert r.exit_code == 2 and "does not exist" in r.output


def test_default_library_is_the_kit_built_once(tmp_path, monkeypatch):
    from coastforge.assets.library import cache as L
    from coastforge.assets.kit import kit_assets

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("COASTFORGE_CACHE", raising=False)
    monkeypatch.setattr(L, "_DEFAULT", {})
    lib = default_library(SMALL)
    assert {a.id for a in lib.assets} == {a.id for a in kit_assets()}
    root = lib.root
    assert root.parent == tmp_path / "cache" / "coastforge" and root.name.startswith("kit-")
    assert not [p for p in root.parent.iterdir() if p.name.startswith(".kit-")]  # no temp folder left
    # the kit keeps its waterline: a floating boat's hull reaches below z = 0 by its draft
    dinghy = lib.asset("dinghy")
    assert lib.mesh("dinghy").vertices[:, 2].min() < 0 and dinghy.floating
    monkeypatch.setattr(L, "_DEFAULT", {})

    def no_build(*a, **k):
        raise AssertionError("the cached kit library must be reused, not rebuilt")

    monkeypatch.setattr(L, "build_library", no_build)
    again = default_library(SMALL)
    assert again.root == root and len(again.assets) == len(lib.assets)


def test_unreal_capture_script_output_builds_a_library(tmp_path, monkeypatch):
    """Run the shipped Unreal script against a small fake ``unreal`` module (Unreal cannot run here) and
    build a library from what it writes: the two sides must agree on thumbnails.json."""
    import runpy
    import sys
    import types

    import cv2

    from coastforge.assets.unreal import CAPTURE_SCRIPT

    state = {"spawned": [], "destroyed": [], "bg": (0.0, 0.0, 0.0), "mesh": None, "ortho": None}

    class V:
        def __init__(self, x=0.0, y=0.0, z=0.0):
            self.x, self.y, self.z = x, y, z

    class Rot:
        def __init__(self, roll=0.0, pitch=0.0, yaw=0.0):
            self.roll, self.pitch, self.yaw = roll, pitch, yaw

    class StaticMesh:
        def __init__(self, name, ext):
            self.name, self.ext = name, ext

        def get_name(self):
            return self.name

        def get_path_name(self):
            return f"/Game/Harbour/{self.name}.{self.name}"

        def get_bounds(self):
            return types.SimpleNamespace(origin=V(0, 0, self.ext[2]), box_extent=V(*self.ext))

    class Mid:
        def set_vector_parameter_value(self, name, colour):
            assert name == "Color"
            state["bg"] = (colour.r, colour.g, colour.b)

    class MeshComp:
        def set_static_mesh(self, m):
            if isinstance(m, StaticMesh):
                state["mesh"] = m

        def create_dynamic_material_instance(self, index, material):
            return Mid()

    class CaptureComp:
        def set_editor_property(self, name, value):
            if name == "ortho_width":
                state["ortho"] = value

        def capture_scene(self):
            pass

    class Actor:
        def __init__(self):
            self.static_mesh_component = MeshComp()
            self.capture_component2d = CaptureComp()
            self.light_component = types.SimpleNamespace(set_intensity=lambda v: None)

        def set_actor_scale3d(self, v):
            pass

        def set_actor_location(self, v, sweep, teleport):
            pass

        def set_actor_rotation(self, r, teleport):
            pass

    class ActorSubsystem:
        def spawn_actor_from_class(self, cls, loc, rot):
            a = Actor()
            state["spawned"].append(a)
            return a

        def destroy_actor(self, a):
            state["destroyed"].append(a)

    def export_render_target(world, rt, folder, name):
        # a top-down picture of the mesh's footprint at the capture's scale, on the background colour
        size = rt["size"]
        gsd_cm = state["ortho"] / size
        bg = np.array(state["bg"]) ** (1 / 2.2) * 255
        img = np.tile(bg.astype(np.uint8), (size, size, 1))
        ex, ey = state["mesh"].ext[:2]
        c = size // 2
        hx, hy = int(ex / gsd_cm), int(ey / gsd_cm)
        img[c - hy:c + hy, c - hx:c + hx] = (230, 60, 40) if "Boat" in state["mesh"].name else (40, 60, 220)
        cv2.imwrite(str(Path(folder) / f"{name}.png"), img[:, :, ::-1])

    meshes = {"/Game/Harbour/SM_Boat": StaticMesh("SM_Boat", (300.0, 100.0, 60.0)),
              "/Game/Harbour/SM_Van": StaticMesh("SM_Van", (260.0, 100.0, 110.0))}
    fake = types.ModuleType("unreal")
    fake.Vector, fake.Rotator = V, Rot
    fake.LinearColor = lambda r, g, b, a: types.SimpleNamespace(r=r, g=g, b=b, a=a)
    fake.StaticMesh, fake.StaticMeshActor, fake.DirectionalLight, fake.SceneCapture2D = StaticMesh, Actor, Actor, Actor
    fake.EditorActorSubsystem, fake.UnrealEditorSubsystem = ActorSubsystem, object
    subsystems = {ActorSubsystem: ActorSubsystem(), object: types.SimpleNamespace(get_editor_world=lambda: "world")}
    fake.get_editor_subsystem = lambda cls: subsystems[cls]
    fake.EditorAssetLibrary = types.SimpleNamespace(
        list_assets=lambda folder, recursive=True, include_folder=False: list(meshes),
        load_asset=lambda p: meshes.get(p, object()))
    fake.EditorUtilityLibrary = types.SimpleNamespace(get_selected_assets=lambda: [])
    fake.RenderingLibrary = types.SimpleNamespace(
        create_render_target2d=lambda world, w, h, fmt: {"size": w}, export_render_target=export_render_target)
    fake.CameraProjectionMode = types.SimpleNamespace(ORTHOGRAPHIC="ortho")
    fake.SceneCaptureSource = types.SimpleNamespace(SCS_FINAL_COLOR_LDR="ldr")
    fake.TextureRenderTargetFormat = types.SimpleNamespace(RTF_RGBA8="rgba8")
    fake.log = fake.log_error = lambda msg: None
    monkeypatch.setitem(sys.modules, "unreal", fake)
    out = tmp_path / "thumbs"
    monkeypatch.setattr(sys, "argv", ["capture_thumbnails.py", "--out", str(out), "--folder", "/Game/Harbour",
                                      "--size", "96"])
    runpy.run_path(str(CAPTURE_SCRIPT), run_name="__main__")
    assert len(state["destroyed"]) == len(state["spawned"]) > 0  # everything spawned is removed again
    doc = json.loads((out / "thumbnails.json").read_text())
    assert doc["format"] == "coastforge.thumbnails/1" and len(doc["assets"]) == 2
    assert all(len(a["views"]) == 6 for a in doc["assets"])
    lib = build_library(None, tmp_path / "lib", from_thumbnails=out, config=SMALL, workers=1)
    boat, van = lib.asset("SM_Boat"), lib.asset("SM_Van")
    assert boat.category == "boat" and van.category == "vehicle"  # guessed from the names
    assert boat.dims_m == pytest.approx((6.0, 2.0, 1.2)) and boat.ue_path == "/Game/Harbour/SM_Boat.SM_Boat"
    img = read_png(out / "SM_Van" / "l1_ground.png")
    assert lib.query(img, doc["assets"][1]["gsd_m"], k=1)[0][0] == "SM_Van"


def test_library_glbs_are_gltf_y_up_and_load_back_z_up(tmp_path):
    """Stored meshes follow glTF (y up) so engines import them upright; Library.mesh gives the scene frame."""
    import trimesh

    from coastforge.assets.kit import kit_dir
    from coastforge.assets.library import build_library

    src = tmp_path / "src"
    src.mkdir()
    shutil.copyfile(kit_dir() / "runabout.glb", src / "runabout.glb")
    (src / "manifest.json").write_text(
        '{"assets": [{"id": "runabout", "category": "boat", "mesh": "runabout.glb", "length_m": 6.0}]}')
    lib = build_library(src / "manifest.json", tmp_path / "lib")
    raw = trimesh.load(lib.asset("runabout").mesh_path, force="mesh")
    ext = raw.extents
    assert ext[1] < ext[0] and abs(ext[1] - lib.asset("runabout").dims_m[2]) < 0.1  # height along y
    m = lib.mesh("runabout")
    L, _W, H = lib.asset("runabout").dims_m
    assert abs(m.extents[0] - L) < 0.05 * L and abs(m.extents[2] - H) < 0.05 * H  # back to z up


def test_library_bench_real_crops_skip_with_the_reason(tmp_path):
    """Without the shared data the retrieval benchmark's real part says what is missing instead of failing."""
    from coastforge.bench.library import real_queries

    crops, why = real_queries(tmp_path)
    assert crops == [] and "marina_p0861" in why and "vehicles_p1053" in why


@pytest.mark.shared_data
def test_library_bench_real_crops_carry_their_category(shared_data):
    """The labelled DOTA ships and vehicles become square crops centred on them, with their category."""
    from coastforge.bench.library import real_queries

    crops, why = real_queries(shared_data)
    assert why == ""
    cats = [c for *_x, c in crops]
    assert cats.count("boat") == 105 and cats.count("vehicle") == 4
    for img, gsd, aid, _c in crops:
        h, w = img.shape[:2]
        assert aid is None and gsd in (0.2, 0.125) and h == w and h >= 12 and img.dtype == np.uint8


def test_cover_recolours_the_deck_and_keeps_the_rim():
    from coastforge.assets.library import cover

    # an 8 x 3 x 1 m "hull" (long axis x, z up), subdivided so its top has faces in the middle and at the rim
    boat = trimesh.creation.box((8.0, 3.0, 1.0)).subdivide().subdivide().subdivide()
    boat.visual.face_colors = np.array([250, 250, 250, 255], np.uint8)
    covered = cover(boat, (30, 40, 80))
    fc = np.asarray(covered.visual.face_colors)[:, :3]
    n, ctr = np.asarray(covered.face_normals), np.asarray(covered.triangles_center)
    middle = (n[:, 2] > 0.3) & (np.abs(ctr[:, 0]) < 2.0) & (np.abs(ctr[:, 1]) < 0.5)
    rim = (n[:, 2] > 0.3) & (np.abs(ctr[:, 0]) > 3.4)  # beyond 0.8 of the half-length
    sides = n[:, 2] <= 0.3
    assert middle.any() and rim.any() and sides.any()
    assert (fc[middle] == (30, 40, 80)).all()
    assert (fc[rim] == 250).all() and (fc[sides] == 250).all()
    assert (np.asarray(boat.visual.face_colors)[:, :3] == 250).all()  # the source mesh is left as it was


@pytest.mark.shared_data
def test_quaternius_split_manifests_are_disjoint_and_parse(shared_data, tmp_path):
    from coastforge.train.qlib import HELD, TRAIN, write_sources

    if not (shared_data / "models" / "quaternius").is_dir():
        pytest.skip(f"{shared_data / 'models' / 'quaternius'} not found")
    train, held = write_sources(tmp_path / "qlib")
    ids = {}
    for p in (train, held):
        specs, skipped = read_manifest(p)
        assert not skipped
        ids[p.stem] = {s.id for s in specs}
        assert {"pier_walkway", "pier_finger", "buoy"} <= ids[p.stem]  # a level needs piers and buoys
    q_train, q_held = ids["train"] - ids["held"], ids["held"] - ids["train"]
    assert q_train == {v[0] for v in TRAIN.values()} and q_held == {v[0] for v in HELD.values()}
