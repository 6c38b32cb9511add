from __future__ import annotations


import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from coastforge.config import IOConfig
from coastforge.errors import GeoreferenceWarning, InputError
from coastforge.fsio import write_jpeg, write_png
from coastforge.io import read_image


def rgb(h=40, w=60):
    return np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8)


def geotiff(path, crs, transform, bands=3, h=40, w=60, dtype="uint8"):
    with rasterio.open(path, "w", driver="GTiff", width=w, height=h, count=bands, dtype=dtype, crs=crs,
                       transform=transform) as dst:
        dst.write(np.random.default_rng(1).integers(0, 200, (bands, h, w)).astype(dtype))
    return path


def test_png_with_gsd(tmp_path):
    write_png(tmp_path / "a.png", rgb())
    img = read_image(tmp_path / "a.png", gsd_m=0.2)
    assert img.rgb.shape == (40, 60, 3) and img.grid.gsd_m == 0.2 and img.grid.extent_m == pytest.approx((12, 8))
    assert img.grid.crs is None


def test_jpeg_with_size(tmp_path):
    write_jpeg(tmp_path / "a.jpg", rgb())
    img = read_image(tmp_path / "a.jpg", size_m=(30.0, 20.0))
    assert img.grid.gsd_m == pytest.approx(0.5)


def test_rgba_png_drops_alpha(tmp_path):
    a = np.dstack([rgb(), np.full((40, 60), 255, np.uint8)])
    write_png(tmp_path / "a.png", a)
    assert read_image(tmp_path / "a.png", gsd_m=1).rgb.shape == (40, 60, 3)


def test_geotiff_projected(tmp_path):
    p = geotiff(tmp_path / "g.tif", "EPSG:32633", from_origin(500000, 4000000, 0.25, 0.25))
    img = read_image(p)
    assert img.grid.gsd_m == 0.25 and img.grid.crs == "EPSG:32633" and img.grid.transform[2] == 500000


def test_geotiff_agreeing_gsd_ok_disagreeing_fails(tmp_path):
    p = geotiff(tmp_path / "g.tif", "EPSG:32633", from_origin(500000, 4000000, 0.25, 0.25))
    assert read_image(p, gsd_m=0.25).grid.gsd_m == 0.25
    with pytest.raises(InputError, match=r"--gsd gives 0.5 m/px but the GeoTIFF georeference gives 0.25"):
        read_image(p, gsd_m=0.5)


def test_geographic_is_reprojected_with_warning(tmp_path):
    p = geotiff(tmp_path / "g.tif", "EPSG:4326", from_origin(10.0, 44.0, 0.00001, 0.00001))
    with pytest.warns(GeoreferenceWarning, match="reprojected to EPSG:32632"):
        img = read_image(p)
    assert img.grid.crs == "EPSG:32632" and 0.5 < img.grid.gsd_m < 1.2


def test_16bit_is_stretched(tmp_path):
    p = geotiff(tmp_path / "g.tif", "EPSG:32633", from_origin(0, 0, 1, 1), dtype="uint16")
    img = read_image(p)
    assert img.rgb.dtype == np.uint8 and img.rgb.max() > 200


@pytest.mark.parametrize("case,msg", [
    ("missing", "does not exist"),
    ("folder", "is a folder"),
    ("text", "not a readable image"),
    ("gray", "single-band"),
    ("graya", "alpha"),
    ("nosize", "pass --gsd M"),
    ("both", "give only one"),
    ("nonsquare", "non-square pixels"),
    ("geo_nonsquare", "non-square pixels"),
    ("bomb", "decompression bomb"),
    ("badgsd", "must be a positive number"),
])
def test_bad_inputs_have_clear_errors(tmp_path, case, msg):
    kw = {}
    if case == "missing":
        p = tmp_path / "nope.png"
    elif case == "folder":
        p = tmp_path
    elif case == "text":
        p = tmp_path / "a.png"
        p.write_text("hello, not an image")
    elif case == "gray":
        p = tmp_path / "g.png"
        write_png(p, rgb()[:, :, 0])
        kw = {"gsd_m": 1}
    elif case == "graya":
        p = geotiff(tmp_path / "ga.tif", None, from_origin(0, 0, 1, 1), bands=2)
        kw = {"gsd_m": 1}
    else:
        p = tmp_path / "a.png"
        write_png(p, rgb())
        if case == "both":
            kw = {"gsd_m": 0.2, "size_m": (60.0, 40.0)}  # size says 1 m/px
        elif case == "nonsquare":
            kw = {"size_m": (60.0, 80.0)}
        elif case == "bomb":
            kw = {"gsd_m": 1.0, "config": IOConfig(max_pixels=1000)}
        elif case == "badgsd":
            kw = {"gsd_m": -1.0}
        elif case == "geo_nonsquare":
            p = geotiff(tmp_path / "n.tif", "EPSG:32633", from_origin(0, 0, 0.5, 0.25))
    with pytest.raises(InputError, match=msg):
        read_image(p, **kw)
