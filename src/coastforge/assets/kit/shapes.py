"""What the kit's models are made of: named colours, geometry primitives (lofts of rings, sweeps,
convex hulls), outlines, and ``Model``, the pieces of one model grouped by colour."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

DECIMALS = 4  # coordinates rounded to 0.1 mm: keeps bytes identical across platforms


# colours: sRGB 0-255 plus a finish (its roughness and metallic factors: ``encoding``)
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


# a piece is (vertices (n, 3), faces (m, 3)) with outward counter-clockwise faces
Piece = tuple[np.ndarray, np.ndarray]


def at_z(ring2d: np.ndarray, z: float) -> np.ndarray:
    r = np.asarray(ring2d, dtype=float)
    return np.column_stack([r[:, 0], r[:, 1], np.full(len(r), float(z))])


def loft(rings: Sequence[np.ndarray], bottom: bool = True, top: bool = True) -> Piece:
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


def cap(ring: np.ndarray, up: bool = True) -> Piece:
    """A flat fan over one ring (normal +axis if ``up``)."""
    ring = np.asarray(ring, dtype=float)
    n = len(ring)
    j = np.arange(n)
    jn = (j + 1) % n
    f = np.column_stack([np.full(n, n), j, jn]) if up else np.column_stack([np.full(n, n), jn, j])
    return np.concatenate([ring, ring.mean(0)[None]]), f


def band(outer: np.ndarray, inner: np.ndarray, z0: float, z1: float) -> Piece:
    """A closed rim between two counter-clockwise rings of equal length (a gunwale, a coaming)."""
    n = len(outer)
    o0, o1, i0, i1 = at_z(outer, z0), at_z(outer, z1), at_z(inner, z0), at_z(inner, z1)
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


def rect(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def box(x0, x1, y0, y1, z0, z1) -> Piece:
    r = rect(x0, x1, y0, y1)
    return loft([at_z(r, z0), at_z(r, z1)])


def circle(cx: float, cy: float, r: float, n: int = 10, phase: float = 0.0) -> np.ndarray:
    t = 2 * np.pi * (np.arange(n) + phase) / n
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _frame(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v with u x v = t (so rings built on them are counter-clockwise about t)."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(t[2]) > 0.7 else np.array([0.0, 0.0, 1.0])
    u = np.cross(t, ref)
    u /= np.linalg.norm(u)
    return u, np.cross(t, u)


def sweep(path: np.ndarray, radius, n: int = 8, flat: float = 1.0) -> Piece:
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
    return loft(rings)


def cylinder(p0, p1, r: float, n: int = 10) -> Piece:
    return sweep(np.array([p0, p1], dtype=float), r, n)


def ellipsoid(c, radii, n_lat: int = 5, n_lon: int = 10, jitter: np.ndarray | None = None) -> Piece:
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
    return loft(rings)


def convex(points: np.ndarray) -> Piece:
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


def hull_ring(length: float, beam: float, x_stern: float, shoulder: float = 0.5, bow_power: float = 1.8,
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


def cabin_ring(x0: float, x1: float, width: float, chamfer: float = 0.0, nose: float = 0.4) -> np.ndarray:
    """A superstructure outline: square aft end at x0, chamfered front at x1 (front face ``nose`` x width)."""
    h = width / 2
    c = min(chamfer, (x1 - x0) * 0.9)
    pts = [[x0, -h], [x1 - c, -h], [x1, -h * nose], [x1, h * nose], [x1 - c, h], [x0, h]]
    return np.array(pts, dtype=float)


def rrect(x0: float, x1: float, width: float, c: float, y0: float = 0.0) -> np.ndarray:
    """A rectangle with chamfered corners (car bodies), 8 points counter-clockwise."""
    h = width / 2
    return np.array([[x0 + c, y0 - h], [x1 - c, y0 - h], [x1, y0 - h + c], [x1, y0 + h - c],
                     [x1 - c, y0 + h], [x0 + c, y0 + h], [x0, y0 + h - c], [x0, y0 - h + c]], dtype=float)


# --------------------------------------------------------------------------------------------------
# the model being built: pieces grouped by colour


class Model:
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
