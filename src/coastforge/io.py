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
from .types import Affine, GeoImage, Grid, affine6

MIN_SIDE_PX = 16  # smaller images hold no shore profile or object to find (1 px broke np.gradient)
MAX_ASPECT = 64  # longer strips are almost always a damaged or mis-sized file (every test image is under 5:1)
MAX_SIDE_PX = 32766  # OpenCV's remap (learned segmentation, renders) takes sides below SHRT_MAX

# Working memory of a generate run (measured with the default preset on 0.8-3.2 Mpx images at 0.1-5 m/px,
# rounded up): the libraries and models, every raster on the image grid (image, class map, height, shore
# field, weight maps, masks), the copies the learned stages resample to their working GSD, and the
# vegetation scatter's candidates (one per cell of its finest spacing over the whole extent in m²).
_BASE_BYTES = 0.5 * 2**30
_BYTES_PER_PX = 160
_BYTES_PER_DETECT_WORK_PX = 8  # learned/hybrid detector: the image at 0.2 m/px (tiles are bounded)
_BYTES_PER_SEGMENT_WORK_PX = 96  # learned segmenter: probabilities and classical votes, 8 float32 each
_BYTES_PER_SCATTER_CELL = 100


def check_image_size(path, w: int, h: int, whole: bool = True) -> None:
    """Refuse sizes no stage can work with (``whole``: the image is read at once, not in tiles)."""
    if w <= 0 or h <= 0:
        raise InputError(f"{path} has zero size ({w}x{h} px)")
    if min(w, h) < MIN_SIDE_PX:
        raise InputError(f"{path} is {w}x{h} px; coastforge needs at least {MIN_SIDE_PX} px on each side "
                         "(a scene a few pixels across has no shore or object to find); use a larger image")
    if max(w, h) > MAX_ASPECT * min(w, h):
        raise InputError(f"{path} is {w}x{h} px, a {max(w, h) / min(w, h):.0f}:1 strip; coastforge takes images "
                         f"up to {MAX_ASPECT}:1; check the file is not damaged, or crop the strip into pieces "
                         "closer to square")
    if whole and max(w, h) > MAX_SIDE_PX:
        raise InputError(f"{path} is {w}x{h} px; an image read whole may be at most {MAX_SIDE_PX} px on a side "
                         "(OpenCV's limit); crop it, or downsample it (gdal_translate -outsize)")


def image_damage(path) -> str | None:
    """Why a PNG or JPEG file is truncated or corrupt, or None (other formats: None). GDAL reads a cut PNG
    with black below the cut and a damaged JPEG with grey blocks, without an error: check first."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
            if head == b"\x89PNG\r\n\x1a\n":
                return _png_damage(fh)
    except OSError as exc:
        return str(exc)
    if head[:3] == b"\xff\xd8\xff":
        import rasterio

        try:  # libjpeg's warnings (missing or corrupt data) as errors; at 1/8 scale it still decodes every block
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # NotGeoreferencedWarning
                with rasterio.Env(GDAL_ERROR_ON_LIBJPEG_WARNING="TRUE"), rasterio.open(path) as src:
                    src.read(1, out_shape=(max(1, src.height // 8), max(1, src.width // 8)))
        except Exception as exc:  # noqa: BLE001 - GDAL raises its own CPLE_* types
            return gdal_reason(exc)
    return None


def gdal_reason(exc: BaseException) -> str:
    """GDAL's own message behind rasterio's "Read failed. See previous exception for details."."""
    import re

    cause = exc.__cause__ or exc.__context__
    msg = str(cause if cause is not None and str(cause) else exc)
    return re.sub(r"^.*IReadBlock failed at X offset \d+, Y offset \d+: ", "", msg)  # keep libjpeg's/libtiff's words


def _png_damage(fh) -> str | None:
    """Walk the PNG chunks after the signature: each must be whole with a matching CRC, up to IEND."""
    import struct
    import zlib

    while True:
        hdr = fh.read(8)
        if len(hdr) < 8:
            return "the file ends before its IEND chunk"
        n, kind = struct.unpack(">I4s", hdr)
        data = fh.read(n)
        crc = fh.read(4)
        if len(data) < n or len(crc) < 4:
            return f"the file ends inside its {kind.decode('latin-1')} chunk"
        if zlib.crc32(data, zlib.crc32(kind)) != struct.unpack(">I", crc)[0]:
            return f"its {kind.decode('latin-1')} chunk fails the CRC check"
        if kind == b"IEND":
            return None


def refuse_damaged(path) -> None:
    """Refuse a truncated or corrupt PNG or JPEG (``image_damage``) before it is read."""
    why = image_damage(path)
    if why:
        raise InputError(f"{path} is truncated or corrupt: {why}; re-export or re-download it")


def estimate_memory_bytes(width: int, height: int, gsd_m: float, stages=None, read_bytes_per_px: float = 0.0,
                          tiled: bool = False) -> dict[str, float]:
    """Estimated working memory (bytes, per part) of a run on a ``width`` x ``height`` image at ``gsd_m``.

    ``stages`` (a ``Config``) adds what its backends allocate beyond the image grid; without it, only the
    image-grid rasters count (reading and one stage). ``tiled``: segmentation and detection run per tile
    (their resampled copies are bounded), the grid is the scene grid."""
    px = float(width) * float(height)
    parts = {"libraries": _BASE_BYTES, "image-sized rasters": px * (_BYTES_PER_PX + read_bytes_per_px)}
    if stages is None:
        return parts
    if stages.detect.backend in ("learned", "hybrid") and not tiled:
        from .detection.learned import DEFAULT_META, MAX_GSD_M, MIN_GSD_M

        if MIN_GSD_M <= gsd_m <= MAX_GSD_M:
            parts["learned detector"] = px * (gsd_m / DEFAULT_META["work_gsd_m"]) ** 2 * _BYTES_PER_DETECT_WORK_PX
    if stages.segment.backend == "learned" and not tiled:
        lo, hi, work = _segmenter_scales()
        if lo <= gsd_m <= hi:
            parts["learned segmenter"] = px * (gsd_m / work) ** 2 * _BYTES_PER_SEGMENT_WORK_PX
    v = stages.vegetation
    if v.enabled:  # candidates over the whole extent, at most vegetation.MAX_CANDIDATES cells per rule
        from .vegetation import MAX_CANDIDATES, RULES

        live = [r for r in RULES if getattr(v, r.density_key) > 0]
        if live:
            cell = min(max(r.spacing_m, v.min_spacing_m if r.asset_category == "tree" else 0.0) for r in live)
            parts["vegetation scatter"] = min(px * gsd_m**2 / cell**2, MAX_CANDIDATES) * _BYTES_PER_SCATTER_CELL
    return parts


def _segmenter_scales() -> tuple[float, float, float]:
    """(lowest, highest, working) GSD of the shipped learned segmenter, from its metadata."""
    import json
    from importlib import resources

    from .segmentation.learned import GSD_RANGE_M

    try:
        meta = json.loads(resources.files("coastforge").joinpath("data/models/segmenter.json").read_text())
        lo, hi = meta.get("gsd_range_m", GSD_RANGE_M)
        return float(lo), float(hi), float(meta["work_gsd_m"])
    except (OSError, KeyError, ValueError, TypeError):
        return GSD_RANGE_M[0], GSD_RANGE_M[1], 0.3


def check_memory(path, width: int, height: int, gsd_m: float, cfg: IOConfig, stages=None,
                 read_bytes_per_px: float = 0.0, tiled: bool = False) -> None:
    """Refuse a run whose estimated working memory is over ``io.max_memory_gb``, before any work."""
    parts = estimate_memory_bytes(width, height, gsd_m, stages, read_bytes_per_px, tiled)
    total = sum(parts.values())
    if total <= cfg.max_memory_gb * 2**30:
        return
    big = max(parts, key=parts.get)
    todo = {"vegetation scatter": "turn vegetation off (--set vegetation.enabled=false) or crop a smaller area",
            "learned detector": "use --set detect.backend=classical, or a crop of the image",
            "learned segmenter": "use --set segment.backend=classical, or a crop of the image",
            }.get(big, "crop or downsample the image (generate reads images over 4096x4096 px in tiles)")
    raise InputError(
        f"{path} ({width}x{height} px at {gsd_m:.4g} m/px, {width * gsd_m / 1000:.3g} x {height * gsd_m / 1000:.3g} "
        f"km) would need about {total / 2**30:.1f} GiB of working memory, over io.max_memory_gb = "
        f"{cfg.max_memory_gb:g} (mostly the {big}: {parts[big] / 2**30:.1f} GiB); {todo}; check the image's scale "
        "(--gsd, --size-m or its georeference); or raise the "
        "limit with --set io.max_memory_gb=N if this machine has the memory")


def open_image(path: Path):
    """The image opened with rasterio, or ``InputError`` saying why it cannot be (missing, a folder, a pipe,
    not an image)."""
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning, RasterioIOError

    if not path.exists():
        raise InputError(f"image {path} does not exist; check the path")
    if path.is_dir():
        raise InputError(f"image {path} is a folder; pass an image file (PNG, JPEG, TIFF or GeoTIFF)")
    if not path.is_file():  # a named pipe or a device: reading it may never end
        raise InputError(f"image {path} is not a regular file (a pipe or a device?); pass an image file (PNG, "
                         "JPEG, TIFF or GeoTIFF), e.g. save the stream to a file first")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            return rasterio.open(path)
    except RasterioIOError as exc:
        raise InputError(
            f"{path} is not a readable image ({exc}); coastforge reads PNG, JPEG, TIFF and GeoTIFF"
        ) from exc


def is_georeferenced(src) -> bool:
    """True when an open raster has a CRS and a non-identity transform."""
    return src.crs is not None and not src.transform.is_identity


def _utm_crs(lon: float, lat: float) -> str:
    zone = int((lon + 180.0) // 6.0) % 60 + 1
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def resolve_gsd(width: int, height: int, gsd_m: float | None, size_m: tuple[float, float] | None,
                geo_gsd: tuple[float, float] | None, tol: float, where: str,
                gsd_range: tuple[float, float] | None = None) -> float:
    """The metres-per-pixel of an image from whichever of the three sources are given; they must agree
    (and lie in ``gsd_range``, when given)."""
    cands: list[tuple[str, float]] = []
    if gsd_m is not None:
        if not (isinstance(gsd_m, (int, float)) and math.isfinite(gsd_m) and 0 < gsd_m):
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
    if gsd_range is not None and not gsd_range[0] <= ref <= gsd_range[1]:
        lo, hi = gsd_range
        fix = {"--gsd": "--gsd is metres per pixel (0.2 for a 20 cm orthophoto): check its value",
               "--size-m": "--size-m is the width and height in metres: check the values",
               }.get(ref_name, "check the GeoTIFF's CRS and transform (a pixel size in degrees or feet under a "
                               "metric CRS?)")
        raise InputError(
            f"{ref_name} gives {ref:.6g} m/px for {where}, outside the {lo:g}-{hi:g} m/px coastforge works with "
            f"(drone to satellite imagery); {fix}; if the value is right, widen the range with --set "
            f"io.{'min' if ref < lo else 'max'}_gsd_m=...")
    return ref


def read_image(path: str | Path, gsd_m: float | None = None, size_m: tuple[float, float] | None = None,
               config: IOConfig | None = None, stages=None) -> GeoImage:
    """Read an RGB image and its grid. Raises ``InputError`` with a clear message on bad input.

    ``stages`` (the run's ``Config``) makes the memory estimate count what its stages will allocate."""
    cfg = config or IOConfig()
    path = Path(path)
    src = open_image(path)
    with src:
        w, h = src.width, src.height
        check_header(src, path, cfg)
        geo = is_georeferenced(src)
        if geo and src.crs.is_geographic:
            return _read_geographic(src, path, gsd_m, size_m, cfg, stages)
        geo_gsd = None
        transform = crs = None
        if geo:
            geo_gsd, transform, crs = north_up_georef(src, path)
        gsd = resolve_gsd(w, h, gsd_m, size_m, geo_gsd, cfg.gsd_tolerance, str(path), (cfg.min_gsd_m, cfg.max_gsd_m))
        check_memory(path, w, h, gsd, cfg, stages, _read_bytes_per_px(src.dtypes[0]))
        refuse_damaged(path)
        rgb = _to_uint8(_read_bands(src, path), path)
    return GeoImage(rgb=rgb, grid=Grid(w, h, gsd, crs, transform), path=str(path))


PIXEL_TYPES = ("uint8", "uint16", "float32", "float64", "int16")


def check_header(src, path, cfg: IOConfig, whole: bool = True) -> None:
    """The checks of an open image's header, before any pixel is read: its pixel count against
    ``io.max_pixels``, its size (``check_image_size``; ``whole``: read at once, not in tiles), its bands and
    its pixel type."""
    w, h = src.width, src.height
    if w * h > cfg.max_pixels:
        raise InputError(
            f"{path} claims {w}x{h} = {w * h / 1e6:.0f} Mpx, over the limit of {cfg.max_pixels / 1e6:.0f} Mpx "
            "(a decompression bomb, or an image to run tiled); raise it with --set io.max_pixels=N if you mean it"
        )
    check_image_size(path, w, h, whole=whole)
    check_bands(src, path)
    if src.dtypes[0] not in PIXEL_TYPES:
        raise InputError(f"{path} has pixel type {src.dtypes[0]}; expected 8- or 16-bit RGB")


def check_bands(src, path) -> None:
    """Refuse what is not a colour image, saying what it is (palette, animation, grey, grey + alpha)."""
    n = src.count
    interp = [ci.name for ci in src.colorinterp]
    if "palette" in interp:
        if src.driver == "GIF" and n > 1:
            kind, how = f"an animated GIF ({n} frames)", "save one frame as an RGB PNG"
        else:
            kind, how = "a palette (indexed-colour) image", "gdal_translate -expand rgb IN OUT.tif"
        raise InputError(f"{path} is {kind}; coastforge needs an RGB image (PNG, JPEG, TIFF or GeoTIFF); convert "
                         f"it, e.g. {how} (or PIL: Image.open(IN).convert('RGB').save(OUT))")
    if n < 3:
        kind = "alpha-only or gray+alpha" if n == 2 or "alpha" in interp else "single-band (grayscale)"
        raise InputError(
            f"{path} is {kind} with {n} band(s); coastforge needs a colour (RGB) image — colour classes "
            "(water, grass, sand) cannot be told apart in one band"
        )


def _read_bytes_per_px(dtype: str) -> float:
    """Extra bytes per pixel of reading a non-8-bit image (the bands, a float32 copy, the stretch)."""
    return 0.0 if dtype == "uint8" else 3 * np.dtype(dtype).itemsize + 24.0


def _read_bands(src, path: Path) -> np.ndarray:
    """Bands 1-3, refusing an image without a single valid pixel (all nodata, or fully transparent)."""
    from rasterio.errors import RasterioIOError

    try:
        bands = src.read([1, 2, 3])
        masked = any(f.name != "all_valid" for flags in src.mask_flag_enums[:3] for f in flags)
        if masked and not src.dataset_mask().any():
            if "alpha" in [c.name for c in src.colorinterp]:
                what, fix = "fully transparent (alpha 0 everywhere)", "export it again with its pixels visible"
            else:
                what, fix = (f"nodata everywhere (nodata = {src.nodata!r})",
                             "check it is the right file, or fix its nodata value (gdal_edit.py -a_nodata V)")
            raise InputError(f"{path} is {what}: it holds no image; {fix}")
    except RasterioIOError as exc:
        raise InputError(f"{path} is truncated or corrupt: {gdal_reason(exc)}; re-export or re-download it") from exc
    return bands


def north_up_georef(src, path) -> tuple[tuple[float, float], Affine, str]:
    """(GSD x, y), the affine transform and the CRS of an open, projected, georeferenced raster."""
    t = src.transform
    if abs(t.b) > 1e-12 or abs(t.d) > 1e-12:
        raise InputError(f"{path} has a rotated georeference; warp it north-up (gdalwarp) first")
    return (abs(t.a), abs(t.e)), affine6((t.a, t.b, t.c, t.d, t.e, t.f)), src.crs.to_string()


def _to_uint8(bands: np.ndarray, path: Path) -> np.ndarray:
    a = np.moveaxis(bands, 0, -1)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    a = a.astype(np.float32)
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        raise InputError(f"{path} holds no finite pixel values (every pixel is NaN or infinite); export the image "
                         "with its pixels")
    lo, hi = np.percentile(finite, [0.5, 99.5])  # a robust stretch for 16-bit or float imagery
    if hi <= lo:
        hi = lo + 1.0
    return np.clip((np.nan_to_num(a, nan=lo) - lo) / (hi - lo) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _read_geographic(src, path: Path, gsd_m, size_m, cfg: IOConfig, stages=None) -> GeoImage:
    """Reproject a lat/lon image to its UTM zone (metres) so the scene is metric."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject, transform_bounds

    try:
        lon0, lat0, lon1, lat1 = transform_bounds(src.crs, "EPSG:4326", *src.bounds)
        dst_crs = _utm_crs((lon0 + lon1) / 2, (lat0 + lat1) / 2)
        transform, w, h = calculate_default_transform(src.crs, dst_crs, src.width, src.height, *src.bounds)
    except Exception as exc:  # GDAL raises its own CPLE_* types (e.g. metres under a lat/lon CRS)
        raise InputError(f"{path} claims a geographic CRS ({src.crs.to_string()}) but its bounds {tuple(src.bounds)} "
                         f"cannot be reprojected ({exc}); check its CRS and transform (gdalinfo)") from exc
    res = (abs(transform.a) + abs(transform.e)) / 2.0
    from affine import Affine

    transform = Affine(res, 0, transform.c, 0, -res, transform.f)
    warnings.warn(
        f"{path} is in a geographic CRS ({src.crs.to_string()}); reprojected to {dst_crs} at {res:.3g} m/px",
        GeoreferenceWarning, stacklevel=3,
    )
    check_image_size(f"{path} reprojected to {dst_crs}", w, h)
    if w * h > cfg.max_pixels:
        raise InputError(f"{path} reprojected to {dst_crs} is {w}x{h} px, over io.max_pixels "
                         f"({cfg.max_pixels / 1e6:.0f} Mpx); check its georeference, or raise the limit with "
                         "--set io.max_pixels=N")
    gsd = resolve_gsd(w, h, gsd_m, size_m, (res, res), cfg.gsd_tolerance, str(path), (cfg.min_gsd_m, cfg.max_gsd_m))
    # the source bands are held beside the reprojected ones
    src_px = src.width * src.height / max(1, w * h)
    check_memory(path, w, h, gsd, cfg, stages,
                 _read_bytes_per_px(src.dtypes[0]) + 3 * np.dtype(src.dtypes[0]).itemsize * (1 + src_px))
    refuse_damaged(path)
    dst = np.zeros((3, h, w), dtype=src.dtypes[0])
    bands = _read_bands(src, path)
    for b in range(3):
        reproject(bands[b], dst[b], src_transform=src.transform, src_crs=src.crs,
                  dst_transform=transform, dst_crs=dst_crs, resampling=Resampling.bilinear)
    rgb = _to_uint8(dst, path)
    return GeoImage(rgb=rgb, grid=Grid(w, h, gsd, dst_crs, tuple(transform)[:6]), path=str(path))
