"""The procedural starter asset kit: low-poly boats, vehicles, pier segments, a buoy and vegetation.

Every mesh is built here from a few primitives (lofts of rings, sweeps, convex hulls) with real-world
dimensions in metres, forward = +x, origin at the footprint centre, z = 0 at the waterline (floating
things) or the ground. ``python -m coastforge.assets.kit --out DIR`` writes one GLB per asset plus the
``kit.json`` manifest (format ``coastforge.kit/1``).

The GLB files follow the glTF convention (y up): a scene point (x, y, z) is stored as (x, z, -y). Each
colour is one primitive with a PBR material (``baseColorFactor`` in linear RGB), so glTF viewers and
Unreal show the colours; vertices carry flat normals and a box-projected UV set (metres). The GLB
writer is our own (no exporter version in the bytes) and all coordinates are rounded to 0.1 mm, so
regenerating gives byte-identical files (tests/test_kit.py checks the committed kit against a fresh one).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import struct
import sys
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ...errors import CoastforgeError, LibraryError
from ...export import glb
from ...export.glb import UINT, USHORT, GlbBuilder
from ...fsio import atomic_write_bytes, atomic_write_text, prepare_output_dir
from ...rng import stage_rng

KIT_FORMAT = "coastforge.kit/1"
MANIFEST_NAME = "kit.json"
KIT_CATEGORIES = ("boat", "vehicle", "pier", "buoy", "tree", "bush", "rock", "grass", "seaweed")
FLOATING_CATEGORIES = ("boat", "buoy")
_KIT_SEED = 20261122  # the kit is a fixed artefact: one seed for its rocks and foliage jitter
_DECIMALS = 4  # coordinates rounded to 0.1 mm: keeps bytes identical across platforms

# glTF is y-up: scene (x, y, z) -> glTF (x, z, -y); a proper rotation, so face winding is kept.
SCENE_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
GLTF_TO_SCENE = SCENE_TO_GLTF.T


# --------------------------------------------------------------------------------------------------
# public API


@dataclass(frozen=True)
class KitAsset:
    """One entry of a kit manifest; ``mesh_path`` is absolute."""

    id: str
    category: str
    mesh_path: Path
    dims_m: tuple[float, float, float]
    draft_m: float
    floating: bool
    tags: tuple[str, ...]

    @property
    def length_m(self) -> float:
        return self.dims_m[0]


def kit_dir() -> Path:
    """The installed ``coastforge/data/kit`` folder."""
    return Path(str(resources.files("coastforge").joinpath("data", "kit")))


def read_manifest(manifest_path: str | Path) -> tuple[KitAsset, ...]:
    """Parse a ``coastforge.kit/1`` manifest; errors name the bad field and value."""
    path = Path(manifest_path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise LibraryError(
            f"kit manifest {path} not found; regenerate it with "
            f"`python -m coastforge.assets.kit --out {path.parent} --overwrite`"
        ) from None
    except (OSError, ValueError) as exc:
        raise LibraryError(f"kit manifest {path} is not readable JSON ({exc}); regenerate it") from None
    if not isinstance(doc, dict) or doc.get("format") != KIT_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise LibraryError(f"{path}: format is {got!r}, expected {KIT_FORMAT!r}")
    assets = []
    for i, a in enumerate(doc.get("assets") or []):
        where = f"{path}: assets[{i}]"
        try:
            dims = tuple(float(v) for v in a["dims_m"])
            if len(dims) != 3 or min(dims) <= 0:
                raise ValueError(f"dims_m {a['dims_m']!r} must be three positive numbers")
            if a["category"] not in KIT_CATEGORIES:
                raise ValueError(f"category {a['category']!r} is not one of {', '.join(KIT_CATEGORIES)}")
            assets.append(
                KitAsset(
                    id=str(a["id"]), category=str(a["category"]),
                    mesh_path=(path.parent / a["mesh"]).resolve(), dims_m=dims,
                    draft_m=float(a.get("draft_m", 0.0)), floating=bool(a.get("floating", False)),
                    tags=tuple(str(t) for t in a.get("tags", ())),
                )
            )
        except KeyError as exc:
            raise LibraryError(f"{where} misses the field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            label = a.get("id", "?") if isinstance(a, dict) else repr(a)
            raise LibraryError(f"{where} ({label}): {exc}") from None
    if not assets:
        raise LibraryError(f"{path} lists no assets")
    return tuple(assets)


@functools.lru_cache(maxsize=1)
def kit_assets() -> tuple[KitAsset, ...]:
    """Every asset of the installed kit, in manifest order (cached)."""
    return read_manifest(kit_dir() / MANIFEST_NAME)


def kit_asset(asset_id: str) -> KitAsset:
    """The installed kit's asset ``asset_id``; an unknown id raises ``LibraryError`` listing the ids."""
    for a in kit_assets():
        if a.id == asset_id:
            return a
    raise LibraryError(
        f"unknown kit asset {asset_id!r}; the kit has: {', '.join(a.id for a in kit_assets())}"
    )


def load_kit_mesh(asset_id: str):
    """One concatenated ``trimesh.Trimesh`` of a kit asset in the scene frame (z up, metres, forward +x),
    with per-face sRGB colours in ``mesh.visual.face_colors``. Loaded once; each call returns a copy,
    so callers may transform it freely."""
    return _load_cached(asset_id).copy()


@functools.lru_cache(maxsize=None)
def _load_cached(asset_id: str):
    return load_glb_mesh(kit_asset(asset_id).mesh_path)


def load_glb_mesh(path: str | Path):
    """Read a GLB written by :func:`glb_bytes` into one scene-frame Trimesh with face colours."""
    import trimesh

    vertices, faces, colours = read_glb(path)
    return trimesh.Trimesh(vertices=vertices, faces=faces, face_colors=colours, process=False)


def generate_kit(out_dir: str | Path, overwrite: bool = False) -> Path:
    """Build every asset and write ``<out_dir>/<id>.glb`` plus ``kit.json``; returns the manifest path.

    Deterministic: the same bytes on every run. Every file is written atomically; ``kit.json`` last,
    so a manifest never points at a missing mesh.
    """
    out = prepare_output_dir(out_dir, overwrite=overwrite)
    entries = []
    for spec in ASSET_SPECS:
        model = spec.build()
        if spec.category not in ("boat", "vehicle", "pier"):
            model.long_axis_x()  # round things too: length_m is the longest horizontal extent
        model.recentre(spec.category in FLOATING_CATEGORIES or spec.category == "pier")
        data = glb_bytes(model, spec.id)
        name = f"{spec.id}.glb"
        atomic_write_bytes(out / name, data)
        os.chmod(out / name, 0o644)  # package data: readable by everyone (temporary files are 0600)
        lo, hi = model.bounds()
        dims = [round(float(v), 3) for v in hi - lo]
        floating = spec.category in FLOATING_CATEGORIES
        entries.append({
            "id": spec.id, "category": spec.category, "mesh": name, "length_m": dims[0], "dims_m": dims,
            "up_axis": "y", "forward_axis": "+x", "draft_m": round(float(-lo[2]), 3) if floating else 0.0,
            "floating": floating, "tags": list(spec.tags),
        })
    manifest = {"format": KIT_FORMAT, "generator": "coastforge.assets.kit", "assets": entries}
    path = out / MANIFEST_NAME
    atomic_write_text(path, json.dumps(manifest, indent=1) + "\n")
    os.chmod(path, 0o644)
    return path


# --------------------------------------------------------------------------------------------------
# colours: sRGB 0-255 plus a finish (roughness, metallic)

_FINISH = {"paint": (0.45, 0.0), "matte": (0.9, 0.0), "glass": (0.08, 0.0), "metal": (0.35, 0.8),
           "rubber": (0.85, 0.0), "plant": (0.85, 0.0)}
Colour = tuple[tuple[int, int, int], str]

WHITE: Colour = ((238, 238, 234), "paint")
OFFWHITE: Colour = ((226, 222, 210), "paint")
CREAM: Colour = ((232, 224, 200), "paint")
GLASS: Colour = ((22, 30, 40), "glass")
TEAK: Colour = ((168, 118, 70), "matte")
BLACK: Colour = ((25, 25, 27), "rubber")
DARK_GREY: Colour = ((60, 62, 66), "matte")
MID_GREY: Colour = ((120, 122, 126), "matte")
STEEL: Colour = ((170, 172, 176), "metal")
ANTIFOUL_RED: Colour = ((150, 35, 30), "matte")
ANTIFOUL_BLUE: Colour = ((30, 40, 70), "matte")
CUSHION: Colour = ((215, 205, 185), "matte")
OAR: Colour = ((200, 170, 120), "matte")
HEAD_LAMP: Colour = ((245, 240, 215), "glass")
TAIL_LAMP: Colour = ((190, 20, 20), "glass")


def _lin(c: int) -> float:
    s = c / 255.0
    return s / 12.92 if s <= 0.04045 else ((s + 0.055) / 1.055) ** 2.4


def _srgb(v: float) -> int:
    v = min(max(v, 0.0), 1.0)
    s = v * 12.92 if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(round(s * 255))


# --------------------------------------------------------------------------------------------------
# geometry primitives; a piece is (vertices (n, 3), faces (m, 3)) with outward counter-clockwise faces

Piece = tuple[np.ndarray, np.ndarray]


def _at(ring2d: np.ndarray, z: float) -> np.ndarray:
    r = np.asarray(ring2d, dtype=float)
    return np.column_stack([r[:, 0], r[:, 1], np.full(len(r), float(z))])


def _loft(rings: Sequence[np.ndarray], bottom: bool = True, top: bool = True) -> Piece:
    """Surface through rings of equal length, each counter-clockwise seen from the last ring's side.

    Caps are fans from the ring centroid (rings must be star-shaped around it)."""
    rings = [np.asarray(r, dtype=float) for r in rings]
    n = len(rings[0])
    verts = np.concatenate(rings)
    faces = []
    j = np.arange(n)
    jn = (j + 1) % n
    for k in range(len(rings) - 1):
        a, b, c, d = k * n + j, k * n + jn, (k + 1) * n + jn, (k + 1) * n + j
        faces.append(np.column_stack([a, b, c]))
        faces.append(np.column_stack([a, c, d]))
    extra = []
    if bottom:
        ci = len(verts) + len(extra)
        extra.append(rings[0].mean(0))
        faces.append(np.column_stack([np.full(n, ci), jn, j]))
    if top:
        ci = len(verts) + len(extra)
        extra.append(rings[-1].mean(0))
        base = (len(rings) - 1) * n
        faces.append(np.column_stack([np.full(n, ci), base + j, base + jn]))
    if extra:
        verts = np.concatenate([verts, np.array(extra)])
    return verts, np.concatenate(faces).astype(np.int64)


def _cap(ring: np.ndarray, up: bool = True) -> Piece:
    """A flat fan over one ring (normal +axis if ``up``)."""
    ring = np.asarray(ring, dtype=float)
    n = len(ring)
    j = np.arange(n)
    jn = (j + 1) % n
    f = np.column_stack([np.full(n, n), j, jn]) if up else np.column_stack([np.full(n, n), jn, j])
    return np.concatenate([ring, ring.mean(0)[None]]), f


def _band(outer: np.ndarray, inner: np.ndarray, z0: float, z1: float) -> Piece:
    """A closed rim between two counter-clockwise rings of equal length (a gunwale, a coaming)."""
    n = len(outer)
    o0, o1, i0, i1 = _at(outer, z0), _at(outer, z1), _at(inner, z0), _at(inner, z1)
    v = np.concatenate([o0, o1, i0, i1])
    j = np.arange(n)
    jn = (j + 1) % n
    O0, O1, I0, I1 = 0, n, 2 * n, 3 * n
    f = [
        np.column_stack([O0 + j, O0 + jn, O1 + jn]), np.column_stack([O0 + j, O1 + jn, O1 + j]),  # outer wall
        np.column_stack([I0 + j, I1 + jn, I0 + jn]), np.column_stack([I0 + j, I1 + j, I1 + jn]),  # inner wall
        np.column_stack([O1 + j, O1 + jn, I1 + jn]), np.column_stack([O1 + j, I1 + jn, I1 + j]),  # top
        np.column_stack([O0 + j, I0 + jn, O0 + jn]), np.column_stack([O0 + j, I0 + j, I0 + jn]),  # bottom
    ]
    return v, np.concatenate(f)


def _rect(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def _box(x0, x1, y0, y1, z0, z1) -> Piece:
    r = _rect(x0, x1, y0, y1)
    return _loft([_at(r, z0), _at(r, z1)])


def _circle(cx: float, cy: float, r: float, n: int = 10, phase: float = 0.0) -> np.ndarray:
    t = 2 * np.pi * (np.arange(n) + phase) / n
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _frame(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v with u x v = t (so rings built on them are counter-clockwise about t)."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(t[2]) > 0.7 else np.array([0.0, 0.0, 1.0])
    u = np.cross(t, ref)
    u /= np.linalg.norm(u)
    return u, np.cross(t, u)


def _sweep(path: np.ndarray, radius, n: int = 8, flat: float = 1.0) -> Piece:
    """A tube along a 3-D polyline; ``radius`` a number or one per point; ``flat`` scales the v axis
    (thin fronds / leaves)."""
    path = np.asarray(path, dtype=float)
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(path),))
    th = 2 * np.pi * np.arange(n) / n
    rings = []
    for i, p in enumerate(path):
        t = path[min(i + 1, len(path) - 1)] - path[max(i - 1, 0)]
        t /= np.linalg.norm(t)
        u, v = _frame(t)
        r = max(float(radius[i]), 1e-3)
        rings.append(p + r * np.cos(th)[:, None] * u + r * flat * np.sin(th)[:, None] * v)
    return _loft(rings)


def _cylinder(p0, p1, r: float, n: int = 10) -> Piece:
    return _sweep(np.array([p0, p1], dtype=float), r, n)


def _ellipsoid(c, radii, n_lat: int = 5, n_lon: int = 10, jitter: np.ndarray | None = None) -> Piece:
    """A low-poly ellipsoid; ``jitter`` (n_lat, n_lon) scales each vertex radius (organic foliage)."""
    c = np.asarray(c, dtype=float)
    rings = []
    lats = np.linspace(-75, 75, n_lat) * np.pi / 180
    th = 2 * np.pi * (np.arange(n_lon) + 0.5 * (np.arange(n_lat)[:, None] % 2)) / n_lon
    for i, lat in enumerate(lats):
        s = 1.0 if jitter is None else jitter[i][:, None]
        ring = np.column_stack([np.cos(lat) * np.cos(th[i]), np.cos(lat) * np.sin(th[i]),
                                np.full(n_lon, np.sin(lat))])
        rings.append(c + ring * np.asarray(radii) * s)
    return _loft(rings)


def _convex(points: np.ndarray) -> Piece:
    """Convex hull of points with outward faces (rocks)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    keep = np.sort(hull.vertices)
    v = points[keep]
    remap = {int(old): new for new, old in enumerate(keep)}
    f = np.array([[remap[int(i)] for i in s] for s in hull.simplices])
    centre = v.mean(0)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    inward = ((v[f].mean(1) - centre) * n).sum(1) < 0
    f[inward] = f[inward][:, ::-1]
    # canonical face order (smallest index first, winding kept; faces sorted) so the bytes do not
    # depend on the order in which a Qhull version reports facets
    f = np.array([np.roll(t, -int(np.argmin(t))) for t in f])
    f = f[np.lexsort(f.T[::-1])]
    return v, f


# --------------------------------------------------------------------------------------------------
# outlines


def _hull_ring(length: float, beam: float, x_stern: float, shoulder: float = 0.5, bow_power: float = 1.8,
               transom: float = 0.85, n: int = 14, y0: float = 0.0) -> np.ndarray:
    """Deck outline seen from above: square transom at ``x_stern``, pointed bow at ``x_stern + length``.

    Counter-clockwise: starboard side stern→bow, then port side bow→stern; 2n-1 points."""
    t = np.linspace(0.0, 1.0, n)
    w = np.where(
        t < shoulder,
        transom + (1 - transom) * np.sin(0.5 * np.pi * np.minimum(t / shoulder, 1.0)),
        1 - np.clip((t - shoulder) / (1 - shoulder), 0.0, 1.0) ** bow_power,
    ) * beam / 2
    x = x_stern + length * t
    stb = np.column_stack([x, y0 - w])
    port = np.column_stack([x[-2::-1], y0 + w[-2::-1]])
    return np.concatenate([stb, port])


def _cabin_ring(x0: float, x1: float, width: float, chamfer: float = 0.0, nose: float = 0.4) -> np.ndarray:
    """A superstructure outline: square aft end at x0, chamfered front at x1 (front face ``nose`` x width)."""
    h = width / 2
    c = min(chamfer, (x1 - x0) * 0.9)
    pts = [[x0, -h], [x1 - c, -h], [x1, -h * nose], [x1, h * nose], [x1 - c, h], [x0, h]]
    return np.array(pts, dtype=float)


def _rrect(x0: float, x1: float, width: float, c: float, y0: float = 0.0) -> np.ndarray:
    """A rectangle with chamfered corners (car bodies), 8 points counter-clockwise."""
    h = width / 2
    return np.array([[x0 + c, y0 - h], [x1 - c, y0 - h], [x1, y0 - h + c], [x1, y0 + h - c],
                     [x1 - c, y0 + h], [x0 + c, y0 + h], [x0, y0 + h - c], [x0, y0 - h + c]], dtype=float)


# --------------------------------------------------------------------------------------------------
# the model being built: pieces grouped by colour


class _Model:
    def __init__(self) -> None:
        self.pieces: list[tuple[np.ndarray, np.ndarray, Colour]] = []

    def add(self, piece: Piece, colour: Colour) -> None:
        v, f = piece
        self.pieces.append((np.asarray(v, dtype=float), np.asarray(f, dtype=np.int64), colour))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        allv = np.concatenate([p[0] for p in self.pieces])
        return allv.min(0), allv.max(0)

    def long_axis_x(self) -> None:
        """Turn a model without a front by 90° about z if it is wider (y) than long (x)."""
        lo, hi = self.bounds()
        if hi[1] - lo[1] > hi[0] - lo[0]:
            self.pieces = [(np.column_stack([-v[:, 1], v[:, 0], v[:, 2]]), f, c) for v, f, c in self.pieces]

    def recentre(self, keep_z: bool) -> None:
        """Origin at the footprint centre; z = 0 kept (waterline) or set to the lowest point (ground)."""
        lo, hi = self.bounds()
        shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.0 if keep_z else lo[2]])
        self.pieces = [(v - shift, f, c) for v, f, c in self.pieces]

    def by_colour(self) -> list[tuple[Colour, np.ndarray, np.ndarray]]:
        """Pieces merged per colour, in order of first use."""
        groups: dict[Colour, list[Piece]] = {}
        for v, f, c in self.pieces:
            groups.setdefault(c, []).append((v, f))
        out = []
        for c, ps in groups.items():
            vs, fs, off = [], [], 0
            for v, f in ps:
                vs.append(v)
                fs.append(f + off)
                off += len(v)
            out.append((c, np.concatenate(vs), np.concatenate(fs)))
        return out


# --------------------------------------------------------------------------------------------------
# boats


def _hull(m: _Model, length: float, beam: float, x_stern: float, freeboard: float, draft: float,
          hull: Colour, deck: Colour | None, bottom: Colour, *, shoulder=0.5, bow_power=1.8, transom=0.85,
          keel_beam=0.2, y0: float = 0.0, deck_cap: bool = True) -> np.ndarray:
    """A hull: bottom (keel to waterline) in antifouling, topsides, a deck cap; returns the sheer ring."""
    kw = dict(shoulder=shoulder, bow_power=bow_power, transom=transom, y0=y0)
    keel = _hull_ring(length * 0.86, beam * keel_beam, x_stern + length * 0.03, **kw)
    wl = _hull_ring(length * 0.95, beam * 0.88, x_stern + length * 0.01, **kw)
    sheer = _hull_ring(length, beam, x_stern, **kw)
    m.add(_loft([_at(keel, -draft), _at(wl, 0.0)], bottom=True, top=False), bottom)
    m.add(_loft([_at(wl, 0.0), _at(sheer, freeboard)], bottom=False, top=False), hull)
    if deck_cap:
        m.add(_cap(_at(sheer, freeboard)), deck if deck is not None else hull)
    return sheer


def _gunwale(m: _Model, length, beam, x_stern, z, width, height, colour, **kw) -> None:
    outer = _hull_ring(length, beam, x_stern, **kw)
    inner = _hull_ring(length - 2.2 * width, beam - 2 * width, x_stern + width, **kw)
    m.add(_band(outer, inner, z, z + height), colour)


def _tier(m: _Model, x0, x1, width, z0, bands: Sequence[tuple[float, Colour]], slope=0.0, inset=0.0,
          chamfer=0.0, nose=0.4, roof: Colour | None = None, y0: float = 0.0) -> float:
    """A superstructure tier: stacked coloured bands (hull-white, window-dark, ...) with a raked front;
    returns the roof height."""
    z = z0
    def ring(zz):
        dz = zz - z0
        r = _cabin_ring(x0 + inset * dz, x1 - slope * dz, width - 2 * inset * dz, chamfer, nose)
        r[:, 1] += y0
        return _at(r, zz)
    for i, (h, colour) in enumerate(bands):
        last = i == len(bands) - 1
        m.add(_loft([ring(z), ring(z + h)], bottom=(i == 0), top=last and roof is None), colour)
        z += h
    if roof is not None:
        m.add(_cap(ring(z)), roof)
    return z


def build_dinghy() -> _Model:
    m = _Model()
    grey, orange = ((128, 132, 136), "rubber"), ((235, 105, 25), "rubber")
    r, half = 0.23, 0.55  # tube radius, tube centreline half-width
    zc = 0.16  # tube centre above the waterline
    # side tubes (grey) from the stern to the start of the bow curve, bow curve orange
    sx, bx, a = -1.22, 0.0, 1.3
    m.add(_sweep(np.array([[sx, -half, zc], [bx, -half, zc]]), r, 10), grey)
    m.add(_sweep(np.array([[bx, half, zc], [sx, half, zc]]), r, 10), grey)
    # the bow tubes converge to a point (taper like a hull: half-width = 1 - u^1.6 along the bow)
    s = np.sin(np.linspace(-np.pi / 2, np.pi / 2, 13))
    u = (1 - np.abs(s)) ** (1 / 1.6)
    bow = np.column_stack([bx + a * u, half * s, zc + 0.12 * u])
    m.add(_sweep(bow, r, 10), orange)
    # floor between the tubes and the transom board
    m.add(_loft([_at(_hull_ring(2.2, 2 * half, sx, shoulder=0.62, bow_power=2.2, transom=1.0), -0.12),
                 _at(_hull_ring(2.35, 2 * half, sx, shoulder=0.62, bow_power=2.2, transom=1.0), 0.0)]),
          DARK_GREY)
    m.add(_box(sx - 0.04, sx + 0.06, -half, half, -0.1, 0.36), MID_GREY)
    # outboard motor on the transom: cowling, shaft, skeg below the water
    m.add(_box(sx - 0.36, sx - 0.04, -0.17, 0.17, 0.22, 0.62), BLACK)
    m.add(_box(sx - 0.24, sx - 0.12, -0.05, 0.05, -0.32, 0.22), DARK_GREY)
    # thwart (seat) and a fuel tank: deck detail seen from above
    m.add(_box(-0.25, 0.05, -half, half, 0.2, 0.26), MID_GREY)
    m.add(_box(-1.0, -0.7, -0.2, 0.12, 0.0, 0.22), ((200, 30, 30), "paint"))
    return m


def build_kayak() -> _Model:
    m = _Model()
    yellow, red = ((250, 200, 20), "paint"), ((215, 50, 30), "paint")
    L, B = 4.0, 0.62
    kw = dict(shoulder=0.45, bow_power=1.5, transom=0.32)
    x0 = -L / 2
    keel = _hull_ring(L * 0.9, B * 0.35, x0 + L * 0.05, **kw)
    wl = _hull_ring(L * 0.96, B * 0.92, x0 + L * 0.02, **kw)
    sheer = _hull_ring(L, B, x0, **kw)
    ridge = _hull_ring(L * 0.9, B * 0.45, x0 + L * 0.05, **kw)
    m.add(_loft([_at(keel, -0.13), _at(wl, 0.0)], top=False), yellow)
    m.add(_loft([_at(wl, 0.0), _at(sheer, 0.2)], bottom=False, top=False), yellow)
    m.add(_loft([_at(sheer, 0.2), _at(ridge, 0.3)], bottom=False, top=True), yellow)
    # cockpit aft of centre: black coaming, dark seat; deck lines and a red stern hatch
    ck = _circle(-0.25, 0.0, 1.0, 12)
    outer = ck * [0.48, 0.25] + [-0.25 * 0.52, 0]
    inner = ck * [0.40, 0.19] + [-0.25 * 0.6, 0]
    m.add(_band(outer, inner, 0.26, 0.36), BLACK)
    m.add(_cap(_at(inner, 0.33)), DARK_GREY)
    m.add(_loft([_at(_circle(-1.05, 0, 0.14, 10), 0.28), _at(_circle(-1.05, 0, 0.14, 10), 0.34)]), red)
    m.add(_loft([_at(_circle(0.95, 0, 0.12, 10), 0.28), _at(_circle(0.95, 0, 0.12, 10), 0.34)]), red)
    m.add(_box(0.45, 1.6, -0.01, 0.01, 0.3, 0.33), BLACK)  # bungee line on the fore deck
    m.add(_box(-1.98, -1.86, -0.015, 0.015, -0.22, 0.22), BLACK)  # rudder blade at the stern
    return m


def build_runabout() -> _Model:
    m = _Model()
    red = ((200, 30, 40), "paint")
    L, B, fb, d = 5.6, 2.4, 0.85, 0.42
    xs = -2.6
    kw = dict(shoulder=0.42, bow_power=1.6, transom=0.9)
    _hull(m, L, B, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, **kw)
    # coloured stripe: a red band on the topsides just under the sheer, and a red rub rail
    sheer_lo = _hull_ring(L * 0.995, B * 1.005, xs + 0.01, **kw)
    sheer_hi = _hull_ring(L * 1.0, B * 1.01, xs, **kw)
    m.add(_loft([_at(sheer_lo, fb - 0.35), _at(sheer_hi, fb - 0.15)]), red)
    _gunwale(m, L, B, xs, fb, 0.12, 0.06, red, **kw)
    # cockpit floor (light grey) aft of the windscreen, bench seats, console
    m.add(_box(xs + 0.2, 0.9, -0.95, 0.95, fb, fb + 0.02), ((190, 190, 185), "matte"))
    m.add(_box(xs + 0.25, xs + 0.85, -1.0, 1.0, fb, fb + 0.45), ((210, 200, 180), "matte"))  # stern bench
    m.add(_box(-0.7, -0.15, -0.85, -0.25, fb, fb + 0.5), ((210, 200, 180), "matte"))  # helm seat
    m.add(_box(-0.7, -0.15, 0.25, 0.85, fb, fb + 0.5), ((210, 200, 180), "matte"))
    m.add(_box(0.1, 0.75, -0.9, -0.2, fb, fb + 0.7), WHITE)  # console
    # V windscreen, raked aft, dark glass
    for sgn in (-1, 1):
        a = np.array([1.2, 0.0])
        b = np.array([0.75, sgn * 1.0])
        d2 = b - a
        nrm = np.array([-d2[1], d2[0]]) / np.linalg.norm(d2) * 0.04
        ring = np.array([a - nrm, b - nrm, b + nrm, a + nrm])
        if sgn > 0:
            ring = ring[::-1]
        # counter-clockwise check (shoelace) so faces point outwards
        area = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
        if area < 0:
            ring = ring[::-1]
        m.add(_loft([_at(ring, fb), _at(ring - [0.25, 0], fb + 0.45)]), GLASS)
    # outboard engine aft of the transom
    m.add(_box(xs - 0.42, xs - 0.02, -0.28, 0.28, 0.35, 1.1), ((30, 30, 32), "paint"))
    m.add(_box(xs - 0.3, xs - 0.12, -0.06, 0.06, -0.55, 0.35), DARK_GREY)
    # bow cleat and a sun pad on the fore deck
    m.add(_box(1.6, 2.4, -0.55, 0.55, fb, fb + 0.08), ((210, 200, 180), "matte"))
    m.add(_box(2.7, 2.85, -0.04, 0.04, fb, fb + 0.06), STEEL)
    return m


def build_cabin_cruiser() -> _Model:
    m = _Model()
    navy = ((25, 45, 95), "paint")
    L, B, fb, d = 9.5, 3.5, 1.3, 0.9
    xs = -4.5
    kw = dict(shoulder=0.45, bow_power=1.7, transom=0.9)
    _hull(m, L, B, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.14, 0.25, navy, **kw)
    # swim platform (teak) aft of the transom
    m.add(_box(-5.0, xs + 0.02, -1.4, 1.4, 0.3, 0.4), TEAK)
    # cockpit (teak) aft, cabin superstructure amidships with raked dark windscreen
    m.add(_box(xs + 0.2, -1.5, -1.5, 1.5, fb, fb + 0.02), TEAK)
    top = _tier(m, -1.5, 2.9, 2.9, fb, [(0.6, WHITE), (0.55, GLASS), (0.2, WHITE)], slope=0.9, inset=0.12,
                chamfer=0.9, nose=0.45, roof=OFFWHITE)
    # radar arch / mast on the roof and a fore-deck hatch
    m.add(_box(-0.9, -0.6, -0.9, 0.9, top, top + 0.35), WHITE)
    m.add(_cylinder([-0.75, 0, top + 0.35], [-0.75, 0, top + 0.8], 0.05, 6), STEEL)
    m.add(_box(3.3, 3.9, -0.35, 0.35, fb, fb + 0.1), ((150, 160, 170), "glass"))
    # cockpit bench across the stern
    m.add(_box(xs + 0.3, xs + 0.8, -1.4, 1.4, fb, fb + 0.45), ((215, 205, 185), "matte"))
    return m


def build_sailboat() -> _Model:
    m = _Model()
    navy = ((20, 35, 80), "paint")
    blue = ((30, 80, 160), "matte")
    L, B, fb, d = 9.0, 3.0, 1.0, 0.45
    xs = -4.5
    kw = dict(shoulder=0.4, bow_power=1.5, transom=0.8)
    _hull(m, L, B, xs, fb, d, navy, CREAM, ANTIFOUL_RED, **kw)
    _gunwale(m, L, B, xs, fb, 0.1, 0.08, navy, **kw)
    # fin keel and rudder below the canoe body
    fin = [_at(_rect(-0.5, 0.6, -0.1, 0.1), -1.7), _at(_rect(-0.8, 0.9, -0.12, 0.12), -0.3)]
    m.add(_loft(fin), ANTIFOUL_RED)
    m.add(_box(-4.0, -3.6, -0.04, 0.04, -1.2, -0.2), ANTIFOUL_RED)
    # cockpit: teak sole with white coamings, a wheel
    cockpit = _rrect(-4.25, -1.2, 1.9, 0.2)
    inner = _rrect(-4.15, -1.3, 1.7, 0.15)
    m.add(_cap(_at(cockpit, fb + 0.01)), TEAK)
    m.add(_band(cockpit, inner, fb, fb + 0.3), WHITE)
    m.add(_box(-3.6, -3.5, -0.45, 0.45, fb, fb + 0.9), BLACK)
    # cabin trunk with dark ports and a hatch
    top = _tier(m, -1.2, 2.2, 2.0, fb, [(0.25, CREAM), (0.12, GLASS), (0.12, CREAM)], slope=0.35, inset=0.1,
                chamfer=0.8, nose=0.5, roof=WHITE)
    m.add(_box(0.8, 1.3, -0.3, 0.3, top, top + 0.06), ((120, 140, 160), "glass"))
    # mast, boom with a blue sail cover, forestay region pulpit
    mx = 1.2
    m.add(_cylinder([mx, 0, top], [mx, 0, fb + 12.5], 0.09, 8), STEEL)
    bz = top + 1.1
    m.add(_cylinder([mx, 0, bz], [-3.3, 0, bz], 0.06, 6), STEEL)
    m.add(_sweep(np.array([[mx - 0.1, 0, bz + 0.15], [0.0, 0, bz + 0.2], [-3.2, 0, bz + 0.12]]),
                 np.array([0.2, 0.22, 0.12]), 8), blue)
    m.add(_cylinder([3.8, 0, fb + 0.05], [4.35, 0, fb + 0.05], 0.04, 6), STEEL)  # bow roller/pulpit
    return m


def build_catamaran() -> _Model:
    m = _Model()
    L, hb, fb, d = 12.0, 1.4, 1.2, 0.7
    xs = -6.0
    kw = dict(shoulder=0.55, bow_power=1.6, transom=0.85, keel_beam=0.25)
    yh = 2.4
    for sgn in (-1, 1):
        _hull(m, L, hb, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, y0=sgn * yh, **kw)
    # bridge deck aft, trampoline (dark net) forward, saloon with dark windows, mast and boom
    m.add(_box(-5.6, 1.8, -yh, yh, fb - 0.25, fb + 0.05), WHITE)
    m.add(_box(1.8, 3.9, -yh + 0.5, yh - 0.5, fb - 0.05, fb), ((45, 48, 52), "matte"))
    m.add(_box(3.85, 4.05, -yh, yh, fb - 0.15, fb + 0.05), WHITE)  # front beam
    m.add(_box(-5.6, -3.0, -1.8, 1.8, fb + 0.05, fb + 0.07), ((190, 190, 185), "matte"))  # cockpit sole
    top = _tier(m, -3.0, 1.6, 4.6, fb + 0.05, [(0.6, WHITE), (0.6, GLASS), (0.15, WHITE)], slope=0.6,
                inset=0.15, chamfer=0.8, nose=0.6, roof=OFFWHITE)
    mx = 1.4
    m.add(_cylinder([mx, 0, top], [mx, 0, 17.0], 0.11, 8), STEEL)
    bz = top + 0.5
    m.add(_cylinder([mx, 0, bz], [-5.0, 0, bz], 0.07, 6), STEEL)
    m.add(_sweep(np.array([[mx - 0.1, 0, bz + 0.15], [-1.5, 0, bz + 0.2], [-4.8, 0, bz + 0.12]]),
                 np.array([0.2, 0.24, 0.12]), 8), ((200, 200, 195), "matte"))
    return m


def build_yacht() -> _Model:
    m = _Model()
    L, B, fb, d = 17.2, 5.0, 2.0, 1.4
    xs = -8.2
    kw = dict(shoulder=0.45, bow_power=1.7, transom=0.92)
    _hull(m, L, B, xs, fb, d, ((28, 35, 55), "paint"), WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.15, 0.7, WHITE, **kw)  # bulwark
    m.add(_box(-9.0, xs + 0.02, -2.2, 2.2, 0.3, 0.45), TEAK)  # swim platform
    m.add(_box(xs + 0.2, -4.5, -2.3, 2.3, fb, fb + 0.02), TEAK)  # aft deck
    # main deck saloon, then the flybridge tier, hardtop; dark window bands and raked windscreens
    z1 = _tier(m, -4.5, 4.5, 4.2, fb, [(0.9, WHITE), (0.95, GLASS), (0.35, WHITE)], slope=0.9, inset=0.08,
               chamfer=1.6, nose=0.45, roof=WHITE)
    z2 = _tier(m, -2.6, 2.4, 3.6, z1, [(0.25, WHITE), (0.75, GLASS), (0.2, WHITE)], slope=1.0, inset=0.1,
               chamfer=1.2, nose=0.5, roof=OFFWHITE)
    m.add(_box(-1.2, 0.2, -1.2, 1.2, z2, z2 + 0.3), MID_GREY)  # radar arch base
    m.add(_ellipsoid([-0.5, 0, z2 + 0.5], [0.35, 0.35, 0.25], 3, 8), WHITE)  # radome
    # fore-deck sun pads and a tender on the aft deck roof overhang
    m.add(_box(5.0, 6.6, -1.2, 1.2, fb, fb + 0.18), ((215, 205, 180), "matte"))
    m.add(_box(7.5, 7.8, -0.1, 0.1, fb, fb + 0.15), STEEL)  # anchor windlass
    return m


def build_fishing_boat() -> _Model:
    m = _Model()
    blue = ((28, 70, 150), "paint")
    L, B, fb, d = 12.0, 4.2, 1.4, 1.3
    xs = -6.0
    kw = dict(shoulder=0.5, bow_power=1.5, transom=0.95)
    _hull(m, L, B, xs, fb, d, blue, ((105, 110, 105), "matte"), ANTIFOUL_RED, **kw)
    _gunwale(m, L, B, xs, fb, 0.16, 0.85, blue, **kw)  # bulwarks: a blue outline from above
    # wheelhouse forward: white, dark window band, orange roof with a mast and radar
    z = _tier(m, 0.8, 4.2, 3.0, fb, [(1.1, WHITE), (0.8, GLASS), (0.25, WHITE)], slope=0.3, inset=0.05,
              chamfer=0.6, nose=0.6, roof=((235, 110, 30), "paint"))
    m.add(_cylinder([2.0, 0, z], [2.0, 0, z + 2.2], 0.08, 6), STEEL)
    m.add(_box(1.55, 2.45, -0.1, 0.1, z + 1.6, z + 1.7), DARK_GREY)  # radar scanner
    # work deck aft: net drum, fish boxes, a stern gantry
    m.add(_cylinder([-1.5, -1.3, fb + 0.65], [-1.5, 1.3, fb + 0.65], 0.65, 10), ((40, 110, 60), "matte"))
    orange = ((240, 130, 20), "matte")
    for i, (x, y) in enumerate([(-3.6, -1.2), (-3.6, -0.55), (-4.3, -1.2), (0.0, 1.2), (-0.6, 1.2)]):
        m.add(_box(x, x + 0.6, y, y + 0.45, fb, fb + 0.35 + 0.3 * (i % 2)), orange)
    yellow = ((240, 200, 30), "paint")
    for sgn in (-1, 1):
        m.add(_cylinder([-5.6, sgn * 1.7, fb], [-5.3, sgn * 1.5, fb + 3.0], 0.1, 6), yellow)
    m.add(_cylinder([-5.3, -1.6, fb + 3.0], [-5.3, 1.6, fb + 3.0], 0.1, 6), yellow)
    return m


def build_rowboat() -> _Model:
    m = _Model()
    wood = ((128, 84, 50), "matte")
    green = ((70, 120, 95), "paint")
    L, B, fb, d = 3.6, 1.4, 0.45, 0.2
    xs = -L / 2
    kw = dict(shoulder=0.45, bow_power=1.5, transom=0.75)
    _hull(m, L, B, xs, fb, d, wood, green, ((60, 45, 35), "matte"), **kw)  # open boat: painted interior
    _gunwale(m, L, B, xs, fb, 0.07, 0.05, wood, **kw)
    for x0 in (-1.35, -0.3, 0.7):  # thwarts (seats)
        half = 0.5 if x0 < 0.5 else 0.42
        m.add(_box(x0, x0 + 0.22, -half, half, fb - 0.02, fb + 0.04), wood)
    # a pair of oars shipped along the sides
    for sgn in (-1, 1):
        m.add(_cylinder([-1.3, sgn * 0.5, fb + 0.08], [1.0, sgn * 0.55, fb + 0.08], 0.03, 6), OAR)
    return m


def build_center_console() -> _Model:
    m = _Model()
    hull = ((150, 190, 215), "paint")
    canvas = ((28, 48, 92), "matte")
    L, B, fb, d = 6.9, 2.6, 1.0, 0.5
    xs = -3.1
    kw = dict(shoulder=0.4, bow_power=1.5, transom=0.9)
    _hull(m, L, B, xs, fb, d, hull, WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.12, 0.12, WHITE, **kw)
    m.add(_box(xs + 0.2, 2.2, -1.05, 1.05, fb, fb + 0.02), ((200, 200, 195), "matte"))  # non-skid sole
    m.add(_box(-0.6, 0.6, -0.45, 0.45, fb, fb + 1.05), WHITE)  # console
    screen = [_at(_rect(0.45, 0.75, -0.45, 0.45), fb + 1.05), _at(_rect(0.35, 0.5, -0.42, 0.42), fb + 1.45)]
    m.add(_loft(screen), GLASS)
    for x in (-0.9, 0.7):  # T-top frame and canvas
        for y in (-0.55, 0.55):
            m.add(_cylinder([x, y, fb], [x, y, fb + 2.15], 0.03, 6), STEEL)
    m.add(_box(-1.1, 0.9, -0.95, 0.95, fb + 2.15, fb + 2.25), canvas)
    m.add(_box(xs + 0.3, xs + 0.8, -1.1, 1.1, fb, fb + 0.45), CUSHION)  # leaning post / bench
    m.add(_box(2.0, 2.9, -0.75, 0.75, fb, fb + 0.35), CUSHION)  # bow seating
    for y in (-0.45, 0.45):  # twin outboards
        m.add(_box(xs - 0.45, xs - 0.02, y - 0.27, y + 0.27, 0.4, 1.2), BLACK)
        m.add(_box(xs - 0.32, xs - 0.14, y - 0.06, y + 0.06, -0.6, 0.4), DARK_GREY)
    return m


# --------------------------------------------------------------------------------------------------
# vehicles


def _car(m: _Model, paint: Colour, *, L, W, body_top, roof_z, gh_x, roof_x, chamfer=0.25, belt_inset=0.1,
         roof_inset=0.2, wheel_r=0.33, wheelbase=2.7, clearance=0.18, rear_lamps=True) -> None:
    """A car: chamfered lower body (hood and trunk in paint), dark-glass greenhouse whose windscreen
    (front) is longer than the rear window, painted roof, wheels, head and tail lamps."""
    x0, x1 = -L / 2, L / 2
    bottom = _rrect(x0 + 0.1, x1 - 0.1, W - 0.1, chamfer)
    mid = _rrect(x0, x1, W, chamfer)
    top = _rrect(x0 + 0.05, x1 - 0.12, W - 0.06, chamfer)
    m.add(_loft([_at(bottom, clearance), _at(mid, clearance + 0.3), _at(top, body_top)]), paint)
    belt = _rrect(gh_x[0], gh_x[1], W - 2 * belt_inset, 0.15)
    roof = _rrect(roof_x[0], roof_x[1], W - 2 * roof_inset, 0.12)
    m.add(_loft([_at(belt, body_top), _at(roof, roof_z - 0.04)], bottom=False, top=False), GLASS)
    m.add(_loft([_at(roof, roof_z - 0.04), _at(roof, roof_z)], bottom=False), paint)
    for sx in (-1, 1):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.16)
            m.add(_cylinder([sx * wheelbase / 2, y - 0.11, wheel_r], [sx * wheelbase / 2, y + 0.11, wheel_r],
                            wheel_r, 10), BLACK)
            lamp_x = x1 - 0.2 if sx > 0 else x0 + 0.08
            colour = HEAD_LAMP if sx > 0 else TAIL_LAMP
            if sx < 0 and not rear_lamps:
                continue
            m.add(_box(lamp_x, lamp_x + 0.1, sy * (W / 2 - 0.3) - 0.14, sy * (W / 2 - 0.3) + 0.14,
                       body_top - 0.15, body_top + 0.01), colour)


def build_sedan() -> _Model:
    m = _Model()
    _car(m, ((165, 25, 32), "paint"), L=4.6, W=1.82, body_top=0.82, roof_z=1.45, gh_x=(-1.25, 0.95),
         roof_x=(-0.85, 0.2))
    return m


def build_suv() -> _Model:
    m = _Model()
    _car(m, ((32, 48, 92), "paint"), L=4.8, W=1.95, body_top=1.05, roof_z=1.8, gh_x=(-2.15, 0.95),
         roof_x=(-2.05, 0.35), wheel_r=0.38, wheelbase=2.85, clearance=0.25, chamfer=0.2)
    m.add(_box(-1.7, 0.1, -0.75, -0.7, 1.8, 1.86), BLACK)  # roof rails
    m.add(_box(-1.7, 0.1, 0.7, 0.75, 1.8, 1.86), BLACK)
    return m


def build_pickup() -> _Model:
    m = _Model()
    paint = ((175, 178, 183), "paint")
    L, W = 5.5, 2.0
    _car(m, paint, L=L, W=W, body_top=1.0, roof_z=1.85, gh_x=(-0.75, 1.05), roof_x=(-0.7, 0.45),
         wheel_r=0.39, wheelbase=3.4, clearance=0.26, chamfer=0.15)
    # open bed: black liner floor, painted walls, tailgate
    bx0, bx1 = -L / 2 + 0.08, -0.85
    m.add(_box(bx0 + 0.08, bx1 - 0.05, -W / 2 + 0.12, W / 2 - 0.12, 1.0, 1.02), BLACK)
    outer = _rect(bx0, bx1, -W / 2 + 0.03, W / 2 - 0.03)
    inner = _rect(bx0 + 0.07, bx1 - 0.07, -W / 2 + 0.1, W / 2 - 0.1)
    m.add(_band(outer, inner, 1.0, 1.3), paint)
    return m


def build_van() -> _Model:
    m = _Model()
    paint = ((240, 240, 238), "paint")
    L, W = 5.2, 2.0
    x0, x1 = -L / 2, L / 2
    m.add(_loft([_at(_rrect(x0 + 0.05, x1 - 0.1, W - 0.08, 0.15), 0.22),
                 _at(_rrect(x0, x1, W, 0.2), 0.55), _at(_rrect(x0, x1 - 0.05, W - 0.04, 0.25), 1.1)]), paint)
    # boxy cargo body behind a short, steep windscreen
    cargo = [_at(_rrect(x0, 1.55, W - 0.04, 0.12), 1.1), _at(_rrect(x0, 1.5, W - 0.1, 0.12), 2.3)]
    m.add(_loft(cargo), paint)
    ws0 = _rrect(1.45, 2.2, W - 0.16, 0.15)
    ws1 = _rrect(1.45, 1.6, W - 0.2, 0.05)
    m.add(_loft([_at(ws0, 1.1), _at(ws1, 2.12)]), GLASS)
    m.add(_box(-0.8, 0.2, -0.35, 0.35, 2.3, 2.34), MID_GREY)  # roof vent
    for sx in (-1.65, 1.6):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.16)
            m.add(_cylinder([sx, y - 0.11, 0.36], [sx, y + 0.11, 0.36], 0.36, 10), BLACK)
    for sy in (-1, 1):
        m.add(_box(2.42, 2.52, sy * 0.7 - 0.14, sy * 0.7 + 0.14, 0.95, 1.11), ((245, 240, 215), "glass"))
        m.add(_box(x0 + 0.02, x0 + 0.1, sy * 0.88 - 0.06, sy * 0.88 + 0.06, 1.2, 2.0), TAIL_LAMP)
    return m


def build_bus() -> _Model:
    m = _Model()
    yellow = ((240, 185, 25), "paint")
    L, W = 12.0, 2.55
    x0, x1 = -L / 2, L / 2
    def ring(zz, front):
        return _at(_rrect(x0 + 0.05, front, W - 0.02, 0.2), zz)
    m.add(_loft([_at(_rrect(x0 + 0.2, x1 - 0.2, W - 0.1, 0.2), 0.3), ring(0.6, x1), ring(1.2, x1)],
                top=False), yellow)
    # raked windscreen: its dark glass shows from above at the front only
    m.add(_loft([ring(1.2, x1), ring(2.55, x1 - 0.5)], bottom=False, top=False), GLASS)
    m.add(_loft([ring(2.55, x1 - 0.5), ring(2.95, x1 - 0.62)], bottom=False), yellow)
    m.add(_box(-2.0, 0.6, -0.8, 0.8, 2.95, 3.2), MID_GREY)  # roof air conditioning
    m.add(_box(-4.8, -3.8, -0.5, 0.5, 2.95, 3.05), DARK_GREY)  # roof hatch
    for sx in (-3.4, 3.4):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.2)
            m.add(_cylinder([sx, y - 0.14, 0.5], [sx, y + 0.14, 0.5], 0.5, 10), BLACK)
    return m


def build_hatchback() -> _Model:
    m = _Model()
    _car(m, ((40, 105, 70), "paint"), L=4.05, W=1.76, body_top=0.85, roof_z=1.48, gh_x=(-1.95, 0.75),
         roof_x=(-1.75, 0.05), wheelbase=2.55, chamfer=0.22)
    return m


def build_box_truck() -> _Model:
    m = _Model()
    cab_paint = ((170, 30, 30), "paint")
    box_paint = ((226, 226, 220), "paint")
    L, W = 7.5, 2.45
    x0, x1 = -L / 2, L / 2
    m.add(_box(x0 + 0.3, x1 - 0.3, -0.6, 0.6, 0.45, 0.9), DARK_GREY)  # chassis
    # cab: short hood, raked windscreen, roof
    def cab(front, width, c, z):
        return _at(_rrect(1.9, front, width, c), z)
    m.add(_loft([cab(x1, W - 0.15, 0.2, 0.55), cab(x1, W - 0.1, 0.25, 1.45)]), cab_paint)
    screen_top = cab(x1 - 0.65, W - 0.25, 0.15, 2.45)
    m.add(_loft([cab(x1 - 0.15, W - 0.12, 0.2, 1.45), screen_top], top=False), GLASS)
    m.add(_loft([screen_top, cab(x1 - 0.75, W - 0.3, 0.15, 2.6)], bottom=False), cab_paint)
    # the cargo box with roof ribs
    m.add(_box(x0, 1.8, -W / 2, W / 2, 0.95, 3.4), box_paint)
    for x in np.linspace(x0 + 0.6, 1.2, 5):
        m.add(_box(x - 0.04, x + 0.04, -W / 2 + 0.05, W / 2 - 0.05, 3.4, 3.43), ((200, 200, 195), "paint"))
    for sx in (-2.2, -1.1, 2.8):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.2)
            m.add(_cylinder([sx, y - 0.14, 0.45], [sx, y + 0.14, 0.45], 0.45, 10), BLACK)
    for sy in (-1, 1):
        m.add(_box(x1 - 0.12, x1 - 0.02, sy * 0.9 - 0.15, sy * 0.9 + 0.15, 1.2, 1.46), HEAD_LAMP)
    return m


# --------------------------------------------------------------------------------------------------
# pier segments (modular along +x: piles every 2.5 m / 2 m continue across segment joints)


def _pier(length: float, width: float, pile_pitch: float, pile_r: float, seed_name: str) -> _Model:
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", seed_name)
    deck_top, plank_t = 0.6, 0.05
    shades = [((152, 118, 82), "matte"), ((140, 106, 72), "matte"), ((163, 130, 92), "matte")]
    n_planks = int(round(length / 0.225))
    pitch = length / n_planks
    for i in range(n_planks):
        x = -length / 2 + i * pitch
        m.add(_box(x + 0.012, x + pitch - 0.012, -width / 2, width / 2, deck_top - plank_t, deck_top),
              shades[int(rng.integers(0, len(shades)))])
    timber = ((95, 75, 55), "matte")
    wet = ((70, 58, 46), "matte")
    for y in np.linspace(-width / 2 + 0.15, width / 2 - 0.15, 3 if width > 2 else 2):
        m.add(_box(-length / 2, length / 2, y - 0.06, y + 0.06, deck_top - plank_t - 0.2, deck_top - plank_t),
              timber)
    n_piles = int(round(length / pile_pitch))
    for i in range(n_piles):
        x = -length / 2 + (i + 0.5) * pile_pitch
        cap_top = deck_top - plank_t - 0.2  # pile cap beam under the stringers
        m.add(_box(x - 0.1, x + 0.1, -width / 2, width / 2, cap_top - 0.2, cap_top), timber)
        for y in (-width / 2 + pile_r + 0.02, width / 2 - pile_r - 0.02):
            m.add(_cylinder([x, y, -2.0], [x, y, deck_top - plank_t - 0.2], pile_r, 8), wet)
    return m


def build_pier_walkway() -> _Model:
    return _pier(10.0, 2.5, 2.5, 0.16, "pier_walkway")


def build_pier_finger() -> _Model:
    m = _pier(8.0, 1.2, 2.0, 0.12, "pier_finger")
    for x in (-3.0, 0.0, 3.0):  # mooring cleats along both edges
        for y in (-0.5, 0.5):
            m.add(_box(x - 0.15, x + 0.15, y - 0.04, y + 0.04, 0.6, 0.7), STEEL)
    return m


# --------------------------------------------------------------------------------------------------
# buoy and vegetation


def build_buoy() -> _Model:
    m = _Model()
    body = np.array([[-0.42, 0.0], [-0.2, 0.42], [0.1, 0.5], [0.35, 0.44], [0.5, 0.26], [0.56, 0.0]])
    rings = [_at(_circle(0, 0, max(r, 0.05), 12), z) for z, r in body]
    blue = ((20, 80, 170), "paint")
    m.add(_loft(rings[:3], top=False), WHITE)
    m.add(_loft(rings[2:4], bottom=False, top=False), blue)
    m.add(_loft(rings[3:], bottom=False), WHITE)
    m.add(_cylinder([0, -0.03, 0.62], [0, 0.03, 0.62], 0.1, 8), STEEL)  # mooring eye
    return m


def build_conifer() -> _Model:
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", "tree_conifer")
    m.add(_cylinder([0, 0, 0], [0, 0, 2.6], 0.22, 8), ((95, 70, 50), "matte"))
    greens = [((28, 72, 40), "plant"), ((36, 84, 46), "plant")]
    layers = [(1.4, 4.8, 2.3), (3.4, 7.0, 1.85), (5.4, 8.8, 1.35), (7.2, 10.0, 0.8)]
    for i, (z0, z1, r) in enumerate(layers):
        n = 14
        jag = np.where(np.arange(n) % 2 == 0, 1.0, 0.72) * (0.92 + 0.16 * rng.random(n))
        base = _circle(0, 0, 1.0, n, phase=0.25 * i) * (r * jag)[:, None]
        m.add(_loft([_at(base, z0), _at(base * 0.06, z1)]), greens[i % 2])
    return m


def build_broadleaf() -> _Model:
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", "tree_broadleaf")
    bark = ((100, 78, 55), "matte")
    trunk = np.array([[0, 0, 0], [0.05, 0, 2.0], [0.0, 0.05, 3.6]])
    m.add(_sweep(trunk, np.array([0.3, 0.24, 0.2]), 8), bark)
    m.add(_cylinder([0, 0, 2.6], [1.0, 0.5, 4.0], 0.11, 6), bark)
    m.add(_cylinder([0, 0, 2.9], [-0.9, -0.6, 4.2], 0.1, 6), bark)
    greens = [((62, 112, 42), "plant"), ((78, 128, 50), "plant"), ((52, 98, 38), "plant")]
    blobs = [([0, 0, 5.6], 2.5), ([1.5, 0.9, 5.0], 1.8), ([-1.5, -0.9, 5.1], 1.8), ([-1.0, 1.4, 5.4], 1.7),
             ([1.2, -1.4, 5.5], 1.7), ([0.2, 0.1, 6.7], 1.35)]
    for i, (c, r) in enumerate(blobs):
        jit = 0.85 + 0.3 * rng.random((5, 10))
        m.add(_ellipsoid(c, [r, r, r * 0.78], 5, 10, jit), greens[i % 3])
    return m


def build_palm() -> _Model:
    m = _Model()
    s = np.linspace(0, 1, 7)
    trunk = np.column_stack([0.9 * s ** 2, 0.3 * s ** 2, 8.6 * s])
    m.add(_sweep(trunk, 0.26 - 0.08 * s, 8), ((135, 112, 82), "matte"))
    top = trunk[-1]
    green = [((74, 128, 46), "plant"), ((95, 140, 55), "plant")]
    n_fronds = 10
    t = np.linspace(0, 1, 7)
    for k in range(n_fronds):
        ang = 2 * np.pi * k / n_fronds + 0.3 * (k % 2)
        reach = 3.8 if k % 2 == 0 else 3.3
        d = np.array([math.cos(ang), math.sin(ang), 0.0])
        path = top + (t * reach)[:, None] * d + np.column_stack([0 * t, 0 * t, 1.6 * t - 2.6 * t ** 2])
        width = 0.5 * np.sin(np.pi * (0.12 + 0.85 * t)) + 0.04
        m.add(_sweep(path, width, 6, flat=0.08), green[k % 2])
    m.add(_ellipsoid(top + [0, 0, -0.15], [0.45, 0.45, 0.4], 3, 8), ((110, 85, 45), "matte"))  # coconuts
    return m


def _bush(name: str, blobs, greens) -> _Model:
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    for i, (c, r) in enumerate(blobs):
        jit = 0.85 + 0.3 * rng.random((4, 9))
        m.add(_ellipsoid(c, r, 4, 9, jit), greens[i % len(greens)])
    return m


def build_bush_round() -> _Model:
    blobs = [([0, 0, 0.65], [0.72, 0.72, 0.6]), ([0.35, 0.25, 0.5], [0.45, 0.45, 0.42]),
             ([-0.3, -0.3, 0.5], [0.42, 0.42, 0.4]), ([0.05, -0.05, 1.0], [0.42, 0.42, 0.35])]
    return _bush("bush_round", blobs, [((40, 92, 38), "plant"), ((52, 104, 44), "plant")])


def build_bush_spreading() -> _Model:
    blobs = [([0, 0, 0.45], [0.85, 0.75, 0.45]), ([0.7, 0.35, 0.35], [0.55, 0.5, 0.35]),
             ([-0.65, -0.3, 0.35], [0.55, 0.5, 0.33]), ([-0.25, 0.55, 0.32], [0.45, 0.4, 0.3]),
             ([0.3, -0.55, 0.3], [0.45, 0.4, 0.28])]
    narrow = np.array([0.78, 0.78, 1.0])  # a low, spreading shrub ~1.8 m across
    blobs = [(np.array(c) * narrow, np.array(r) * narrow) for c, r in blobs]
    return _bush("bush_spreading", blobs,
                 [((112, 130, 52), "plant"), ((128, 140, 60), "plant"), ((96, 118, 46), "plant")])


def _rock(name: str, size: tuple[float, float, float], shades) -> _Model:
    """An irregular rock: convex hull of jittered points on an ellipsoid, bottom flattened into the ground."""
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    n = 34
    z = 2 * rng.random(n) - 1
    phi = 2 * np.pi * rng.random(n)
    rad = 0.75 + 0.35 * rng.random(n)
    ring = np.sqrt(1 - z ** 2)
    pts = np.column_stack([ring * np.cos(phi), ring * np.sin(phi), z]) * rad[:, None]
    pts = pts * np.array(size) / 2
    pts[:, 2] += size[2] * 0.28  # partly buried: the flat base is the ground contact
    pts[:, 2] = np.maximum(pts[:, 2], 0.0)
    v, f = _convex(np.round(pts, _DECIMALS))
    pick = rng.integers(0, len(shades), len(f))
    for k, shade in enumerate(shades):
        sel = f[pick == k]
        if len(sel):
            m.add((v, sel), shade)
    return m


def build_rock_small() -> _Model:
    return _rock("rock_small", (1.25, 0.95, 0.85), [((128, 122, 114), "matte"), ((112, 106, 100), "matte")])


def build_rock_medium() -> _Model:
    return _rock("rock_medium", (2.1, 1.6, 1.3), [((140, 132, 120), "matte"), ((120, 114, 106), "matte"),
                                                  ((152, 146, 136), "matte")])


def build_rock_large() -> _Model:
    return _rock("rock_large", (3.2, 2.4, 1.8), [((105, 100, 96), "matte"), ((92, 88, 84), "matte"),
                                                 ((124, 118, 110), "matte")])


def _grass(name: str, greens, height: float) -> _Model:
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    n = 14
    for k in range(n):
        ang = 2 * np.pi * (k + 0.5 * rng.random()) / n
        r0 = 0.08 * rng.random()
        lean = 0.12 + 0.14 * rng.random()
        h = height * (0.7 + 0.3 * rng.random())
        d = np.array([math.cos(ang), math.sin(ang)])
        base = np.array([r0 * d[0], r0 * d[1]])
        tri = _circle(0, 0, 0.025, 3, phase=rng.random()) + base
        tip = _circle(0, 0, 0.004, 3) + base + lean * d
        mid = (tri + tip) / 2 + 0.3 * lean * d  # blades bow outwards
        m.add(_loft([_at(tri, 0.0), _at(mid, h * 0.55), _at(tip, h)]), greens[k % 2])
    return m


def build_grass_clump() -> _Model:
    return _grass("grass_clump", [((88, 150, 52), "plant"), ((70, 132, 44), "plant")], 0.5)


def build_grass_dry() -> _Model:
    return _grass("grass_dry", [((186, 170, 104), "plant"), ((160, 148, 90), "plant")], 0.55)


def build_buoy_channel() -> _Model:
    """A red can (lateral mark): a floating cylinder with a dark top ring."""
    m = _Model()
    red = ((200, 30, 30), "paint")
    m.add(_loft([_at(_circle(0, 0, 0.38, 12), -0.55), _at(_circle(0, 0, 0.42, 12), 0.1)], top=False),
          ((60, 40, 35), "matte"))
    def ring(r, z):
        return _at(_circle(0, 0, r, 12), z)
    m.add(_loft([ring(0.42, 0.1), ring(0.41, 0.75)], bottom=False, top=False), red)
    m.add(_loft([ring(0.41, 0.75), ring(0.405, 0.88)], bottom=False, top=False), WHITE)  # reflective band
    m.add(_loft([ring(0.405, 0.88), ring(0.4, 1.1), ring(0.34, 1.2)], bottom=False), red)
    m.add(_cylinder([0, -0.02, 1.2], [0, 0.02, 1.2], 0.09, 8), STEEL)  # lifting eye
    return m


def _seaweed(name: str, n: int, height: float, spread: float, width: float, colours) -> _Model:
    """Fronds/blades rising from one holdfast on the sea bed (z = 0 is the bed), swaying a little."""
    m = _Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    t = np.linspace(0, 1, 7)
    for k in range(n):
        ang = 2 * np.pi * (k + 0.4 * rng.random()) / n
        d = np.array([math.cos(ang), math.sin(ang), 0.0])
        side = np.array([-d[1], d[0], 0.0])
        h = height * (0.7 + 0.3 * rng.random())
        sway = 0.1 * spread * math.sin(3 * t[3] + k)
        path = (np.column_stack([0 * t, 0 * t, h * t]) + (spread / 2) * (t ** 1.5)[:, None] * d
                + sway * np.sin(np.pi * t)[:, None] * side)
        w = width * (0.35 + 0.65 * np.sin(np.pi * (0.08 + 0.84 * t)))
        m.add(_sweep(path, w, 6, flat=0.12), colours[k % len(colours)])
    return m


def build_seaweed_kelp() -> _Model:
    return _seaweed("seaweed_kelp", 7, 2.5, 1.1, 0.2, [((105, 92, 38), "plant"), ((122, 104, 44), "plant")])


def build_seaweed_eelgrass() -> _Model:
    greens = [((62, 112, 52), "plant"), ((78, 124, 58), "plant")]
    return _seaweed("seaweed_eelgrass", 16, 0.8, 0.5, 0.025, greens)


# --------------------------------------------------------------------------------------------------
# the asset table


@dataclass(frozen=True)
class AssetSpec:
    id: str
    category: str
    build: Callable[[], _Model]
    tags: tuple[str, ...]


ASSET_SPECS: tuple[AssetSpec, ...] = (
    AssetSpec("dinghy", "boat", build_dinghy, ("inflatable", "tender", "outboard", "grey", "orange")),
    AssetSpec("kayak", "boat", build_kayak, ("paddle", "yellow", "narrow", "small")),
    AssetSpec("runabout", "boat", build_runabout, ("motorboat", "outboard", "windscreen", "red_stripe")),
    AssetSpec("cabin_cruiser", "boat", build_cabin_cruiser, ("motorboat", "cabin", "white", "navy", "teak")),
    AssetSpec("sailboat", "boat", build_sailboat, ("sail", "mast", "monohull", "navy_hull", "cockpit")),
    AssetSpec("catamaran", "boat", build_catamaran, ("sail", "mast", "multihull", "trampoline", "white")),
    AssetSpec("yacht", "boat", build_yacht, ("motor_yacht", "flybridge", "tiered", "white", "dark_windows")),
    AssetSpec("fishing_boat", "boat", build_fishing_boat, ("work_boat", "wheelhouse", "blue_hull")),
    AssetSpec("rowboat", "boat", build_rowboat, ("oars", "wooden", "open_boat", "small")),
    AssetSpec("center_console", "boat", build_center_console, ("motorboat", "t_top", "twin_outboard")),
    AssetSpec("sedan", "vehicle", build_sedan, ("car", "red")),
    AssetSpec("suv", "vehicle", build_suv, ("car", "dark_blue", "tall")),
    AssetSpec("pickup", "vehicle", build_pickup, ("truck", "open_bed", "silver")),
    AssetSpec("van", "vehicle", build_van, ("van", "boxy", "white")),
    AssetSpec("bus", "vehicle", build_bus, ("bus", "yellow", "large")),
    AssetSpec("hatchback", "vehicle", build_hatchback, ("car", "green", "compact")),
    AssetSpec("box_truck", "vehicle", build_box_truck, ("truck", "box", "white", "red_cab")),
    AssetSpec("pier_walkway", "pier", build_pier_walkway, ("walkway", "timber", "piles", "modular_x")),
    AssetSpec("pier_finger", "pier", build_pier_finger, ("finger", "timber", "piles", "cleats", "modular_x")),
    AssetSpec("buoy", "buoy", build_buoy, ("mooring", "white", "blue_band")),
    AssetSpec("buoy_channel", "buoy", build_buoy_channel, ("lateral_mark", "can", "red")),
    AssetSpec("tree_conifer", "tree", build_conifer, ("conifer", "evergreen")),
    AssetSpec("tree_broadleaf", "tree", build_broadleaf, ("broadleaf", "deciduous")),
    AssetSpec("tree_palm", "tree", build_palm, ("palm", "tropical")),
    AssetSpec("bush_round", "bush", build_bush_round, ("shrub", "dark_green")),
    AssetSpec("bush_spreading", "bush", build_bush_spreading, ("shrub", "olive", "low")),
    AssetSpec("rock_small", "rock", build_rock_small, ("boulder", "small")),
    AssetSpec("rock_medium", "rock", build_rock_medium, ("boulder", "medium")),
    AssetSpec("rock_large", "rock", build_rock_large, ("boulder", "large")),
    AssetSpec("grass_clump", "grass", build_grass_clump, ("tuft", "green")),
    AssetSpec("grass_dry", "grass", build_grass_dry, ("tuft", "dry", "straw")),
    AssetSpec("seaweed_kelp", "seaweed", build_seaweed_kelp, ("kelp", "underwater", "brown")),
    AssetSpec("seaweed_eelgrass", "seaweed", build_seaweed_eelgrass, ("eelgrass", "underwater", "green")),
)


# --------------------------------------------------------------------------------------------------
# GLB files (``export.glb`` lays them out): one node, one mesh, one primitive per colour


def _flat_primitive(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions, normals, UVs and indices with flat shading: vertices shared only where position and face
    normal agree (so boxes stay crisp in every viewer and engine). UVs are a box projection in metres
    along the normal's dominant axis, so engines that want a UV set (Unreal lightmaps, detail
    textures) get a sensible one."""
    v = np.round(v, _DECIMALS)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ln = np.linalg.norm(n, axis=1)
    keep = ln > 1e-9
    tri, n = tri[keep], n[keep] / ln[keep][:, None]
    n = np.round(n, 5)
    n /= np.linalg.norm(n, axis=1)[:, None]
    n = np.round(n, 6)
    corners = np.concatenate([tri.reshape(-1, 3), np.repeat(n, 3, axis=0)], axis=1)
    uniq, inverse = np.unique(corners, axis=0, return_inverse=True)
    pos, nrm = uniq[:, :3].astype(np.float32), uniq[:, 3:].astype(np.float32)
    axis = np.argmax(np.abs(uniq[:, 3:]), axis=1)
    keep_axes = np.array([[2, 1], [0, 2], [0, 1]])[axis]  # drop the dominant axis
    uv = np.round(np.take_along_axis(uniq[:, :3], keep_axes, axis=1), _DECIMALS).astype(np.float32)
    return pos, nrm, uv, inverse.reshape(-1).astype(np.uint32)


def glb_bytes(model: _Model, name: str) -> bytes:
    """Encode a model as GLB (glTF y-up), one primitive + PBR material per colour; deterministic (the
    document's keys sorted)."""
    b = GlbBuilder(generator="coastforge.assets.kit")
    primitives = []
    for colour, v, f in model.by_colour():
        pos, nrm, uv, idx = _flat_primitive(v @ SCENE_TO_GLTF.T, f)
        if len(idx) == 0:
            continue
        (r, g, bl), finish = colour
        rough, metal = _FINISH[finish]
        material = {
            "name": f"{finish}_{r:02x}{g:02x}{bl:02x}",
            "pbrMetallicRoughness": {"baseColorFactor": [round(_lin(c), 6) for c in (r, g, bl)] + [1.0],
                                     "metallicFactor": metal, "roughnessFactor": rough},
        }
        index_type = UINT if len(pos) > 65535 else USHORT
        primitives.append(b.primitive(pos, nrm, idx, b.material(material), uv=uv, index_type=index_type))
    b.node({"name": name, "mesh": b.add_mesh(name, primitives)})
    return b.to_bytes(sort_keys=True)


def read_glb(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (scene frame), faces and per-face sRGB RGBA colours of a kit GLB."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LibraryError(f"cannot read kit mesh {path} ({exc}); regenerate the kit") from None
    try:
        doc, binary = glb.read_glb(data)
        vs, fs, cs, off = [], [], [], 0
        for node in doc["nodes"]:
            if "mesh" not in node:
                continue
            if any(k in node for k in ("matrix", "rotation", "translation", "scale")):
                raise ValueError("node transforms are not used by kit meshes")
            for prim in doc["meshes"][node["mesh"]]["primitives"]:
                pos = glb.accessor_array(doc, binary, prim["attributes"]["POSITION"]).astype(np.float64)
                idx = glb.accessor_array(doc, binary, prim["indices"]).astype(np.int64).reshape(-1, 3)
                mat = doc["materials"][prim["material"]]
                fac = mat.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])
                rgba = [_srgb(c) for c in fac[:3]] + [int(round(fac[3] * 255))]
                vs.append(pos @ GLTF_TO_SCENE.T)
                fs.append(idx + off)
                cs.append(np.tile(np.array(rgba, dtype=np.uint8), (len(idx), 1)))
                off += len(pos)
    except (ValueError, KeyError, IndexError, struct.error) as exc:
        raise LibraryError(f"kit mesh {path} is not a valid kit GLB ({exc}); regenerate the kit") from None
    if not vs:
        raise LibraryError(f"kit mesh {path} holds no mesh; regenerate the kit")
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(cs)


# --------------------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m coastforge.assets.kit",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True,
                        help="output folder (the committed kit: src/coastforge/data/kit)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the kit files in a non-empty folder")
    args = parser.parse_args(argv)
    try:
        manifest = generate_kit(args.out, overwrite=args.overwrite)
    except CoastforgeError as exc:
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    size = sum(p.stat().st_size for p in manifest.parent.glob("*.glb"))
    print(f"wrote {len(ASSET_SPECS)} assets ({size / 1e6:.2f} MB of GLB) and {manifest}")
    return 0
