"""Tiled Unreal landscapes: names, shared Z scale, seamless edges, heights and weights that decode back."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from coastforge.classes import GRASS, SAND, WATER
from coastforge.errors import InputError
from coastforge.export.terrain_mesh import resample_height
from coastforge.export.ue5 import LANDSCAPE_SIZES, decode_heights
from coastforge.export.ue5_tiles import export_ue5_tiles, tile_counts
from coastforge.scene import Scene


def _scene(h=300, w=300, name="harbor"):
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    z = (xx - w * 0.4) * 0.05 + 0.4 * np.sin(yy / 17.0)  # sea in the west, land rising to the east
    classes = np.where(z < 0, WATER, np.where(xx < w * 0.55, SAND, GRASS)).astype(np.uint8)
    z = np.where(classes == WATER, np.minimum(z, -0.05), np.maximum(z, 0.05)).astype(np.float32)
    return Scene(name=name, seed=0, gsd_m=0.5, extent_m=(w * 0.5, h * 0.5), height=z, classes=classes)


def _png(b: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_UNCHANGED)


def test_tiles_names_scales_and_round_trip():
    scene = _scene()
    files = export_ue5_tiles(scene, tile_size=127)
    spec = json.loads(files["landscape_tiles.json"])
    tx, ty = spec["tiles"]
    assert (tx, ty) == tile_counts(300, 300, 127) == (3, 3)
    nx, ny = spec["vertices"]
    assert nx == tx * 126 + 1 and ny == ty * 126 + 1
    # Unreal's tiled-import naming, for the heightmap and every layer
    names = [p for p in files if p.startswith("heightmap/") and p.endswith(".png")]
    assert sorted(names) == sorted(f"heightmap/harbor_x{i}_y{j}.png" for i in range(tx) for j in range(ty))
    assert all(re.search(r"_x\d+_y\d+\.(png|r16)$", p) for p in files if p != "landscape_tiles.json")
    assert "weightmaps/Water_x2_y1.png" in files and "weightmaps/Grass_x0_y0.png" in files

    scale_z = spec["scale"][2]
    zmax = float(np.abs(scene.height).max())
    assert scale_z >= zmax * 100 / 256
    assert spec["location"] == [-75.0 * 100, -75.0 * 100, 0.0]
    assert spec["scale"][0] == pytest.approx(150.0 * 100 / (nx - 1))
    step_m = scale_z / 128.0 / 100.0

    # assemble the tiles and compare with the raster sampled at the same vertices
    full = np.zeros((ny, nx), np.uint16)
    for t in spec["tile_list"]:
        a = _png(files[t["heightmap_png"]])
        assert a.dtype == np.uint16 and a.shape == (127, 127)
        r16 = np.frombuffer(files[t["heightmap_r16"]], "<u2").reshape(127, 127)
        assert np.array_equal(a, r16)
        c0, r0 = t["first_vertex"]
        if t["x"] > 0:  # shared edge: the first column equals the neighbour's last
            assert np.array_equal(a[:, 0], full[r0:r0 + 127, c0])
        if t["y"] > 0:
            assert np.array_equal(a[0, :], full[r0, c0:c0 + 127])
        full[r0:r0 + 127, c0:c0 + 127] = a
        assert t["location"][0] == pytest.approx(spec["location"][0] + c0 * spec["scale"][0])
    z_ref = resample_height(scene, nx, ny)
    z_dec = decode_heights(full, scale_z)
    assert np.abs(z_dec - z_ref).max() <= step_m * 0.5 + 1e-9
    assert np.array_equal(z_dec > 0, z_ref > 0)  # land stays above the water value, water below


def test_weight_tiles_sum_and_follow_classes():
    scene = _scene()
    files = export_ue5_tiles(scene, tile_size=127)
    spec = json.loads(files["landscape_tiles.json"])
    for t in spec["tile_list"]:
        maps = {layer: _png(files[rel]).astype(int) for layer, rel in t["weightmaps"].items()}
        total = sum(maps.values())
        assert (total == 255).all()
        h = _png(files[t["heightmap_png"]]).astype(int)
        # full water weight only where the height is below the water value, full land weight above
        assert (h[maps["Water"] == 255] < 32768).all()
        assert (h[(maps["Sand"] + maps["Grass"]) == 255] > 32768).all()


def test_explicit_tile_grid_and_bad_input():
    scene = _scene(120, 200, name="Scan 4033x4033")
    files = export_ue5_tiles(scene, tile_size=253, tiles=(2, 1))
    spec = json.loads(files["landscape_tiles.json"])
    assert spec["vertices"] == [505, 253]
    base = spec["heightmap_base"].split("/")[-1]
    assert not re.search(r"\d[xX]\d", base)  # Unreal would read 4033x4033 as tile naming
    assert f"heightmap/{base}_x1_y0.png" in files
    with pytest.raises(InputError, match="tile_size"):
        export_ue5_tiles(scene, tile_size=1000)
    with pytest.raises(InputError, match="tiles"):
        export_ue5_tiles(scene, tile_size=127, tiles=(0, 2))
    assert 1009 in LANDSCAPE_SIZES


def test_registered_as_an_export_format(tmp_path):
    """`ue5_tiles` is a format like the others: listed by the registry, accepted by parse_formats and
    written by export_scene under DIR/ue5_tiles/ (refused without overwrite the second time)."""
    from coastforge import registry
    from coastforge.errors import OutputExistsError
    from coastforge.export import FORMATS, export_scene, parse_formats

    assert "ue5_tiles" in FORMATS and "ue5_tiles" in [s.name for s in registry.specs("export")]
    assert parse_formats("ue5,ue5_tiles") == ["ue5", "ue5_tiles"]
    scene = _scene(260, 260)
    written = export_scene(scene, ["ue5_tiles"], tmp_path)
    paths = {p.relative_to(tmp_path / "ue5_tiles").as_posix() for p in written["ue5_tiles"]}
    spec = json.loads((tmp_path / "ue5_tiles" / "landscape_tiles.json").read_text())
    # the registry calls it with the exporters' signature: default tile size, one tile covers 260 samples
    assert spec["tiles"] == [1, 1] and "heightmap/harbor_x0_y0.png" in paths
    h = cv2.imread(str(tmp_path / "ue5_tiles" / "heightmap" / "harbor_x0_y0.png"), cv2.IMREAD_UNCHANGED)
    assert h.dtype == np.uint16 and h.shape == (1009, 1009)
    with pytest.raises(OutputExistsError):
        export_scene(scene, ["ue5_tiles"], tmp_path)


def test_cli_export_ue5_tiles(tmp_path):
    from click.testing import CliRunner

    from coastforge.cli import cli
    from coastforge.scene import save_scene

    save_scene(_scene(200, 200, name="bay"), tmp_path / "scene")
    res = CliRunner().invoke(cli, ["export", str(tmp_path / "scene"), "--format", "ue5_tiles",
                                    "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "ue5_tiles" / "heightmap" / "bay_x0_y0.r16").is_file()
    assert (tmp_path / "out" / "ue5_tiles" / "weightmaps" / "Water_x0_y0.png").is_file()
