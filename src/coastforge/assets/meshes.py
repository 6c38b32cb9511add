"""Load third-party 3D models and normalise them to the scene frame: metres, z up, forward +x.

Real models come in any unit (m, cm, mm, or the artist's own), y-up (glTF convention) or z-up
(CAD, STL), with the long axis along any horizontal axis. ``normalise_mesh`` uses what the manifest
says and otherwise guesses, and always reports what it guessed so users can correct it:

- **up axis**: the file format's convention (glTF/OBJ: +y, STL/PLY: +z) as a prior, checked against a
  per-category vertical-extent rule (boats, vehicles and piers are lower than they are long and wide;
  trees, bushes and seaweed stand on a narrow base);
- **forward axis**: the long horizontal axis; for boats the bow is the narrower end, for vehicles the
  cabin (highest part) sits behind the middle; other categories have no front;
- **units**: ``length_m`` / ``height_m`` scale exactly; otherwise the unit (m, cm, mm) that gives a
  plausible size for the category.

The normalised mesh has its footprint centred on the origin and its lowest point at z = 0.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LibraryError

MESH_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl")

_AXES = {"x": 0, "y": 1, "z": 2}

# Characteristic size (what the unit guess compares): (measure, lowest, typical, highest) in metres.
_SIZE_PRIOR: dict[str, tuple[str, float, float, float]] = {
    "boat": ("length", 1.5, 8.0, 400.0),
    "vehicle": ("length", 2.0, 4.5, 25.0),
    "pier": ("length", 1.0, 10.0, 300.0),
    "buoy": ("max", 0.2, 1.0, 6.0),
    "tree": ("height", 1.5, 8.0, 60.0),
    "bush": ("height", 0.2, 1.2, 5.0),
    "rock": ("max", 0.1, 1.5, 15.0),
    "grass": ("height", 0.03, 0.5, 2.5),
    "seaweed": ("height", 0.05, 1.0, 15.0),
}
_UNITS = (("m", 1.0), ("cm", 0.01), ("mm", 0.001))
_LOW_PROFILE = ("boat", "vehicle", "pier")  # lower than long and wide
_NARROW_BASE = ("tree", "bush", "seaweed")  # stand on a trunk / stem


@dataclass(frozen=True)
class Normalisation:
    """What was done to a model (and what was guessed), for library.json and the build report."""

    up_axis: str  # source axis that became +z, e.g. "+y"
    forward_axis: str  # source axis that became +x
    unit: str  # "m", "cm", "mm", "length_m", "height_m" or "custom"
    scale: float  # source units → metres
    dims_m: tuple[float, float, float]  # length (x), width (y), height (z)
    transform: tuple[tuple[float, ...], ...]  # 4x4 source → normalised
    notes: tuple[str, ...]  # guesses, one sentence each


def parse_axis(value: str | None, what: str, asset_id: str) -> tuple[int, int] | None:
    """``"+y"``, ``"-Z"``, ``"x"`` → (axis index, sign); None stays None."""
    if value is None:
        return None
    m = re.fullmatch(r"\s*([+-]?)\s*([xyzXYZ])\s*", str(value))
    if not m:
        raise LibraryError(
            f"asset {asset_id!r}: {what} {value!r} is not an axis; use one of +x, -x, +y, -y, +z, -z"
        )
    return _AXES[m.group(2).lower()], (-1 if m.group(1) == "-" else 1)


def axis_name(axis: int, sign: int) -> str:
    return ("+" if sign > 0 else "-") + "xyz"[axis]


def file_hash(path: str | Path) -> str:
    """SHA-256 of a model file plus the side files it references (glTF buffers/images, OBJ materials)."""
    path = Path(path)
    h = hashlib.sha256()
    h.update(path.read_bytes())
    for side in sorted(_side_files(path)):
        h.update(side.name.encode())
        h.update(side.read_bytes())
    return h.hexdigest()


def _side_files(path: Path) -> set[Path]:
    out: set[Path] = set()
    try:
        if path.suffix.lower() == ".gltf":
            doc = json.loads(path.read_text(encoding="utf-8"))
            for key in ("buffers", "images"):
                for item in doc.get(key, []):
                    uri = item.get("uri", "")
                    if uri and not uri.startswith("data:"):
                        out.add(path.parent / uri)
        elif path.suffix.lower() == ".obj":
            for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
                if line.startswith("mtllib"):
                    out.add(path.parent / line.split(None, 1)[1].strip())
    except (OSError, ValueError):
        return set()
    return {p for p in out if p.is_file()}


def load_mesh(path: str | Path, asset_id: str = "") -> trimesh.Trimesh:  # noqa: F821
    """Read a model file into one triangle mesh with vertex colours (textures sampled per vertex)."""
    import trimesh

    path = Path(path)
    name = asset_id or path.name
    if not path.is_file():
        raise LibraryError(f"asset {name!r}: mesh file {path} does not exist; fix the 'mesh' path")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise LibraryError(
            f"asset {name!r}: {path.name} is not a supported model ({', '.join(MESH_SUFFIXES)})"
        )
    try:
        loaded = trimesh.load(str(path), process=False)
    except Exception as exc:  # trimesh raises many types for broken files
        raise LibraryError(f"asset {name!r}: cannot read mesh {path}: {exc}; re-export it as GLB") from exc
    parts = []
    if isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            transform, geom_name = loaded.graph[node]
            g = loaded.geometry.get(geom_name)
            if isinstance(g, trimesh.Trimesh) and len(g.faces):
                parts.append(_coloured(g).apply_transform(transform))
    elif isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        parts.append(_coloured(loaded))
    if not parts:
        raise LibraryError(f"asset {name!r}: mesh {path} has no triangles (empty or point cloud only)")
    mesh = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    if not np.all(np.isfinite(mesh.vertices)):
        raise LibraryError(f"asset {name!r}: mesh {path} has non-finite vertex coordinates")
    ext = mesh.extents
    if float(ext.max()) <= 0.0:
        raise LibraryError(f"asset {name!r}: mesh {path} is degenerate (all vertices at one point)")
    return mesh


def _coloured(g):
    """A copy with ColorVisuals (vertex colours), whatever the source visual was."""
    import trimesh

    g = g.copy()
    try:
        vis = g.visual.to_color() if hasattr(g.visual, "to_color") else g.visual
        colors = np.asarray(vis.vertex_colors, dtype=np.uint8)
        if colors.ndim == 1 and colors.size in (3, 4):  # one material colour for the whole part
            colors = np.tile(np.append(colors[:3], 255)[None, :], (len(g.vertices), 1)).astype(np.uint8)
        elif colors.ndim == 2 and colors.shape[1] == 3:
            colors = np.hstack([colors, np.full((len(colors), 1), 255, np.uint8)])
        if colors.shape != (len(g.vertices), 4):
            raise ValueError("no per-vertex colours")
    except Exception:  # noqa: BLE001 - no material / broken texture: neutral grey keeps the geometry usable
        colors = np.tile(np.array([[180, 180, 180, 255]], np.uint8), (len(g.vertices), 1))
    g.visual = trimesh.visual.ColorVisuals(g, vertex_colors=colors)
    return g


def _surface_points(mesh, n: int = 6000) -> np.ndarray:
    """Area-weighted surface samples (deterministic), so sparse low-poly vertices do not bias shapes."""
    tri = mesh.triangles
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        return np.asarray(mesh.vertices, float)
    rng = np.random.default_rng(12345)  # fixed: the same model must always normalise the same way
    idx = rng.choice(len(tri), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    a, b, c = tri[idx, 0], tri[idx, 1], tri[idx, 2]
    pts = (1 - s)[:, None] * a + (s * (1 - r2))[:, None] * b + (s * r2)[:, None] * c
    return np.vstack([pts, mesh.vertices])


def _format_up(suffix: str) -> tuple[int, int]:
    return (2, 1) if suffix in (".stl", ".ply") else (1, 1)


def _up_score(pts: np.ndarray, axis: int, sign: int, category: str) -> float:
    """How plausible ``axis*sign`` is as 'up' for this category (0 = no opinion, negative = unlikely)."""
    h = sign * pts[:, axis]
    horiz = [a for a in range(3) if a != axis]
    ext = np.ptp(pts, axis=0)
    height = float(np.ptp(h))
    widths = sorted(float(ext[a]) for a in horiz)
    if category in _LOW_PROFILE:
        return -3.0 * max(0.0, math.log(max(height, 1e-9) / max(widths[0], 1e-9)))
    if category in _NARROW_BASE:
        base = pts[h <= h.min() + 0.08 * height]
        if len(base) < 3:
            return 0.0
        base_w = max(float(np.ptp(base[:, a])) for a in horiz)
        return 2.0 * (0.5 - base_w / max(widths[1], 1e-9))
    return 0.0


def _detect_up(pts: np.ndarray, category: str, suffix: str) -> tuple[tuple[int, int], str]:
    prior = _format_up(suffix)
    cands = [(1, 1), (2, 1)]
    scores = {c: (0.75 if c == prior else 0.0) + _up_score(pts, c[0], c[1], category) for c in cands}
    best = max(cands, key=lambda c: scores[c])
    other = next(c for c in cands if c != best)
    conv = "glTF/OBJ y-up" if prior == (1, 1) else "STL/PLY z-up"
    why = "the format convention" if best == prior else f"the {category} shape (against the {conv} convention)"
    sure = "" if scores[best] - scores[other] > 0.5 else " (low confidence: set up_axis to be sure)"
    return best, f"up axis {axis_name(*best)} guessed from {why}{sure}"


def _detect_forward(pts: np.ndarray, long_axis: int, lat_axis: int, category: str, src_sign: int):
    """Sign of the forward direction along the long horizontal axis, with a note (or None)."""
    u = pts[:, long_axis]
    lo, hi = float(u.min()), float(u.max())
    length = max(hi - lo, 1e-9)
    t = (u - lo) / length
    ax = axis_name(long_axis, 1)[1]
    if category == "boat":
        def end_width(mask):
            sel = pts[mask, lat_axis]
            return float(np.percentile(sel, 98) - np.percentile(sel, 2)) if len(sel) > 3 else 0.0

        w_neg, w_pos = end_width(t < 0.12), end_width(t > 0.88)
        sign = 1 if w_pos < w_neg else -1
        sure = abs(w_pos - w_neg) > 0.08 * max(w_pos, w_neg, 1e-9)
        return sign, (f"forward {axis_name(long_axis, sign)} guessed: the bow is the narrower end of the long "
                      f"{ax} axis" + ("" if sure else " (low confidence: ends are similar; set forward_axis)"))
    return src_sign, None


def _vehicle_forward(pts_up: np.ndarray, long_axis: int, lat_axis: int) -> tuple[int, str]:
    """Cars: the cabin (top of the body) sits behind the middle, the hood in front of it."""
    z = pts_up[:, 2]
    top = pts_up[z >= z.min() + 0.75 * np.ptp(z)]
    u = pts_up[:, 0]
    centre = 0.5 * (u.min() + u.max())
    offset = float(top[:, 0].mean() - centre) / max(float(np.ptp(u)), 1e-9) if len(top) else 0.0
    sign = -1 if offset > 0 else 1
    sure = abs(offset) > 0.03
    return sign, ("forward guessed for a vehicle: the cabin sits behind the middle"
                  + ("" if sure else " (low confidence: set forward_axis)"))


def _rotation(up: tuple[int, int], fwd: tuple[int, int]) -> np.ndarray:
    z = np.zeros(3)
    z[up[0]] = up[1]
    x = np.zeros(3)
    x[fwd[0]] = fwd[1]
    y = np.cross(z, x)
    return np.vstack([x, y, z])  # rows: new axes in source coordinates


def normalise_mesh(mesh, category: str, *, asset_id: str = "", length_m: float | None = None,
                   height_m: float | None = None, up_axis: str | None = None,
                   forward_axis: str | None = None, unit: str | float | None = None, suffix: str = ".glb",
                   keep_z: bool = False, source: str | Path | None = None):
    """Return ``(mesh in metres, z up, forward +x, footprint centred, base at z=0; Normalisation)``.

    ``keep_z`` keeps the model's own vertical origin (models already authored with z = 0 at the water
    level or the ground, like the starter kit). ``source``: the model file, for messages."""
    name = asset_id or "?"
    notes: list[str] = []
    pts = _surface_points(mesh)
    up = parse_axis(up_axis, "up_axis", name)
    if up is None:
        up, note = _detect_up(pts, category, suffix.lower())
        notes.append(note)
    fwd = parse_axis(forward_axis, "forward_axis", name)
    if fwd is not None and fwd[0] == up[0]:
        raise LibraryError(
            f"asset {name!r}: forward_axis {forward_axis!r} is the up axis {axis_name(*up)}; "
            "forward must be horizontal"
        )
    if fwd is None:
        horiz = [a for a in range(3) if a != up[0]]
        ext = np.ptp(pts, axis=0)
        long_axis = max(horiz, key=lambda a: ext[a])
        lat_axis = next(a for a in horiz if a != long_axis)
        if category == "vehicle":
            r = _rotation(up, (long_axis, 1))
            sign, note = _vehicle_forward(pts @ r.T, long_axis, lat_axis)
        else:
            sign, note = _detect_forward(pts, long_axis, lat_axis, category, 1)
        fwd = (long_axis, sign)
        notes.append(note or f"forward {axis_name(*fwd)}: the long horizontal axis ({category} has no front)")
    rot = _rotation(up, fwd)
    ext = np.ptp(np.asarray(mesh.vertices, float) @ rot.T, axis=0)
    if (length_m is not None and length_m <= 0) or (height_m is not None and height_m <= 0):
        raise LibraryError(f"asset {name!r}: length_m/height_m must be positive, got {length_m}/{height_m}")
    if length_m is not None:
        long_h = max(ext[0], ext[1])
        scale, unit_name = float(length_m) / long_h, "length_m"
        if ext[1] > ext[0] * 1.001:
            notes.append("length_m applied to the longest horizontal extent, which is across the forward axis")
        if height_m is not None and abs(ext[2] * scale - height_m) > 0.1 * height_m:
            notes.append(f"height_m {height_m} disagrees with length_m (height comes out {ext[2] * scale:.2f} m); "
                         "length_m was used")
    elif height_m is not None:
        scale, unit_name = float(height_m) / ext[2], "height_m"
    elif unit is not None:
        scale, unit_name = _unit_scale(unit, name)
    else:
        scale, unit_name, note = _guess_unit(ext, category)
        _refuse_absurd_guess(name, source, ext, category, scale, unit_name)
        notes.append(note)
    m = mesh.copy()
    t = np.eye(4)
    t[:3, :3] = rot * scale
    m.apply_transform(t)
    b = m.bounds
    shift = np.eye(4)
    shift[:3, 3] = [-(b[0, 0] + b[1, 0]) / 2, -(b[0, 1] + b[1, 1]) / 2, 0.0 if keep_z else -b[0, 2]]
    m.apply_transform(shift)
    full = shift @ t
    dims = tuple(float(v) for v in m.extents)
    return m, Normalisation(axis_name(*up), axis_name(*fwd), unit_name, float(scale), dims,
                            tuple(tuple(float(v) for v in row) for row in full), tuple(notes))


def _unit_scale(unit, name: str) -> tuple[float, str]:
    if isinstance(unit, (int, float)) and not isinstance(unit, bool):
        if unit <= 0:
            raise LibraryError(f"asset {name!r}: unit {unit!r} must be a positive number of metres per unit")
        return float(unit), "custom"
    for u, s in _UNITS:
        if str(unit).strip().lower() == u:
            return s, u
    raise LibraryError(f"asset {name!r}: unknown unit {unit!r}; use m, cm, mm or metres per unit (e.g. 0.0254)")


def characteristic_size(ext, category: str) -> float:
    measure = _SIZE_PRIOR.get(category, ("max", 0, 1, 1))[0]
    if measure == "length":
        return float(max(ext[0], ext[1]))
    if measure == "height":
        return float(ext[2])
    return float(max(ext))


def _guess_unit(ext, category: str) -> tuple[float, str, str]:
    measure, lo, typical, hi = _SIZE_PRIOR[category]
    size = characteristic_size(ext, category)
    best = min(_UNITS, key=lambda us: (not (lo <= size * us[1] <= hi), abs(math.log(size * us[1] / typical))))
    got = size * best[1]
    plausible = lo <= got <= hi
    note = (f"unit guessed as {best[0]}: {measure} {got:.3g} m is "
            + ("plausible" if plausible else "unusual") + f" for a {category} ({lo:g}–{hi:g} m); "
            "give length_m or height_m for the real size")
    return best[1], best[0], note


ABSURD_FACTOR = 2.0  # a guessed size this far outside the category's range is no unit's fault: refuse it


def _refuse_absurd_guess(name: str, source, ext, category: str, scale: float, unit: str) -> None:
    """No unit (m, cm, mm) gives a believable size: a placed 1 km boat or 1 mm car would be garbage."""
    measure, lo, _typical, hi = _SIZE_PRIOR[category]
    got = characteristic_size(ext, category) * scale
    if lo / ABSURD_FACTOR <= got <= hi * ABSURD_FACTOR:
        return
    where = f" ({source})" if source else ""
    raise LibraryError(
        f"asset {name!r}{where}: its raw extent is {ext[0]:.4g} x {ext[1]:.4g} x {ext[2]:.4g} units and no unit "
        f"makes it a plausible {category}: the closest guess, {unit}, gives a {measure} of {got:.4g} m "
        f"({lo:g}-{hi:g} m expected); state its unit in the manifest (unit = \"m\", \"cm\", \"mm\" or metres per "
        "unit) or its real length_m / height_m")


def footprint_mask(mesh, n: int, gsd: float) -> np.ndarray:
    """The mesh seen from above: an n x n uint8 0/1 mask at ``gsd`` metres per pixel, its footprint's
    bounding-box centre at the image centre (as the library's views are rendered), +x to the right."""
    import cv2

    mask = np.zeros((n, n), np.uint8)
    v = np.asarray(mesh.vertices)
    b = np.asarray(mesh.bounds)
    cx, cy = 0.5 * (b[0, 0] + b[1, 0]), 0.5 * (b[0, 1] + b[1, 1])
    col = (v[:, 0] - cx) / gsd + n / 2.0 - 0.5
    row = n / 2.0 - (v[:, 1] - cy) / gsd - 0.5
    pts = np.round(np.stack([col, row], 1) * 16).astype(np.int32)
    for tri in pts[np.asarray(mesh.faces)]:  # one by one: fillPoly would cancel overlapping faces
        cv2.fillConvexPoly(mask, tri, 1, lineType=cv2.LINE_8, shift=4)
    return mask
