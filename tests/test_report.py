"""report.html: built from a small synthetic scene, then opened in real headless Chromium."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge.bench.report import browser_missing, open_report
from coastforge.errors import InputError, OutputExistsError
from coastforge.report import SECTION_FAILED, SECTIONS, build_report, match_objects_to_decisions
from coastforge.scene import SceneObject

SCREENSHOT_COPY = Path("/tmp/report_test.png")


def _fake_outputs(scene, folder: Path):
    """What generate writes beside scene.json, made from the truth: image, detections, matches, sections."""
    import cv2

    from coastforge.classes import colorize
    from coastforge.fsio import write_png

    grid = scene.grid
    k = 3  # the "input image" has 3 px per scene cell, like a finer photo
    img = cv2.resize(colorize(scene.classes), (grid.width_px * k, grid.height_px * k),
                     interpolation=cv2.INTER_NEAREST)
    rng = np.random.default_rng(0)
    img = np.clip(img.astype(int) + rng.integers(-12, 13, img.shape), 0, 255).astype(np.uint8)
    objs = [o for o in scene.objects if o.category in ("boat", "vehicle", "buoy")]
    dets, matches = [], []
    for i, o in enumerate(objs):
        col, row = grid.to_pixel(o.x_m, o.y_m)
        r = np.deg2rad(o.yaw_deg)
        u, n = np.array([np.cos(r), -np.sin(r)]), np.array([np.sin(r), np.cos(r)])
        L, W = o.length_m / grid.gsd_m * k, o.width_m / grid.gsd_m * k
        c = np.array([col * k, row * k])
        corners = [c + u * L / 2 + n * W / 2, c - u * L / 2 + n * W / 2, c - u * L / 2 - n * W / 2,
                   c + u * L / 2 - n * W / 2]
        cv2.fillPoly(img, [np.round(corners).astype(np.int32)], (240, 240, 240))
        dets.append({"category": o.category, "score": 0.9,
                     "corners_px": [list(map(float, p)) for p in corners],
                     "cx_px": float(c[0]), "cy_px": float(c[1]), "length_px": float(L), "width_px": float(W),
                     "yaw_deg": o.yaw_deg, "heading_known": i % 2 == 0})
        matches.append({"index": i, "asset_id": o.asset_id, "score": 0.8, "yaw_deg": o.yaw_deg,
                        "heading_source": "detector", "flip_evidence": 0.1,
                        "candidates": [{"asset_id": o.asset_id, "score": 0.8},
                                       {"asset_id": "dinghy", "score": 0.5},
                                       {"asset_id": "sedan", "score": 0.3}]})
    write_png(folder / "image.png", img)
    write_png(folder / "cleaned.png", colorize(scene.classes))
    (folder / "detections.json").write_text(json.dumps({"detections": dets}))
    # a real transect of the scene's height: the centre column from north (land) to south (water)
    z = scene.height[:, grid.width_px // 2]
    shore = int(np.argmax(z < 0))
    d = (np.arange(z.size) - shore) * grid.gsd_m
    (folder / "terrain_outputs").mkdir()
    (folder / "terrain_outputs" / "cross_section.json").write_text(json.dumps({"sections": [
        {"shore_type": "quay", "start_px": [grid.width_px / 2, 0.0],
         "end_px": [grid.width_px / 2, z.size - 1.0],
         "distance_m": d.tolist(), "height_m": z.astype(float).tolist()}]}))
    objects = tuple(replace(o, source="detection") if o.category in ("boat", "vehicle", "buoy") else o
                    for o in scene.objects)
    prov = {**scene.provenance, "matches": matches, "command": "coastforge generate image.png --gsd 0.13",
            "input": {"image": str(folder / "image.png")}, "library": "starter-kit",
            "timings_s": {"segment": 1.5, "detect": 0.7, "terrain": 0.4, "total": 2.6}, "version": "0.1.0",
            "warnings": [{"code": "boats_without_water", "message": "40 boats were found but only 1.0 % of the "
                          "image is water.", "hint": "Try --set segment.learned_water=net."}],
            "consistency": {"water_from_boats_m2": 120.5, "boat_clusters_made_water": 2}}
    # the segmenter's confidence and who decided each pixel, as generate writes them
    from coastforge.fsio import write_png

    h, w = scene.classes.shape
    write_png(folder / "segmentation" / "confidence.png", np.full((h, w), 200, np.uint8))
    src = np.zeros((h, w), np.uint8)
    src[:, : w // 4] = 3  # made water by moored boats
    write_png(folder / "segmentation" / "source.png", src)
    return replace(scene, objects=objects, provenance=prov), len(objs)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    from coastforge.cli import cli
    from coastforge.scene import save_scene
    from coastforge.synth import synthesize

    d = tmp_path_factory.mktemp("report")
    truth = synthesize("pier_parking", 2, size_m=56, grid_m=0.4)
    scene, n_obj = _fake_outputs(truth, d)
    save_scene(scene, d)
    save_scene(truth, d / "truth", filename="truth.json")
    res = CliRunner().invoke(cli, ["report", str(d), "--truth", str(d / "truth" / "truth.json")])
    assert res.exit_code == 0, res.output
    path = Path(res.output.strip().splitlines()[-1])
    assert path == d / "report.html" and path.is_file()
    return path, n_obj


def test_report_is_self_contained(built):
    path, n_obj = built
    from importlib import resources

    page = path.read_text()
    assert page.count('<section id="sec-') == len(SECTIONS)
    assert SECTION_FAILED not in page
    # nothing refers outside the page: no http(s) sources, links or imports (the vendored three.js has loader
    # code that can fetch; the browser test checks that no request is made)
    static = resources.files("coastforge.report").joinpath("static")
    bundle = static.joinpath("viewer.bundle.js").read_text("utf-8")
    assert bundle in page
    for name in ("report.css", "report.js"):  # the page's stylesheet and script, installed as package data
        assert static.joinpath(name).read_text("utf-8").strip() in page
    page = page.replace(bundle, "")
    for bad in ('src="http', "src='http", 'href="http', "@import", "<link ", "fetch(", 'src="/',
                'src="file:'):
        assert bad not in page, bad
    assert 'id="glb-data"' in page and "CoastforgeViewer" in page
    assert page.count('<img class="thumb"') == n_obj  # one crop per boat/vehicle/buoy
    assert "runner-up" in page and "dinghy" in page
    assert "mIoU" in page or "miou" in page  # metrics against the truth
    assert path.stat().st_size < 15e6


def test_report_in_headless_chromium(built, tmp_path):
    why = browser_missing()
    if why:
        pytest.skip(f"cannot open the report in a browser: {why}")
    path, _ = built
    shot = tmp_path / "report.png"
    info = open_report(path, shot)
    assert info["console_errors"] == []
    assert info["failed_requests"] == []
    assert info["foreign_requests"] == []
    assert info["broken_images"] == []
    assert set(info["sections"]) == set(SECTIONS)
    assert all(info["sections"].values()), info["sections"]
    assert info["viewer_state"] == "drawn", info
    assert info["canvas_non_background"] > 0.05, info["canvas_non_background"]
    assert info["orbit_changed"] > 0.01, info["orbit_changed"]  # dragging orbits the camera
    assert shot.is_file() and shot.stat().st_size > 10_000
    shutil.copy(shot, SCREENSHOT_COPY)


def test_report_shows_the_self_check_and_the_segmentation_confidence(built):
    page = built[0].read_text()
    assert "This scene looks implausible" in page and "learned_water=net" in page
    assert "Segmentation and detection reconciled: water from boats m2 120.5" in page
    assert "Segmentation confidence" in page and "mean 78 %" in page
    assert "Who decided each pixel" in page and "detections 25.0 %" in page


def test_rebuild_and_errors(built, tmp_path):
    path, _ = built
    d = path.parent
    with pytest.raises(InputError, match=r"scene.json"):
        build_report(tmp_path / "nowhere")
    with pytest.raises(InputError, match="truth"):
        build_report(d, truth=tmp_path / "missing.json")
    other = tmp_path / "r.html"
    other.write_text("keep me")
    with pytest.raises(OutputExistsError, match="--overwrite"):
        build_report(d, out=other)
    assert other.read_text() == "keep me"
    from coastforge.cli import cli

    res = CliRunner().invoke(cli, ["report", str(tmp_path / "nowhere")])
    assert res.exit_code == 2 and "scene.json" in res.output and "Traceback" not in res.output


def _obj(i, asset, yaw=0.0, **attrs):
    return SceneObject(f"o{i}", "boat", asset, 0, 0, 0, yaw, (1, 1, 1), 4, 2, attrs=attrs)


def test_match_links():
    ms = [{"index": 0, "asset_id": "a", "yaw_deg": 0}, {"index": 1, "asset_id": "b", "yaw_deg": 90},
          {"index": 2, "asset_id": "b", "yaw_deg": -90}]
    # explicit links win, even out of order
    objs = [_obj(0, "b", -90, match=2), _obj(1, "a", match=0), _obj(2, "b", 90, match=1)]
    got = match_objects_to_decisions(objs, ms)
    assert [got[o.id]["index"] for o in objs] == [2, 0, 1]
    # without links: by order, and by asset + closest yaw when the order breaks
    objs = [_obj(0, "a"), _obj(1, "b", 95), _obj(2, "b", -85)]
    got = match_objects_to_decisions(objs, ms)
    assert [got[o.id]["index"] for o in objs] == [0, 1, 2]
    objs = [_obj(0, "b", -85), _obj(1, "a")]
    got = match_objects_to_decisions(objs, ms)
    assert [got[o.id]["index"] for o in objs] == [2, 0]
    # an object whose asset has no decision stays unlinked
    assert "o9" not in match_objects_to_decisions([_obj(9, "zzz")], ms)


def test_terrain_figures_are_inline_svg(built):
    """The height map and the cross-sections are SVG drawn from the data (no plotting library): the relief
    as an embedded JPEG with axes in metres, the transect as an arrow labelled with its shore type, and the
    profile as a polyline on axes that span it."""
    import base64
    import re

    page = built[0].read_text()
    sec = page[page.index('id="sec-terrain"'):]
    sec = sec[:sec.index("</section>")]
    svgs = [base64.b64decode(u).decode() for u in re.findall(r'src="data:image/svg\+xml;base64,([^"]+)"', sec)]
    assert len(svgs) == 2
    hill, prof = svgs
    assert "data:image/jpeg;base64," in hill and "x east (m)" in hill and "y north (m)" in hill
    assert ">quay</text>" in hill and "<polygon" in hill  # the transect's label and arrow head
    assert 'id="cbar"' in hill  # the colour bar
    pts = re.findall(r'<polyline points="([^"]+)"', prof)
    assert len(pts) == 1 and len(pts[0].split()) >= 10
    assert "quay shore" in prof and "water level" in prof


def test_nice_ticks():
    from coastforge.report.figures import nice_ticks

    assert nice_ticks(-100, 100) == [-100, -50, 0, 50, 100]
    assert nice_ticks(-7.8, 0, 4) == [-6, -4, -2, 0]
    assert nice_ticks(0, 3.2, 4) == [0, 1, 2, 3]
    assert nice_ticks(1.0, 1.0) == [1.0]


def test_the_pages_static_files_are_package_data():
    """report/static (stylesheet, script, 3D viewer and its licence) ships in wheels: pyproject's
    package-data covers each of its files."""
    import fnmatch
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    root = Path(__file__).resolve().parents[1]
    pkg = root / "src" / "coastforge"
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    files = sorted((pkg / "report" / "static").iterdir())
    assert {f.name for f in files} >= {"report.css", "report.js", "viewer.bundle.js", "THREE_LICENSE.txt"}
    for f in files:
        rel = f.relative_to(pkg).as_posix()
        assert any(fnmatch.fnmatch(rel, p) for p in patterns["coastforge"]), rel
