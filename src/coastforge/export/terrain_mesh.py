"""Shared terrain helpers for the exporters: raster sampling in scene metres, the decimated terrain
mesh (a regular grid under a vertex budget), PNG encoding and mesh conversions."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fsio import png_bytes  # noqa: F401  (the exporters import it from here)

from ..classes import N_CLASSES, PALETTE, WATER


def _index_coords(scene, x_m, y_m):
    """Scene metres → fractional array indices (row, col) of the scene rasters (pixel centres at i)."""
    h, w = scene.height.shape
    ew, eh = scene.extent_m
    col = (np.asarray(x_m, float) + ew / 2.0) / ew * w - 0.5
    row = (eh / 2.0 - np.asarray(y_m, float)) / eh * h - 0.5
    return row, col


def sample_height(scene, x_m, y_m) -> np.ndarray:
    """Bilinear height (m) at scene positions, clamped at the borders."""
    from scipy.ndimage import map_coordinates

    row, col = _index_coords(scene, x_m, y_m)
    shape = np.shape(row)
    out = map_coordinates(scene.height.astype(np.float64), [np.ravel(row), np.ravel(col)], order=1, mode="nearest")
    return out.reshape(shape)


def sample_class(scene, x_m, y_m) -> np.ndarray:
    """Nearest class id at scene positions."""
    h, w = scene.classes.shape
    row, col = _index_coords(scene, x_m, y_m)
    r = np.clip(np.floor(np.asarray(row) + 0.5).astype(int), 0, h - 1)
    c = np.clip(np.floor(np.asarray(col) + 0.5).astype(int), 0, w - 1)
    return scene.classes[r, c]


def vertex_grid(extent_m, nx: int, ny: int):
    """Scene coordinates of an nx × ny vertex grid spanning the whole extent; row 0 is the north edge."""
    ew, eh = extent_m
    xs = np.linspace(-ew / 2.0, ew / 2.0, nx)
    ys = np.linspace(eh / 2.0, -eh / 2.0, ny)
    return np.meshgrid(xs, ys)  # (ny, nx) each


def _axis_weights(coord: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Clamped linear-interpolation indices and weights along one axis of length n."""
    c = np.clip(coord, 0.0, n - 1.0)
    i0 = np.minimum(np.floor(c).astype(np.intp), max(n - 2, 0))
    return i0, (c - i0) if n > 1 else np.zeros_like(c)


def grid_corners(shape, rows: np.ndarray, cols: np.ndarray):
    """Corner indices and weights of the separable bilinear grid rows (ny,) × cols (nx,), clamped."""
    h, w = shape
    r0, tr = _axis_weights(rows, h)
    c0, tc = _axis_weights(cols, w)
    return (r0, np.minimum(r0 + 1, h - 1), tr), (c0, np.minimum(c0 + 1, w - 1), tc)


def grid_bilinear(src: np.ndarray, rows: np.ndarray, cols: np.ndarray, dtype=np.float64,
                   block: int = 256) -> np.ndarray:
    """Bilinear samples of src (H, W) on the separable grid rows (ny,) × cols (nx,), clamped at the borders.

    Same values as ``map_coordinates(order=1, mode='nearest')`` but whole-array gathers instead of a
    per-sample loop, done ``block`` output rows at a time so memory stays at a few blocks even for
    8129² landscapes from 20 000² rasters (the source is never copied or converted as a whole)."""
    (r0, r1, tr), (c0, c1, tc) = grid_corners(src.shape, rows, cols)
    out = np.empty((len(rows), len(cols)), dtype)
    tc_ = tc.astype(dtype)[None, :]
    for s0 in range(0, len(rows), block):
        sl = slice(s0, min(s0 + block, len(rows)))
        tr_ = tr[sl].astype(dtype)[:, None]
        top = src[np.ix_(r0[sl], c0)].astype(dtype) * (1 - tc_) + src[np.ix_(r0[sl], c1)].astype(dtype) * tc_
        bot = src[np.ix_(r1[sl], c0)].astype(dtype) * (1 - tc_) + src[np.ix_(r1[sl], c1)].astype(dtype) * tc_
        out[sl] = top * (1 - tr_) + bot * tr_
    return out


def _grid_index_axes(scene, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Fractional raster row (ny,) and column (nx,) indices of the vertex grid spanning the extent."""
    h, w = scene.height.shape if scene.height is not None else scene.classes.shape
    ew, eh = scene.extent_m
    xs = np.linspace(-ew / 2.0, ew / 2.0, nx)
    ys = np.linspace(eh / 2.0, -eh / 2.0, ny)
    cols = (xs + ew / 2.0) / ew * w - 0.5
    rows = (eh / 2.0 - ys) / eh * h - 0.5
    return rows, cols


def resample_height(scene, nx: int, ny: int, dtype=np.float64) -> np.ndarray:
    """Heights (ny, nx) at the vertices of a grid spanning the extent (row 0 = north)."""
    rows, cols = _grid_index_axes(scene, nx, ny)
    return grid_bilinear(scene.height, rows, cols, dtype=dtype)


def class_weight(scene, k: int, rows: np.ndarray, cols: np.ndarray, block: int = 256) -> np.ndarray:
    """Weight (ny, nx) float32 of class k on the grid: bilinear resampling of its one-hot mask, computed
    from the four corner class ids (four compares per sample) a block of rows at a time."""
    (r0, r1, tr), (c0, c1, tc) = grid_corners(scene.classes.shape, rows, cols)
    cls = scene.classes
    out = np.zeros((len(rows), len(cols)), np.float32)
    wc = tc.astype(np.float32)[None, :]
    for s0 in range(0, len(rows), block):
        sl = slice(s0, min(s0 + block, len(rows)))
        wr = tr[sl].astype(np.float32)[:, None]
        for rr, wrow in ((r0, 1 - wr), (r1, wr)):
            for cc, wcol in ((c0, 1 - wc), (c1, wc)):
                out[sl] += np.where(cls[np.ix_(rr[sl], cc)] == k, wrow * wcol, np.float32(0))
    return out


def class_weights(scene, nx: int, ny: int) -> np.ndarray:
    """Per-class weights (N_CLASSES, ny, nx) float32 in [0, 1] summing to 1 (bilinear one-hot resampling)."""
    rows, cols = _grid_index_axes(scene, nx, ny)
    out = np.zeros((N_CLASSES, ny, nx), np.float32)
    for k in np.unique(scene.classes):
        out[k] = class_weight(scene, int(k), rows, cols)
    return out


def class_weight_maps_u8(scene, nx: int, ny: int, keep=()) -> tuple[np.ndarray, dict]:
    """uint8 weight maps (N_CLASSES, ny, nx) summing to exactly 255 per vertex, one class at a time (memory:
    the uint8 maps plus a few float maps, so 8129² landscapes fit), and ``{k: round(255·weight)}`` as uint8
    for the classes in ``keep`` (PCG masks). Rounding down, the remainder going to the dominant class (as
    ``weights_to_u8``)."""
    rows, cols = _grid_index_axes(scene, nx, ny)
    maps = np.zeros((N_CLASSES, ny, nx), np.uint8)
    total = np.zeros((ny, nx), np.int16)
    best = np.full((ny, nx), -1.0, np.float32)
    dom = np.zeros((ny, nx), np.uint8)
    kept: dict = {}
    present = {int(k) for k in np.unique(scene.classes)}
    for k in range(N_CLASSES):
        if k not in present:
            if k in keep:
                kept[k] = np.zeros((ny, nx), np.uint8)
            continue
        w = class_weight(scene, k, rows, cols)
        maps[k] = np.floor(w * np.float32(255.0)).clip(0, 255).astype(np.uint8)
        total += maps[k]
        better = w > best
        best[better] = w[better]
        dom[better] = k
        if k in keep:
            kept[k] = np.clip(np.round(w * np.float32(255.0)), 0, 255).astype(np.uint8)
    rem = (255 - total).astype(np.int16)
    for k in present:
        sel = dom == k
        maps[k][sel] = (maps[k][sel].astype(np.int16) + rem[sel]).clip(0, 255).astype(np.uint8)
    return maps, kept


def weights_to_u8(w: np.ndarray) -> np.ndarray:
    """Weights (K, H, W) summing to 1 → uint8 maps that sum to exactly 255 per pixel (rounding down, the
    remainder going to the dominant class: cheap on 8129² maps, error < K/255 on that class only)."""
    base = np.floor(w * 255.0).astype(np.int16)
    rem = 255 - base.sum(0)
    top = np.argmax(w, axis=0)
    np.put_along_axis(base, top[None], np.take_along_axis(base, top[None], 0) + rem[None], axis=0)
    return base.astype(np.uint8)


def terrain_image(scene, texture: np.ndarray | None, max_px: int) -> np.ndarray:
    """The terrain's colour image (RGB uint8, north up): the cleaned image if given, else class colours."""
    import cv2

    img = texture if texture is not None else PALETTE[np.clip(scene.classes, 0, N_CLASSES - 1)]
    h, w = img.shape[:2]
    s = min(1.0, max_px / max(h, w))
    if s < 1.0:
        interp = cv2.INTER_AREA if texture is not None else cv2.INTER_NEAREST
        img = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=interp)
    return np.ascontiguousarray(img.astype(np.uint8))


@dataclass(frozen=True, eq=False)
class TerrainMesh:
    vertices: np.ndarray  # (N, 3) float64, scene frame
    faces: np.ndarray  # (F, 3) int, counter-clockwise seen from above
    uv: np.ndarray  # (N, 2) float, u east, v south (image convention: v = 0 at the north edge)
    normals: np.ndarray  # (N, 3) unit, scene frame
    nx: int
    ny: int


def grid_size_for_budget(extent_m, max_vertices: int, shape_px) -> tuple[int, int]:
    """Vertex columns/rows under ``max_vertices`` with square-ish cells, never finer than the raster."""
    ew, eh = extent_m
    h_px, w_px = shape_px
    max_vertices = max(4, int(max_vertices))
    nx = max(2, int(math.sqrt(max_vertices * ew / eh)))
    ny = max(2, int(max_vertices / nx))
    nx = min(nx, w_px + 1)
    ny = min(ny, h_px + 1)
    while nx * ny > max_vertices:  # rounding can overshoot by a row
        if nx >= ny:
            nx -= 1
        else:
            ny -= 1
    return max(2, nx), max(2, ny)


def terrain_mesh(scene, max_vertices: int) -> TerrainMesh:
    """The height field as a triangle mesh of at most ``max_vertices`` vertices spanning the extent."""
    nx, ny = grid_size_for_budget(scene.extent_m, max_vertices, scene.height.shape)
    gx, gy = vertex_grid(scene.extent_m, nx, ny)
    gz = resample_height(scene, nx, ny)
    verts = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], 1)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()  # north row: a (west), b (east)
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()  # south row: c (west), d (east)
    # counter-clockwise seen from +z: south-west → south-east → north-east, ...
    faces = np.concatenate([np.stack([c, d, b], 1), np.stack([c, b, a], 1)])
    u = (np.arange(nx) / (nx - 1))[None, :].repeat(ny, 0).ravel()
    v = (np.arange(ny) / (ny - 1))[:, None].repeat(nx, 1).ravel()
    return TerrainMesh(verts, faces.astype(np.int64), np.stack([u, v], 1), vertex_normals(verts, faces), nx, ny)


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    n = len(verts)
    vn = np.zeros((n, 3), np.float64)
    for k in range(3):  # bincount is far faster than np.add.at for scatter-adds
        for a in range(3):
            vn[:, a] += np.bincount(faces[:, k], weights=fn[:, a], minlength=n)
    n = np.linalg.norm(vn, axis=1, keepdims=True)
    vn = np.where(n > 0, vn / np.where(n > 0, n, 1.0), np.array([0.0, 0.0, 1.0]))
    return vn


def flat_mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A trimesh → unshared (positions (3F, 3), normals, colours RGBA uint8 (3F, 4), faces (F, 3)).

    Unsharing vertices lets per-face colours become per-vertex colours and keeps facets flat."""
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    pos = v[f].reshape(-1, 3)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    ln = np.linalg.norm(fn, axis=1, keepdims=True)
    fn = np.where(ln > 0, fn / np.where(ln > 0, ln, 1.0), np.array([0.0, 0.0, 1.0]))
    nrm = np.repeat(fn, 3, axis=0)
    col = face_colors(mesh)
    cols = np.repeat(col, 3, axis=0)
    faces = np.arange(len(pos)).reshape(-1, 3)
    return pos, nrm, cols, faces


def face_colors(mesh) -> np.ndarray:
    """(F, 4) uint8 face colours of a trimesh (grey when it has none)."""
    f = len(mesh.faces)
    try:
        c = np.asarray(mesh.visual.face_colors, dtype=np.uint8)
        if c.shape == (f, 4):
            return c
    except (AttributeError, ValueError):
        pass
    return np.tile(np.array([180, 180, 180, 255], np.uint8), (f, 1))


def is_water(scene, x_m: float, y_m: float) -> bool:
    return int(sample_class(scene, x_m, y_m)) == WATER
