"""Placed meshes for the top-down renderer: embree ray casting (through trimesh) + instancing.

Each distinct mesh is ray-cast once, straight down, with embree into a small "sprite" G-buffer
(albedo, normal, top height, coverage) at half the output pixel size. Every instance is then a
rotated/scaled copy of its sprite (orthographic projection along z commutes with yaw and scale),
z-tested into the output G-buffer. This casts rays only where objects are and keeps a scene of
thousands of trees cheap: embree's BVH build, not the ray count, dominates for many instances.

Shadows (of objects on terrain, water and each other, and of terrain on itself) come from the
resulting height field, swept along the sun direction with a running maximum.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math
import threading
import warnings
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import CoastforgeWarning, InputError

F32 = np.float32

_BACKEND: str | None = None

if TYPE_CHECKING:  # trimesh takes ~1 s to import: only the functions that touch meshes load it
    import trimesh


class RayBackendWarning(CoastforgeWarning):
    """embree is not available; the (much slower) pure-numpy triangle intersector is used."""


def ray_backend() -> str:
    """'embree' when trimesh can use embreex, else 'triangle' (warns once)."""
    global _BACKEND
    if _BACKEND is None:
        try:
            from trimesh.ray import ray_pyembree  # noqa: F401

            _BACKEND = "embree"
        except ImportError as exc:  # pragma: no cover - depends on the environment
            warnings.warn(
                f"embreex is not usable ({exc}); falling back to trimesh's slow triangle intersector. "
                "pip install embreex for fast renders",
                RayBackendWarning,
                stacklevel=2,
            )
            _BACKEND = "triangle"
    return _BACKEND


# set at the first embree intersector: from then on embree's TBB pool has native threads, and a forked child
# can hang on a lock one of them held (the library build then spawns its workers instead)
EMBREE_USED = False


def _intersector(mesh: trimesh.Trimesh):
    global EMBREE_USED
    if ray_backend() == "embree":
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        EMBREE_USED = True
    else:  # pragma: no cover
        from trimesh.ray.ray_triangle import RayMeshIntersector
    return RayMeshIntersector(mesh)


def mesh_colors(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per-face RGB in 0..1 from face colours, vertex colours or a texture's main colour."""
    vis = mesh.visual
    try:
        if getattr(vis, "kind", None) == "texture":
            vis = vis.to_color()
        fc = np.asarray(vis.face_colors)[:, :3]
    except Exception:  # noqa: BLE001 - odd visuals: fall back to a neutral grey rather than fail a render
        fc = np.full((len(mesh.faces), 3), 128, np.uint8)
    if len(fc) != len(mesh.faces):
        fc = np.full((len(mesh.faces), 3), 128, np.uint8)
    return fc.astype(np.float32) / 255.0


@dataclass(eq=False)
class Sprite:
    """A mesh seen from straight above on its own local grid, premultiplied by coverage."""

    data: (
        tuple  # (h, w, 4) and (h, w, 3) float32: r·a, g·a, b·a, nx·a | ny·a, a, z·a (local normals facing up)
    )
    x0: float  # local x of the sprite's left edge
    y1: float  # local y of the sprite's top edge
    gs: float  # metres per sprite pixel
    n_rays: int
    mesh: trimesh.Trimesh  # kept so that id(mesh) cannot be reused while cached


_SPRITES: dict = {}  # (id(mesh), hash(mesh), gs) -> Sprite; bounded, for repeated library views
_SPRITES_LOCK = threading.Lock()


def make_sprite(mesh: trimesh.Trimesh, gs: float, cache: dict | None = None) -> Sprite:
    """Ray-cast ``mesh`` straight down on a grid of ``gs`` metres (one ray per sprite pixel)."""
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise InputError(f"mesh {mesh!r} is not a trimesh.Trimesh; load assets with force='mesh'")
    # hash(mesh) follows in-place edits of the geometry (trimesh tracks its arrays), so no stale sprite
    key = (id(mesh), hash(mesh), round(gs, 9))
    store = _SPRITES if cache is None else cache
    sp = store.get(key)
    if sp is not None and sp.mesh is mesh:
        return sp
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if not np.all(np.isfinite(v)):
        raise InputError(f"mesh {mesh!r} has non-finite vertex coordinates; fix or re-export the asset")
    if len(f) == 0:
        sp = Sprite((np.zeros((1, 1, 4), np.float32), np.zeros((1, 1, 3), np.float32)), 0.0, 0.0, gs, 0, mesh)
        store[key] = sp
        return sp
    lo, hi = v.min(0), v.max(0)
    gs = max(gs, float(np.sqrt((hi[0] - lo[0]) * (hi[1] - lo[1]) / 4e6)))  # at most ~4 M rays per mesh
    w = int(np.ceil((hi[0] - lo[0]) / gs)) + 3
    h = int(np.ceil((hi[1] - lo[1]) / gs)) + 3
    x0 = 0.5 * (lo[0] + hi[0]) - 0.5 * w * gs
    y1 = 0.5 * (lo[1] + hi[1]) + 0.5 * h * gs
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    x = x0 + (jj.ravel() + 0.5) * gs
    y = y1 - (ii.ravel() + 0.5) * gs
    o = np.stack([x, y, np.full_like(x, hi[2] + 1.0)], -1)
    dvec = np.zeros_like(o)
    dvec[:, 2] = -1.0
    tri = _intersector(mesh).intersects_first(o, dvec)
    data = np.zeros((h * w, 7), np.float32)
    ok = np.flatnonzero(tri >= 0)
    if len(ok):
        t = tri[ok]
        tv = v[f[t]]
        n = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
        nl = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(nl > 1e-12, n / np.maximum(nl, 1e-12), np.array([0.0, 0.0, 1.0]))
        n = np.where(n[:, 2:3] < 0, -n, n)  # seen from above: the visible side faces up
        steep = n[:, 2] < 1e-4
        nz = np.where(steep, 1.0, n[:, 2])
        z = tv[:, 0, 2] - (n[:, 0] * (x[ok] - tv[:, 0, 0]) + n[:, 1] * (y[ok] - tv[:, 0, 1])) / nz
        z = np.where(steep, tv[:, :, 2].max(1), np.clip(z, tv[:, :, 2].min(1), tv[:, :, 2].max(1)))
        data[ok, :3] = mesh_colors(mesh)[t]
        data[ok, 3:5] = n[:, :2]  # nz = sqrt(1 - nx² - ny²): normals seen from above face up
        data[ok, 5] = 1.0
        data[ok, 6] = z
    data = data.reshape(h, w, 7)
    sp = Sprite(
        (np.ascontiguousarray(data[..., :4]), np.ascontiguousarray(data[..., 4:])),
        float(x0),
        float(y1),
        float(gs),
        h * w,
        mesh,
    )
    with _SPRITES_LOCK:
        if cache is None and len(_SPRITES) >= 64:
            _SPRITES.pop(next(iter(_SPRITES)))
        store[key] = sp
    return sp


class PixelGrid:
    """Output pixel centres in the scene frame."""

    def __init__(self, extent_m: tuple[float, float], width_px: int, height_px: int):
        self.w_m, self.h_m = float(extent_m[0]), float(extent_m[1])
        self.W, self.H = int(width_px), int(height_px)
        self.gx = self.w_m / self.W
        self.gy = self.h_m / self.H
        self.gsd = 0.5 * (self.gx + self.gy)
        self.x0 = -self.w_m / 2.0
        self.y0 = self.h_m / 2.0  # top edge

    def to_px(self, xy: np.ndarray) -> np.ndarray:
        """Scene (x, y) → continuous (col, row)."""
        return np.stack([(xy[..., 0] - self.x0) / self.gx, (self.y0 - xy[..., 1]) / self.gy], -1)

    def xy(self, rows: np.ndarray, cols: np.ndarray):
        return self.x0 + (cols + 0.5) * self.gx, self.y0 - (rows + 0.5) * self.gy


def sun_vector(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    a, e = np.deg2rad(azimuth_deg), np.deg2rad(np.clip(elevation_deg, 1.0, 90.0))
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


@dataclass(eq=False)
class ObjectLayer:
    """Instances composited onto the output grid (a one-layer G-buffer with coverage)."""

    alpha: np.ndarray  # (H, W) float32 coverage of the top object (anti-aliased edges)
    rgb: np.ndarray  # (3, H, W) float32 albedo, planar (valid where alpha > 0)
    normal: np.ndarray  # (3, H, W) float32 upward unit normals in the scene frame, planar
    z: np.ndarray  # (H, W) float32 object top height (valid where alpha > 0)
    height: np.ndarray  # (H, W) float32 max(surface, objects): the height field that casts shadows
    n_rays: int
    n_instances: int


def composite_instances(
    instances,
    grid: PixelGrid,
    floor_z: np.ndarray,
    surface_z: np.ndarray,
    supersample: float = 2.0,
    cache: dict | None = None,
) -> ObjectLayer:
    """Draw every instance (a warped copy of its mesh's sprite) with a z-test against the terrain
    (``floor_z``: the seabed under water, so submerged parts stay visible) and each other."""
    H, W = grid.H, grid.W
    G = np.zeros((6, H, W), np.float32)  # planar, premultiplied r, g, b, nx, ny, alpha of the top objects
    zobj = np.full((H, W), -np.inf, np.float32)
    zbuf = np.asarray(floor_z, np.float32).copy()
    gs = grid.gsd / supersample
    n_rays = 0
    drawn = 0
    # one sprite per mesh, fine enough for the largest horizontal scale any of its instances is drawn at
    max_scale: dict = {}
    for inst in instances:
        k = id(inst.mesh)
        max_scale[k] = max(max_scale.get(k, 0.0), float(np.max(np.abs(np.asarray(inst.scale, float)[:2]))))
    sprites: dict = {}
    for inst in instances:
        k = id(inst.mesh)
        if k not in sprites:
            sp = make_sprite(inst.mesh, gs / max(max_scale[k], 1e-3), cache=cache)
            n_rays += sp.n_rays
            sprites[k] = sp
    n = len(instances)
    try:
        S = np.array([tuple(inst.scale) for inst in instances], dtype=np.float64).reshape(
            n, 3 if n == 0 else -1
        )
        P = np.array(
            [(inst.x_m, inst.y_m, inst.z_m, inst.yaw_deg) for inst in instances], dtype=np.float64
        ).reshape(n, 4)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"every instance needs numeric x_m, y_m, z_m, yaw_deg and scale (sx, sy, sz): {exc}"
        ) from None
    if S.shape[1] != 3 or not np.all(np.isfinite(S)) or np.any(S <= 0):
        bad = next(
            i for i in range(n) if S.shape[1] != 3 or not np.all(np.isfinite(S[i])) or np.any(S[i] <= 0)
        )
        raise InputError(
            f"instance {bad}: scale {instances[bad].scale!r} must be 3 positive numbers (sx, sy, sz)"
        )
    if not np.all(np.isfinite(P)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(P), axis=1))[0])
        raise InputError(
            f"instance {bad}: position/yaw {P[bad].tolist()} is not finite; check x_m, y_m, z_m, yaw_deg"
        )
    kx, ky = -grid.x0 / grid.gx - 0.5, grid.y0 / grid.gy - 0.5
    igx, igy = 1.0 / grid.gx, 1.0 / grid.gy
    for i, inst in enumerate(instances):
        sx, sy, sz = S[i]
        px, py, pz, yaw = P[i]
        sp = sprites[id(inst.mesh)]
        h, w = sp.data[0].shape[:2]
        r = math.radians(yaw)
        c, s = math.cos(r), math.sin(r)
        # sprite index (u, v) -> local (lx, ly) -> world (X, Y) -> output index (col, row), pixel centres
        lx0, ly0 = sp.x0 + 0.5 * sp.gs, sp.y1 - 0.5 * sp.gs
        F = np.array(
            [
                [c * sx * sp.gs * igx, s * sy * sp.gs * igx, (c * sx * lx0 - s * sy * ly0 + px) * igx + kx],
                [-s * sx * sp.gs * igy, c * sy * sp.gs * igy, -(s * sx * lx0 + c * sy * ly0 + py) * igy + ky],
            ]
        )
        uc, vc = (w - 1) / 2.0, (h - 1) / 2.0
        ccol = F[0, 0] * uc + F[0, 1] * vc + F[0, 2]
        crow = F[1, 0] * uc + F[1, 1] * vc + F[1, 2]
        hcol = abs(F[0, 0]) * w / 2.0 + abs(F[0, 1]) * h / 2.0
        hrow = abs(F[1, 0]) * w / 2.0 + abs(F[1, 1]) * h / 2.0
        c0, c1 = max(int(ccol - hcol) - 1, 0), min(int(ccol + hcol) + 2, W)
        r0, r1 = max(int(crow - hrow) - 1, 0), min(int(crow + hrow) + 2, H)
        if c1 <= c0 or r1 <= r0:
            continue
        Fr = F
        Fr[0, 2] -= c0
        Fr[1, 2] -= r0
        size = (c1 - c0, r1 - r0)
        # two warps of <= 4 channels (OpenCV's fast paths), then planar: numpy is slow on a 7-wide inner axis
        X = np.empty((7, size[1], size[0]), np.float32)
        X[:4] = cv2.warpAffine(sp.data[0], Fr, size, flags=cv2.INTER_LINEAR).transpose(2, 0, 1)
        X[4:] = cv2.warpAffine(sp.data[1], Fr, size, flags=cv2.INTER_LINEAR).transpose(2, 0, 1)
        a = X[5]
        z = X[6] * F32(sz)
        z /= np.maximum(a, F32(1e-6))
        z += F32(pz)
        zb = zbuf[r0:r1, c0:c1]
        front = z > zb
        front &= a > 0.02
        if not front.any():
            continue
        drawn += 1
        if inst.tint is not None:
            X[:3] *= np.asarray(inst.tint, np.float32)[:, None, None]
        nx, ny = X[3], X[4]
        if sx != sy or sy != sz:  # normals transform with the inverse scale
            am = np.maximum(a, F32(1e-6))
            nz = np.sqrt(np.maximum(a * a - nx * nx - ny * ny, 0.0)) / F32(sz)
            nx, ny = nx / F32(sx), ny / F32(sy)
            k = a / np.maximum(np.sqrt(nx * nx + ny * ny + nz * nz), am * F32(1e-6))
            nx, ny = nx * k, ny * k
        if yaw != 0.0:
            X[3], X[4] = nx * F32(c) - ny * F32(s), nx * F32(s) + ny * F32(c)
        np.minimum(a, F32(1.0), out=a)
        # "over" compositing of premultiplied values, only where the new surface is in front
        Xc = X[:6]
        Xc *= front
        g = G[:, r0:r1, c0:c1]
        g *= 1.0 - a  # a is 0 outside the front pixels now
        g += Xc
        np.copyto(zb, z, where=front & (a > 0.5))
        np.copyto(zobj[r0:r1, c0:c1], z, where=front)
    alpha = np.minimum(G[5], F32(1.0))
    inv = 1.0 / np.maximum(G[5], F32(1e-6))
    rgb = G[:3] * inv
    normal = np.empty((3, H, W), np.float32)
    normal[:2] = G[3:5] * inv
    normal[2] = np.sqrt(np.maximum(1.0 - normal[0] ** 2 - normal[1] ** 2, F32(1e-4)))
    normal /= np.sqrt(normal[0] ** 2 + normal[1] ** 2 + normal[2] ** 2)
    height = np.maximum(zbuf, np.asarray(surface_z, np.float32))
    return ObjectLayer(alpha, rgb, normal, zobj, height, n_rays, drawn)


def heightfield_shadow(height: np.ndarray, grid: PixelGrid, sun: np.ndarray) -> np.ndarray:
    """Fraction (H, W) in 0..1 of each pixel that is in a cast shadow of the height field.

    The field is resampled onto a canvas whose columns run towards the sun; along a column, a point is
    shadowed when any point further sunward rises above the sun ray through it:
    max_{t>0} Z(t) - t·tanE > Z(0). With A(t) = Z(t) - t·tanE that is a reverse running maximum."""
    H, W = height.shape
    sxy = np.hypot(sun[0], sun[1])
    if sxy < 1e-6:
        return np.zeros((H, W), np.float32)
    d = np.array([sun[0] / sxy, -sun[1] / sxy])  # towards the sun in image (col, row)
    p = np.array([-d[1], d[0]])
    La = int(np.ceil(abs(W * d[0]) + abs(H * d[1]))) + 4
    Lb = int(np.ceil(abs(W * p[0]) + abs(H * p[1]))) + 4
    cc = np.array([(W - 1) / 2.0, (H - 1) / 2.0])
    # canvas (a, b) -> image (col, row) = cc + (a - ca)·d + (b - cb)·p
    ca, cb = (La - 1) / 2.0, (Lb - 1) / 2.0
    M = np.array([[d[0], p[0], cc[0] - ca * d[0] - cb * p[0]], [d[1], p[1], cc[1] - ca * d[1] - cb * p[1]]])
    Z = cv2.warpAffine(
        np.asarray(height, np.float32),
        M,
        (La, Lb),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=-1e6,
    )
    tan_e = sun[2] / sxy
    step = F32(tan_e * grid.gsd)
    A = Z - np.arange(La, dtype=np.float32)[None, :] * step
    occ = np.maximum.accumulate(A[:, ::-1], axis=1)[:, ::-1]
    shade = np.zeros_like(A)
    # a pixel's own slope must not shadow it: compare with points at least one pixel sunward
    eps = F32(0.03) + step
    shade[:, :-1] = (occ[:, 1:] > A[:, :-1] + eps).astype(np.float32)
    # back to the image (the inverse of M); bilinear gives soft, anti-aliased shadow edges
    back = cv2.warpAffine(
        shade, M, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
    return back
