"""Pier structures: walkway and finger boxes → chains of library pier segments, connected to land.

Each detected walkway/finger box is extended along its axis to reach land or the pier it attaches to
(within ``max_gap_m``); a structure that still floats gets a connecting walkway to the nearest land, unless
that walkway would be longer than the deck the structure has: a missing stretch longer than everything seen of
the pier says the piece is more likely a false detection (a hull, a wake) than a pier, and it is dropped.
Each box then becomes ``n = ceil(length / segment length)`` segments scaled to fit exactly. The paper's
piers sometimes did not connect; here connectivity is checked and reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .classes import WATER
from .config import PierConfig
from .frames import wrap_half_deg
from .scene import SceneObject
from .types import ClassMap, Detection, Grid, HeightMap

# a pier end this close to solid land touches the shore (the evaluation allows 0.75 m between footprint and land)
LAND_TOUCH_M = 0.4


@dataclass(frozen=True)
class PierBox:
    """A pier part in scene metres; ``yaw_deg`` is its axis (mod 180)."""

    role: str  # walkway | finger | connector
    x_m: float
    y_m: float
    length_m: float
    width_m: float
    yaw_deg: float
    score: float = 1.0

    @property
    def axis(self) -> np.ndarray:
        r = math.radians(self.yaw_deg)
        return np.array([math.cos(r), math.sin(r)])

    def ends(self) -> tuple[np.ndarray, np.ndarray]:
        c, u = np.array([self.x_m, self.y_m]), self.axis
        return c - u * self.length_m / 2, c + u * self.length_m / 2

    def polygon(self, grow: float = 0.0):
        from shapely.geometry import Polygon

        c, u = np.array([self.x_m, self.y_m]), self.axis
        n = np.array([-u[1], u[0]])
        hl, hw = self.length_m / 2 + grow, self.width_m / 2 + grow
        return Polygon([c + u * hl + n * hw, c - u * hl + n * hw, c - u * hl - n * hw, c + u * hl - n * hw])


def box_from_ends(a: np.ndarray, b: np.ndarray, width: float, role: str, score: float) -> PierBox:
    d = b - a
    c = (a + b) / 2
    return PierBox(role, float(c[0]), float(c[1]), float(np.linalg.norm(d)), width,
                   float(wrap_half_deg(math.degrees(math.atan2(d[1], d[0])))), score)


@dataclass(frozen=True)
class PierResult:
    objects: tuple[SceneObject, ...]
    boxes: tuple[PierBox, ...]  # after extension, before chaining
    structures: tuple[tuple[int, ...], ...]  # box indices per structure
    structure_on_land: tuple[bool, ...]
    extensions_m: tuple[float, ...]  # how far each box was extended
    report: dict = field(default_factory=dict)


class LandProbe:
    """Where is real land? Pier decks themselves are often classified as paving, so pixels inside pier boxes
    do not count as land. Works on a raster mask, so a probe costs microseconds."""

    def __init__(self, class_map: ClassMap, boxes: list[PierBox]):
        import cv2

        self.grid = g = class_map.grid
        land = (class_map.ids != WATER).astype(np.uint8)
        deck = np.zeros(g.shape, np.uint8)
        for b in boxes:
            pts = np.array(b.polygon().exterior.coords)[:4]
            col, row = g.to_pixel(pts[:, 0], pts[:, 1])
            cv2.fillPoly(deck, [np.round(np.stack([col, row], 1)).astype(np.int32)], 1)
        self.land = land & (1 - deck)
        # disc offsets are cached per radius in pixels
        self._discs: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._nearest = None  # (opened land, k-d tree of its edge pixels, their indices), on first use

    def _disc(self, r_px: int):
        if r_px not in self._discs:
            yy, xx = np.mgrid[-r_px:r_px + 1, -r_px:r_px + 1]
            keep = xx * xx + yy * yy <= r_px * r_px
            self._discs[r_px] = (yy[keep], xx[keep])
        return self._discs[r_px]

    def nearest_land(self, p: np.ndarray, max_dist_m: float) -> np.ndarray | None:
        """The centre of the land pixel nearest ``p`` (land opened so single stray pixels do not count), or
        None when none lies within ``max_dist_m``. The nearest land pixel of a point in water lies on the
        land's edge, so a k-d tree of the edge pixels answers exactly what a distance transform of the whole
        image would, for a few queries at a fraction of its cost."""
        if self._nearest is None:
            import cv2
            from scipy.spatial import cKDTree

            solid = cv2.morphologyEx(self.land, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
            edge = solid & (1 - cv2.erode(solid, cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))))
            rc = np.argwhere(edge)
            self._nearest = (solid, cKDTree(rc) if len(rc) else None, rc)
        solid, tree, rc = self._nearest
        if tree is None:
            return None
        g = self.grid
        col, row = g.to_pixel(p[0], p[1])
        r = int(np.clip(np.floor(row), 0, g.height_px - 1))
        c = int(np.clip(np.floor(col), 0, g.width_px - 1))
        if solid[r, c]:
            hit = (r, c)
        else:
            d, k = tree.query((r, c), distance_upper_bound=max_dist_m / g.gsd_m + 1e-9)
            if not np.isfinite(d):
                return None
            hit = rc[k]
        x, y = g.to_scene(hit[1] + 0.5, hit[0] + 0.5)
        return np.array([float(x), float(y)])

    def land_within(self, p: np.ndarray, radius_m: float) -> bool:
        """Is any land pixel (decks excluded) within ``radius_m`` of ``p``? A disc lookup: no distance
        transform of the whole image for a yes/no question about a point."""
        g = self.grid
        col, row = g.to_pixel(p[0], p[1])
        dy, dx = self._disc(max(1, int(np.ceil(radius_m / g.gsd_m))))
        r = np.floor(row).astype(int) + dy
        c = np.floor(col).astype(int) + dx
        inside = (r >= 0) & (r < g.height_px) & (c >= 0) & (c < g.width_px)
        return bool(self.land[r[inside], c[inside]].any())

    def end_touches(self, box: PierBox, end: np.ndarray, tol_m: float) -> bool:
        """Does the end edge of ``box`` at ``end`` come within ``tol_m`` of land (its centre or a corner)? A
        structure called grounded must really touch the shore, as the evaluation checks it."""
        return bool(self.ends_touch(box, np.asarray(end, float)[None, :], tol_m)[0])

    def ends_touch(self, box: PierBox, ends: np.ndarray, tol_m: float) -> np.ndarray:
        """``end_touches`` for many candidate ends (k, 2) at once: one gather for every step of a ray."""
        g = self.grid
        side = np.array([-box.axis[1], box.axis[0]]) * (box.width_m / 2)
        pts = np.concatenate([ends, ends + side, ends - side])  # (3k, 2)
        col, row = g.to_pixel(pts[:, 0], pts[:, 1])
        dy, dx = self._disc(max(1, int(np.ceil(tol_m / g.gsd_m))))
        r = np.floor(np.asarray(row)).astype(int)[:, None] + dy[None, :]
        c = np.floor(np.asarray(col)).astype(int)[:, None] + dx[None, :]
        inside = (r >= 0) & (r < g.height_px) & (c >= 0) & (c < g.width_px)
        hit = np.zeros(r.shape, bool)
        hit[inside] = self.land[r[inside], c[inside]] > 0
        return hit.any(axis=1).reshape(3, len(ends)).any(axis=0)


def detections_to_boxes(dets: list[Detection], grid: Grid) -> list[PierBox]:
    out = []
    for d in dets:
        if d.category not in ("pier_walkway", "pier_finger"):
            continue
        x, y = grid.to_scene(d.cx_px, d.cy_px)
        out.append(PierBox("walkway" if d.category == "pier_walkway" else "finger", float(x), float(y),
                           d.length_px * grid.gsd_m, d.width_px * grid.gsd_m, float(wrap_half_deg(d.yaw_deg)),
                           float(d.score)))
    return out


def _extend(boxes: list[PierBox], probe: LandProbe, cfg: PierConfig, step: float) -> tuple[list[PierBox], list[float]]:
    """Extend each box end that floats along its axis until it meets land or another box.

    The other boxes are queried through an STRtree, so the cost grows with the number of boxes, not its square."""
    import shapely
    from shapely.strtree import STRtree

    polys = np.array([b.polygon(grow=0.3) for b in boxes], dtype=object)
    tree = STRtree(polys)
    n_steps = int(cfg.max_gap_m / step)
    out, ext = [], []
    for i, b in enumerate(boxes):
        a, e = b.ends()
        u = b.axis
        new_ends = []
        grown = 0.0
        for end, sign in ((a, -1.0), (e, 1.0)):
            near = [j for j in tree.query(shapely.Point(end), predicate="dwithin", distance=0.3) if j != i]
            if probe.end_touches(b, end, LAND_TOUCH_M) or near:
                new_ends.append(end)
                continue
            # every step of the ray at once: which steps fall inside another box?
            ks = np.arange(1, n_steps + 1)
            qs = end[None, :] + sign * u[None, :] * (ks * step)[:, None]
            hit_box = np.zeros(len(ks), bool)
            pts = shapely.points(qs)
            pi, bi = tree.query(pts, predicate="within")
            hit_box[pi[bi != i]] = True
            found = None
            stop = np.flatnonzero(hit_box | probe.ends_touch(b, qs, LAND_TOUCH_M))
            if len(stop):
                found = qs[stop[0]] + sign * u * min(0.5, step)  # a little overlap so the parts touch
            if found is None:
                new_ends.append(end)
            else:
                grown += float(np.linalg.norm(found - end))
                new_ends.append(found)
        out.append(box_from_ends(new_ends[0], new_ends[1], b.width_m, b.role, b.score))
        ext.append(grown)
    return out, ext


def _components(boxes: list[PierBox], tol: float = 0.4) -> list[list[int]]:
    """Connected groups of boxes that touch (within ``tol``), via an STRtree of the footprints."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from shapely.strtree import STRtree

    n = len(boxes)
    if n == 0:
        return []
    polys = np.array([b.polygon() for b in boxes], dtype=object)
    left, right = STRtree(polys).query(polys, predicate="dwithin", distance=tol)
    graph = coo_matrix((np.ones(len(left)), (left, right)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    comps: dict[int, list[int]] = {}
    for i, lab in enumerate(labels):
        comps.setdefault(int(lab), []).append(i)
    return [sorted(c) for c in sorted(comps.values(), key=min)]


def build_piers(dets: list[Detection], class_map: ClassMap, walkway_asset, finger_asset, config: PierConfig,
                water_level_m: float = 0.0) -> PierResult:
    """Chain library pier segments along detected walkways and fingers, connected to land."""
    grid = class_map.grid
    boxes = detections_to_boxes(dets, grid)
    if not boxes:
        return PierResult((), (), (), (), (), {"n_structures": 0, "n_segments": 0})
    probe = LandProbe(class_map, boxes)
    step = max(grid.gsd_m, 0.25)
    boxes, ext = _extend(boxes, probe, config, step)
    probe = LandProbe(class_map, boxes)
    comps = _components(boxes)
    # a structure that still does not reach land gets a connecting walkway to whatever is nearer: land, or a
    # structure that reaches land (detectors often break one long walkway into pieces)
    dropped = _connect_floating(boxes, ext, comps, probe, config)
    if dropped:
        keep = [i for i in range(len(boxes)) if i not in dropped]
        boxes, ext = [boxes[i] for i in keep], [ext[i] for i in keep]
    if not boxes:
        return PierResult((), (), (), (), (), {"n_structures": 0, "n_segments": 0, "dropped_floating": len(dropped)})
    probe = LandProbe(class_map, boxes)
    comps = _components(boxes)
    on_land = tuple(_reaches_land(boxes, comp, probe) for comp in comps)
    objects: list[SceneObject] = []
    for s, comp in enumerate(comps):
        for i in comp:
            b = boxes[i]
            asset = finger_asset if b.role == "finger" else walkway_asset
            objects.extend(_chain(b, asset, f"pier{s}_{i}", s, water_level_m))
    report = {
        "n_structures": len(comps), "n_boxes": len(boxes), "n_segments": len(objects),
        "structures_on_land": int(sum(on_land)), "connectors_added": sum(b.role == "connector" for b in boxes),
        "dropped_floating": len(dropped),
        "extended_m": [round(e, 2) for e in ext],
    }
    return PierResult(tuple(objects), tuple(boxes), tuple(tuple(c) for c in comps), on_land, tuple(ext), report)


def _reaches_land(boxes: list[PierBox], comp: list[int], probe: LandProbe) -> bool:
    return any(probe.end_touches(boxes[i], end, LAND_TOUCH_M) for i in comp for end in boxes[i].ends())


def _connect_floating(boxes: list[PierBox], ext: list[float], comps: list[list[int]], probe: LandProbe,
                      config: PierConfig) -> set[int]:
    """Connect each floating group to land or to a grounded structure (appending connector boxes); returns the
    box indices of the groups left out because their connector would be longer than their own deck."""
    from shapely.ops import nearest_points, unary_union

    limit = 8 * config.max_gap_m
    grounded = [c for c in comps if _reaches_land(boxes, c, probe)]
    floating = [c for c in comps if c not in grounded]
    shapes = {id(c): unary_union([boxes[i].polygon() for i in c]) for c in floating}
    # the nearest land of each floating group does not change as others are connected: compute it once
    to_land: dict[int, tuple] = {}
    for comp in floating:
        w = max(1.5, max(boxes[i].width_m for i in comp))
        for i in comp:
            for end in boxes[i].ends():
                q = probe.nearest_land(end, limit)
                if q is not None:
                    d = float(np.linalg.norm(q - end))
                    if id(comp) not in to_land or d < to_land[id(comp)][0]:
                        to_land[id(comp)] = (d, end, q, w)
    ground_shape = unary_union([boxes[i].polygon() for c in grounded for i in c]) if grounded else None
    # the longest plausible connector of a group: the deck it has (at least max_gap_m, which _extend bridges anyway)
    reach = {id(c): max(config.max_gap_m, sum(boxes[i].length_m for i in c)) for c in floating}
    # nearest first, so a chain of floating pieces grows outwards from the shore; a group whose way to land is
    # longer than its reach waits (another group connected later may come closer) and is dropped at the end
    too_far: set[int] = set()
    while floating:
        best = None
        for comp in floating:
            w = max(1.5, max(boxes[i].width_m for i in comp))
            options = []
            if id(comp) in to_land:
                d, end, q, _ = to_land[id(comp)]
                options.append((d, comp, end, q, w, True))
            if ground_shape is not None and not ground_shape.is_empty:
                pa, pb = nearest_points(shapes[id(comp)], ground_shape)
                d = pa.distance(pb)
                if d <= limit:
                    options.append((d, comp, np.array(pa.coords[0]), np.array(pb.coords[0]), w, False))
            for opt in options:
                if opt[0] > reach[id(comp)]:
                    too_far.add(id(comp))
                elif best is None or opt[0] < best[0]:
                    best = opt
        if best is None:
            break
        d, comp, a, b, w, land = best
        u = (b - a) / max(np.linalg.norm(b - a), 1e-6)
        into = max(1.5, w) if land else 0.3  # reach well onto land; just touch another deck
        boxes.append(box_from_ends(a - u * 0.3, b + u * into, w, "connector", 0.5))
        ext.append(0.0)
        floating.remove(comp)
        grounded.append(comp + [len(boxes) - 1])
        new = unary_union([shapes[id(comp)], boxes[-1].polygon()])
        ground_shape = new if ground_shape is None else unary_union([ground_shape, new])
    # still floating although land or a pier lies within reach of a connector: too far for what was seen of it
    # (a group with nothing within 8 max_gap_m stays as it is: the shore may lie outside the image)
    return {i for comp in floating if id(comp) in too_far for i in comp}


def _chain(b: PierBox, asset, prefix: str, structure: int, water_level_m: float) -> list[SceneObject]:
    seg_len, seg_w, _ = asset.dims_m
    n = max(1, math.ceil(b.length_m / seg_len - 1e-6))
    piece = b.length_m / n
    sx = piece / seg_len
    sy = float(np.clip(b.width_m / seg_w, 0.5, 2.5))
    c, u = np.array([b.x_m, b.y_m]), b.axis
    start = c - u * b.length_m / 2
    out = []
    for k in range(n):
        p = start + u * (k + 0.5) * piece
        out.append(SceneObject(
            id=f"{prefix}_{k}", category="pier", asset_id=asset.id, x_m=float(p[0]), y_m=float(p[1]),
            z_m=float(water_level_m), yaw_deg=float(b.yaw_deg), scale=(float(sx), sy, 1.0), length_m=float(piece),
            width_m=float(seg_w * sy), source="pier", score=float(b.score),
            attrs={"structure": f"pier{structure}", "role": b.role, "segment": k, "of": n},
        ))
    return out


def set_deck_heights(objects, class_ids: np.ndarray, height: HeightMap, config: PierConfig,
                     quay_height_m: float, water_level_m: float = 0.0) -> list[SceneObject]:
    """Pier segments raised to their real height: a structure's deck is level with the ground at its land
    end (a walkway leaves the quay flush), the convention of the truth scenes ``coastforge synth`` makes.

    A pier object's z is its asset's origin, and the deck top stands ``config.deck_height_m`` above it (the
    kit's decks: 0.6 m, ``synth.PIER_DECK_M``); so z = deck top - deck_height_m, where the deck top is the
    ground at the land end or the quay height, whichever is higher, and z stays between the water level and
    the quay height. A structure with no land near any end gets the quay height as its deck. Other objects
    pass unchanged."""
    import cv2

    piers = [o for o in objects if o.category == "pier"]
    if not piers or height is None:
        return list(objects)
    g = height.grid
    # ground pixels: land, minus the decks themselves (pier decks are often classified as paving)
    land = (np.asarray(class_ids) != WATER).astype(np.uint8)
    if land.shape != g.shape:
        land = cv2.resize(land, (g.width_px, g.height_px), interpolation=cv2.INTER_NEAREST)
    for o in piers:
        col, row = g.to_pixel(*o.footprint_m().T)
        cv2.fillPoly(land, [np.round(np.stack([col, row], 1)).astype(np.int32)], 0)
    by_structure: dict[str, list[SceneObject]] = {}
    for o in piers:
        by_structure.setdefault(str(o.attrs.get("structure", o.id)), []).append(o)
    z_of: dict[str, float] = {}
    for sid, segs in by_structure.items():
        best = (0, quay_height_m)  # (land pixels near the end, ground height there)
        for o in segs:
            u = np.array([np.cos(np.radians(o.yaw_deg)), np.sin(np.radians(o.yaw_deg))])
            r_m = max(1.5, o.width_m)
            for end in (np.array([o.x_m, o.y_m]) + s * u * o.length_m / 2 for s in (-1.0, 1.0)):
                z = _ground_near(land, height, end, r_m)
                if z is not None and z[0] > best[0]:
                    best = z
        # the terrain estimated near a shoreline runs low (its profiles rise from the water level), so the
        # deck stands at least at the quay height: a walkway leaves the top of a quay, not its toe
        deck_top = max(best[1], water_level_m + quay_height_m)
        z_of[sid] = float(np.clip(deck_top - config.deck_height_m, water_level_m, water_level_m + quay_height_m))
    from dataclasses import replace

    return [replace(o, z_m=z_of[str(o.attrs.get("structure", o.id))]) if o.category == "pier" else o
            for o in objects]


def _ground_near(land: np.ndarray, height: HeightMap, p: np.ndarray, radius_m: float) -> tuple[int, float] | None:
    """(number of ground pixels, their median height) within ``radius_m`` of ``p``, or None without any."""
    g = height.grid
    col, row = g.to_pixel(p[0], p[1])
    r = max(1, int(np.ceil(radius_m / g.gsd_m)))
    c0, c1 = int(max(0, np.floor(col) - r)), int(min(g.width_px, np.floor(col) + r + 1))
    r0, r1 = int(max(0, np.floor(row) - r)), int(min(g.height_px, np.floor(row) + r + 1))
    if c1 <= c0 or r1 <= r0:
        return None
    yy, xx = np.mgrid[r0:r1, c0:c1]
    disc = (xx + 0.5 - col) ** 2 + (yy + 0.5 - row) ** 2 <= r * r
    sel = disc & (land[r0:r1, c0:c1] > 0)
    if not sel.any():
        return None
    return int(sel.sum()), float(np.median(height.z_m[r0:r1, c0:c1][sel]))
