"""Bad-input campaign, output side (issue #28): every command's output folder is all-or-nothing, one run
writes a folder at a time, OS errors and our own bugs reach the user as one clear line, and a library
missing a category falls back to the starter kit. Each test builds its own inputs and checks the exit
code, the message and the exact state on disk after the run."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge.cli import cli
from coastforge.demo import example_dir
from coastforge.fsio import STAGING_SUFFIX, FolderLock, _recover, output_folder

GSD = ["--gsd", "0.2"]


def _crop(path: Path, rows: slice, cols: slice) -> Path:
    import cv2

    img = cv2.imread(str(example_dir() / "image.jpg"))
    cv2.imwrite(str(path), img[rows, cols])
    return path


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    d = tmp_path_factory.mktemp("img")
    return _crop(d / "a.png", slice(0, 320), slice(0, 320)), _crop(d / "b.png", slice(-320, None), slice(-320, None))


@pytest.fixture(scope="module")
def scene_a(images, tmp_path_factory):
    """A complete scene folder with a report and two exports (copied per test)."""
    out = tmp_path_factory.mktemp("scene") / "A"
    r = CliRunner().invoke(cli, ["generate", str(images[0]), *GSD, "--out", str(out), "--export", "gltf,sdf"])
    assert r.exit_code == 0, r.output
    return out


def _state(folder: Path) -> dict[str, str]:
    """Relative path -> content hash of every file under ``folder`` (the exact on-disk state)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


class _Result:
    """CliRunner's result with ``output`` unwrapped (rich breaks long lines, paths among them)."""

    def __init__(self, r):
        self.exit_code, self.raw, self.output = r.exit_code, r.output, r.output

    def has(self, text: str) -> bool:
        flat = "".join(self.raw.split())
        return "".join(str(text).split()) in flat


def _run(args: list[str]) -> _Result:
    return _Result(CliRunner().invoke(cli, [str(a) for a in args]))


def _siblings(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.parent.iterdir() if p.name != folder.name and folder.name in p.name)


# ---------------------------------------------------------------- a failed --overwrite keeps the old scene

@pytest.mark.parametrize("why", ["no_library", "not_a_library", "stage_fails"])
def test_a_failed_overwrite_leaves_the_previous_scene_exactly(why, images, scene_a, tmp_path, monkeypatch):
    out = _copy(scene_a, tmp_path / "A")
    before = _state(out)
    args = ["generate", images[1], *GSD, "--out", out, "--overwrite", "--export", "gltf"]
    if why == "no_library":
        args += ["--library", tmp_path / "nosuch"]
        expect = "does not exist"
    elif why == "not_a_library":
        (tmp_path / "notlib").mkdir()
        args += ["--library", tmp_path / "notlib"]
        expect = "not an asset library"
    else:  # a stage fails after files were written: the partial output is kept beside, the scene untouched
        from coastforge.segmentation import outputs

        def broken(*a, **k):
            raise RuntimeError("a bug in a background stage (test)")

        monkeypatch.setattr(outputs, "write_segmentation", broken)
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
        expect = "unexpected RuntimeError"
    r = _run(args)
    assert r.exit_code in (2, 3) and r.has(expect) and not r.has("Traceback")
    assert _state(out) == before  # not one file of the other image
    if why == "stage_fails":
        assert r.has(f"the partial output is in {out}{STAGING_SUFFIX}")
        assert _siblings(out) == ["A" + STAGING_SUFFIX]
        # the next run cleans it up and says so
        r2 = _run(["generate", images[1], *GSD, "--out", tmp_path / "A", "--overwrite", "--no-report"])
        assert r2.exit_code == 3  # still broken, but the old staging was removed first
    else:
        assert _siblings(out) == []  # nothing was written: no staging, no lock


def test_overwrite_replaces_the_whole_folder(images, scene_a, tmp_path):
    out = _copy(scene_a, tmp_path / "A")
    (out / "gltf").is_dir() and (out / "report.html").is_file()
    r = _run(["generate", images[1], *GSD, "--out", out, "--overwrite", "--no-report"])
    assert r.exit_code == 0, r.output
    names = {p.name for p in out.iterdir()}
    assert not ({"gltf", "sdf", "report.html"} & names)  # no stale file from the earlier run survives
    assert "scene.json" in names and _siblings(out) == []


def test_overwrite_refuses_a_folder_coastforge_did_not_make(images, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    r = _run(["generate", images[0], *GSD, "--out", out, "--overwrite", "--no-report"])
    assert r.exit_code == 2 and r.has("coastforge did not write")
    assert _state(out) == {"thesis.tex": hashlib.sha256(b"years of work").hexdigest()}


# ---------------------------------------------------------------- one writer per folder

def test_a_second_writer_fails_at_once_naming_the_first(images, tmp_path):
    out = tmp_path / "A"
    with FolderLock(out, "coastforge generate first.png --out A"):
        t0 = time.perf_counter()
        r = _run(["generate", images[0], *GSD, "--out", out, "--no-report"])
        assert time.perf_counter() - t0 < 10
    assert r.exit_code == 2
    assert r.has(f"pid {os.getpid()}") and r.has("first.png") and r.has("is writing to")
    assert not out.exists() and _siblings(out) == []


def test_export_and_generate_share_the_lock(scene_a, tmp_path):
    out = _copy(scene_a, tmp_path / "A")
    before = _state(out)
    with FolderLock(out, "coastforge generate x --out A"):
        r = _run(["export", out, "--format", "usd" if False else "gltf", "--out", out, "--overwrite"])
    assert r.exit_code == 2 and r.has("is writing to")
    assert _state(out) == before


# ---------------------------------------------------------------- killed runs

def _cli_process(args: list[str], env=None) -> subprocess.Popen:
    code = "import sys; from coastforge.cli import main; main(sys.argv[1:])"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, env=env)


def test_a_kill_during_overwrite_keeps_the_previous_scene(images, scene_a, tmp_path):
    out = _copy(scene_a, tmp_path / "A")
    before = _state(out)
    staging = out.parent / f"A{STAGING_SUFFIX}"
    p = _cli_process(["generate", images[1], *GSD, "--out", out, "--overwrite", "--export", "gltf,sdf"])
    t0 = time.time()
    while not (staging / "detections.json").exists() and p.poll() is None and time.time() - t0 < 60:
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert _state(out) == before
    assert staging.is_dir()  # clearly named, beside the folder
    r = _run(["generate", images[1], *GSD, "--out", out, "--overwrite", "--no-report"])
    assert r.exit_code == 0 and r.has(f"removed {staging}")
    assert _siblings(out) == []


def test_a_swap_cut_half_way_is_rolled_back(tmp_path):
    out = tmp_path / "A"
    old = tmp_path / ".A.coastforge-old"
    old.mkdir()
    (old / "scene.json").write_text("{}")
    notes = _recover(out)  # killed between the two renames: A is gone, the old folder is beside it
    assert (out / "scene.json").read_text() == "{}" and not old.exists()
    assert notes and "restored" in notes[0]


# ---------------------------------------------------------------- the other commands

def test_export_is_all_or_nothing(scene_a, tmp_path, monkeypatch):
    out = _copy(scene_a, tmp_path / "A")
    before = _state(out)
    r = _run(["export", out, "--format", "gltf"])  # exists: refused before any work
    assert r.exit_code == 2 and r.has("pass --overwrite") and r.has(f"{out / 'gltf'}")
    assert _state(out) == before
    from coastforge import export as exp

    real = exp.run_exporter

    def second_fails(fmt, *a, **k):
        if fmt == "sdf":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fmt, *a, **k)

    monkeypatch.setattr(exp, "run_exporter", second_fails)
    r = _run(["export", out, "--format", "gltf,sdf", "--overwrite"])
    assert r.exit_code == 2 and r.has("disk is full")
    assert _state(out) == before  # the gltf export was not replaced alone
    assert _siblings(out) == []  # the failure came before anything was written: no staging kept
    monkeypatch.setattr(exp, "run_exporter", real)
    (out / "gltf" / "stale.txt").write_text("from an older export")
    r = _run(["export", out, "--format", "gltf", "--overwrite"])
    assert r.exit_code == 0 and not (out / "gltf" / "stale.txt").exists()
    assert {k: v for k, v in _state(out).items() if not k.startswith(("gltf/", ".coastforge"))} == {
        k: v for k, v in before.items() if not k.startswith(("gltf/", ".coastforge"))}


def test_terrain_is_all_or_nothing(scene_a, tmp_path, monkeypatch):
    out = _copy(scene_a, tmp_path / "A")
    before = _state(out)
    from coastforge.terrain import outputs as tout

    def broken(*a, **k):
        raise OSError(errno.EROFS, "Read-only file system", str(out / "terrain_outputs" / "hillshade.png"))

    monkeypatch.setattr(tout, "write_terrain_outputs", broken)
    r = _run(["terrain", out, "--overwrite"])
    assert r.exit_code == 2 and r.has("read-only") and r.has("hillshade.png")
    assert _state(out) == before


def test_segment_is_all_or_nothing(images, tmp_path, monkeypatch):
    out = tmp_path / "seg"
    r = _run(["segment", images[0], *GSD, "--out", out])
    assert r.exit_code == 0, r.output
    before = _state(out)
    r = _run(["segment", images[1], *GSD, "--out", out])
    assert r.exit_code == 2 and r.has("pass --overwrite") and _state(out) == before
    from coastforge.segmentation import outputs

    calls = {"n": 0}
    real_png = outputs.write_png if hasattr(outputs, "write_png") else None

    def fail_late(*a, **k):  # the first raster is written, then the disk is full
        calls["n"] += 1
        if calls["n"] > 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_png(*a, **k)

    if real_png is None:
        pytest.skip("segmentation.outputs writes through another helper")
    monkeypatch.setattr(outputs, "write_png", fail_late)
    r = _run(["segment", images[1], *GSD, "--out", out, "--overwrite"])
    assert r.exit_code == 2 and r.has("disk is full")
    assert _state(out) == before
    assert _siblings(out) == ["seg" + STAGING_SUFFIX]  # partial output kept, clearly named


def test_library_build_never_drops_assets_without_overwrite(tmp_path):
    import trimesh


    src = tmp_path / "src"
    src.mkdir()
    for name, ext in (("boat", (6.0, 2.0, 1.0)), ("car", (4.5, 1.9, 1.4))):
        (src / f"{name}.glb").write_bytes(trimesh.creation.box(extents=ext).export(file_type="glb"))
    entries = [{"id": "b1", "category": "boat", "mesh": "boat.glb", "up_axis": "+z", "forward_axis": "+x"},
               {"id": "c1", "category": "vehicle", "mesh": "car.glb", "up_axis": "+z", "forward_axis": "+x"}]
    (src / "m.json").write_text(json.dumps({"assets": entries}))
    cfg = tmp_path / "small.toml"
    cfg.write_text("[library]\nlightings = 1\nbackgrounds = ['water']\nembed_scales = [1.0]\nview_size_px = 48\n"
                   "paint_variants = false\nquery_view_gsds_m = []\ncrowded_views = 0\n")
    lib = tmp_path / "lib"
    r = _run(["library", "build", src / "m.json", "--out", lib, "--config", cfg, "--workers", "1", "--json"])
    assert r.exit_code == 0, r.output
    before = _state(lib)
    (src / "m.json").write_text(json.dumps({"assets": entries[:1]}))
    r = _run(["library", "build", src / "m.json", "--out", lib, "--config", cfg, "--workers", "1", "--json"])
    assert r.exit_code == 2 and r.has("c1") and r.has("--overwrite")
    after = _state(lib)
    assert {k: (before.get(k), after.get(k)) for k in set(before) | set(after) if before.get(k) != after.get(k)} == {}
    assert _siblings(lib) == []
    r = _run(["library", "build", src / "m.json", "--out", lib, "--config", cfg, "--workers", "1", "--json",
              "--overwrite"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["assets"] == ["b1"]


# ---------------------------------------------------------------- OS errors: one line naming the path

@pytest.mark.parametrize("case", ["under_a_file", "broken_link", "link_loop", "proc", "disk_full", "read_only",
                                  "disk_full_geotiff"])
def test_os_errors_name_the_path(case, images, tmp_path, monkeypatch):
    out = tmp_path / "out"
    expect = ""
    if case == "under_a_file":
        (tmp_path / "f").write_text("x")
        out, expect = tmp_path / "f" / "out", "is a file, not a folder"
    elif case == "broken_link":
        (tmp_path / "l").symlink_to(tmp_path / "nowhere")
        out, expect = tmp_path / "l", "leads nowhere"
    elif case == "link_loop":
        (tmp_path / "l1").symlink_to(tmp_path / "l2")
        (tmp_path / "l2").symlink_to(tmp_path / "l1")
        out, expect = tmp_path / "l1" / "x", "broken symbolic link"
    elif case == "proc":
        out, expect = Path("/proc/coastforge-test"), "/proc"
    else:
        import coastforge.fsio as fsio

        code = errno.EROFS if case == "read_only" else errno.ENOSPC
        expect = "read-only" if case == "read_only" else "disk is full"
        target = "height.tif" if case == "disk_full_geotiff" else "hillshade.png"  # GeoTIFFs: encoded in memory
        real = fsio.atomic_path

        def failing(path, suffix=None):
            if str(path).endswith(target):
                raise OSError(code, os.strerror(code))
            return real(path, suffix)

        monkeypatch.setattr(fsio, "atomic_path", failing)
    r = _run(["generate", images[0], *GSD, "--out", out, "--no-report"])
    assert r.exit_code == 2, r.output
    assert r.has(expect) and not r.has("Traceback")
    if case in ("disk_full", "read_only", "disk_full_geotiff"):
        assert r.has(target) and not out.exists()


def test_an_unexpected_error_is_one_line_and_a_log(images, tmp_path, monkeypatch):
    from coastforge.pipeline import chain as pipeline

    def bug(*a, **k):
        raise ZeroDivisionError("a bug (test)")

    monkeypatch.setattr(pipeline, "fill_under_objects", bug)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    r = _run(["generate", images[0], *GSD, "--out", tmp_path / "out", "--no-report"])
    assert r.exit_code == 3
    assert r.has("unexpected ZeroDivisionError: a bug (test)") and not r.has("Traceback")
    logs = list((tmp_path / "cache" / "coastforge" / "logs").glob("crash-*.log"))
    assert len(logs) == 1 and r.has(str(logs[0]))
    assert "Traceback" in logs[0].read_text() and not r.has("fill_under_objects")


# ---------------------------------------------------------------- missing library categories

def test_a_library_without_buoys_or_piers_falls_back_to_the_kit(images, tmp_path):
    import trimesh

    src = tmp_path / "src"
    src.mkdir()
    hull = trimesh.creation.box(extents=(7.0, 2.4, 1.2))
    (src / "boat.glb").write_bytes(hull.export(file_type="glb"))
    (src / "m.json").write_text(json.dumps({"assets": [
        {"id": "my_boat", "category": "boat", "mesh": "boat.glb", "up_axis": "+z", "forward_axis": "+x"}]}))
    cfg = tmp_path / "small.toml"
    cfg.write_text("[library]\nlightings = 1\nbackgrounds = ['water']\nembed_scales = [1.0]\nview_size_px = 48\n"
                   "paint_variants = false\nquery_view_gsds_m = []\ncrowded_views = 0\n")
    r = _run(["library", "build", src / "m.json", "--out", tmp_path / "lib", "--config", cfg, "--workers", "1",
              "--json"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "out"
    r = _run(["generate", example_dir() / "image.jpg", *GSD, "--out", out, "--library", tmp_path / "lib",
              "--no-report"])
    assert r.exit_code == 0, r.output
    assert r.has("starter kit") and r.has("vehicle")
    scene = json.loads((out / "scene.json").read_text())
    ids = {o["asset_id"] for o in scene["objects"]}
    assert "my_boat" in ids  # the user's boats are used ...
    assert any(o["category"] in ("vehicle", "pier") for o in scene["objects"])  # ... the kit fills the rest
    assert any(w["code"] == "library_fallback" for w in scene["provenance"]["warnings"])


def test_output_folder_removes_a_staging_folder_with_nothing_written(tmp_path):
    out = tmp_path / "A"
    with pytest.raises(ValueError), output_folder(out):
        raise ValueError("checked input was bad")
    assert not out.exists() and _siblings(out) == []
    np.testing.assert_equal(sorted(p.name for p in tmp_path.iterdir()), [])
