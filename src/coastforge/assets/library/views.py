"""The top-down views a library keeps of each asset: standard lightings and backgrounds at a scale
that fits the asset, scaled copies, views as a query sees them (coarse, random yaw, cropped like the matcher's
crops) and between copies of themselves."""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path
from typing import Any
from collections.abc import Sequence

import numpy as np

from ...config import LibraryConfig
from ...errors import LibraryError
from ...fsio import atomic_write_bytes
from .paints import PAINTS, is_paintable, repaint


def view_lightings():
    from ...render import standard_view_lightings

    return standard_view_lightings()


def _render_source_hash() -> str:
    """Renderer code changes make old views stale: hash its source into the view settings."""
    h = hashlib.sha256()
    from ... import render

    for p in sorted(Path(render.__file__).parent.glob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def view_settings(config: LibraryConfig) -> dict:
    return {
        "size_px": int(config.view_size_px), "base_gsd_m": float(config.view_gsd_m),
        "backgrounds": list(config.backgrounds), "lightings": int(config.lightings),
        "lighting_params": [dataclasses.asdict(lt) for lt in view_lightings()[: config.lightings]],
        "renderer": _render_source_hash(),
        "paint_variants": bool(config.paint_variants), "paints": [list(p) for p in PAINTS],
        "silhouette": 1,  # footprint masks stored beside the views
        "query_views": {"version": 2, "gsds_m": [float(g) for g in config.query_view_gsds_m],
                        "random_lightings": int(config.query_view_random_lightings),
                        "max_px": float(config.query_view_max_px), "pad": QUERY_PAD, "min_px": QUERY_MIN_PX},
        "crowded_views": {"version": 1, "n": int(config.crowded_views),
                          "gsds_m": [float(g) for g in config.crowded_gsds_m]},
    }


def choose_view_gsd(dims_m: Sequence[float], config: LibraryConfig) -> float:
    """The finest standard scale (base x 2^k) at which the footprint and its shadow fit the view."""
    L, W, H = (float(v) for v in dims_m)
    # diagonal of the footprint plus room for a low sun's shadow
    reach = math.hypot(L, W) + 0.6 * min(H, 2.0 * max(L, W))
    for k in range(-4, 12):
        g = config.view_gsd_m * 2.0 ** k
        if reach / g <= 0.9 * config.view_size_px:
            return float(g)
    raise LibraryError(f"an asset of {L:.1f} x {W:.1f} m does not fit the views; raise library.view_size_px")


def view_conditions(config: LibraryConfig) -> list[tuple[int, str]]:
    n = int(config.lightings)
    if not 1 <= n <= 3:
        raise LibraryError(f"library.lightings = {n} must be 1, 2 or 3")
    for b in config.backgrounds:
        if b not in ("water", "ground"):
            raise LibraryError(f"library.backgrounds has {b!r}; use water and/or ground")
    return [(k, b) for b in config.backgrounds for k in range(n)]


def scale_variants(img: np.ndarray, gsd: float, length_m: float, factors: Sequence[float]):
    """The view plus coarser copies (area-averaged), as a coarser sensor would see it: queries come at any
    metres-per-pixel and small objects lose detail; matching against a copy at a similar scale helps."""
    import cv2

    out = []
    for f in factors:
        if f <= 1.0:
            out.append((img, gsd))
            continue
        if length_m / (gsd * f) < 8:  # too few pixels along the object to say anything more
            break
        h, w = img.shape[:2]
        small = cv2.resize(img, (max(4, round(w / f)), max(4, round(h / f))), interpolation=cv2.INTER_AREA)
        out.append((small, gsd * w / small.shape[1]))
    return out


QUERY_PAD = 1.5  # query-like views are cropped as the matcher crops a detection: 1.5 x its size + 4 px ...


QUERY_MIN_PX = 12  # ... and at least this many pixels, so even a one-pixel object has background around it


def query_view_plan(dims_m: Sequence[float], view_gsd: float, config: LibraryConfig) -> list[tuple[float, int]]:
    """(gsd, crop side in px) of the query-like views of an asset: every configured GSD coarser than its
    standard views at which it is shorter than ``query_view_max_px`` pixels."""
    size = round(max(float(dims_m[0]), float(dims_m[1])), 4)  # as recorded (dims_m are stored rounded)
    out = []
    for g in sorted(float(x) for x in config.query_view_gsds_m):
        if not (g > 0 and math.isfinite(g)):
            raise LibraryError(f"library.query_view_gsds_m has {g!r}; give positive metres per pixel")
        if g <= view_gsd * 1.0001 or size / g >= float(config.query_view_max_px):
            continue
        out.append((g, int(max(QUERY_MIN_PX, math.ceil(size * QUERY_PAD / g - 1e-6) + 4))))
    return out


CROWD_MAX_LENGTH_M = 25.0  # larger boats lie alone (ships at a quay, not in berths)


CROWD_MAX_PX = 160  # crowded views at most this many pixels across


def crowd_mesh(mesh, category: str, dims_m: Sequence[float], rng) -> tuple[Any, tuple[float, float]]:
    """The asset between copies of itself as cars are parked or boats berthed (side by side, a small gap,
    some bays empty; cars facing either way, sometimes a row behind), repainted where it can be. Returns the
    mesh and the centre of the middle asset's footprint."""
    import trimesh

    L, W = float(dims_m[0]), float(dims_m[1])
    b = mesh.bounds
    c = np.array([0.5 * (b[0, 0] + b[1, 0]), 0.5 * (b[0, 1] + b[1, 1]), 0.0])
    paintable = is_paintable(category, dims_m)
    vehicle = category == "vehicle"

    def copy(dx: float, dy: float, flip: bool, paint: bool):
        m = repaint(mesh, PAINTS[int(rng.integers(len(PAINTS)))]) if paint else mesh.copy()
        if flip:
            m.apply_transform(trimesh.transformations.rotation_matrix(math.pi, [0, 0, 1], c))
        m.apply_translation([dx, dy, 0.0])
        return m

    parts = [copy(0.0, 0.0, False, paintable and rng.random() < 0.5)]
    gap = (0.4, 1.2) if vehicle else (0.6, 2.0)
    for side in (-1.0, 1.0):
        if rng.random() < 0.85:
            parts.append(copy(float(rng.uniform(-0.1, 0.1)) * L, side * (W + float(rng.uniform(*gap))),
                              vehicle and rng.random() < 0.5, paintable))
    if vehicle and rng.random() < 0.5:  # the row behind (or in front), nose to nose
        sx = float(rng.choice([-1.0, 1.0])) * (L + float(rng.uniform(0.3, 1.0)))
        parts.append(copy(sx, float(rng.uniform(-0.3, 0.3)), rng.random() < 0.5, paintable))
    return trimesh.util.concatenate(parts), (float(c[0]), float(c[1]))


def render_query_views(mesh, asset_id: str, dims_m: Sequence[float], view_gsd: float, config: LibraryConfig,
                       category: str | None = None):
    """Query-like views (see ``LibraryConfig.query_view_gsds_m``): list of (image, meta dict)."""
    from ...render import render_mesh_view
    from ...rng import stage_rng

    n_random = int(config.query_view_random_lightings)
    if n_random < 0:
        raise LibraryError(f"library.query_view_random_lightings = {n_random} must be 0 or more")
    lightings = view_lightings()
    rng = stage_rng(0, "library-query-views", asset_id)
    out = []
    for g, side in query_view_plan(dims_m, view_gsd, config):
        for k, bg in view_conditions(config):
            yaw = round(float(rng.uniform(-180.0, 180.0)), 3)
            img = render_mesh_view(mesh, g, side, lightings[k], bg, yaw_deg=yaw, seed=int(rng.integers(1 << 30)))
            out.append((img, {"lighting": k, "background": bg, "gsd_m": g, "yaw_deg": yaw}))
        # a few-pixel object shows little more than its contrast with the background, which the water's
        # colour, the sun and haze change: these views sample that variety (random lightings of the library's
        # own stream)
        for bg in config.backgrounds:
            out.extend(random_lit_view(mesh, g, side, bg, rng) for _ in range(n_random))
    n_crowd = int(config.crowded_views)
    if n_crowd < 0:
        raise LibraryError(f"library.crowded_views = {n_crowd} must be 0 or more")
    for g in config.crowded_gsds_m:
        if not (float(g) > 0 and math.isfinite(float(g))):
            raise LibraryError(f"library.crowded_gsds_m has {g!r}; give positive metres per pixel")
    if n_crowd > 0 and category in ("vehicle", "boat") and float(dims_m[0]) <= CROWD_MAX_LENGTH_M:
        size = max(float(dims_m[0]), float(dims_m[1]))
        crng = stage_rng(0, "library-crowded-views", asset_id)
        bg = "ground" if category == "vehicle" else "water"
        for g in sorted(float(x) for x in config.crowded_gsds_m):
            side = int(max(QUERY_MIN_PX, math.ceil(size * QUERY_PAD / g - 1e-6) + 4))
            if side > CROWD_MAX_PX:
                continue
            out.extend(crowded_view(mesh, category, dims_m, g, side, bg, crng) for _ in range(n_crowd))
    return out


def crowded_view(mesh, category: str, dims_m: Sequence[float], gsd: float, side: int, background: str, rng):
    """One view of the asset between copies of itself (``crowd_mesh``), centred on it, under a random
    lighting and yaw drawn from ``rng``: (image, meta dict)."""
    crowd, centre = crowd_mesh(mesh, category, dims_m, rng)
    img, meta = random_lit_view(crowd, gsd, side, background, rng, centre)
    return img, {**meta, "crowded": True}


def random_lit_view(mesh, gsd: float, side: int, background: str, rng, centre_xy=None):
    """One query-like view under a random lighting and yaw drawn from ``rng``: (image, meta dict)."""
    from ...render import random_lighting, render_mesh_view

    light = random_lighting(rng)
    yaw = round(float(rng.uniform(-180.0, 180.0)), 3)
    img = render_mesh_view(mesh, gsd, side, light, background, yaw_deg=yaw, seed=int(rng.integers(1 << 30)),
                           centre_xy=centre_xy)
    return img, {"lighting": "random", "background": background, "gsd_m": gsd, "yaw_deg": yaw}


def write_query_views(path: Path, images: Sequence[np.ndarray]) -> None:
    """All query-like views of one asset in one file (one write instead of dozens of tiny PNGs)."""
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, *[np.asarray(i, np.uint8) for i in images])
    atomic_write_bytes(path, buf.getvalue())


def read_query_views(path: Path, n: int) -> list[np.ndarray]:
    try:
        with np.load(path) as z:
            imgs = [z[f"arr_{i}"] for i in range(n)]
    except (OSError, KeyError, ValueError) as exc:
        raise LibraryError(f"query views {path} are missing or unreadable ({exc}); rebuild the library") from exc
    return imgs
