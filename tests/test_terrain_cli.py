"""``coastforge terrain SCENE_DIR`` and the terrain output files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge.bench.terrain import synthetic_class_map
from coastforge.cli import cli
from coastforge.fsio import read_png, write_geotiff
from coastforge.scene import Scene, load_scene, save_scene
from coastforge.terrain.outputs import colour_relief, cross_section_plot, hillshade, _plot_cv2

N, GSD = 128, 0.5


def _scene(folder, georef=False):
    ids = synthetic_class_map("mixed", N, GSD)
    crs, tr = ("EPSG:32610", (GSD, 0.0, 550_000.0, 0.0, -GSD, 4_180_000.0)) if georef else (None, None)
    save_scene(Scene(name="t", seed=3, gsd_m=GSD, extent_m=(N * GSD, N * GSD), classes=ids, crs=crs,
                     transform=tr), folder)
    return ids


def test_terrain_command_writes_heights_and_outputs(tmp_path):
    ids = _scene(tmp_path)
    r = CliRunner().invoke(cli, ["terrain", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "shore types" in r.output
    scene = load_scene(tmp_path)
    assert scene.height is not None and scene.height.dtype == np.float32 and scene.height.shape == ids.shape
    assert (scene.height[ids == 0] < 0).all() and (scene.height[ids != 0] > 0).all()
    assert scene.provenance["terrain"]["backend"] == "default"
    t = tmp_path / "terrain"
    hs = read_png(t / "hillshade.png")
    assert hs.shape == (N, N, 3)
    data = json.loads((t / "cross_section.json").read_text())
    assert {s["shore_type"] for s in data["sections"]} <= {"beach", "revetment", "quay", "bank"}
    assert len(data["sections"]) >= 3
    csv = (t / "cross_section.csv").read_text().splitlines()
    assert csv[0] == "shore_type,distance_m,height_m" and len(csv) > 20
    assert read_png(t / "cross_section.png").ndim == 3
    # refuses to overwrite without --overwrite, then replaces with it
    r2 = CliRunner().invoke(cli, ["terrain", str(tmp_path)])
    assert r2.exit_code == 2 and "--overwrite" in r2.output
    r3 = CliRunner().invoke(cli, ["terrain", str(tmp_path), "--overwrite", "--set", "terrain.max_depth_m=12"])
    assert r3.exit_code == 0, r3.output
    assert load_scene(tmp_path).height.min() < scene.height.min()


def test_terrain_command_with_a_dem(tmp_path):
    _scene(tmp_path, georef=True)
    dem = tmp_path / "dem.tif"
    write_geotiff(dem, np.full((20, 20), 5.0, np.float32), (1.0, 0, 550_010.0, 0, -1.0, 4_179_990.0),
                  crs="EPSG:32610")
    r = CliRunner().invoke(cli, ["terrain", str(tmp_path), "--dem", f"{dem}:offset=-0.5"])
    assert r.exit_code == 0, r.output
    assert "DEM coverage" in r.output
    z = load_scene(tmp_path).height
    assert np.allclose(z[25:55, 25:55], 4.5, atol=1e-4)


def test_terrain_command_errors_are_one_line(tmp_path):
    _scene(tmp_path)
    dem = tmp_path / "dem.tif"
    write_geotiff(dem, np.ones((4, 4), np.float32), (1.0, 0, 10.0, 0, -1.0, 10.0), crs="EPSG:32610")
    r = CliRunner().invoke(cli, ["terrain", str(tmp_path), "--dem", str(dem)])
    assert r.exit_code == 2 and "--dem-origin" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli, ["terrain", str(tmp_path), "--dem-crs", "EPSG:32610"])
    assert r.exit_code == 2 and "go together" in r.output
    r = CliRunner().invoke(cli, ["terrain", str(tmp_path), "--set", "terrain.berth_depth_m=-2"])
    assert r.exit_code == 2 and "berth_depth_m" in r.output


def test_hillshade_and_plots():
    z = np.zeros((40, 40), np.float32)
    z[:, 20:] = np.linspace(0, 10, 20)[None]  # rising to the east: a west-facing slope
    west = hillshade(z, 1.0, azimuth_deg=270.0, altitude_deg=45.0)
    east = hillshade(z, 1.0, azimuth_deg=90.0, altitude_deg=45.0)
    assert west[:, :18].mean() == pytest.approx(np.sin(np.pi / 4), abs=1e-3)  # flat ground
    assert west[:, 22:38].mean() > west[:, :18].mean() > east[:, 22:38].mean()
    col = colour_relief(np.array([[-8.0, -0.1, 0.1, 5.0]]), 8.0)
    assert col[0, 0, 2] < col[0, 1, 2]  # deep water darker than shallow
    from coastforge.terrain import CrossSection

    heights = np.r_[np.full(10, 1.2), np.full(21, -4.0)]
    sec = CrossSection("quay", np.linspace(-10, 20, 31), heights, (0, 0), (30, 0))
    assert cross_section_plot([sec], engine="auto").shape[2] == 3
    img = _plot_cv2([sec], 400, 200)
    assert img.shape == (200, 400, 3) and (img != 255).any()
