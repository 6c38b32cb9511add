"""DEM / bathymetry fusion: user GeoTIFFs (any CRS, any vertical offset) override the estimate where they
have data and are blended into it across a seam band, so there is no step at the edge of their coverage.

Each file is reprojected onto the scene grid with ``rasterio.warp.reproject`` (bilinear, nodata honoured),
shifted by its vertical offset (``value * scale + offset``, e.g. a datum-to-water-level correction), and
mosaicked (later files win). Outside the data the estimate is corrected by the DEM-minus-estimate residual
found at the nearest data pixel, fading to zero over ``seam_m``: the fused surface equals the DEM on its
data and is continuous across its edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from ..config import TerrainConfig
from ..errors import CoastforgeWarning, InputError
from ..types import Grid

# deeper than the Challenger Deep and higher than Everest: such values are an undeclared nodata value
# (1e30, -3.4e38, 32767 in feet x ...) or wrong units, and bilinear resampling would smear them into real cells
DEM_MAX_ABS_M = 12_000.0


def check_dem_files(specs: Sequence) -> list[DemSource]:
    """The parsed ``--dem`` specs; an ``InputError`` for one whose file is missing or a folder (before any
    work is done)."""
    out = [DemSource.parse(spec) for spec in specs]
    for dem in out:
        if not dem.path.is_file():
            raise InputError(f"--dem {dem.path} {'is a folder' if dem.path.is_dir() else 'does not exist'}; "
                             "pass a DEM / bathymetry GeoTIFF")
    return out


@dataclass(frozen=True)
class DemSource:
    path: Path
    offset_m: float = 0.0  # added after scaling: heights relative to the scene's water level
    scale: float = 1.0  # e.g. 0.3048 for a DEM in feet

    @staticmethod
    def parse(spec: str | Path | DemSource) -> DemSource:
        """``FILE``, ``FILE:offset=-0.3`` or ``FILE:offset=-0.3,scale=0.3048``."""
        if isinstance(spec, DemSource):
            return spec
        if isinstance(spec, Path):
            return DemSource(spec)
        text = str(spec)
        path, opts = text, ""
        head, sep, tail = text.rpartition(":")
        if sep and "=" in tail and head:
            path, opts = head, tail
        offset, scale = 0.0, 1.0
        for item in filter(None, (o.strip() for o in opts.split(","))):
            key, _, val = item.partition("=")
            try:
                num = float(val)
            except ValueError:
                num = math.nan
            if not math.isfinite(num):
                raise InputError(f"--dem {text!r}: {key}={val!r} is not a finite number; e.g. {path}:offset=-0.3")
            if key.strip() == "offset":
                offset = num
            elif key.strip() == "scale":
                if num == 0:
                    raise InputError(f"--dem {text!r}: scale must not be 0")
                scale = num
            else:
                raise InputError(f"--dem {text!r}: unknown option {key!r}; use offset=M and/or scale=S")
        return DemSource(Path(path), offset, scale)


@dataclass(frozen=True)
class Placement:
    """Where an un-georeferenced scene lies on a map: the CRS and the map coordinates of the scene's
    top-left corner (north-up, square pixels of the scene's gsd)."""

    crs: str
    origin_x: float
    origin_y: float


@dataclass(frozen=True)
class FusionInfo:
    files: tuple[str, ...]
    coverage: float  # fraction of scene pixels with DEM data
    per_file_coverage: tuple[float, ...]


def scene_georeference(grid: Grid, placement: Placement | None = None):
    """(CRS, Affine) of the scene grid, from the placement if given, else from the input GeoTIFF."""
    from affine import Affine
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    if placement is not None:
        try:
            crs = CRS.from_user_input(placement.crs)
        except CRSError as exc:
            raise InputError(f"--dem-crs {placement.crs!r} is not a CRS rasterio understands ({exc}); "
                             "use e.g. EPSG:32633") from exc
        if crs.is_geographic:
            raise InputError(f"--dem-crs {placement.crs!r} is geographic (degrees); the scene is in metres, "
                             "so "
                             "place it in a projected CRS (e.g. its UTM zone, EPSG:326xx)")
        g = grid.gsd_m
        return crs, Affine(g, 0.0, placement.origin_x, 0.0, -g, placement.origin_y)
    if grid.crs is None or grid.transform is None:
        raise InputError(
            "--dem needs to know where the scene is on the map, but the scene has no georeference; use a "
            "GeoTIFF input image, or give the placement with --dem-crs CRS --dem-origin X Y (map coordinates "
            "of the image's top-left corner)")
    try:
        crs = CRS.from_user_input(grid.crs)
    except CRSError as exc:
        raise InputError(f"the scene's crs {grid.crs!r} is not readable ({exc}); give --dem-crs/--dem-origin") from exc
    return crs, Affine(*grid.transform)


def reproject_dem(src_path: Path, grid: Grid, dst_crs, dst_transform, scale: float = 1.0,
                  offset_m: float = 0.0) -> np.ndarray:
    """One DEM on the scene grid, float32 with NaN where it has no data (raw values: ``scale`` and
    ``offset_m`` only say which values are absurd heights, beyond ±``DEM_MAX_ABS_M`` m)."""
    import rasterio
    from rasterio.errors import RasterioIOError, WindowError
    from rasterio.warp import Resampling, reproject, transform_bounds
    from rasterio.windows import Window

    if not src_path.is_file():
        raise InputError(f"--dem {src_path} does not exist; check the path")
    try:
        src = rasterio.open(src_path)
    except RasterioIOError as exc:
        raise InputError(f"--dem {src_path} is not a readable GeoTIFF ({exc})") from exc
    with src:
        if src.crs is None or src.transform.is_identity:
            raise InputError(f"--dem {src_path} has no georeference (CRS and transform); a DEM must be a "
                             "GeoTIFF "
                             "with both, e.g. from NOAA CUDEM, GEBCO or EMODnet")
        # read only the part of the DEM under the scene (a national tile may be far larger than the scene)
        h, w = grid.shape
        x0, y0 = dst_transform @ (0, 0)
        x1, y1 = dst_transform @ (w, h)
        win = None
        overlap = True
        try:
            sb = transform_bounds(dst_crs, src.crs, min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1),
                                  densify_pts=21)
            inv = ~src.transform
            cr = np.array([inv @ (x, y) for x in (sb[0], sb[2]) for y in (sb[1], sb[3])])
            c0, r0 = np.floor(cr.min(axis=0)).astype(int) - 2
            c1, r1 = np.ceil(cr.max(axis=0)).astype(int) + 3
            win = Window(int(c0), int(r0), int(c1 - c0), int(r1 - r0))
            win = win.intersection(Window(0, 0, src.width, src.height))
            overlap = win.width > 0 and win.height > 0
        except WindowError:
            overlap = False  # the windows do not intersect
        except ValueError:
            win = None  # bounds that do not transform (e.g. beyond a projection's domain): read it all
        if not overlap:
            _no_data(src, src_path, dst_crs, x0, y0, x1, y1)
        try:
            data = src.read(1, window=win, masked=True)
        except RasterioIOError as exc:
            from ..io import gdal_reason

            raise InputError(f"--dem {src_path} is truncated or corrupt: {gdal_reason(exc)}; re-download or "
                             "re-export it") from exc
        src_transform = src.transform
        if win is not None:
            from affine import Affine

            src_transform = src.transform @ Affine.translation(win.col_off, win.row_off)
        arr = data.filled(np.nan).astype(np.float32) if np.ma.isMaskedArray(data) else data.astype(np.float32)
        if src.nodata is not None and not np.isnan(src.nodata):
            arr[arr == np.float32(src.nodata)] = np.nan
        _drop_absurd(arr, src_path, scale, offset_m)
        dst = np.full(grid.shape, np.nan, np.float32)
        reproject(arr, dst, src_transform=src_transform, src_crs=src.crs, src_nodata=np.nan,
                  dst_transform=dst_transform, dst_crs=dst_crs, dst_nodata=np.nan,
                  resampling=Resampling.bilinear)
        if not np.isfinite(dst).any():
            _no_data(src, src_path, dst_crs, x0, y0, x1, y1)
    return dst


def _drop_absurd(arr: np.ndarray, src_path: Path, scale: float, offset_m: float) -> None:
    """NaN (no data) for heights beyond ±DEM_MAX_ABS_M m, with a warning; refuse a DEM with nothing else."""
    import warnings

    valid = np.isfinite(arr)
    if not valid.any():
        raise InputError(f"--dem {src_path} holds only nodata (or NaN) under the scene; check it is the right "
                         "file and that its nodata value is set right (gdalinfo -stats)")
    with np.errstate(over="ignore", invalid="ignore"):
        absurd = valid & ~(np.abs(arr.astype(np.float64) * scale + offset_m) <= DEM_MAX_ABS_M)
    n = int(absurd.sum())
    if not n:
        return
    example = float(arr[absurd][0])
    fix = (f"declare the file's nodata value (gdal_edit.py -a_nodata {example:g} FILE), or fix its units with "
           "--dem FILE:scale=S")
    if n == int(valid.sum()):
        raise InputError(f"--dem {src_path}: every value under the scene is beyond ±{DEM_MAX_ABS_M:g} m (e.g. "
                         f"{example:g}), which no real height is; {fix}")
    warnings.warn(f"--dem {src_path}: {n} of {int(valid.sum())} cells under the scene hold values beyond "
                  f"±{DEM_MAX_ABS_M:g} m (e.g. {example:g}); they are treated as nodata. To silence this, {fix}",
                  CoastforgeWarning, stacklevel=3)
    arr[absurd] = np.nan


def _no_data(src, src_path, dst_crs, x0, y0, x1, y1):
    from rasterio.warp import transform_bounds

    sb = transform_bounds(src.crs, dst_crs, *src.bounds)
    raise InputError(
        f"--dem {src_path} has no data over the scene: it covers {tuple(round(v, 2) for v in sb)} but the "
        f"scene covers ({min(x0, x1):.2f}, {min(y0, y1):.2f}, {max(x0, x1):.2f}, {max(y0, y1):.2f}) in "
        f"{dst_crs}; check the DEM's CRS or the scene's placement")


def blend_dem(estimate: np.ndarray, dem: np.ndarray, gsd_m: float, seam_m: float) -> np.ndarray:
    """DEM values where finite; elsewhere the estimate plus the nearest DEM residual, fading over
    ``seam_m``."""
    from scipy.ndimage import distance_transform_edt

    from .default import smooth

    valid = np.isfinite(dem)
    if valid.all():
        return dem.astype(np.float32)
    if not valid.any():
        return estimate.astype(np.float32)
    est = estimate.astype(np.float32)
    resid = np.where(valid, dem - est, np.float32(0))
    dist_px, (ir, ic) = distance_transform_edt(~valid, return_indices=True)
    r_nn = resid[ir, ic]  # residual carried out from the nearest data pixel
    seam_px = max(seam_m / gsd_m, 1.0)
    # the nearest-pixel residual jumps where two edge stretches meet; smooth it away from the edge only,
    # so the surface still meets the DEM exactly at the edge
    r_s = smooth(r_nn, seam_px / 4.0)
    a = np.clip(dist_px / (0.5 * seam_px), 0.0, 1.0).astype(np.float32)
    r_ext = r_nn + (r_s - r_nn) * a
    fade = (0.5 * (1.0 + np.cos(np.pi * np.clip(dist_px / seam_px, 0.0, 1.0)))).astype(np.float32)
    return np.where(valid, dem, est + r_ext * fade).astype(np.float32)


def fuse_dems(estimate: np.ndarray, grid: Grid, dems: Sequence, config: TerrainConfig,
              placement: Placement | None = None) -> tuple[np.ndarray, FusionInfo]:
    """Reproject, offset and mosaic ``dems`` (later ones win) and blend them into ``estimate``."""
    sources = [DemSource.parse(d) for d in dems]
    if not sources:
        return estimate, FusionInfo((), 0.0, ())
    crs, transform = scene_georeference(grid, placement)
    mosaic = np.full(grid.shape, np.nan, np.float32)
    per_file = []
    for s in sources:
        v = reproject_dem(s.path, grid, crs, transform, s.scale, s.offset_m)
        ok = np.isfinite(v)
        mosaic[ok] = v[ok] * np.float32(s.scale) + np.float32(s.offset_m)
        per_file.append(float(ok.mean()))
    fused = blend_dem(estimate, mosaic, grid.gsd_m, config.seam_m)
    info = FusionInfo(tuple(str(s.path) for s in sources), float(np.isfinite(mosaic).mean()), tuple(per_file))
    return fused, info
