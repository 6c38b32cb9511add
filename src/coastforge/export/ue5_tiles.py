"""A large terrain as World-Partition-ready Unreal landscape tiles (DESIGN.md §6).

Unreal's Landscape mode → "Import from File" recognises a tiled heightmap by the file name suffix
``_x<i>_y<j>`` (i = tile column along +X_ue = east, j = tile row along +Y_ue = south) and offers to load the
whole set; the same naming holds for the paint-layer weight maps. Every tile has a valid landscape size
``n`` and neighbouring tiles share their edge vertices (tile (i, j) starts at vertex (i·(n−1), j·(n−1))),
so the landscape is ``tiles·(n−1)+1`` vertices per side with no seam.

One Z scale serves all tiles (water at 32768 with LocationZ = 0, ScaleZ ≥ max|z|·100/256), so a height
value means the same in every file. ``landscape_tiles.json`` holds the grid, the scales, the location and
every file. The function is pure: ``scene → {relative path: bytes}`` like the other exporters, and it
resamples one tile at a time (memory grows with the tile, not the landscape).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np

from .. import __version__
from ..classes import N_CLASSES
from ..errors import InputError
from . import safe_name
from .terrain_mesh import grid_bilinear, grid_corners, png_bytes, weights_to_u8
from .ue5 import LANDSCAPE_SIZES, LAYER_NAMES, WATER_VALUE, encode_heights, landscape_layout, scale_z_for

FORMAT = "coastforge.ue5_tiles/1"
DEFAULT_TILE_SIZE = 1009  # 8 x 8 components of 2 x 2 sections of 63 quads: a typical World Partition region


def tile_name(base: str, i: int, j: int, ext: str) -> str:
    """``<base>_x<i>_y<j>.<ext>``: Unreal's tiled-import naming."""
    return f"{base}_x{i}_y{j}.{ext}"


def _check_base(name: str) -> str:
    base = safe_name(name)
    # Unreal reads "<a>x<b>" as a size/tile pattern and "_x<i>_y<j>" as tile coordinates: keep both out of the base
    base = re.sub(r"(\d)[xX](\d)", r"\1-\2", base)
    base = re.sub(r"_[xX]\d+_[yY]\d+", "", base) or "terrain"
    return base


def tile_counts(samples_x: int, samples_y: int, tile_size: int) -> tuple[int, int]:
    """Tiles per axis so the landscape has at least as many vertices as the raster has samples."""
    q = tile_size - 1
    return max(1, math.ceil((samples_x - 1) / q)), max(1, math.ceil((samples_y - 1) / q))


def _axes(shape: tuple[int, int], nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Fractional raster (row, col) indices of an nx x ny vertex grid spanning the extent (the first and last
    vertex on the outer pixel edges, like ``terrain_mesh``)."""
    h, w = shape
    cols = np.linspace(0.0, 1.0, nx) * w - 0.5
    rows = np.linspace(0.0, 1.0, ny) * h - 0.5
    return rows, cols


def _tile_weights(classes: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Per-class bilinear one-hot weights (K, len(rows), len(cols)) summing to 1."""
    (r0, r1, tr), (c0, c1, tc) = grid_corners(classes.shape, rows, cols)
    top, bot = classes[r0], classes[r1]
    corners = (top[:, c0], top[:, c1], bot[:, c0], bot[:, c1])
    wc, wr = tc[None, :], tr[:, None]
    weights = ((1 - wc) * (1 - wr), wc * (1 - wr), (1 - wc) * wr, wc * wr)
    out = np.zeros((N_CLASSES, len(rows), len(cols)), np.float32)
    for k in np.unique(classes):
        for ids, wt in zip(corners, weights):
            out[int(k)] += (ids == k) * wt
    return out


def export_ue5_tiles(scene, assets=None, config=None, tile_size: int = DEFAULT_TILE_SIZE, name: str | None = None,
                     tiles: tuple[int, int] | None = None) -> dict[str, bytes]:
    """Heightmap tiles (16-bit PNG and ``.r16``), 8-bit weight-map tiles per class and ``landscape_tiles.json``.

    ``tile_size``: vertices per tile side, a valid landscape size. ``tiles``: (columns, rows) of tiles;
    default: enough that the landscape keeps the scene raster's resolution. ``assets`` and ``config`` make the
    signature the exporters' ``(scene, assets, config)``; the terrain needs neither (``export.ue_max_size``
    does not cap a tiled landscape: that is the point of tiling)."""
    if scene.height is None:
        raise InputError("the scene has no height raster; run terrain (or generate) before exporting ue5 tiles")
    if tile_size not in LANDSCAPE_SIZES:
        raise InputError(f"tile_size = {tile_size!r} is not a landscape size; use one of "
                         f"{', '.join(map(str, LANDSCAPE_SIZES))}")
    z_raster = np.asarray(scene.height)
    if not np.isfinite(z_raster).all():
        raise InputError("the scene's height raster holds NaN or infinite values; re-run terrain")
    h_px, w_px = z_raster.shape
    if tiles is None:
        tx, ty = tile_counts(w_px, h_px, tile_size)
    else:
        tx, ty = (int(v) for v in tiles)
        if tx < 1 or ty < 1 or tx * ty > 1024:
            raise InputError(f"tiles = {tiles!r} must be 1..1024 tiles in all (columns, rows), e.g. (4, 4)")
    q = tile_size - 1
    nx, ny = tx * q + 1, ty * q + 1
    ew, eh = (float(v) for v in scene.extent_m)
    base = _check_base(name or scene.name)
    # one Z scale for every tile: from the raster (vertex samples interpolate it, so they never exceed it)
    scale_z = scale_z_for(float(np.abs(z_raster).max()) if z_raster.size else 0.0)
    sx, sy = ew * 100.0 / (nx - 1), eh * 100.0 / (ny - 1)
    loc = [-ew / 2.0 * 100.0, -eh / 2.0 * 100.0, 0.0]
    rows_all, cols_all = _axes(z_raster.shape, nx, ny)
    classes = np.asarray(scene.classes) if scene.classes is not None else None
    # weight maps sample the class raster on its own grid (it may differ from the height raster's)
    crow_all, ccol_all = _axes(classes.shape, nx, ny) if classes is not None else (rows_all, cols_all)
    qps, spc, comps = landscape_layout(tile_size)
    files: dict[str, bytes] = {}
    entries = []
    zmin, zmax = math.inf, -math.inf
    for j in range(ty):
        rs = slice(j * q, j * q + tile_size)
        for i in range(tx):
            cs_ = slice(i * q, i * q + tile_size)
            z = grid_bilinear(z_raster, rows_all[rs], cols_all[cs_])
            zmin, zmax = min(zmin, float(z.min())), max(zmax, float(z.max()))
            h16 = encode_heights(z, scale_z)
            png = tile_name(f"heightmap/{base}", i, j, "png")
            r16 = tile_name(f"heightmap/{base}", i, j, "r16")
            files[png] = png_bytes(h16)
            files[r16] = h16.astype("<u2").tobytes()
            layers = {}
            if classes is not None:
                w8 = weights_to_u8(_tile_weights(classes, crow_all[rs], ccol_all[cs_]))
                for k, layer in enumerate(LAYER_NAMES):
                    rel = tile_name(f"weightmaps/{layer}", i, j, "png")
                    files[rel] = png_bytes(w8[k])
                    layers[layer] = rel
            entries.append({
                "x": i, "y": j, "heightmap_png": png, "heightmap_r16": r16, "weightmaps": layers,
                "first_vertex": [i * q, j * q],
                "location": [loc[0] + i * q * sx, loc[1] + j * q * sy, 0.0],
            })
    spec = {
        "format": FORMAT, "generator": f"coastforge {__version__}", "scene": scene.name,
        "naming": "<base>_x<i>_y<j>: i = tile column along +X_ue (east), j = tile row along +Y_ue (south)",
        "tile_size": tile_size, "tiles": [tx, ty], "vertices": [nx, ny],
        "tile_overlap_vertices": 1,
        "quads_per_section": qps, "sections_per_component": spc, "components_per_tile": comps,
        "location": loc, "scale": [sx, sy, scale_z],
        "water_height_value": WATER_VALUE, "height_step_cm": scale_z / 128.0,
        "z_range_m": [zmin, zmax], "extent_m": [ew, eh],
        "heightmap_base": f"heightmap/{base}", "layers": list(LAYER_NAMES) if classes is not None else [],
        "import": ("Landscape mode > New > Import from File: pick heightmap/" + tile_name(base, 0, 0, "png")
                   + " and accept the tiled import; set Location and Scale as above (World Partition: region size "
                   f"{comps} components = one tile)."),
        "tile_list": entries,
    }
    files["landscape_tiles.json"] = (json.dumps(spec, indent=1, allow_nan=False) + "\n").encode("utf-8")
    return files


__all__ = ["DEFAULT_TILE_SIZE", "export_ue5_tiles", "tile_counts", "tile_name"]
