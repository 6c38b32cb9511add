"""Aerial images of synthetic levels: the renderer plus the variety that keeps the benchmark honest.

``coastforge.render`` draws terrain, water and meshes (lighting, shadows, per-instance tints). This
module adds what a real photo of a harbour has and a clean render lacks: painted parking lines, oil
stains and tyre marks, small debris, wakes behind boats under way, and at coarse resolutions a little
extra blur, sensor noise and JPEG compression. Overlays multiply the rendered colour (paint is
brighter *albedo*), so they stay correctly shadowed, and they are masked out under objects.
"""

from __future__ import annotations

import math
from pathlib import Path
from collections.abc import Callable

import cv2
import numpy as np

from .. import frames
from ..classes import ASPHALT, SIDEWALK, WATER
from ..rng import stage_rng, stage_seed


def mesh_source(library: str | Path | None = None) -> Callable[[str], object]:
    """asset id → trimesh (scene frame, metres, forward +x): the starter kit, or a library's meshes
    (with the kit for roles the library could not fill)."""
    from ..assets.kit import load_kit_mesh

    if library is None:
        return load_kit_mesh
    from ..assets.library import Library

    lib = Library.load(library)

    def mesh(asset_id: str):
        return lib.mesh(asset_id) if asset_id in lib else load_kit_mesh(asset_id)

    return mesh


def _instances(level, meshes) -> list:
    from ..assets.library import cover, repaint  # the same repaint as the library's painted views
    from ..render import MeshInstance

    scene = level.scene
    cache: dict = {}

    def get(a: str, paint=None, canvas=None):
        key = (a, tuple(paint) if paint else None, tuple(canvas) if canvas else None)
        if key not in cache:
            if canvas:
                cache[key] = cover(get(a, paint), canvas)
            elif paint:
                cache[key] = repaint(get(a), paint)
            else:
                cache[key] = meshes(a)
        return cache[key]

    out = []
    for o in scene.objects:
        tint = o.attrs.get("tint")
        mesh = get(o.asset_id, o.attrs.get("paint"), o.attrs.get("cover"))
        out.append(MeshInstance(mesh, o.x_m, o.y_m, o.z_m, o.yaw_deg,
                                tuple(o.scale), tuple(tint) if tint else None))
    veg = scene.vegetation
    if veg is not None and len(veg):
        rng = stage_rng(scene.seed, "synth", scene.name, "veg_tint")
        tints = rng.uniform(0.85, 1.12, (len(veg), 3)) * rng.uniform(0.85, 1.1, (len(veg), 1))
        for i in range(len(veg)):
            s = float(veg.scale[i])
            out.append(MeshInstance(get(str(veg.asset_id[i])), float(veg.x_m[i]), float(veg.y_m[i]),
                                    float(veg.z_m[i]), float(veg.yaw_deg[i]), (s, s, s), tuple(tints[i])))
    return out


def _to_px(layout, u, v, n: int, gsd: float):
    x, y = layout.to_scene(u, v)
    return frames.scene_to_pixel(x, y, n, n, gsd)


def _object_mask(level, n: int, gsd: float) -> np.ndarray:
    """Pixels under placed objects (cars, boats, piers, buoys): overlays are not painted there."""
    mask = np.zeros((n, n), np.uint8)
    L = level.layout
    for o in L.objects:
        ring = np.asarray(o.footprint.buffer(0.15, join_style=2).exterior.coords)
        c, r = _to_px(L, ring[:, 0], ring[:, 1], n, gsd)
        pts = np.round(np.stack([c - 0.5, r - 0.5], -1) * 16).astype(np.int32)
        cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=4)
    return mask.astype(bool)


def _classes_at(level, n: int) -> np.ndarray:
    cls = level.scene.classes
    return cv2.resize(cls, (n, n), interpolation=cv2.INTER_NEAREST)


def _paint_lines(level, n: int, gsd: float, rng: np.random.Generator) -> np.ndarray:
    """Alpha (0..1) of painted parking-bay lines, slightly worn."""
    alpha = np.zeros((n, n), np.float32)
    L = level.layout
    for line, width in L.decor.lines:
        (u0, v0), (u1, v1) = line.coords[0], line.coords[-1]
        c, r = _to_px(L, np.array([u0, u1]), np.array([v0, v1]), n, gsd)
        p0 = (int(round((c[0] - 0.5) * 16)), int(round((r[0] - 0.5) * 16)))
        p1 = (int(round((c[1] - 0.5) * 16)), int(round((r[1] - 0.5) * 16)))
        t = max(1, int(round(width / gsd)))
        cover = min(1.0, width / gsd)  # a line thinner than a pixel covers only part of it
        cv2.line(alpha, p0, p1, float(rng.uniform(0.55, 0.95)) * cover, t, lineType=cv2.LINE_AA, shift=4)
    if alpha.any():
        alpha *= np.clip(0.75 + 0.6 * _lowres_noise(n, max(2.0, 1.5 / gsd), rng), 0.25, 1.0)
    return alpha


def _lowres_noise(n: int, cell_px: float, rng: np.random.Generator) -> np.ndarray:
    """Smooth noise (about unit amplitude) with features of ``cell_px`` pixels, cheap at any size."""
    m = max(2, int(n / cell_px) + 2)
    g = rng.standard_normal((m, m)).astype(np.float32)
    return cv2.resize(g, (n, n), interpolation=cv2.INTER_CUBIC)


def _stains(cls: np.ndarray, gsd: float, rng: np.random.Generator) -> np.ndarray:
    """Multiplier (<= 1) of oil stains and tyre marks on asphalt."""
    n = cls.shape[0]
    stain = np.zeros((n, n), np.float32)
    idx = np.flatnonzero(cls.ravel() == ASPHALT)
    if len(idx):
        area = len(idx) * gsd * gsd
        for p in idx[rng.integers(0, len(idx), int(rng.poisson(area / 40.0)))]:
            r, c = divmod(int(p), n)
            ax = max(1, int(rng.uniform(0.2, 0.9) / gsd))
            axes = (ax, max(1, int(ax * rng.uniform(0.4, 1.0))))
            cv2.ellipse(stain, (c, r), axes, float(rng.uniform(0, 180)), 0, 360,
                        float(rng.uniform(0.08, 0.3)), -1)
        stain = cv2.GaussianBlur(stain, (0, 0), max(0.5, 0.15 / gsd))
    return 1.0 - np.clip(stain, 0, 0.35)


def _debris(img: np.ndarray, cls: np.ndarray, free: np.ndarray, gsd: float, rng: np.random.Generator) -> None:
    """Small specks (litter, leaves, gulls, floating weed), blended into ``img`` (uint8) in place."""
    n = cls.shape[0]
    k = int(rng.poisson(n * n * gsd * gsd / 150.0))
    for r, c in zip(rng.integers(0, n, k), rng.integers(0, n, k)):
        on_water = cls[r, c] == WATER
        # floating litter is rarer than litter on land
        if (on_water and rng.random() < 0.85) or not free[r, c]:
            continue
        rad = max(0, int(round(rng.uniform(0.04, 0.18) / gsd)))
        if on_water:
            rgb = rng.uniform(140, 205, 3) if rng.random() < 0.4 else np.array([64.0, 76.0, 30.0])
        else:
            rgb = rng.uniform(200, 255, 3) if rng.random() < 0.7 else rng.uniform(40, 90, 3)
        a = float(rng.uniform(0.3, 0.8)) * (0.5 if on_water else 1.0) * min(1.0, 0.15 / gsd)
        r0, r1, c0, c1 = max(0, r - rad), min(n, r + rad + 1), max(0, c - rad), min(n, c + rad + 1)
        mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.circle(mask, (int(c - c0), int(r - r0)), rad, 1, -1)
        roi = img[r0:r1, c0:c1]
        m = mask.astype(bool)
        roi[m] = (roi[m] * (1 - a) + rgb * a).astype(np.uint8)


def _wakes(level, n: int, gsd: float, rng: np.random.Generator) -> np.ndarray:
    """Foam alpha of wakes: a turbulent centre stripe and a V of diverging waves behind each boat."""
    alpha = np.zeros((n, n), np.float32)
    L = level.layout
    half = math.radians(19.5)  # the Kelvin wake angle
    for u, v, yaw, length, beam in L.decor.wakes:
        r = math.radians(yaw)
        f = np.array([math.cos(r), math.sin(r)])
        side = np.array([-f[1], f[0]])
        stern = np.array([u, v]) - f * (beam * 1.2)
        arms = [(-f * math.cos(half) + side * s * math.sin(half), 1.0, max(1, int(0.5 / gsd)), 0.55)
                for s in (-1, 1)]
        arms.append((-f, 0.8, max(1, int(beam * 0.8 / gsd)), 0.8))
        for dir_, frac, thick, val in arms:
            k = 16
            for i in range(k - 1, -1, -1):  # far to near, so the brighter part near the stern wins
                a, b = stern + dir_ * length * frac * i / k, stern + dir_ * length * frac * (i + 1) / k
                c, rr = _to_px(L, np.array([a[0], b[0]]), np.array([a[1], b[1]]), n, gsd)
                fade = val * (1.0 - (i + 0.5) / k) ** 1.5
                cv2.line(alpha, (int(c[0]), int(rr[0])), (int(c[1]), int(rr[1])), fade, thick,
                         lineType=cv2.LINE_AA)
    if alpha.any():
        alpha = cv2.GaussianBlur(alpha, (0, 0), max(0.6, 0.4 / gsd))
        alpha *= np.clip(0.6 + 0.8 * _lowres_noise(n, max(2.0, 0.4 / gsd), rng), 0, 1)
    return alpha


def _degrade(img: np.ndarray, gsd: float, rng: np.random.Generator) -> np.ndarray:
    """Camera and compression artefacts; stronger at coarse resolutions (satellite-like products)."""
    coarse = gsd >= 0.15
    sigma = float(rng.uniform(0.35, 0.8) if coarse else rng.uniform(0.0, 0.35))
    out = cv2.GaussianBlur(img, (0, 0), sigma) if sigma > 0.05 else img
    amp = float(rng.uniform(1.0, 3.5) if coarse else rng.uniform(0.5, 2.0))
    noise = (rng.standard_normal(out.shape[:2], dtype=np.float32) * amp).astype(np.int16)
    out = np.clip(out.astype(np.int16) + noise[..., None], 0, 255).astype(np.uint8)
    q = int(rng.integers(55, 82) if coarse else rng.integers(80, 95))
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(out[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, q])
    if ok:
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[:, :, ::-1]
    return np.ascontiguousarray(out)


def render_level(level, meshes, gsd_m: float, seed: int) -> np.ndarray:
    """One aerial image (H, W, 3) uint8 of a synthesized level at ``gsd_m`` metres per pixel.

    The lighting and clutter depend on the seed only (not on the GSD), so the images of one level at
    several GSDs show the same moment."""
    from ..render import random_lighting, render_topdown

    scene = level.scene
    name = scene.name
    lighting = random_lighting(stage_rng(seed, "synth", name, "lighting"))
    img = render_topdown(scene.classes, scene.height, scene.extent_m, _instances(level, meshes), gsd_m,
                         lighting, stage_seed(seed, "synth", name, "render"), scene.water_level_m)
    n = img.shape[0]
    cls = _classes_at(level, n)
    free = ~_object_mask(level, n, gsd_m)
    # painted lines are ~2.5x brighter than asphalt, stains darker: multiply, so shadows stay shadows
    mult = 1.0 + 1.6 * _paint_lines(level, n, gsd_m, stage_rng(seed, "synth", name, "lines"))
    paved = (cls == ASPHALT) | (cls == SIDEWALK)
    mult *= np.where(paved, _stains(cls, gsd_m, stage_rng(seed, "synth", name, "stains")), 1.0)
    sel = free & (np.abs(mult - 1.0) > 1e-3)
    img[sel] = np.clip(img[sel] * mult[sel][:, None], 0, 255).astype(np.uint8)
    _debris(img, cls, free, gsd_m, stage_rng(seed, "synth", name, "debris"))
    w = _wakes(level, n, gsd_m, stage_rng(seed, "synth", name, "wakes"))
    sel = free & (cls == WATER) & (w > 0.01)
    if sel.any():
        a = w[sel][:, None]
        img[sel] = (img[sel] * (1 - a) + np.array([220.0, 229.0, 229.0]) * a).astype(np.uint8)
    return _degrade(img, gsd_m, stage_rng(seed, "synth", name, "degrade", f"{gsd_m:.3f}"))
