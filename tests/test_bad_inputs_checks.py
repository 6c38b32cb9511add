"""Issue #28: bad inputs are refused up front, with a message saying what, the value, and what to do.

Each case builds its own bad input in tmp_path; CLI cases also check exit code 2 and that nothing was written.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge.cli import cli
from coastforge.config import Config, load_config, validate_config
from coastforge.errors import ConfigError
from coastforge.fsio import write_png


def _image(tmp_path, name="a.png", h=64, w=64):
    p = tmp_path / name
    write_png(p, np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8))
    return p


def _no_output(out):
    """Nothing written: the output folder was not even created."""
    return not out.exists()


# ------------------------------------------------------------------------------------------- 1. config

@pytest.mark.parametrize("sets,seed,phrase", [
    (["terrain.max_depth_m=-5"], None, "terrain.max_depth_m = -5.0 must be > 0 (metres; depth far from shore)"),
    (["terrain.max_depth_m=nan"], None, "terrain.max_depth_m = nan must be a finite number"),
    (["terrain.max_depth_m=inf"], None, "must be a finite number"),
    (["match.scale_max=-1"], None, "match.scale_max = -1.0 must be > 0"),
    (["match.scale_min=3"], None, "match.scale_min = 3.0 is larger than match.scale_max = 2.0"),
    (["vegetation.tree_density_per_100m2=-1"], None, "must be >= 0 (instances per 100 m²)"),
    (["vegetation.seaweed_density_per_100m2=-0.1"], None, "vegetation.seaweed_density_per_100m2 = -0.1"),
    (["vegetation.min_spacing_m=-2"], None, "vegetation.min_spacing_m = -2.0 must be >= 0 (metres)"),
    (["detect.min_score=1.5"], None, "detect.min_score = 1.5 must be between 0 and 1"),
    (["detect.nms_iou=-0.1"], None, "detect.nms_iou = -0.1 must be between 0 and 1"),
    (["detect.min_boat_length_m=80"], None, "detect.min_boat_length_m = 80.0 is larger than detect.max_boat_length_m"),
    (["detect.slice_overlap_px=2048"], None, "must be smaller than detect.slice_px"),
    (["detect.work_gsd_m=0"], None, "detect.work_gsd_m = 0.0 must be > 0"),
    (["segment.learned_water=maybe"], None, "segment.learned_water = 'maybe' is not one of fused, classical, net"),
    (["match.mode=random"], None, "match.mode = 'random' is not one of best, sample"),
    (["match.scale_mode=free"], None, "is not one of uniform, per_axis"),
    (["detect.boat_mask=blob"], None, "is not one of core, struct, region"),
    (["detect.backend=magic"], None, "detect.backend = 'magic' is not a known detect backend; valid: classical"),
    (["export.formats=['gltf','fbx']"], None, "export.formats = 'fbx' is not a known export format"),
    (["library.embed_scales=[1.0,-2.0]"], None, "library.embed_scales = (1.0, -2.0) must be a list whose every item"),
    (["detect.snap_deg=120"], None, "detect.snap_deg = 120.0 must be between 0.0 and 90.0"),
    (["detect.big_pass=0.5"], None, "detect.big_pass = 0.5 must be 0 (off) or how many times to shrink"),
    (["detect.big_pass=12"], None, "detect.big_pass = 12.0 must be between 0.0 and 8.0"),
    (["io.max_memory_gb=0"], None, "io.max_memory_gb = 0.0 must be > 0"),
    (["seed=-3"], None, "seed = -3 must be between 0 and 9223372036854775807"),
    ([], -1, "seed = -1 must be between 0 and 9223372036854775807; fix it with --seed N"),
    ([], 2**64, "seed = 18446744073709551616 must be between 0"),
])
def test_config_values_checked_when_built(sets, seed, phrase):
    with pytest.raises(ConfigError) as e:
        load_config(sets=sets, seed=seed)
    assert phrase in str(e.value)
    assert "fix it with" in str(e.value) or "fix one of them" in str(e.value)


@pytest.mark.parametrize("section,key,value,phrase", [
    ("terrain", "depth_scale_m", 0.0, "terrain.depth_scale_m = 0.0 must be > 0"),
    ("vegetation", "bush_density_per_100m2", float("nan"), "must be a finite number"),
    ("match", "scale_max", 0.0, "match.scale_max = 0.0 must be > 0"),
])
def test_validate_config_on_a_config_built_in_code(section, key, value, phrase):
    cfg = dataclasses.replace(Config(), **{section: dataclasses.replace(getattr(Config(), section), **{key: value})})
    with pytest.raises(ConfigError, match=phrase):
        validate_config(cfg)


def test_every_preset_and_the_defaults_are_valid():
    from coastforge.config import preset_names

    assert validate_config(Config()) == Config()
    for name in preset_names():
        load_config(name)
    # negative where documented: <= 0 turns the heading prior's scaling off
    load_config(sets=["match.heading_prior_ref_px=-1"])


@pytest.mark.parametrize("args,phrase", [
    (["--seed", "-1"], "seed = -1 must be between 0"),
    (["--set", "terrain.max_depth_m=-5"], "terrain.max_depth_m = -5.0 must be > 0"),
    (["--set", "terrain.max_depth_m=nan"], "terrain.max_depth_m = nan must be a finite number"),
    (["--set", "match.scale_max=-1"], "match.scale_max = -1.0 must be > 0"),
    (["--set", "vegetation.grass_density_per_100m2=-2"], "vegetation.grass_density_per_100m2 = -2.0 must be >= 0"),
    (["--set", "vegetation.min_spacing_m=-1"], "vegetation.min_spacing_m = -1.0 must be >= 0"),
])
def test_generate_refuses_bad_config_before_writing(tmp_path, args, phrase):
    img, out = _image(tmp_path), tmp_path / "out"
    r = CliRunner().invoke(cli, ["generate", str(img), "--gsd", "0.2", "--out", str(out), *args])
    assert r.exit_code == 2, r.output
    assert phrase in r.output and "Traceback" not in r.output
    assert _no_output(out)


# ------------------------------------------------------------------------------------------- 2. images

def _geotiff(path, crs, transform, h=64, w=64, dtype="uint8", nodata=None, fill=None):
    import rasterio

    data = (np.full((3, h, w), fill, dtype) if fill is not None
            else np.random.default_rng(1).integers(0, 200, (3, h, w)).astype(dtype))
    with rasterio.open(path, "w", driver="GTiff", width=w, height=h, count=3, dtype=dtype, crs=crs,
                       transform=transform, nodata=nodata, compress="deflate") as dst:
        dst.write(data)
    return path


def _bad_image(tmp_path, case):
    """(path, read_image kwargs) of one bad image."""
    from PIL import Image
    from rasterio.transform import from_origin

    rgb = np.random.default_rng(0).integers(0, 255, (200, 300, 3), dtype=np.uint8)
    if case in ("truncated_png", "truncated_jpeg", "corrupt_png", "corrupt_jpeg"):
        ext = "png" if "png" in case else "jpg"
        p = tmp_path / f"a.{ext}"
        Image.fromarray(rgb).save(p)
        b = bytearray(p.read_bytes())
        if case.startswith("truncated"):
            b = b[:len(b) // 2]
        else:  # a damaged run of 200 bytes mid-file (GDAL reads such a JPEG with grey blocks, without an error)
            m = len(b) // 2
            b[m:m + 200] = b"\xff" * 200
        p.write_bytes(bytes(b))
        return p, {"gsd_m": 0.2}
    if case == "truncated_geotiff":
        p = _geotiff(tmp_path / "a.tif", "EPSG:32633", from_origin(5e5, 4e6, 0.5, 0.5), h=200, w=300)
        p.write_bytes(p.read_bytes()[:-2000])
        return p, {}
    if case == "palette_png":
        p = tmp_path / "p.png"
        Image.fromarray(rgb).convert("P").save(p)
        return p, {"gsd_m": 0.2}
    if case == "animated_gif":
        p = tmp_path / "a.gif"
        frames = [Image.fromarray(rgb).convert("P"), Image.fromarray(255 - rgb).convert("P")]
        frames[0].save(p, save_all=True, append_images=frames[1:], duration=100)
        return p, {"gsd_m": 0.2}
    if case == "transparent_rgba":
        p = tmp_path / "t.png"
        write_png(p, np.dstack([rgb, np.zeros(rgb.shape[:2], np.uint8)]))
        return p, {"gsd_m": 0.2}
    if case == "nodata_geotiff":
        return _geotiff(tmp_path / "nd.tif", "EPSG:32633", from_origin(5e5, 4e6, 0.5, 0.5), nodata=0, fill=0), {}
    if case == "one_pixel":
        return _image(tmp_path, "one.png", 1, 1), {"gsd_m": 0.2}
    if case == "3x100000":
        return _image(tmp_path, "strip.png", 3, 100_000), {"gsd_m": 0.2}
    if case == "strip_100_to_1":
        return _image(tmp_path, "strip.png", 20, 2000), {"gsd_m": 0.2}
    if case.startswith("gsd_"):
        return _image(tmp_path), {"gsd_m": float(case[4:])}
    if case == "georef_in_degrees_under_utm":  # a 1e-5 "m" pixel: degrees written under a metric CRS
        return _geotiff(tmp_path / "u.tif", "EPSG:32633", from_origin(10.0, 44.0, 1e-5, 1e-5)), {}
    if case == "geographic_with_metre_coordinates":
        return _geotiff(tmp_path / "g.tif", "EPSG:4326", from_origin(5e5, 4e6, 0.25, 0.25)), {}
    if case == "memory_limit":
        return _image(tmp_path), {"gsd_m": 0.2, "config": dataclasses.replace(Config().io, max_memory_gb=0.1)}
    raise AssertionError(case)


@pytest.mark.parametrize("case,phrase", [
    ("truncated_png", "a.png is truncated or corrupt: the file ends inside its IDAT chunk; re-export or re-download"),
    ("truncated_jpeg", "a.jpg is truncated or corrupt: libjpeg: Premature end of JPEG file; re-export or re-download"),
    ("corrupt_png", "a.png is truncated or corrupt: its IDAT chunk fails the CRC check"),
    ("truncated_geotiff", "a.tif is truncated or corrupt: "),
    ("corrupt_jpeg", "a.jpg is truncated or corrupt: libjpeg: Corrupt JPEG data"),
    ("palette_png", "p.png is a palette (indexed-colour) image; coastforge needs an RGB image"),
    ("animated_gif", "a.gif is an animated GIF (2 frames); coastforge needs an RGB image"),
    ("transparent_rgba", "t.png is fully transparent (alpha 0 everywhere): it holds no image"),
    ("nodata_geotiff", "nd.tif is nodata everywhere (nodata = 0.0): it holds no image"),
    ("one_pixel", "one.png is 1x1 px; coastforge needs at least 16 px on each side"),
    ("3x100000", "strip.png is 100000x3 px; coastforge needs at least 16 px on each side"),
    ("strip_100_to_1", "strip.png is 2000x20 px, a 100:1 strip; coastforge takes images up to 64:1"),
    ("gsd_1e-9", "--gsd gives 1e-09 m/px for"),
    ("gsd_1000", "--gsd gives 1000 m/px for"),
    ("gsd_1e6", "--gsd gives 1e+06 m/px for"),
    ("georef_in_degrees_under_utm", "the GeoTIFF georeference gives 1e-05 m/px"),
    ("geographic_with_metre_coordinates", "claims a geographic CRS (EPSG:4326) but its bounds"),
    ("memory_limit", "GiB of working memory, over io.max_memory_gb = 0.1"),
])
def test_images_checked_up_front(tmp_path, case, phrase):
    from coastforge.errors import InputError
    from coastforge.io import read_image

    p, kw = _bad_image(tmp_path, case)
    with pytest.raises(InputError) as e:
        read_image(p, **kw)
    msg = str(e.value)
    assert phrase in msg, msg
    assert "See previous exception" not in msg
    if case.startswith("gsd_"):
        assert "must be positive" not in msg and "outside the 0.005-50 m/px" in msg


@pytest.mark.parametrize("size,gsd", [((16, 16), 0.2), ((40, 60), 0.01), ((40, 60), 8.0), ((30, 1900), 0.2)])
def test_plausible_images_still_read(tmp_path, size, gsd):
    from coastforge.io import read_image

    img = read_image(_image(tmp_path, "ok.png", *size), gsd_m=gsd, stages=load_config())
    assert img.rgb.shape == (*size, 3)


def test_geographic_geotiff_with_a_wrong_scale_stays_bounded(tmp_path):
    """0.0004° pixels (~40 m) over 1000 px, a 40 km scene: its vegetation scatter once tried to allocate
    hundreds of GiB. It is bounded now; the estimate says so and refuses only above io.max_memory_gb."""
    from rasterio.transform import from_origin

    from coastforge.errors import InputError
    from coastforge.io import estimate_memory_bytes, read_image

    p = _geotiff(tmp_path / "geo.tif", "EPSG:4326", from_origin(10.0, 44.0, 0.0004, 0.0004), h=1000, w=1000)
    assert sum(estimate_memory_bytes(1000, 1000, 40.0, load_config()).values()) < 2 * 2**30
    with pytest.warns(UserWarning, match="reprojected"):
        assert read_image(p, stages=load_config()).grid.gsd_m > 30
    small = load_config(sets=["io.max_memory_gb=0.2"])
    with pytest.warns(UserWarning, match="reprojected"), pytest.raises(InputError) as e:
        read_image(p, config=small.io, stages=small)
    assert "GiB of working memory" in str(e.value) and "io.max_memory_gb" in str(e.value)


def test_vegetation_scatter_is_bounded_on_a_large_extent():
    """A 20 km x 20 km scene of grass and trees: the densities are thinned to max_instances before any
    point is drawn (it once drew millions of candidates to drop them)."""
    from coastforge.classes import GRASS, TREES
    from coastforge.config import VegetationConfig
    from coastforge.types import Grid
    from coastforge.vegetation import scatter

    n = 1000
    classes = np.full((n, n), GRASS, np.uint8)
    classes[:, : n // 2] = TREES
    grid = Grid(n, n, 20.0)
    cfg = VegetationConfig(max_instances=5000)
    res = scatter(classes, np.ones((n, n), np.float32), grid, {"tree": ["t"], "grass": ["g"], "bush": ["b"]}, [],
                  cfg, seed=0)
    assert 3000 < len(res.vegetation) <= 5000
    cats = set(res.vegetation.asset_id)
    assert cats == {"t", "g", "b"}  # every rule keeps its share


def test_memory_estimate_grows_with_pixels_and_gsd():
    from coastforge.io import estimate_memory_bytes

    cfg = load_config()

    def est(w, g):
        return sum(estimate_memory_bytes(w, w, g, cfg).values())

    assert est(2000, 0.2) < est(4000, 0.2) and est(2000, 0.2) < est(2000, 2.0)
    assert est(4096, 0.2) < 8 * 2**30  # the largest untiled generate at a usual GSD passes the default limit


@pytest.mark.parametrize("case,phrase", [
    ("truncated_png", "is truncated or corrupt"),
    ("palette_png", "is a palette (indexed-colour) image"),
    ("one_pixel", "is 1x1 px"),
    ("gsd_1e6", "--gsd gives 1e+06 m/px"),
    ("gsd_1e-9", "--gsd gives 1e-09 m/px"),
    ("transparent_rgba", "fully transparent"),
])
def test_generate_refuses_bad_images_before_writing(tmp_path, case, phrase):
    p, kw = _bad_image(tmp_path, case)
    out = tmp_path / "out"
    args = ["generate", str(p), "--out", str(out), "--no-report"]
    if "gsd_m" in kw:
        args += ["--gsd", repr(kw["gsd_m"])]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 2, r.output
    assert phrase in r.output and "Traceback" not in r.output
    assert _no_output(out)


def test_generate_refuses_a_run_over_the_memory_limit_before_writing(tmp_path):
    from rasterio.transform import from_origin

    p = _geotiff(tmp_path / "geo.tif", "EPSG:4326", from_origin(10.0, 44.0, 0.0004, 0.0004), h=1000, w=1000)
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["generate", str(p), "--out", str(out), "--set", "io.max_memory_gb=0.2"])
    assert r.exit_code == 2, r.output
    assert "GiB of working memory, over io.max_memory_gb = 0.2" in r.output and "Traceback" not in r.output
    assert _no_output(out)


# ------------------------------------------------------------------------------- 3. DEMs and heights

DEM_CRS, X0, Y0, N, GSD = "EPSG:32610", 550_000.0, 4_180_000.0, 64, 0.5


def _georef_scene(folder):
    from coastforge.scene import Scene, save_scene

    ids = np.zeros((N, N), np.uint8)
    ids[:, : N // 2] = 3  # grass west, water east
    save_scene(Scene(name="t", seed=0, gsd_m=GSD, extent_m=(N * GSD, N * GSD), classes=ids, crs=DEM_CRS,
                     transform=(GSD, 0.0, X0, 0.0, -GSD, Y0)), folder)
    return folder


def _dem(path, values, nodata=None):
    from coastforge.fsio import write_geotiff

    write_geotiff(path, np.asarray(values, np.float32), (1.0, 0, X0, 0, -1.0, Y0), crs=DEM_CRS, nodata=nodata)
    return path


def _fuse(dem):
    from coastforge.terrain.dem import fuse_dems
    from coastforge.types import Grid

    grid = Grid(N, N, GSD, DEM_CRS, (GSD, 0.0, X0, 0.0, -GSD, Y0))
    return fuse_dems(np.zeros((N, N), np.float32), grid, [dem], Config().terrain)


@pytest.mark.parametrize("case,phrase", [
    ("all_1e30", "every value under the scene is beyond ±12000 m (e.g. 1e+30), which no real height is"),
    ("all_minus_3e38", "every value under the scene is beyond ±12000 m"),
    ("nan_only", "holds only nodata (or NaN) under the scene"),
    ("declared_nodata_only", "holds only nodata (or NaN) under the scene"),
    ("feet_beyond_12km", "every value under the scene is beyond ±12000 m (e.g. 50000)"),
    ("truncated", "is truncated or corrupt"),
])
def test_absurd_dems_refused(tmp_path, case, phrase):
    from coastforge.errors import InputError

    p = tmp_path / "dem.tif"
    spec = str(p)
    if case == "all_1e30":
        _dem(p, np.full((40, 40), 1e30))
    elif case == "all_minus_3e38":
        _dem(p, np.full((40, 40), -3.4e38))
    elif case == "nan_only":
        _dem(p, np.full((40, 40), np.nan), nodata=float("nan"))
    elif case == "declared_nodata_only":
        _dem(p, np.full((40, 40), -9999.0), nodata=-9999.0)
    elif case == "feet_beyond_12km":
        _dem(p, np.full((40, 40), 50_000.0))  # 15 km even in feet: refused at any scale
        spec = f"{p}:scale=0.3048"
    elif case == "truncated":  # the DEM just covers the scene, cut in half
        _dem(p, np.random.default_rng(0).random((32, 32)) * 5)
        p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    with pytest.raises(InputError) as e:
        _fuse(spec)
    assert phrase in str(e.value) and str(p) in str(e.value)
    assert "See previous exception" not in str(e.value)


def test_dem_cells_beyond_12km_become_nodata_with_a_warning(tmp_path):
    from coastforge.errors import CoastforgeWarning

    z = np.full((40, 40), -3.0)
    z[:10] = 1e30  # an undeclared nodata value in the northern rows
    with pytest.warns(CoastforgeWarning, match=r"of \d+ cells .* beyond ±12000 m \(e.g. 1e\+30\); they are "
                                               r"treated as nodata"):
        fused, info = _fuse(_dem(tmp_path / "dem.tif", z))
    assert np.isfinite(fused).all() and np.abs(fused).max() < 10  # no 1e30 smeared into real cells
    assert 0 < info.coverage < 1
    # a DEM in feet: 20 000 ft is 6 km, a real height once scaled
    fused, _ = _fuse(f"{_dem(tmp_path / 'feet.tif', np.full((40, 40), -20_000.0))}:scale=0.3048")
    assert fused.min() == pytest.approx(-6096.0, abs=1)


def test_terrain_command_refuses_an_absurd_dem_before_writing(tmp_path):
    scene = _georef_scene(tmp_path / "scene")
    before = {p: p.read_bytes() for p in scene.rglob("*") if p.is_file()}
    dem = _dem(tmp_path / "dem.tif", np.full((40, 40), 1e30))
    r = CliRunner().invoke(cli, ["terrain", str(scene), "--dem", str(dem), "--overwrite"])
    assert r.exit_code == 2, r.output
    assert "beyond ±12000 m" in r.output and "Traceback" not in r.output
    assert {p: p.read_bytes() for p in scene.rglob("*") if p.is_file()} == before


# ---------------------------------------------------------------------------------- 4. scene contract

def _scene_with_objects(folder, x_m=1.0, y_m=2.0, veg_x=0.0):
    from coastforge.scene import Scene, SceneObject, Vegetation, save_scene

    boat = SceneObject("boat_000", "boat", "runabout", x_m, y_m, 0.0, 10.0, (1.0, 1.0, 1.0), 6.0, 2.2)
    veg = Vegetation(np.array(["tree_a"], dtype=object), np.array(["vegetation"], dtype=object),
                     np.array([veg_x]), np.array([0.0]), np.array([0.0]), np.array([0.0]), np.array([1.0]))
    ids = np.zeros((N, N), np.uint8)
    save_scene(Scene(name="t", seed=0, gsd_m=GSD, extent_m=(N * GSD, N * GSD), height=np.zeros((N, N), np.float32),
                     classes=ids, objects=(boat,), vegetation=veg), folder)
    return folder


def _bad_scene(tmp_path, case):
    import json

    from coastforge.fsio import write_png

    folder = _scene_with_objects(tmp_path / "scene")
    doc = json.loads((folder / "scene.json").read_text())
    if case == "truncated_height":
        h = folder / "terrain" / "height.tif"
        h.write_bytes(h.read_bytes()[: len(h.read_bytes()) // 2])
    elif case == "truncated_classes":
        c = folder / "terrain" / "classes.png"
        c.write_bytes(c.read_bytes()[: len(c.read_bytes()) // 2])
    elif case == "classes_of_another_size":  # a 100x100 class map over the 64x64 scene (height gone)
        (folder / "terrain" / "height.tif").unlink()
        write_png(folder / "terrain" / "classes.png", np.zeros((100, 100), np.uint8))
    elif case == "height_of_another_size":
        from coastforge.fsio import write_geotiff

        write_geotiff(folder / "terrain" / "height.tif", np.zeros((32, 32), np.float32), (1, 0, 0, 0, -1, 0))
    elif case == "object_at_1e7":
        doc["objects"][0]["x_m"] = 1e7
    elif case == "object_at_nan":
        (folder / "scene.json").write_text(json.dumps(doc).replace('"y_m": 2.0', '"y_m": NaN'))
        return folder
    elif case == "vegetation_at_1e7":
        return _scene_with_objects(tmp_path / "scene2", veg_x=-1e7)
    (folder / "scene.json").write_text(json.dumps(doc))
    return folder


SCENE_CASES = [
    ("truncated_height", "height.tif is truncated or corrupt"),
    ("truncated_classes", "classes.png is truncated or corrupt"),
    ("classes_of_another_size", "classes.png is 100x100 px but the scene's grid is 64x64 px (extent_m 32 x 32 m at "
                                "gsd_m 0.5)"),
    ("height_of_another_size", "height.tif is 32x32 px but the scene's grid is 64x64 px"),
    ("object_at_1e7", "object 'boat_000' is at x_m = 10000000.0, y_m = 2.0, more than 100 m outside the scene"),
    ("object_at_nan", "objects[0] (id 'boat_000'): y_m = nan is not a finite number"),
    ("vegetation_at_1e7", "vegetation instance 0 (tree_a) is at x_m = -10000000.0"),
]


@pytest.mark.parametrize("case,phrase", SCENE_CASES)
def test_scene_contract_checked_on_load(tmp_path, case, phrase):
    from coastforge.errors import SceneFormatError
    from coastforge.scene import load_scene

    folder = _bad_scene(tmp_path, case)
    with pytest.raises(SceneFormatError) as e:
        load_scene(folder)
    assert phrase in str(e.value), str(e.value)
    assert "See previous exception" not in str(e.value)


def test_objects_near_the_border_still_load(tmp_path):
    from coastforge.scene import load_scene

    s = load_scene(_scene_with_objects(tmp_path / "s", x_m=16.0 + 99.0, veg_x=-110.0))  # within 100 m outside
    assert s.objects[0].x_m == 115.0


@pytest.mark.parametrize("case,phrase", [
    ("truncated_height", "height.tif is truncated or corrupt"),
    ("classes_of_another_size", "classes.png is 100x100 px but the scene's grid is 64x64 px"),
    ("object_at_1e7", "object 'boat_000' is at x_m = 10000000.0"),
    ("object_at_nan", "y_m = nan is not a finite number"),
])
def test_export_refuses_a_broken_scene_before_writing(tmp_path, case, phrase):
    folder = _bad_scene(tmp_path, case)
    out = tmp_path / "exports"
    r = CliRunner().invoke(cli, ["export", str(folder), "--format", "gltf", "--out", str(out)])
    assert r.exit_code == 2, r.output
    assert phrase in r.output.replace("\n", " ") and "Traceback" not in r.output
    assert _no_output(out)


# ---------------------------------------------------------------------------------------- 5. assets

def _box_glb(path, extents):
    import trimesh

    trimesh.creation.box(extents=extents).export(path)
    return path


def _manifest(folder, entries):
    import json

    p = folder / "manifest.json"
    p.write_text(json.dumps({"assets": entries}))
    return p


@pytest.mark.parametrize("category,extents,phrase", [
    ("boat", (1e6, 2.5e5, 1.5e5), "the closest guess, mm, gives a length of 1000 m (1.5-400 m expected)"),
    ("vehicle", (0.02, 0.008, 0.006), "the closest guess, m, gives a length of 0.02 m (2-25 m expected)"),
    ("tree", (4e5, 4e5, 9e5), "gives a height of 900 m"),
])
def test_absurd_mesh_sizes_refused(tmp_path, category, extents, phrase):
    from coastforge.assets.meshes import load_mesh, normalise_mesh
    from coastforge.errors import LibraryError

    p = _box_glb(tmp_path / "big.glb", extents)
    with pytest.raises(LibraryError) as e:
        normalise_mesh(load_mesh(p), category, asset_id="x", up_axis="+z", forward_axis="+x", source=p)
    msg = str(e.value)
    assert phrase in msg and str(p) in msg and "its raw extent is" in msg and "state its unit" in msg
    # with its unit stated the same model is taken at its word
    normalise_mesh(load_mesh(p), category, asset_id="x", up_axis="+z", forward_axis="+x", unit=1e-5)


def test_library_build_reports_an_absurd_mesh_with_its_file(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    _box_glb(src / "huge.glb", (1e6, 2.5e5, 1.5e5))
    man = _manifest(src, [{"id": "huge", "category": "boat", "mesh": "huge.glb", "up_axis": "+z"}])
    r = CliRunner().invoke(cli, ["library", "build", str(man), "--out", str(tmp_path / "lib"), "--strict",
                                 "--set", "library.lightings=1", "--set", "library.view_size_px=32"])
    assert r.exit_code == 2, r.output
    assert "asset 'huge'" in r.output and "huge.glb" in r.output and "raw extent" in r.output
    assert "Traceback" not in r.output
    assert not (tmp_path / "lib" / "library.json").exists()


@pytest.mark.parametrize("how", ["dotdot", "symlink", "symlinked_folder"])
def test_mesh_paths_outside_the_manifest_folder_refused(tmp_path, how):
    from coastforge.assets.library import read_manifest

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    _box_glb(outside / "boat.glb", (8, 2.5, 1.5))
    src = tmp_path / "src"
    src.mkdir()
    if how == "dotdot":
        mesh = "../elsewhere/boat.glb"
    elif how == "symlink":
        (src / "boat.glb").symlink_to(outside / "boat.glb")
        mesh = "boat.glb"
    else:
        (src / "models").symlink_to(outside, target_is_directory=True)
        mesh = "models/boat.glb"
    man = _manifest(src, [{"id": "b", "category": "boat", "mesh": mesh, "length_m": 8.0}])
    specs, skipped = read_manifest(man)
    assert not specs and len(skipped) == 1
    err = skipped[0].error
    assert "outside the manifest folder" in err or "escapes the manifest folder" in err
    assert "copy the model inside it" in err
    if how != "dotdot":
        assert f"is a link to {(outside / 'boat.glb').resolve()}" in err
    out = tmp_path / "lib"
    r = CliRunner().invoke(cli, ["library", "build", str(man), "--out", str(out)])
    assert r.exit_code == 2, r.output
    assert "no usable assets" in r.output and "copy the model inside it" in r.output.replace("\n", " ")
    assert _no_output(out)


def test_a_symlink_inside_the_folder_still_works(tmp_path):
    from coastforge.assets.library import read_manifest

    src = tmp_path / "src"
    (src / "real").mkdir(parents=True)
    _box_glb(src / "real" / "boat.glb", (8, 2.5, 1.5))
    (src / "boat.glb").symlink_to(src / "real" / "boat.glb")
    specs, skipped = read_manifest(_manifest(src, [{"id": "b", "category": "boat", "mesh": "boat.glb"}]))
    assert [s.id for s in specs] == ["b"] and not skipped
