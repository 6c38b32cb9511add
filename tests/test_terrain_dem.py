"""DEM fusion: generated GeoTIFFs in UTM and EPSG:4326 with nodata holes, onto a UTM scene grid."""

from __future__ import annotations

import numpy as np
import pytest
from affine import Affine

from coastforge.bench.terrain import synthetic_class_map
from coastforge.config import TerrainConfig
from coastforge.errors import InputError
from coastforge.fsio import write_geotiff
from coastforge.terrain import estimate_terrain
from coastforge.terrain.dem import DemSource, Placement, blend_dem
from coastforge.types import ClassMap, Grid

CRS = "EPSG:32610"
X0, Y0 = 550_000.0, 4_180_000.0  # top-left corner of the scene in UTM 10N (San Francisco Bay)
GSD = 1.0
N = 160


def plane(x, y):
    """The 'true' surface the DEMs sample: a tilted plane in UTM metres (bilinear reproduces it exactly)."""
    return -6.0 + 0.03 * (x - X0) + 0.02 * (Y0 - y)


def scene_grid() -> Grid:
    return Grid(N, N, GSD, CRS, (GSD, 0.0, X0, 0.0, -GSD, Y0))


def _utm_dem(path, nodata=-9999.0):
    """A 2 m UTM DEM over the west 60 % of the scene, with a square nodata hole."""
    res = 2.0
    w, h = int(0.6 * N * GSD / res), int(N * GSD / res)
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    z = plane(X0 + cols * res, Y0 - rows * res).astype(np.float32)
    z[15:30, 10:25] = nodata
    write_geotiff(path, z, (res, 0.0, X0, 0.0, -res, Y0), crs=CRS, nodata=nodata)
    return path


def _geo_dem(path):
    """An EPSG:4326 DEM over the south-east of the scene, NaN nodata in a stripe."""
    from rasterio.warp import transform as warp_transform

    xs, ys = [X0 + 0.5 * N, X0 + N + 20], [Y0 - 0.5 * N, Y0 - N - 20]
    lon, lat = warp_transform(CRS, "EPSG:4326", [xs[0], xs[1], xs[0], xs[1]], [ys[0], ys[0], ys[1], ys[1]])
    lon0, lon1, lat0, lat1 = min(lon), max(lon), min(lat), max(lat)
    w, h = 120, 120
    dlon, dlat = (lon1 - lon0) / w, (lat1 - lat0) / h
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    lons, lats = lon0 + cols * dlon, lat1 - rows * dlat
    ux, uy = warp_transform("EPSG:4326", CRS, lons.ravel(), lats.ravel())
    z = plane(np.array(ux), np.array(uy)).reshape(h, w).astype(np.float32) + 0.3  # a datum 0.3 m off
    z[:, 50:56] = np.nan
    write_geotiff(path, z, tuple(Affine(dlon, 0, lon0, 0, -dlat, lat1))[:6], crs="EPSG:4326",
                  nodata=float("nan"))
    return path


def _fused(tmp_path, dems, grid=None, placement=None, seam_m=12.0):
    ids = synthetic_class_map("bank", N, GSD)
    cm = ClassMap(ids, grid or scene_grid())
    cfg = TerrainConfig(seam_m=seam_m)
    base = estimate_terrain(cm, cfg).height.z_m
    res = estimate_terrain(cm, cfg, dems=dems, placement=placement)
    return base, res


def test_utm_and_geographic_dems_match_where_they_have_data(tmp_path):
    a = _utm_dem(tmp_path / "utm.tif")
    b = _geo_dem(tmp_path / "geo.tif")
    base, res = _fused(tmp_path, [str(a), f"{b}:offset=-0.3"])
    z = res.height.z_m
    cols, rows = np.meshgrid(np.arange(N) + 0.5, np.arange(N) + 0.5)
    truth = plane(X0 + cols * GSD, Y0 - rows * GSD)
    # where each DEM has data well inside its coverage, the result is the DEM (bilinear of a plane = plane)
    hole = (rows > 28) & (rows < 62) & (cols > 18) & (cols < 52)
    utm_in = (cols < 0.6 * N - 3) & (cols > 2) & (rows > 2) & (rows < N - 2) & ~hole
    assert np.abs(z[utm_in] - truth[utm_in]).max() < 0.02
    geo_in = (cols > 0.5 * N + 3) & (rows > 0.5 * N + 3)
    geo_in &= np.abs(z - truth) < 10  # the NaN stripe is filled from the estimate
    err = np.abs(z[geo_in] - truth[geo_in])
    assert np.median(err) < 0.02 and (err < 0.05).mean() > 0.8
    assert 0.3 < res.diagnostics.dem_coverage < 1.0
    assert len(res.diagnostics.dem_files) == 2
    # far from any DEM data the estimate is untouched
    far = (cols > 0.6 * N + 15) & (rows < 0.5 * N - 15)
    assert np.allclose(z[far], base[far])


def test_seam_has_no_step_beyond_the_local_slope(tmp_path):
    a = _utm_dem(tmp_path / "utm.tif")
    base, res = _fused(tmp_path, [str(a)], seam_m=12.0)
    z = res.height.z_m
    # neighbour steps of the estimate alone and of the plane bound what a seamless blend may show
    slope_est = max(np.abs(np.diff(base, axis=0)).max(), np.abs(np.diff(base, axis=1)).max())
    slope_dem = 0.03 * GSD
    resid = np.abs(z - base).max()
    # the residual fades over seam_m with a cosine: at most resid * pi / (2 * seam_px) extra per pixel
    allowed = max(slope_est, slope_dem) + resid * np.pi / (2 * 12.0 / GSD) + 0.05
    step = max(np.abs(np.diff(z, axis=0)).max(), np.abs(np.diff(z, axis=1)).max())
    assert step <= allowed, f"step {step:.3f} > allowed {allowed:.3f}"
    # the check is sensitive: pasting the DEM in without the seam would step at its edge
    from affine import Affine as _A
    from rasterio.crs import CRS as _CRS

    from coastforge.terrain.dem import reproject_dem

    grid = scene_grid()
    dem = reproject_dem(a, grid, _CRS.from_user_input(CRS), _A(*grid.transform))
    naive = np.where(np.isfinite(dem), dem, base)
    naive_step = max(np.abs(np.diff(naive, axis=0)).max(), np.abs(np.diff(naive, axis=1)).max())
    assert naive_step > allowed


def test_blend_meets_the_dem_exactly_at_its_edge():
    est = np.zeros((50, 50), np.float32)
    dem = np.full((50, 50), np.nan, np.float32)
    dem[:, :20] = 3.0
    out = blend_dem(est, dem, 1.0, 10.0)
    assert np.all(out[:, :20] == 3.0)
    assert np.allclose(out[:, 20], 3.0, atol=0.1)  # first pixel outside: nearly the DEM
    assert np.allclose(out[:, 31:], 0.0)  # beyond the seam: the estimate
    assert (np.diff(out[:, 19:32], axis=1) <= 1e-6).all()  # monotone fade, no bump


def test_placement_for_an_ungeoreferenced_scene(tmp_path):
    a = _utm_dem(tmp_path / "utm.tif")
    plain = Grid(N, N, GSD)
    with pytest.raises(InputError, match="--dem-origin"):
        _fused(tmp_path, [str(a)], grid=plain)
    _, res = _fused(tmp_path, [str(a)], grid=plain, placement=Placement(CRS, X0, Y0))
    assert res.diagnostics.dem_coverage > 0.3
    with pytest.raises(InputError, match="geographic"):
        _fused(tmp_path, [str(a)], grid=plain, placement=Placement("EPSG:4326", -122.4, 37.8))


def test_bad_dem_inputs(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        _fused(tmp_path, [str(tmp_path / "missing.tif")])
    far = tmp_path / "far.tif"
    write_geotiff(far, np.ones((10, 10), np.float32), (1.0, 0, 100.0, 0, -1.0, 200.0), crs=CRS)
    with pytest.raises(InputError, match="no data over the scene"):
        _fused(tmp_path, [str(far)])
    with pytest.raises(InputError, match="offset"):
        DemSource.parse("x.tif:offset=abc")
    with pytest.raises(InputError, match="unknown option"):
        DemSource.parse("x.tif:shift=1")


def test_dem_spec_parsing():
    s = DemSource.parse("/data/cudem.tif:offset=-0.3,scale=0.3048")
    assert str(s.path) == "/data/cudem.tif" and s.offset_m == -0.3 and s.scale == 0.3048
    assert DemSource.parse("C:/dems/a.tif").path.name == "a.tif"
    assert DemSource.parse("plain.tif").offset_m == 0.0
