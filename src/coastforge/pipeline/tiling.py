"""Large orthophotos in bounded memory: windowed reads, tiled segmentation / detection / terrain.

The image is never read whole. It is cut into *core* tiles of ``tile_px`` that partition it; each tile is
read with ``overlap_px`` of context on every side (clipped at the image border) and only its core is kept,
so a pixel-local result equals untiled processing everywhere, and a context-dependent one (the classical
segmenter) equals it away from the seams as far as its context reaches.

- ``open_source`` resolves the grid (``coastforge.io`` rules) and one global 8-bit stretch from a
  decimated read, so every tile is stretched alike.
- ``segment_tiled`` writes class ids into a uint8 array (or a memory-mapped ``.npy`` for huge images).
- ``detect_tiled`` returns detections in full-image pixels, merged across tiles with rotated NMS: a box
  cut by a tile edge loses to the whole box the neighbouring tile holds; pier walkways longer than the
  overlap are joined from their cut pieces.
- ``terrain_tiled`` runs the terrain per tile with an overlap of the terrain's influence distance.
- ``piers_tiled`` and ``match_tiled`` run pier chaining and matching region by region.

``tiled.TiledImage``, the chain's front end for such images, runs its stages with these.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from collections.abc import Callable, Iterator

import numpy as np

from ..classes import N_CLASSES
from ..config import Config, DetectConfig, IOConfig, SegmentConfig, TerrainConfig
from ..errors import ConfigError, InputError
from ..types import ClassMap, Detection, GeoImage, Grid

PIER_CATEGORIES = ("pier_walkway", "pier_finger")


# ------------------------------------------------------------------------------------------ windows

@dataclass(frozen=True)
class Tile:
    """One tile: the read window (core plus overlap, clipped to the image) and the core it owns."""

    i: int  # column index of the tile
    j: int  # row index
    col_off: int  # read window, full-image pixels
    row_off: int
    width: int
    height: int
    core: tuple[int, int, int, int]  # (c0, r0, c1, r1) owned part, full-image pixels, end exclusive

    @property
    def window(self):
        from rasterio.windows import Window

        return Window(self.col_off, self.row_off, self.width, self.height)

    def core_local(self) -> tuple[slice, slice]:
        """(rows, cols) slices of the core inside the read window."""
        c0, r0, c1, r1 = self.core
        return (slice(r0 - self.row_off, r1 - self.row_off), slice(c0 - self.col_off, c1 - self.col_off))

    def core_global(self) -> tuple[slice, slice]:
        c0, r0, c1, r1 = self.core
        return (slice(r0, r1), slice(c0, c1))


def check_tiling(tile_px: int, overlap_px: int) -> None:
    if not (isinstance(tile_px, int) and tile_px >= 32):
        raise ConfigError(f"tile_px = {tile_px!r} must be an integer ≥ 32 (e.g. 2048)")
    if not (isinstance(overlap_px, int) and 0 <= overlap_px <= 4 * tile_px):
        raise ConfigError(f"overlap_px = {overlap_px!r} must be an integer between 0 and 4 x tile_px "
                          f"({4 * tile_px}); e.g. 256")


def iter_windows(width: int, height: int, tile_px: int, overlap_px: int) -> Iterator[Tile]:
    """Tiles in row-major order whose cores partition the ``width`` x ``height`` image."""
    check_tiling(tile_px, overlap_px)
    if width <= 0 or height <= 0:
        raise InputError(f"cannot tile an image of {width}x{height} px")
    nx, ny = -(-width // tile_px), -(-height // tile_px)
    for j in range(ny):
        r0, r1 = j * tile_px, min(height, (j + 1) * tile_px)
        wr0, wr1 = _span(r0, r1, height, tile_px, overlap_px)
        for i in range(nx):
            c0, c1 = i * tile_px, min(width, (i + 1) * tile_px)
            wc0, wc1 = _span(c0, c1, width, tile_px, overlap_px)
            yield Tile(i, j, wc0, wr0, wc1 - wc0, wr1 - wr0, (c0, r0, c1, r1))


def _span(a: int, b: int, size: int, tile_px: int, overlap_px: int) -> tuple[int, int]:
    """Read span of the core [a, b): the overlap on both sides, and at the image border (or for a short last
    tile) pushed inward so every window has the same size: an edge tile gets as much context as the others
    (a context-dependent backend sees a strip of open water, not a corner of it)."""
    want = min(size, tile_px + 2 * overlap_px)
    w0, w1 = max(0, a - overlap_px), min(size, b + overlap_px)
    w0 = max(0, min(w0, w1 - want))
    w1 = min(size, max(w1, w0 + want))
    return w0, w1


# ------------------------------------------------------------------------------------------- source

@dataclass(frozen=True)
class Source:
    """An image opened for windowed reading: its grid and the global 8-bit stretch (None for uint8)."""

    path: str
    grid: Grid
    stretch: tuple[float, float] | None


def open_source(path: str | Path, gsd_m: float | None = None, size_m: tuple[float, float] | None = None,
                config: IOConfig | None = None, overview_px: int = 2048) -> Source:
    """Check the image like ``coastforge.io.read_image`` does and resolve its grid without reading it whole."""
    from .. import io as cio

    cfg = config or IOConfig()
    path = Path(path)
    with cio.open_image(path) as src:
        w, h = src.width, src.height
        cio.check_header(src, path, cfg, whole=False)
        dtype = src.dtypes[0]
        geo_gsd = crs = transform = None
        if cio.is_georeferenced(src):
            if src.crs.is_geographic:
                raise InputError(f"{path} is in a geographic CRS ({src.crs.to_string()}); a large image is read in "
                                 "tiles and cannot be reprojected on the fly: warp it to its UTM zone first "
                                 "(gdalwarp -t_srs EPSG:326xx)")
            geo_gsd, transform, crs = cio.north_up_georef(src, path)
        gsd = cio.resolve_gsd(w, h, gsd_m, size_m, geo_gsd, cfg.gsd_tolerance, str(path),
                              (cfg.min_gsd_m, cfg.max_gsd_m))
        stretch = None
        if dtype != "uint8":
            # one stretch for every tile, from a decimated read (GDAL uses overviews when the file has them)
            f = max(1, int(math.ceil(max(w, h) / overview_px)))
            ov = src.read([1, 2, 3], out_shape=(3, max(1, h // f), max(1, w // f))).astype(np.float32)
            finite = ov[np.isfinite(ov)]
            if finite.size == 0:
                raise InputError(f"{path} holds no finite pixel values")
            lo, hi = (float(v) for v in np.percentile(finite, [0.5, 99.5]))
            stretch = (lo, hi if hi > lo else lo + 1.0)
    cio.refuse_damaged(path)
    return Source(str(path), Grid(w, h, gsd, crs, transform), stretch)


def _to_u8(bands: np.ndarray, stretch: tuple[float, float] | None) -> np.ndarray:
    a = np.moveaxis(bands, 0, -1)
    if stretch is None:
        return np.ascontiguousarray(a, dtype=np.uint8)
    lo, hi = stretch
    a = np.nan_to_num(a.astype(np.float32), nan=lo)
    return np.clip((a - lo) / (hi - lo) * 255.0 + 0.5, 0, 255).astype(np.uint8)


def read_window(path: str | Path | Source, window, source: Source | None = None) -> GeoImage:
    """RGB uint8 of one window (a ``Tile`` or a rasterio ``Window``) as a ``GeoImage`` whose grid carries the
    window's size and, for a georeferenced image, the window's own transform."""
    import rasterio
    from rasterio.windows import Window

    src_info = path if isinstance(path, Source) else (source or open_source(path))
    win = window.window if isinstance(window, Tile) else window
    if not isinstance(win, Window):
        raise InputError(f"read_window needs a Tile or a rasterio Window, got {type(window).__name__}")
    g = src_info.grid
    with warnings.catch_warnings():
        from rasterio.errors import NotGeoreferencedWarning

        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(src_info.path) as src:
            bands = src.read([1, 2, 3], window=win, boundless=False)
    t = None
    if g.transform is not None:
        a, b, c, d, e, f = g.transform
        co, ro = float(win.col_off), float(win.row_off)
        t = (a, b, c + a * co + b * ro, d, e, f + d * co + e * ro)
    rgb = _to_u8(bands, src_info.stretch)
    h, w = rgb.shape[:2]
    return GeoImage(rgb=rgb, grid=Grid(w, h, g.gsd_m, g.crs, t), path=src_info.path)


def read_overview(source: Source, width_px: int, height_px: int) -> GeoImage:
    """The whole image averaged down to ``width_px`` x ``height_px`` (for previews and scene-grid outputs)."""
    import rasterio
    from rasterio.enums import Resampling

    with warnings.catch_warnings():
        from rasterio.errors import NotGeoreferencedWarning

        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(source.path) as src:
            bands = src.read([1, 2, 3], out_shape=(3, height_px, width_px), resampling=Resampling.average)
    return GeoImage(_to_u8(bands, source.stretch), source.grid.resized(width_px, height_px), source.path)


def _source_for(path, grid: Grid | None) -> Source:
    if grid is None:
        return open_source(path)
    # the caller's grid wins (it may carry a --gsd the file does not know); the stretch comes from the file
    probe = open_source(path, gsd_m=None if grid.transform is not None else grid.gsd_m)
    if (probe.grid.width_px, probe.grid.height_px) != (grid.width_px, grid.height_px):
        raise InputError(f"the grid is {grid.width_px}x{grid.height_px} px but {path} is "
                         f"{probe.grid.width_px}x{probe.grid.height_px}; pass the grid of this image")
    return Source(probe.path, grid, probe.stretch)


def _source(path, grid, source) -> Source:
    if isinstance(path, Source):
        return path
    return source if source is not None else _source_for(path, grid)


# ----------------------------------------------------------------------------------------- segment

Segmenter = Callable[[GeoImage, int], ClassMap]


def segment_tiled(path, grid: Grid | None = None, config: SegmentConfig | None = None, tile_px: int = 2048,
                  overlap_px: int = 256, seed: int = 0, *, source: Source | None = None, backend: str | None = None,
                  segmenter: Segmenter | None = None, out: str | Path | None = None,
                  progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Class ids (H, W) uint8 for the whole image, segmented tile by tile; each tile's overlap is discarded.

    ``segmenter(image, seed) -> ClassMap`` replaces the registry backend (tests, custom models). ``out``:
    write into a memory-mapped ``.npy`` file instead of RAM (for images whose ids do not fit)."""
    from ..segmentation import segment

    src = _source(path, grid, source)
    cfg = config or SegmentConfig()
    W, H = src.grid.width_px, src.grid.height_px
    ids: np.ndarray
    if out is not None:
        ids = np.lib.format.open_memmap(str(out), mode="w+", dtype=np.uint8, shape=(H, W))
    else:
        ids = np.empty((H, W), np.uint8)
    tiles = list(iter_windows(W, H, tile_px, overlap_px))
    for k, t in enumerate(tiles):
        img = read_window(src, t)
        cm = segmenter(img, seed) if segmenter is not None else segment(img, cfg, backend=backend, seed=seed)
        tid = np.asarray(cm.ids)
        if tid.shape != img.rgb.shape[:2]:
            raise InputError(f"the segmenter returned a {tid.shape} class map for a {img.rgb.shape[:2]} tile")
        ids[t.core_global()] = tid[t.core_local()]
        del img, cm, tid
        if progress:
            progress(k + 1, len(tiles))
    if isinstance(ids, np.memmap):
        ids.flush()
    return ids


# ------------------------------------------------------------------------------------------ detect

Detector = Callable[[GeoImage, ClassMap | None, int], list[Detection]]


def _shift(d: Detection, dc: float, dr: float) -> Detection:
    o = d.mask_origin_px
    return replace(d, cx_px=d.cx_px + dc, cy_px=d.cy_px + dr,
                   mask_origin_px=None if o is None else (int(o[0] + dc), int(o[1] + dr)))


def _cut_by_edge(d: Detection, t: Tile, W: int, H: int, margin: float) -> bool:
    """True when the box reaches a side of the tile's read window that is inside the image."""
    c = d.corners_px()
    lo, hi = c.min(0), c.max(0)
    x0, y0, x1, y1 = t.col_off, t.row_off, t.col_off + t.width, t.row_off + t.height
    return bool((x0 > 0 and lo[0] <= x0 + margin) or (y0 > 0 and lo[1] <= y0 + margin)
                or (x1 < W and hi[0] >= x1 - margin) or (y1 < H and hi[1] >= y1 - margin))


def _axis_extent(d: Detection, ux: float, uy: float, cx: float, cy: float) -> tuple[float, float, float]:
    """Along-axis start/end and the lateral offset of a box relative to a line (c, u)."""
    s = (d.cx_px - cx) * ux + (d.cy_px - cy) * uy
    lat = -(d.cx_px - cx) * uy + (d.cy_px - cy) * ux
    return s - d.length_px / 2.0, s + d.length_px / 2.0, lat


def _bbox(d: Detection) -> np.ndarray:
    c = d.corners_px()
    return np.concatenate([c.min(0), c.max(0)])


class _GridIndex:
    """Axis-aligned boxes hashed into square cells, for "which boxes may touch this one" in O(1) per query
    (the all-pairs checks were quadratic in the number of boxes, i.e. in the image area)."""

    def __init__(self, cell_px: float = 256.0):
        self.cell = float(cell_px)
        self.cells: dict[tuple[int, int], list[int]] = {}
        self.boxes: list[np.ndarray] = []

    def _keys(self, b: np.ndarray):
        c = self.cell
        for gy in range(int(b[1] // c), int(b[3] // c) + 1):
            for gx in range(int(b[0] // c), int(b[2] // c) + 1):
                yield gx, gy

    def add(self, b: np.ndarray) -> int:
        k = len(self.boxes)
        self.boxes.append(b)
        for key in self._keys(b):
            self.cells.setdefault(key, []).append(k)
        return k

    def query(self, b: np.ndarray, pad: float = 0.0) -> list[int]:
        """Indices of the added boxes whose bounds overlap ``b`` grown by ``pad``, in insertion order."""
        q = b + np.array([-pad, -pad, pad, pad])
        found: set[int] = set()
        for key in self._keys(q):
            found.update(self.cells.get(key, ()))
        return sorted(k for k in found if self.boxes[k][0] <= q[2] and q[0] <= self.boxes[k][2]
                      and self.boxes[k][1] <= q[3] and q[1] <= self.boxes[k][3])


def merge_cut_fragments(dets: list[Detection], angle_tol_deg: float = 6.0) -> list[Detection]:
    """Join collinear, overlapping or touching pieces of one long structure (a pier walkway cut by tile
    edges) into one box spanning them. Pieces are merged only within a category.

    Pieces can only join when their bounds touch, so the pieces are split into groups of touching bounds
    (grown by a few pixels and the widest piece, the most a joined box can reach past its pieces) and each
    group is merged on its own: linear in the number of groups instead of cubic in all pieces."""
    if len(dets) < 2:
        return list(dets)
    pad = 4.0 + max(d.width_px for d in dets)
    boxes = [_bbox(d) for d in dets]
    index = _GridIndex(max(256.0, 4 * pad))
    parent = list(range(len(dets)))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for k, b in enumerate(boxes):
        for j in index.query(b, pad):
            if dets[j].category == dets[k].category:
                parent[root(j)] = root(k)
        index.add(b)
    groups: dict[int, list[Detection]] = {}
    for k, d in enumerate(dets):
        groups.setdefault(root(k), []).append(d)
    out: list[Detection] = []
    for g in groups.values():  # dict order: groups in order of their first piece
        out.extend(_merge_fragment_group(g, angle_tol_deg))
    return out


def _merge_fragment_group(dets: list[Detection], angle_tol_deg: float) -> list[Detection]:
    from ..frames import direction_px, wrap_half_deg

    pending = list(dets)
    merged = True
    while merged and len(pending) > 1:
        merged = False
        for a_i in range(len(pending)):
            a = pending[a_i]
            ux, uy = direction_px(a.yaw_deg)
            for b_i in range(a_i + 1, len(pending)):
                b = pending[b_i]
                if b.category != a.category:
                    continue
                if abs(float(wrap_half_deg(a.yaw_deg - b.yaw_deg))) > angle_tol_deg:
                    continue
                a0, a1, _ = _axis_extent(a, ux, uy, a.cx_px, a.cy_px)
                b0, b1, lat = _axis_extent(b, ux, uy, a.cx_px, a.cy_px)
                if abs(lat) > 0.5 * max(a.width_px, b.width_px) + 1.0:
                    continue
                if b0 > a1 + 2.0 or a0 > b1 + 2.0:
                    continue  # a gap along the axis: two structures
                s0, s1 = min(a0, b0), max(a1, b1)
                mid = (s0 + s1) / 2.0
                wa, wb = a.length_px, b.length_px
                width = (a.width_px * wa + b.width_px * wb) / (wa + wb)
                keep = a if a.score >= b.score else b
                joined = replace(keep, cx_px=a.cx_px + ux * mid + (-uy) * lat * wb / (wa + wb),
                                 cy_px=a.cy_px + uy * mid + ux * lat * wb / (wa + wb),
                                 length_px=s1 - s0, width_px=width, yaw_deg=a.yaw_deg,
                                 mask=None, mask_origin_px=None)
                pending[a_i] = joined
                del pending[b_i]
                merged = True
                break
            if merged:
                break
    return pending


def indexed_nms(dets: list[Detection], iou_threshold: float = 0.3, ioa_threshold: float | None = None,
                cell_px: float = 256.0) -> list[Detection]:
    """``detection.nms.rotated_nms`` (class-aware) with the kept boxes in a grid index: the same greedy
    order and tests, so the same result, but each box is compared with the kept boxes near it only
    (``rotated_nms`` scans every kept box for every box: quadratic in the area of a large image)."""
    from ..detection.nms import polygon_ioa, polygon_iou

    if not dets:
        return []
    order = sorted(range(len(dets)), key=lambda i: -dets[i].score)
    corners = [d.corners_px() for d in dets]
    index = _GridIndex(cell_px)
    kept: list[int] = []
    for i in order:
        b = np.concatenate([corners[i].min(0), corners[i].max(0)])
        ok = True
        for slot in index.query(b):
            j = kept[slot]
            if dets[j].category != dets[i].category:
                continue
            if polygon_iou(corners[i], corners[j]) > iou_threshold or (
                    ioa_threshold is not None and polygon_ioa(corners[i], corners[j]) > ioa_threshold):
                ok = False
                break
        if ok:
            index.add(b)
            kept.append(i)
    return [dets[i] for i in kept]


def merge_tile_detections(per_tile: list[tuple[Tile, list[Detection]]], width: int, height: int,
                          iou: float = 0.3, ioa: float = 0.6, edge_margin_px: float = 1.5) -> list[Detection]:
    """Detections of all tiles (already in full-image pixels) → one list without duplicates.

    Ranking for the rotated NMS: whole boxes beat boxes cut by a tile edge, then boxes whose centre lies in
    their tile's core (the tile that sees the most context around them), then the score. Pier pieces cut
    by tile edges are first joined along their axis (a walkway may be longer than the overlap)."""
    entries: list[tuple[Detection, bool, bool]] = []  # (detection, cut, centre in core)
    cut_piers: list[Detection] = []
    for t, dets in per_tile:
        c0, r0, c1, r1 = t.core
        for d in dets:
            cut = _cut_by_edge(d, t, width, height, edge_margin_px)
            in_core = c0 <= d.cx_px < c1 and r0 <= d.cy_px < r1
            if cut and d.category in PIER_CATEGORIES:
                cut_piers.append(d)
            else:
                entries.append((d, cut, in_core))
    for d in merge_cut_fragments(cut_piers):
        entries.append((d, True, True))
    proxies, back = [], {}
    for d, cut, in_core in entries:
        rank = (0.0 if cut else 4.0) + (2.0 if in_core else 0.0) + min(max(d.score, 0.0), 1.0)
        p = replace(d, score=rank, mask=None)
        back[id(p)] = d
        proxies.append(p)
    kept = indexed_nms(proxies, iou_threshold=iou, ioa_threshold=ioa)
    out = [back[id(p)] for p in kept]
    out.sort(key=lambda d: (-d.score, d.cy_px, d.cx_px))
    return out


def detect_tiled(path, grid: Grid | None = None, config: DetectConfig | None = None,
                 class_ids: np.ndarray | None = None, tile_px: int = 2048, overlap_px: int = 256, seed: int = 0, *,
                 source: Source | None = None, backend: str | None = None, detector: Detector | None = None,
                 keep_masks: bool = False, progress: Callable[[int, int], None] | None = None,
                 side=None) -> list[Detection]:
    """Detections over the whole image in full-image pixel coordinates, tile by tile, merged across tile
    borders (see ``merge_tile_detections``). ``class_ids``: the full (H, W) class map, if any.
    An object is found whole when ``overlap_px`` ≥ half its length; longer pier walkways are joined.
    ``side`` (a ``runtime.SideProcess``): the hybrid detector's classical half of each tile runs there,
    beside its network here, as in a whole-image run."""
    from ..detection import detect, drop_cut_by_frame

    src = _source(path, grid, source)
    cfg = config or DetectConfig()
    split = side is not None and detector is None and (backend or cfg.backend) == "hybrid"
    W, H = src.grid.width_px, src.grid.height_px
    if class_ids is not None and class_ids.shape != (H, W):
        raise InputError(f"class_ids shape {class_ids.shape} differs from the image's {(H, W)}; "
                         "pass the class map of the same image")
    tiles = list(iter_windows(W, H, tile_px, overlap_px))
    per_tile = []
    for k, t in enumerate(tiles):
        img = read_window(src, t)
        cm = None
        if class_ids is not None:
            cm = ClassMap(np.ascontiguousarray(class_ids[t.row_off:t.row_off + t.height,
                                                         t.col_off:t.col_off + t.width]), img.grid)
        if detector is not None:
            dets = detector(img, cm, seed)
        else:
            opts = {}
            if split:
                from ..detection.hybrid import classical_part

                opts["classical_dets"] = side.submit(classical_part, img, cm, cfg, seed)
            dets = detect(img, cfg, class_map=cm, backend=backend, seed=seed, whole_image=False, **opts)
        shifted = [_shift(d if keep_masks else replace(d, mask=None, mask_origin_px=None), t.col_off, t.row_off)
                   for d in dets]
        per_tile.append((t, shifted))
        del img, cm
        if progress:
            progress(k + 1, len(tiles))
    return drop_cut_by_frame(merge_tile_detections(per_tile, W, H, iou=cfg.nms_iou), W, H, cfg.min_inside)


# ----------------------------------------------------------------------------------------- terrain

def terrain_overlap_px(config: TerrainConfig, gsd_m: float) -> int:
    """Context a terrain tile needs: three depth scales (the seabed is within 5 % of its maximum depth)."""
    return int(math.ceil(3.0 * config.depth_scale_m / gsd_m))


def terrain_tiled(class_ids: np.ndarray, grid: Grid, config: TerrainConfig | None = None, tile_px: int = 2048,
                  seed: int = 0, overlap_px: int | None = None, backend: str | None = None) -> np.ndarray:
    """Heights (H, W) float32 from the class ids, per tile with an overlap of the terrain's influence
    distance and the cores kept. Equals the untiled estimate where the nearest shoreline of every pixel
    lies within the overlap (the seabed beyond three depth scales is at its maximum depth anyway);
    the ±``noise_m`` variation is seeded per tile, so it is not continuous across seams."""
    from ..terrain import estimate_terrain

    cfg = config or TerrainConfig()
    H, W = class_ids.shape
    if (grid.height_px, grid.width_px) != (H, W):
        raise InputError(f"class_ids {class_ids.shape} do not match the grid {grid.shape}")
    ov = terrain_overlap_px(cfg, grid.gsd_m) if overlap_px is None else int(overlap_px)
    z = np.empty((H, W), np.float32)
    for t in iter_windows(W, H, tile_px, min(ov, 4 * tile_px)):
        sub = np.ascontiguousarray(class_ids[t.row_off:t.row_off + t.height, t.col_off:t.col_off + t.width])
        tgrid = Grid(t.width, t.height, grid.gsd_m)
        res = estimate_terrain(ClassMap(sub, tgrid), cfg, seed=seed, backend=backend)
        z[t.core_global()] = res.height.z_m[t.core_local()]
        del res, sub
    return z


# -------------------------------------------------------------------------------------- scene grid

def downsample_classes(ids: np.ndarray, width_px: int, height_px: int, band_rows: int = 1024) -> np.ndarray:
    """Majority class of each block of a large id raster, row band by row band (bounded memory)."""
    H, W = ids.shape
    out = np.empty((height_px, width_px), np.uint8)
    rows = np.minimum((np.arange(height_px + 1) * H) // height_px, H)
    cols = np.minimum((np.arange(width_px + 1) * W) // width_px, W)
    fy, fx = -(-H // height_px), -(-W // width_px)
    if fy == 1 and fx == 1 and (H, W) == (height_px, width_px):
        out[:] = ids
        return out
    col_idx = np.repeat(np.arange(width_px), np.diff(cols))
    step = max(1, band_rows // max(fy, 1))
    for y0 in range(0, height_px, step):
        y1 = min(height_px, y0 + step)
        band = np.asarray(ids[rows[y0]:rows[y1]])
        row_idx = np.repeat(np.arange(y1 - y0), np.diff(rows[y0:y1 + 1]))
        counts = np.zeros((N_CLASSES, y1 - y0, width_px), np.int32)
        flat = (row_idx[:, None] * width_px + col_idx[None, :]).ravel()
        for c in range(N_CLASSES):
            m = (band == c).ravel()
            counts[c].ravel()[:] = np.bincount(flat[m], minlength=(y1 - y0) * width_px)
        out[y0:y1] = counts.argmax(0).astype(np.uint8)
    return out


def scale_detection(d: Detection, f: float) -> Detection:
    """A detection on a grid ``f`` times coarser."""
    return replace(d, cx_px=d.cx_px / f, cy_px=d.cy_px / f, length_px=d.length_px / f,
                   width_px=max(d.width_px / f, 1e-3), mask=None, mask_origin_px=None)


# ------------------------------------------------------------------------------- later stages

def piers_tiled(dets: list[Detection], class_map: ClassMap, walkway_asset, finger_asset, config,
                tile_px: int = 1024, margin_m: float | None = None):
    """``pier_chains.build_piers`` region by region, so its cost grows with the area and not with the
    square of the number of pier boxes. Each core tile of the class map's grid runs with the boxes within
    ``margin_m`` around it (default: 8 x ``max_gap_m`` + 30 m, the reach of its connectors) and a
    class-map crop as context, and keeps the segments whose position falls in its core, so every segment is
    emitted once. Returns (objects, report). Detections are in the class map's pixels."""
    from ..pier_chains import build_piers

    g = class_map.grid
    piers = [d for d in dets if d.category in PIER_CATEGORIES]
    if not piers:
        return [], {"n_structures": 0, "n_segments": 0, "tiles": 0}
    margin_m = 8.0 * config.max_gap_m + 30.0 if margin_m is None else margin_m
    margin = int(math.ceil(margin_m / g.gsd_m))
    reach = np.array([max(d.length_px, d.width_px) / 2.0 for d in piers])
    cx = np.array([d.cx_px for d in piers])
    cy = np.array([d.cy_px for d in piers])
    objects, report = [], {"n_structures": 0, "n_segments": 0, "tiles": 0}
    for t in iter_windows(g.width_px, g.height_px, tile_px, 0):
        c0, r0, c1, r1 = t.core
        mine = (cx >= c0) & (cx < c1) & (cy >= r0) & (cy < r1)
        if not mine.any():
            continue
        near = ((cx + reach >= c0 - margin) & (cx - reach < c1 + margin)
                & (cy + reach >= r0 - margin) & (cy - reach < r1 + margin))
        sel = [piers[k] for k in np.nonzero(near)[0]]
        boxes = np.array([d.corners_px() for d in sel]).reshape(-1, 2)
        wc0 = int(max(0, min(c0 - margin, math.floor(boxes[:, 0].min()) - margin)))
        wr0 = int(max(0, min(r0 - margin, math.floor(boxes[:, 1].min()) - margin)))
        wc1 = int(min(g.width_px, max(c1 + margin, math.ceil(boxes[:, 0].max()) + margin)))
        wr1 = int(min(g.height_px, max(r1 + margin, math.ceil(boxes[:, 1].max()) + margin)))
        sub = ClassMap(np.ascontiguousarray(class_map.ids[wr0:wr1, wc0:wc1]), Grid(wc1 - wc0, wr1 - wr0, g.gsd_m))
        res = build_piers([_shift(d, -wc0, -wr0) for d in sel], sub, walkway_asset, finger_asset, config)
        # crop frame (origin at the crop's centre) -> scene frame
        dx = (wc0 + (wc1 - wc0) / 2.0 - g.width_px / 2.0) * g.gsd_m
        dy = (g.height_px / 2.0 - (wr0 + (wr1 - wr0) / 2.0)) * g.gsd_m
        prefix = f"t{t.i}_{t.j}_"
        kept = 0
        for o in res.objects:
            x, y = o.x_m + dx, o.y_m + dy
            col, row = g.to_pixel(x, y)
            if not (c0 <= col < c1 and r0 <= row < r1):
                continue  # the neighbouring region owns it
            attrs = dict(o.attrs)
            if "structure" in attrs:
                attrs["structure"] = prefix + str(attrs["structure"])
            objects.append(replace(o, id=prefix + o.id, x_m=float(x), y_m=float(y), attrs=attrs))
            kept += 1
        report["tiles"] += 1
        report["n_segments"] += kept
    # a structure crossing a region border counts once per region
    report["n_structures"] = len({o.attrs.get("structure") for o in objects})
    return objects, report


def match_tiled(source: Source, tile_px: int, dets: list[Detection], library, config: Config, kit=None) -> list:
    """``matching.match_detections`` by windows: the detections (input pixels) grouped by tile, each group
    with a window just big enough for its crops (``kit``: the fallback library)."""
    from rasterio.windows import Window

    from ..matching import ASSET_CATEGORIES_FOR, match_detections

    W, H = source.grid.width_px, source.grid.height_px
    groups: dict[tuple[int, int], list[int]] = {}
    for k, d in enumerate(dets):
        if d.category in ASSET_CATEGORIES_FOR:
            groups.setdefault((int(d.cx_px // tile_px), int(d.cy_px // tile_px)), []).append(k)
    decisions = []
    for _key, idx in sorted(groups.items()):
        boxes = np.array([dets[k].corners_px() for k in idx]).reshape(-1, 2)
        pad = max(max(dets[k].length_px, dets[k].width_px) for k in idx) * 1.1 + 8
        c0, r0 = (int(max(0, math.floor(v - pad))) for v in boxes.min(0))
        c1, r1 = int(min(W, math.ceil(boxes[:, 0].max() + pad))), int(min(H, math.ceil(boxes[:, 1].max() + pad)))
        img = read_window(source, Window(c0, r0, c1 - c0, r1 - r0))
        local = [_shift(dets[k], -c0, -r0) for k in idx]
        for dec in match_detections(img, local, library, config.match, config.seed, fallback=kit):
            decisions.append(replace(dec, index=idx[dec.index]))
        del img
    decisions.sort(key=lambda m: m.index)
    return decisions
