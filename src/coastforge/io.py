"""Image input: PNG, JPEG, TIFF and GeoTIFF through rasterio, with the ground size resolved.

The size comes from ``gsd_m`` (metres per pixel), ``size_m`` (width, height in metres) or the
GeoTIFF's georeference. A geographic CRS is reprojected to its UTM zone with a warning.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from .config import IOConfig
from .errors import GeoreferenceWarning, InputError
from .types import GeoImage, Grid


def _open(path: Path):
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning, RasterioIOError

    if not path.exists():
        raise InputError(f"image {path} does not exist; check the path")
    if path.is_dir():
        raise InputError(f"image {path} is a folder; pass an image file (PNG, JPEG, TIFF or GeoTIFF)")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            return rasterio.open(path)
    except RasterioIOError as exc:
        raise InputError(
            f"{path} is not a readable image ({exc}); coastforge reads PNG, JPEG, TIFF and GeoTIFF"
        ) from exc


def _is_georeferenced(src) -> bool:
    return src.crs is not None and not src.transform.is_identity


def _utm_crs(lon: float, lat: float) -> str:
    zone = int((lon + 180.0) // 6.0) % 60 + 1
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def resolve_gsd(width: int, height: int, gsd_m: float | None, size_m: tuple[float, float] | None,
                geo_gsd: tuple[float, float] | None, tol: float, where: str) -> float:
    """The metres-per-pixel of an image from whichever of the three sources are given; they must agree."""
    cands: list[tuple[str, float]] = []
    if gsd_m is not None:
        if not (isinstance(gsd_m, (int, float)) and math.isfinite(gsd_m) and 0 < gsd_m <= 1000):
            raise InputError(f"--gsd {gsd_m!r} must be a positive number of metres per pixel (e.g. 0.2)")
        cands.append(("--gsd", float(gsd_m)))
    if size_m is not None:
        w_m, h_m = size_m
        if not all(math.isfinite(v) and v > 0 for v in (w_m, h_m)):
            raise InputError(f"--size-m {w_m} {h_m} must be two positive widths in metres")
        gx, gy = w_m / width, h_m / height
        if abs(gx - gy) > tol * max(gx, gy):
            raise InputError(
                f"--size-m {w_m:g} {h_m:g} gives non-square pixels for a {width}x{height} image "
                f"({gx:.4g} x {gy:.4g} m/px); check the size, or resample the image to square pixels"
            )
        cands.append(("--size-m", (gx + gy) / 2.0))
    if geo_gsd is not None:
        gx, gy = geo_gsd
        if abs(gx - gy) > tol * max(gx, gy):
            raise InputError(
                f"{where} has non-square pixels ({gx:.6g} x {gy:.6g} m/px); resample it to square pixels "
                "(e.g. gdalwarp -tr R R) first"
            )
        cands.append(("the GeoTIFF georeference", (gx + gy) / 2.0))
    if not cands:
        raise InputError(
            f"{where} has no georeference, so its size is unknown; pass --gsd M (metres per pixel) "
            "or --size-m WIDTH HEIGHT (metres)"
        )
    ref_name, ref = cands[0]
    for name, v in cands[1:]:
        if abs(v - ref) > tol * max(v, ref):
            raise InputError(
                f"{ref_name} gives {ref:.6g} m/px but {name} gives {v:.6g} m/px for {where}; "
                "give only one, or make them agree"
            )
    return ref


def read_image(path: str | Path, gsd_m: float | None = None, size_m: tuple[float, float] | None = None,
               config: IOConfig | None = None) -> GeoImage:
    """Read an RGB image and its grid. Raises ``InputError`` with a clear message on bad input."""
    cfg = config or IOConfig()
    path = Path(path)
    src = _open(path)
    with src:
        w, h, n = src.width, src.height, src.count
        if w <= 0 or h <= 0:
            raise InputError(f"{path} has zero size ({w}x{h} px)")
        if w * h > cfg.max_pixels:
            raise InputError(
                f"{path} claims {w}x{h} = {w * h / 1e6:.0f} Mpx, over the limit of {cfg.max_pixels / 1e6:.0f} Mpx "
                "(a decompression bomb, or an image to run tiled); raise it with --set io.max_pixels=N if you mean it"
            )
        interp = [ci.name for ci in src.colorinterp]
        if n < 3:
            kind = "alpha-only or gray+alpha" if n == 2 or "alpha" in interp else "single-band (grayscale)"
            raise InputError(
                f"{path} is {kind} with {n} band(s); coastforge needs a colour (RGB) image — colour classes "
                "(water, grass, sand) cannot be told apart in one band"
            )
        if src.dtypes[0] not in ("uint8", "uint16", "float32", "float64", "int16"):
            raise InputError(f"{path} has pixel type {src.dtypes[0]}; expected 8- or 16-bit RGB")
        geo = _is_georeferenced(src)
        if geo and src.crs.is_geographic:
            return _read_geographic(src, path, gsd_m, size_m, cfg)
        geo_gsd = None
        transform = crs = None
        if geo:
            geo_gsd, transform, crs = north_up_georef(src, path)
        gsd = resolve_gsd(w, h, gsd_m, size_m, geo_gsd, cfg.gsd_tolerance, str(path))
        rgb = _to_uint8(src.read([1, 2, 3]), path)
    return GeoImage(rgb=rgb, grid=Grid(w, h, gsd, crs, transform), path=str(path))


def north_up_georef(src, path) -> tuple[tuple[float, float], tuple[float, ...], str]:
    """(GSD x, y), the affine transform and the CRS of an open, projected, georeferenced raster."""
    t = src.transform
    if abs(t.b) > 1e-12 or abs(t.d) > 1e-12:
        raise InputError(f"{path} has a rotated georeference; warp it north-up (gdalwarp) first")
    return (abs(t.a), abs(t.e)), tuple(float(v) for v in (t.a, t.b, t.c, t.d, t.e, t.f)), src.crs.to_string()


def _to_uint8(bands: np.ndarray, path: Path) -> np.ndarray:
    a = np.moveaxis(bands, 0, -1)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    a = a.astype(np.float32)
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        raise InputError(f"{path} holds no finite pixel values")
    lo, hi = np.percentile(finite, [0.5, 99.5])  # a robust stretch for 16-bit or float imagery
    if hi <= lo:
        hi = lo + 1.0
    return np.clip((np.nan_to_num(a, nan=lo) - lo) / (hi - lo) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _read_geographic(src, path: Path, gsd_m, size_m, cfg: IOConfig) -> GeoImage:
    """Reproject a lat/lon image to its UTM zone (metres) so the scene is metric."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject, transform_bounds

    lon0, lat0, lon1, lat1 = transform_bounds(src.crs, "EPSG:4326", *src.bounds)
    dst_crs = _utm_crs((lon0 + lon1) / 2, (lat0 + lat1) / 2)
    transform, w, h = calculate_default_transform(src.crs, dst_crs, src.width, src.height, *src.bounds)
    res = (abs(transform.a) + abs(transform.e)) / 2.0
    from affine import Affine

    transform = Affine(res, 0, transform.c, 0, -res, transform.f)
    warnings.warn(
        f"{path} is in a geographic CRS ({src.crs.to_string()}); reprojected to {dst_crs} at {res:.3g} m/px",
        GeoreferenceWarning, stacklevel=3,
    )
    if w * h > cfg.max_pixels:
        raise InputError(f"{path} reprojected is {w}x{h} px, over the io.max_pixels limit")
    gsd = resolve_gsd(w, h, gsd_m, size_m, (res, res), cfg.gsd_tolerance, str(path))
    dst = np.zeros((3, h, w), dtype=src.dtypes[0])
    for b in range(3):
        reproject(src.read(b + 1), dst[b], src_transform=src.transform, src_crs=src.crs,
                  dst_transform=transform, dst_crs=dst_crs, resampling=Resampling.bilinear)
    rgb = _to_uint8(dst, path)
    return GeoImage(rgb=rgb, grid=Grid(w, h, gsd, dst_crs, tuple(transform)[:6]), path=str(path))
