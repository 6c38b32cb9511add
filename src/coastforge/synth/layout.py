"""Procedural layouts for the synthetic levels: land use, piers, moored/anchored boats, parked cars.

Everything is laid out in a *local shore frame* (u along the shore, v towards land, metres, origin at
the scene centre) and rotated by the level's random angle into the scene frame at the end, so the
coast can face any direction. The land is the region ``v > shore(u)`` (plus optional land additions
such as breakwaters); every land-use polygon is clipped to it, so the class map and the geometry used
for object checks agree.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from .. import frames
from ..classes import ASPHALT, SIDEWALK

# ---------------------------------------------------------------- asset dimensions


@dataclass(frozen=True)
class AssetDims:
    """What the layout needs to know about an asset: category, size (metres), flotation."""

    id: str
    category: str
    length_m: float
    width_m: float
    height_m: float
    draft_m: float = 0.0
    floating: bool = False
    tags: tuple[str, ...] = ()


# ---------------------------------------------------------------- geometry helpers


def obox(cx: float, cy: float, length: float, width: float, yaw_deg: float) -> Polygon:
    """An oriented rectangle in a right-handed frame (yaw CCW from +u)."""
    r = math.radians(yaw_deg)
    c, s = math.cos(r), math.sin(r)
    hl, hw = length / 2.0, width / 2.0
    corners = ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))
    pts = [(cx + c * dx - s * dy, cy + s * dx + c * dy) for dx, dy in corners]
    return Polygon(pts)


def blob(rng: np.random.Generator, cx: float, cy: float, radius: float, n: int = 7) -> Polygon:
    """An irregular patch (a union of random discs, smoothed) of about ``radius`` metres."""
    pts = [(cx, cy)]
    for _ in range(n - 1):
        a = rng.uniform(0, 2 * math.pi)
        d = rng.uniform(0.2, 0.8) * radius
        pts.append((cx + d * math.cos(a), cy + d * math.sin(a)))
    discs = [Point(p).buffer(rng.uniform(0.35, 0.6) * radius, 12) for p in pts]
    return unary_union(discs).buffer(radius * 0.15, 8).buffer(-radius * 0.15, 8)


def wiggly_line(rng: np.random.Generator, p0, p1, amp: float, n: int = 12) -> LineString:
    """A path from p0 to p1 with smooth lateral wiggles of ``amp`` metres."""
    t = np.linspace(0, 1, n)
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    nrm = np.array([-d[1], d[0]]) / (np.linalg.norm(d) + 1e-9)
    ph = rng.uniform(0, 2 * math.pi, 2)
    off = amp * (np.sin(2 * math.pi * t * rng.uniform(0.5, 1.5) + ph[0]) * np.sin(math.pi * t))
    pts = p0[None] + t[:, None] * d[None] + off[:, None] * nrm[None]
    return LineString(pts)


def angle_of(dx: float, dy: float) -> float:
    return math.degrees(math.atan2(dy, dx))


# ---------------------------------------------------------------- layout containers


@dataclass
class PlacedObject:
    """An object in the local frame (converted to a SceneObject when the layout is finished)."""

    id: str
    category: str
    asset_id: str
    u: float
    v: float
    yaw_local: float
    scale: tuple[float, float, float]
    length_m: float
    width_m: float
    footprint: Polygon
    z_kind: str  # "water" | "terrain" | "deck"
    attrs: dict = field(default_factory=dict)


@dataclass
class Decor:
    """Render-only clutter in the local frame: painted lines (parking bays), wakes of moving boats."""

    lines: list = field(default_factory=list)  # (LineString, width_m)
    wakes: list = field(default_factory=list)  # (u, v, yaw_local, length_m, beam_m)


@dataclass(frozen=True)
class Mix:
    """Which asset types a level draws and how often. The benchmark's levels use the defaults; training
    data for the learned detector uses ``TRAINING_MIX``, which shows the rare types (buses, small boats,
    the kit's hatchback and box truck) often enough to be learned without changing any benchmark level."""

    car_types: tuple[str, ...] = ("sedan", "sedan", "sedan", "suv", "suv", "pickup", "van")
    boat_prior: tuple[tuple[str, float], ...] = (
        ("sailboat", 1.0), ("cabin_cruiser", 1.0), ("runabout", 0.8), ("yacht", 0.45), ("fishing_boat", 0.5),
        ("dinghy", 0.35), ("catamaran", 0.25), ("kayak", 0.3))
    extra_boats: tuple[str, ...] = ()  # added to every berth's and anchorage's choice of boat types
    bus_p: float = 0.35  # a bus beside a car park's last row
    aisle_p: float = 0.0  # a large vehicle (bus, box truck) driving along a car park's aisle
    # piers: a side of a walkway left without fingers (its boats then lie alongside), the gap between boats
    # tied alongside, and a second boat rafted outboard of one (real marinas pack them end to end and
    # several deep: the ``RAFTED_MIX`` for training the detector)
    finger_drop_p: float = 0.0
    side_gap_m: tuple[float, float] = (1.0, 4.0)
    raft_p: float = 0.0
    # big vessels (``BIG_LENGTH_M``: ferries, trawlers, superyachts; the kit's largest boat is 18 m): the share
    # of anchored boats and of boats tied alongside a walkway that are a kit boat scaled up (``big_boat``)
    big_p: float = 0.0

    def prior(self, asset_id: str) -> float:
        return dict(self.boat_prior).get(asset_id, 0.5)


BENCHMARK_MIX = Mix()
TRAINING_MIX = Mix(
    car_types=("sedan", "sedan", "suv", "suv", "pickup", "van", "hatchback", "hatchback", "box_truck", "bus"),
    boat_prior=(("sailboat", 1.0), ("cabin_cruiser", 1.0), ("runabout", 0.8), ("yacht", 0.45),
                ("fishing_boat", 0.5), ("dinghy", 0.9), ("catamaran", 0.4), ("kayak", 0.7), ("rowboat", 0.6),
                ("center_console", 0.7)),
    extra_boats=("dinghy", "kayak", "rowboat", "center_console"),
    bus_p=0.85, aisle_p=0.6)
RAFTED_MIX = replace(TRAINING_MIX, finger_drop_p=0.5, side_gap_m=(0.35, 1.5), raft_p=0.3)
BIG_MIX = replace(TRAINING_MIX, finger_drop_p=0.5, big_p=0.4)
MIXES = {"benchmark": BENCHMARK_MIX, "training": TRAINING_MIX, "rafted": RAFTED_MIX, "big": BIG_MIX}


class Layout:
    """A level under construction in the local shore frame."""

    def __init__(self, size_m: float, theta_deg: float, shore_u: np.ndarray, shore_v: np.ndarray,
                 catalog: dict[str, AssetDims], rng: np.random.Generator, mix: Mix = BENCHMARK_MIX):
        self.mix = mix
        self.size_m = float(size_m)
        self.theta_deg = float(theta_deg)
        self.catalog = catalog
        self.rng = rng
        self.R = size_m * 0.8  # local content must cover the rotated square (half-diagonal 0.707 S)
        self.shore_u, self.shore_v = shore_u, shore_v
        far = self.R + 20.0
        ring = list(zip(shore_u, shore_v)) + [(shore_u[-1], far), (shore_u[0], far)]
        self.land = Polygon(ring).buffer(0)
        self.paints: list[tuple[float, int, object, int]] = []  # (priority, order, geometry, class)
        self.objects: list[PlacedObject] = []
        self.obstacles: list[Polygon] = []
        self.owners: list[str] = []  # the pier structure an obstacle belongs to ("" for none)
        self.decor = Decor()
        self.counters: dict[str, int] = {}
        self.pier_roots: dict[str, tuple[float, float]] = {}  # structure -> its land end (u, v)
        h = size_m / 2.0
        sq = np.array([(-h, -h), (h, -h), (h, h), (-h, h)])
        self.scene_poly = Polygon([self.to_local(x, y) for x, y in sq])
        self.water_zone_poly = self.scene_poly.difference(self.land)

    # frames
    def to_scene(self, u, v):
        r = math.radians(self.theta_deg)
        c, s = math.cos(r), math.sin(r)
        u, v = np.asarray(u, float), np.asarray(v, float)
        return c * u - s * v, s * u + c * v

    def to_local(self, x, y):
        r = math.radians(self.theta_deg)
        c, s = math.cos(r), math.sin(r)
        return (c * x + s * y, -s * x + c * y)

    def shore(self, u: float) -> float:
        return float(np.interp(u, self.shore_u, self.shore_v))

    def shore_span(self, margin: float = 0.0) -> tuple[float, float]:
        """The u-range over which the shoreline is inside the scene (shrunk by ``margin``)."""
        inner = self.scene_poly.buffer(-margin) if margin else self.scene_poly
        us = np.linspace(-self.R, self.R, 400)
        ok = shapely.contains_xy(inner, us, np.interp(us, self.shore_u, self.shore_v))
        if not ok.any():
            return (0.0, 0.0)
        return float(us[ok].min()), float(us[ok].max())

    def next_id(self, prefix: str) -> str:
        k = self.counters.get(prefix, 0)
        self.counters[prefix] = k + 1
        return f"{prefix}_{k:03d}"

    # land use
    def add_land(self, geom, cls: int, z: float = 4.0) -> None:
        """Extend the land (e.g. a breakwater) and paint it."""
        self.land = self.land.union(geom).buffer(0)
        self.water_zone_poly = self.scene_poly.difference(self.land)
        self.paints.append((z, len(self.paints), geom, cls))

    def paint(self, geom, cls: int, z: float = 1.0):
        """Paint a land-use class over everything of lower priority ``z``; clipped to the land so water
        stays water. Returns the clipped geometry."""
        g = geom.intersection(self.land)
        if not g.is_empty:
            self.paints.append((z, len(self.paints), g, cls))
        return g

    def band_along_shore(self, u0: float, u1: float, w0: float, w1: float, step: float = 1.0,
                         wobble: float = 0.0) -> Polygon:
        """The strip between shore+w0 and shore+w1 (metres inland) for u in [u0, u1]."""
        us = np.arange(u0, u1 + step, step)
        vs = np.interp(us, self.shore_u, self.shore_v)
        wob = np.zeros_like(us)
        if wobble:
            ph = self.rng.uniform(0, 2 * math.pi, 3)
            wob = wobble * (0.6 * np.sin(us / 9.0 + ph[0]) + 0.4 * np.sin(us / 3.7 + ph[1]))
        taper = 1.0
        if u1 - u0 < 2 * self.R - 1:  # a band that ends inside the scene: round its ends off
            e = np.clip(np.minimum(us - u0, u1 - us) / max(4.0, (w1 - w0) * 1.5), 0, 1)
            taper = np.sqrt(np.sin(e * math.pi / 2))
        inner = list(zip(us, vs + w0))
        outer = list(zip(us[::-1], (vs + w0 + (w1 - w0 + wob) * taper)[::-1]))
        return Polygon(inner + outer).buffer(0)

    # object placement
    def dims(self, asset_id: str) -> AssetDims:
        return self.catalog[asset_id]

    def in_scene(self, poly: Polygon, margin: float = 1.0) -> bool:
        return self.scene_poly.buffer(-margin, join_style=2).contains(poly)

    def is_free(self, poly: Polygon, clearance: float, ignore: str = "") -> bool:
        """True if ``poly`` grown by ``clearance`` touches no object (except structure ``ignore``'s)."""
        if not self.obstacles:
            return True
        grown = poly.buffer(clearance, join_style=2)
        hits = shapely.intersects(np.array(self.obstacles, dtype=object), grown)
        if ignore:
            hits &= np.array([o != ignore for o in self.owners])
        return not bool(np.any(hits))

    def on_water(self, poly: Polygon, clearance: float = 0.3) -> bool:
        return not poly.buffer(clearance).intersects(self.land)

    def add_object(self, prefix: str, category: str, asset_id: str, u: float, v: float, yaw_local: float,
                   scale: float | tuple[float, float, float], z_kind: str, attrs: dict | None = None,
                   length_m: float | None = None, width_m: float | None = None,
                   obstacle: bool = True) -> PlacedObject:
        d = self.dims(asset_id)
        sc = (scale, scale, scale) if isinstance(scale, (int, float)) else tuple(scale)
        length = length_m if length_m is not None else d.length_m * sc[0]
        width = width_m if width_m is not None else d.width_m * sc[1]
        fp = obox(u, v, length, width, yaw_local)
        # ``asset_id`` names a layout role (a kit id); the placed asset is the one filling that role
        o = PlacedObject(self.next_id(prefix), category, d.id, float(u), float(v), float(yaw_local),
                         tuple(float(s) for s in sc), float(length), float(width), fp, z_kind,
                         dict(attrs or {}))
        self.objects.append(o)
        if obstacle:
            self.obstacles.append(fp)
            self.owners.append(str(o.attrs.get("structure", "")) if category == "pier" else "")
        return o

    def try_boat(self, asset_id: str, u: float, v: float, yaw_local: float, scale: float, attrs: dict,
                 clearance: float = 0.3) -> PlacedObject | None:
        """Place a boat if it is fully on water, inside the scene and clear of every other object."""
        d = self.dims(asset_id)
        fp = obox(u, v, d.length_m * scale, d.width_m * scale, yaw_local)
        if not (self.in_scene(fp, 1.0) and self.on_water(fp) and self.is_free(fp, clearance)):
            return None
        return self.add_object("boat", "boat", asset_id, u, v, yaw_local, scale, "water", attrs)


# ---------------------------------------------------------------- boats


BOAT_SLIP_TYPES = ("dinghy", "runabout", "cabin_cruiser", "sailboat", "fishing_boat", "yacht", "catamaran")


def pick_boat(layout: Layout, rng: np.random.Generator, max_len: float, max_beam: float, min_len: float = 0.0,
              types: tuple[str, ...] = BOAT_SLIP_TYPES) -> tuple[str, float] | None:
    """A boat type and scale that fits a berth of ``max_len`` × ``max_beam`` (None if nothing fits)."""
    cands = []
    types = tuple(types) + tuple(t for t in layout.mix.extra_boats if t not in types)
    for t in types:
        if t not in layout.catalog:
            continue
        d = layout.catalog[t]
        for s in (1.0, 0.9, 1.1, 0.8):
            L, W = d.length_m * s, d.width_m * s
            if L <= max_len and W <= max_beam and L >= min_len:
                cands.append((t, s, L))
                break
    if not cands:
        # nothing of a fitting length: a smaller boat in a big berth is still a moored boat
        return pick_boat(layout, rng, max_len, max_beam, 0.0, types) if min_len > 0 else None
    # prefer boats that use the berth well (a 4 m dinghy in a 15 m slip is rare), and the types that
    # are common in leisure marinas (work boats and catamarans are the exception there)
    w = np.array([(0.25 + (L / max_len) ** 2) * layout.mix.prior(t) for t, _s, L in cands])
    t, s, _L = cands[int(rng.choice(len(cands), p=w / w.sum()))]
    return t, float(s * rng.uniform(0.96, 1.04) if s * 1.04 * layout.catalog[t].length_m <= max_len else s)


BIG_LENGTH_M = (20.0, 50.0)  # the real sets' boats reach 60 m; the detector's range is 2-60 m
BIG_TYPES = ("yacht", "fishing_boat", "catamaran", "cabin_cruiser", "sailboat")


def big_boat(layout: Layout, rng: np.random.Generator, max_len: float = BIG_LENGTH_M[1]) -> tuple[str, float] | None:
    """A kit boat type and the scale that makes it a big vessel of ``BIG_LENGTH_M`` (at most ``max_len``), or
    None when the mix has no big boats or this draw is not one. Draws nothing when ``big_p`` is 0, so the
    other mixes' levels stay as they were."""
    if layout.mix.big_p <= 0 or rng.random() >= layout.mix.big_p:
        return None
    types = [t for t in BIG_TYPES if t in layout.catalog]
    if not types or max_len < BIG_LENGTH_M[0]:
        return None
    t = str(rng.choice(types))
    length = float(rng.uniform(BIG_LENGTH_M[0], min(BIG_LENGTH_M[1], max_len)))
    return t, length / layout.catalog[t].length_m


# ---------------------------------------------------------------- piers


@dataclass(frozen=True)
class PierSpec:
    u0: float  # where the walkway leaves the shore
    length_m: float  # over the water
    walk_w: float = 2.5
    angle_dev_deg: float = 0.0  # deviation from perpendicular to the shore
    finger_len: float = 8.0
    finger_w: float = 1.2
    pitch: float = 4.5  # finger spacing (slip width + finger width)
    sides: tuple[int, ...] = (1, -1)  # +1: right of the walkway direction, -1: left
    head_len: float = 0.0  # T-head walkway at the outer end (0: none)
    occupancy: float = 0.75
    bow_in_p: float = 0.6  # probability that this pier's boats are moored bow in
    flip_p: float = 0.12  # boats that break the pier's habit
    double_p: float = 0.3  # slips that hold two boats side by side
    side_tie: bool = True  # boats alongside the walkway where a side has no fingers
    boat_types: tuple[str, ...] = BOAT_SLIP_TYPES
    seg_len: float = 0.0  # nominal walkway segment length (0: the asset's length)


def _raft_outboard(layout: Layout, rng: np.random.Generator, spec: PierSpec, c: np.ndarray, d: np.ndarray,
                   out: np.ndarray, width: float, length: float, attrs: dict) -> None:
    """A boat rafted alongside the outer side of the boat at ``c`` (beam ``width``), no longer than it."""
    pick = pick_boat(layout, rng, length, 5.0, 3.0, spec.boat_types)
    if pick is None:
        return
    t_id, sc = pick
    bd = layout.dims(t_id)
    c2 = c + d * rng.uniform(-0.15, 0.15) * length + out * (width / 2 + rng.uniform(0.1, 0.5) + bd.width_m * sc / 2)
    yaw = angle_of(*d) + rng.normal(0, 2.0) + (180.0 if rng.random() < 0.3 else 0.0)
    layout.try_boat(t_id, c2[0], c2[1], yaw, sc, {**attrs, "bow": "alongside", "rafted": True}, clearance=0.05)


def add_pier(layout: Layout, spec: PierSpec, structure: str, rng: np.random.Generator) -> list[PlacedObject]:
    """A walkway from land over the water with fingers, a T-head and boats. Returns the pier segments."""
    a = math.radians(spec.angle_dev_deg)
    d = np.array([math.sin(a), -math.cos(a)])  # into the water (-v)
    n = np.array([-d[1], d[0]])  # +1 side
    yaw_d = angle_of(*d)
    v_sh = layout.shore(spec.u0)
    root = np.array([spec.u0, v_sh])
    # start on land: walk back until 1.5 m inside the land
    start = root - d * 1.5
    for _ in range(20):
        if layout.land.buffer(-1.0).contains(Point(*start)):
            break
        start = start - d * 0.5
    total = float(np.dot(root - start, d)) + spec.length_m
    layout.pier_roots[structure] = (float(start[0]), float(start[1]))
    wd = layout.dims("pier_walkway")
    seg_nom = spec.seg_len or max(wd.length_m, 4.0)
    nseg = max(1, int(round(total / seg_nom)))
    seg_len = total / nseg
    segs: list[PlacedObject] = []
    wsx, wsy = 1.0 / wd.length_m, spec.walk_w / wd.width_m
    for i in range(nseg):
        c = start + d * (i + 0.5) * seg_len
        o = layout.add_object(f"{structure}_walk", "pier", "pier_walkway", c[0], c[1], yaw_d,
                              (seg_len * wsx, wsy, 1.0), "deck",
                              {"structure": structure, "role": "walkway", "connects_to": [],
                               "touches_land": i == 0}, length_m=seg_len, width_m=spec.walk_w)
        segs.append(o)
    for i in range(nseg - 1):
        segs[i].attrs["connects_to"].append(segs[i + 1].id)
        segs[i + 1].attrs["connects_to"].append(segs[i].id)
    main_segs = list(segs)

    def seg_at(t: float) -> PlacedObject:
        return main_segs[min(nseg - 1, max(0, int(t // seg_len)))]

    # where the walkway is far enough from land for slips
    t_water = total
    for t in np.arange(0.0, total, 0.5):
        if layout.land.distance(Point(*(start + d * t))) > 3.0:
            t_water = float(t)
            break
    fd = layout.dims("pier_finger")
    bow_in = rng.random() < spec.bow_in_p
    fingers: dict[int, list[float]] = {s: [] for s in spec.sides}
    t0 = t_water + spec.pitch * rng.uniform(0.3, 0.8)
    ts = np.arange(t0, total - spec.finger_w / 2 - 0.3, spec.pitch)
    finger_sides = spec.sides
    if layout.mix.finger_drop_p > 0:  # no draw otherwise: the benchmark's levels stay as they were
        finger_sides = tuple(s for s in spec.sides if rng.random() >= layout.mix.finger_drop_p)
    for s in finger_sides:
        for t in ts:
            c = start + d * t + n * s * (spec.walk_w / 2 + spec.finger_len / 2)
            fp = obox(c[0], c[1], spec.finger_len, spec.finger_w, angle_of(*(n * s)))
            if not (layout.on_water(fp, 1.0) and layout.in_scene(fp, 1.0)
                    and layout.is_free(fp, 0.5, structure)):
                continue
            host = seg_at(t)
            o = layout.add_object(f"{structure}_finger", "pier", "pier_finger", c[0], c[1],
                                  angle_of(*(n * s)),
                                  (spec.finger_len / fd.length_m, spec.finger_w / fd.width_m, 1.0), "deck",
                                  {"structure": structure, "role": "finger", "connects_to": [host.id],
                                   "touches_land": False}, length_m=spec.finger_len, width_m=spec.finger_w)
            host.attrs["connects_to"].append(o.id)
            segs.append(o)
            fingers[s].append(float(t))
    # T-head
    head = None
    if spec.head_len > 0:
        c = start + d * (total + spec.walk_w / 2)
        fp = obox(c[0], c[1], spec.head_len, spec.walk_w, angle_of(*n))
        if layout.on_water(fp, 1.0) and layout.in_scene(fp, 1.0) and layout.is_free(fp, 0.5, structure):
            head = layout.add_object(f"{structure}_walk", "pier", "pier_walkway", c[0], c[1], angle_of(*n),
                                     (spec.head_len * wsx, wsy, 1.0), "deck",
                                     {"structure": structure, "role": "walkway",
                                      "connects_to": [main_segs[-1].id], "touches_land": False},
                                     length_m=spec.head_len, width_m=spec.walk_w)
            main_segs[-1].attrs["connects_to"].append(head.id)
            segs.append(head)

    def heading(out_dir: np.ndarray) -> tuple[float, str]:
        inward = bow_in if rng.random() >= spec.flip_p else not bow_in
        v = -out_dir if inward else out_dir
        return angle_of(*v) + rng.normal(0, 1.5), "in" if inward else "out"

    attrs = {"state": "moored", "structure": structure}
    # boats in slips between fingers (and beside the outermost fingers)
    for s, tl in fingers.items():
        if not tl:
            continue
        edges = [tl[0] - spec.pitch] + tl + [tl[-1] + spec.pitch]
        for ta, tb in itertools.pairwise(edges):
            if tb - ta > spec.pitch * 1.5 or rng.random() > spec.occupancy:
                continue
            ta_, tb_ = ta + spec.finger_w / 2, tb - spec.finger_w / 2
            if ta_ < t_water or tb_ > total + 0.5 * spec.pitch:
                continue
            width = tb_ - ta_
            nb = 2 if (rng.random() < spec.double_p and width > 6.0) else 1
            for k in range(nb):
                slot_w = width / nb
                pick = pick_boat(layout, rng, spec.finger_len * 1.3 + 1.0, slot_w - 1.0,
                                 spec.finger_len * 0.45, spec.boat_types)
                if pick is None:
                    continue
                t_id, sc = pick
                bd = layout.dims(t_id)
                L = bd.length_m * sc
                tc = ta_ + slot_w * (k + 0.5) + rng.normal(0, 0.1)
                off = spec.walk_w / 2 + rng.uniform(0.4, 1.0) + L / 2
                c = start + d * tc + n * s * off
                yaw, bow = heading(n * s)
                layout.try_boat(t_id, c[0], c[1], yaw, sc, {**attrs, "bow": bow})
    # side-tied boats along the walkway where a side has no fingers
    if spec.side_tie:
        for s in (1, -1):
            if fingers.get(s):
                continue
            t = t_water + rng.uniform(0.5, 3.0)
            while t < total:
                pick = big_boat(layout, rng) or pick_boat(layout, rng, rng.uniform(6, 14), 4.5, 3.0, spec.boat_types)
                if pick is None:
                    break
                t_id, sc = pick
                bd = layout.dims(t_id)
                L, W = bd.length_m * sc, bd.width_m * sc
                if t + L > total + 1.0:
                    break
                if rng.random() < spec.occupancy:
                    c = start + d * (t + L / 2) + n * s * (spec.walk_w / 2 + 0.4 + W / 2)
                    yaw = heading(d)[0] if rng.random() < 0.85 else heading(-d)[0]
                    placed = layout.try_boat(t_id, c[0], c[1], yaw, sc, {**attrs, "bow": "alongside"})
                    if placed is not None and layout.mix.raft_p > 0 and rng.random() < layout.mix.raft_p:
                        _raft_outboard(layout, rng, spec, c, d, n * s, W, L, attrs)
                t += L + rng.uniform(*layout.mix.side_gap_m)
    # side-tied boats along the outer face of the T-head
    if head is not None:
        c0 = np.array([head.u, head.v]) + d * (spec.walk_w / 2)
        t = -spec.head_len / 2 + rng.uniform(0.3, 2.0)
        flow = n if rng.random() < 0.5 else -n
        while t < spec.head_len / 2:
            pick = pick_boat(layout, rng, 18.0, 6.0, 6.0, spec.boat_types)
            if pick is None:
                break
            t_id, sc = pick
            bd = layout.dims(t_id)
            L, W = bd.length_m * sc, bd.width_m * sc
            if t + L > spec.head_len / 2 + 2.0:
                break
            if rng.random() < spec.occupancy:
                c = c0 + n * (t + L / 2) + d * (0.4 + W / 2)
                yaw = angle_of(*flow) + rng.normal(0, 1.5)
                if rng.random() < spec.flip_p:
                    yaw += 180.0
                layout.try_boat(t_id, c[0], c[1], yaw, sc, {**attrs, "bow": "alongside"})
            t += L + rng.uniform(1.0, 3.5)
    return segs


# ---------------------------------------------------------------- open water


def open_water_points(layout: Layout, rng: np.random.Generator, n: int, min_shore: float,
                      max_shore: float = 1e9) -> np.ndarray:
    """Random points in the scene's water at a distance from land within [min_shore, max_shore]."""
    zone = layout.water_zone_poly.buffer(-4.0)
    far = zone.difference(layout.land.buffer(min_shore))
    if max_shore < 1e8:
        far = far.intersection(layout.land.buffer(max_shore))
    if far.is_empty:
        return np.zeros((0, 2))
    minx, miny, maxx, maxy = far.bounds
    pts = rng.uniform((minx, miny), (maxx, maxy), size=(max(64, n * 40), 2))
    ok = shapely.contains_xy(far, pts[:, 0], pts[:, 1])
    return pts[ok][: n * 10]


def add_anchored(layout: Layout, rng: np.random.Generator, count: int, wind_deg: float,
                 types: tuple[str, ...], min_shore: float = 15.0, buoy_p: float = 0.5) -> None:
    """Boats at anchor or on mooring buoys: roughly head to wind, spread out."""
    pts = open_water_points(layout, rng, count, min_shore)
    placed = 0
    for u, v in pts:
        if placed >= count:
            break
        big = big_boat(layout, rng)
        if big is not None:
            t_id, sc = big
        else:
            t_id = str(rng.choice([t for t in types + layout.mix.extra_boats if t in layout.catalog]))
            sc = float(rng.uniform(0.9, 1.1))
        yaw = wind_deg + rng.normal(0, 35.0)
        mooring = big is None and rng.random() < buoy_p
        state = {"state": "mooring" if mooring else "anchored"}
        o = layout.try_boat(t_id, u, v, yaw, sc, state, clearance=4.0)
        if o is None:
            continue
        placed += 1
        if mooring and "buoy" in layout.catalog:
            r = math.radians(o.yaw_local)
            dist = o.length_m / 2 + rng.uniform(1.5, 4.0)
            add_buoy(layout, rng, u + dist * math.cos(r), v + dist * math.sin(r),
                     {"role": "mooring", "boat": o.id})


def add_buoy(layout: Layout, rng: np.random.Generator, u: float, v: float,
             attrs: dict) -> PlacedObject | None:
    d = layout.dims("buoy")
    sc = float(rng.uniform(0.85, 1.2))
    fp = obox(u, v, d.length_m * sc, d.width_m * sc, 0.0)
    if not (layout.in_scene(fp, 1.0) and layout.on_water(fp, 1.0) and layout.is_free(fp, 0.8)):
        return None
    # a buoy looks the same from every side: its yaw is arbitrary, and the truth says so (evaluate.py)
    return layout.add_object("buoy", "buoy", "buoy", u, v, float(rng.uniform(-179, 180)), sc, "water",
                             {**attrs, "symmetry": "rotational"})


def add_underway(layout: Layout, rng: np.random.Generator, count: int, types: tuple[str, ...]) -> None:
    """Boats under way in open water, each with a wake behind it (render clutter)."""
    pts = open_water_points(layout, rng, count, 20.0)
    placed = 0
    for u, v in pts:
        if placed >= count:
            break
        t_id = str(rng.choice([t for t in types if t in layout.catalog]))
        yaw = float(rng.uniform(-180, 180))
        d = layout.dims(t_id)
        r = math.radians(yaw)
        wake_len = rng.uniform(3, 7) * d.length_m
        # keep the wake clear of other objects too
        tail = (u - wake_len * math.cos(r), v - wake_len * math.sin(r))
        wake = LineString([(u, v), tail]).buffer(d.width_m)
        if not layout.is_free(wake, 2.0) or not layout.on_water(wake, 0.0):
            continue
        o = layout.try_boat(t_id, u, v, yaw, 1.0, {"state": "underway"}, clearance=6.0)
        if o is None:
            continue
        layout.decor.wakes.append((u, v, yaw, wake_len, d.width_m))
        placed += 1


# ---------------------------------------------------------------- parking


def add_parking(layout: Layout, rng: np.random.Generator, cu: float, cv: float, length: float, depth: float,
                yaw_local: float, occupancy: float, lot_id: str, sidewalk_w: float = 2.0) -> Polygon | None:
    """An asphalt lot (with a sidewalk border) of rows of 2.5 × 5.2 m bays, cars parked either way."""
    lot = obox(cu, cv, length, depth, yaw_local)
    if not layout.land.buffer(-0.5).contains(lot):
        return None
    layout.paint(obox(cu, cv, length + 2 * sidewalk_w, depth + 2 * sidewalk_w, yaw_local), SIDEWALK, z=5)
    layout.paint(lot, ASPHALT, z=6)
    r = math.radians(yaw_local)
    ax = np.array([math.cos(r), math.sin(r)])  # along the rows
    ay = np.array([-ax[1], ax[0]])  # across the rows
    c = np.array([cu, cv])
    bay_w, bay_d, aisle = rng.uniform(2.4, 2.7), rng.uniform(5.0, 5.5), rng.uniform(6.0, 7.0)
    # rows across the depth: [row, aisle, row][row, aisle, row]...; a module is two rows + an aisle
    rows: list[tuple[float, int]] = []  # (offset of the row's centre along ay, which way the bay's back is)
    y = -depth / 2 + 0.5
    while y + 2 * bay_d + aisle <= depth / 2 - 0.5:
        rows.append((y + bay_d / 2, -1))
        rows.append((y + bay_d + aisle + bay_d / 2, +1))
        y += 2 * bay_d + aisle
    if depth / 2 - 0.5 - y >= bay_d + aisle:  # room left for a single row facing the last aisle
        rows.append((depth / 2 - 0.5 - bay_d / 2, +1) if rows else (y + bay_d / 2, -1))
    nb = int((length - 2.0) // bay_w)
    x0 = -nb * bay_w / 2
    nose_in_p = rng.uniform(0.3, 0.9)  # drivers' habit in this lot
    for ry, back in rows:
        # painted lines: between bays (render clutter; class "sidewalk incl. parking lines" is too thin here)
        for k in range(nb + 1):
            p = c + ax * (x0 + k * bay_w) + ay * ry
            a_, b_ = p - ay * bay_d / 2, p + ay * bay_d / 2
            layout.decor.lines.append((LineString([tuple(a_), tuple(b_)]), 0.12))
        for k in range(nb):
            if rng.random() > occupancy:
                continue
            t_id = str(rng.choice([t for t in layout.mix.car_types if t in layout.catalog]))
            cd = layout.dims(t_id)
            sc = float(rng.uniform(0.96, 1.04))
            if cd.length_m * sc > bay_d + 0.3 or cd.width_m * sc > bay_w - 0.2:
                continue
            nose_to_back = rng.random() < nose_in_p
            fwd = ay * back if nose_to_back else -ay * back
            p = (c + ax * (x0 + (k + 0.5) * bay_w + rng.normal(0, 0.12))
                 + ay * (ry + back * rng.uniform(-0.3, 0.2)))
            yaw = angle_of(*fwd) + rng.normal(0, 2.5)
            fp = obox(p[0], p[1], cd.length_m * sc, cd.width_m * sc, yaw)
            if not (lot.buffer(0.3).contains(fp) and layout.in_scene(fp, 0.5) and layout.is_free(fp, 0.2)):
                continue
            layout.add_object("car", "vehicle", t_id, p[0], p[1], yaw, sc, "terrain",
                              {"lot": lot_id, "nose": "in" if nose_to_back else "out"})
    # a large vehicle (bus, box truck) driving through the lot: only in the training mix (rare in the
    # benchmark's levels); it goes where it finds room, which is the aisle or the free side of a row
    if layout.mix.aisle_p > 0 and rng.random() < layout.mix.aisle_p:
        t_id = str(rng.choice([t for t in ("bus", "box_truck") if t in layout.catalog] or ["van"]))
        d = layout.dims(t_id)
        for _ in range(12):
            p = c + ax * rng.uniform(-length / 3, length / 3) + ay * rng.uniform(-depth / 2, depth / 2)
            yaw = angle_of(*ax) + (180.0 if rng.random() < 0.5 else 0.0) + rng.normal(0, 2.0)
            fp = obox(p[0], p[1], d.length_m, d.width_m, yaw)
            if lot.contains(fp) and layout.in_scene(fp, 0.5) and layout.is_free(fp, 0.3):
                layout.add_object("car", "vehicle", t_id, p[0], p[1], yaw, 1.0, "terrain", {"lot": lot_id})
                break
    # a bus or van parked along the lot edge beside the last row, sometimes
    if "bus" in layout.catalog and rng.random() < layout.mix.bus_p:
        bd = layout.dims("bus")
        edge = depth / 2 - bd.width_m / 2 - 0.6
        if rows and edge > rows[-1][0] + bay_d / 2 + bd.width_m / 2 + 0.5:
            p = c + ay * edge + ax * rng.uniform(-length / 4, length / 4)
            yaw = angle_of(*ax) + (180.0 if rng.random() < 0.5 else 0.0)
            fp = obox(p[0], p[1], bd.length_m, bd.width_m, yaw)
            if lot.contains(fp) and layout.in_scene(fp, 0.5) and layout.is_free(fp, 0.3):
                layout.add_object("car", "vehicle", "bus", p[0], p[1], yaw, 1.0, "terrain", {"lot": lot_id})
    return lot


def add_street_parking(layout: Layout, rng: np.random.Generator, road: LineString, offset: float,
                       occupancy: float, paved) -> None:
    """Cars parallel-parked along one side of a road, facing the traffic direction of that side."""
    length = road.length
    t = rng.uniform(1, 6)
    while t < length - 6:
        p0 = np.array(road.interpolate(t).coords[0])
        p1 = np.array(road.interpolate(min(length, t + 1)).coords[0])
        tang = (p1 - p0) / (np.linalg.norm(p1 - p0) + 1e-9)
        nrm = np.array([-tang[1], tang[0]])
        t_id = str(rng.choice([t_ for t_ in layout.mix.car_types if t_ in layout.catalog]))
        cd = layout.dims(t_id)
        step = cd.length_m + rng.uniform(1.0, 2.5)
        if rng.random() < occupancy:
            p = p0 + tang * cd.length_m / 2 + nrm * offset
            fwd = tang if offset < 0 else -tang  # right-hand traffic
            if rng.random() < 0.1:
                fwd = -fwd
            yaw = angle_of(*fwd) + rng.normal(0, 1.5)
            fp = obox(p[0], p[1], cd.length_m, cd.width_m, yaw)
            if layout.in_scene(fp, 1.0) and paved.contains(fp) and layout.is_free(fp, 0.3):
                layout.add_object("car", "vehicle", t_id, p[0], p[1], yaw, 1.0, "terrain", {"street": True})
        t += step


# ---------------------------------------------------------------- land-use helpers


def scatter_patches(layout: Layout, rng: np.random.Generator, region, count: int, r_min: float, r_max: float,
                    cls: int, avoid=None, z: float = 1.0) -> list:
    """Paint ``count`` irregular patches of ``cls`` inside ``region`` (avoiding ``avoid``)."""
    out = []
    if region.is_empty:
        return out
    minx, miny, maxx, maxy = region.bounds
    tries = 0
    while len(out) < count and tries < count * 30:
        tries += 1
        p = rng.uniform((minx, miny), (maxx, maxy))
        if not region.contains(Point(*p)):
            continue
        g = blob(rng, p[0], p[1], rng.uniform(r_min, r_max)).intersection(region)
        if avoid is not None:
            g = g.difference(avoid)
        if g.is_empty or g.area < 4.0:
            continue
        out.append(layout.paint(g, cls, z=z))
    return out


def yaw_to_scene(layout: Layout, yaw_local: float) -> float:
    return float(frames.wrap_deg(yaw_local + layout.theta_deg))
