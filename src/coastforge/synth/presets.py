"""The synthetic levels: the paper's five ground-truth levels (two simple pier scenes, a pier with a
parking lot, a marina section, a lake harbor) plus a sand beach and a rocky shore.

Each builder draws its own parameters from the level's generator (sizes, shore shape, land use,
occupancy, mooring habits), so every seed gives a different level of the same kind.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from shapely.geometry import LineString, Point

from ..classes import ASPHALT, DIRT, GRASS, ROCKS, SAND, SIDEWALK, TREES
from .layout import (
    BENCHMARK_MIX, AssetDims, Layout, Mix, PierSpec, add_anchored, add_buoy, add_parking, add_pier,
    add_street_parking, add_underway, obox, open_water_points, scatter_patches, wiggly_line,
)
from .terrain import TruthTerrainParams

CRUISERS = ("sailboat", "cabin_cruiser", "fishing_boat", "runabout", "yacht", "catamaran")
SMALL = ("dinghy", "kayak", "runabout")
LAKE_SLIP = ("dinghy", "runabout", "kayak", "sailboat", "cabin_cruiser")


def even(x: float) -> float:
    """Round a size to an even number of metres (whole pixels at 0.1 and 0.2 m per pixel)."""
    return float(2 * round(x / 2))


def shore_curve(rng: np.random.Generator, R: float, v0: float, amp: float, wl: float,
                slope: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A smooth shoreline v(u): a few sinusoids of decreasing amplitude and wavelength."""
    us = np.arange(-R - 40.0, R + 40.0, 0.5)
    vs = v0 + slope * us
    for a, f in ((1.0, 1.0), (0.4, 0.45), (0.15, 0.2)):
        vs = vs + amp * a * np.sin(2 * math.pi * us / (wl * f) + rng.uniform(0, 2 * math.pi))
    return us, vs


def water_run(L: Layout, u0: float, angle_dev_deg: float = 0.0, margin: float = 6.0) -> float:
    """How far the water reaches from the shore at ``u0`` (perpendicular, into the water) inside the scene."""
    a = math.radians(angle_dev_deg)
    d = np.array([math.sin(a), -math.cos(a)])
    p0 = np.array([u0, L.shore(u0)])
    inner = L.scene_poly.buffer(-margin)
    t = 1.0
    while t < 2 * L.size_m:
        p = p0 + d * t
        if not inner.contains(Point(*p)) or (t > 3 and L.land.contains(Point(*p))):
            return t - 1.0
        t += 1.0
    return t


def terrain_params(rng: np.random.Generator, **over) -> TruthTerrainParams:
    base = dict(
        max_depth_m=float(rng.uniform(5.0, 12.0)), depth_scale_m=float(rng.uniform(25.0, 70.0)),
        berth_depth_m=float(rng.uniform(2.5, 5.0)), quay_height_m=float(rng.uniform(0.9, 1.8)),
        d50_mm=float(rng.uniform(0.2, 0.8)), beach_slope=float(rng.uniform(0.04, 0.09)),
        berm_height_m=float(rng.uniform(1.2, 2.2)), revetment_slope=float(rng.uniform(0.45, 0.8)),
        revetment_top_m=float(rng.uniform(1.6, 3.0)), revetment_toe_m=float(rng.uniform(1.8, 3.5)),
        bank_slope=float(rng.uniform(0.1, 0.25)), bank_top_m=float(rng.uniform(0.6, 1.4)),
        land_rise_m=float(rng.uniform(1.0, 5.0)), land_rise_scale_m=float(rng.uniform(60.0, 200.0)),
        noise_m=float(rng.uniform(0.06, 0.18)), seabed_noise_m=float(rng.uniform(0.1, 0.4)),
    )
    base.update(over)
    return TruthTerrainParams(**base)


# ---------------------------------------------------------------- shared land-use pieces


def _inland(L: Layout, w0: float, w1: float | None = None):
    """The land between w0 and w1 metres behind the shore (inside the scene)."""
    u0, u1 = -L.R, L.R
    band = L.band_along_shore(u0, u1, w0, w1 if w1 is not None else L.R * 3)
    return band.intersection(L.scene_poly.buffer(10)).intersection(L.land)


def _base_land(L: Layout, rng: np.random.Generator, trees: int, tree_r: tuple[float, float], setback: float,
               dirt: int = 2) -> None:
    L.paint(L.land, GRASS, z=0)
    region = _inland(L, setback)
    scatter_patches(L, rng, region, trees, tree_r[0], tree_r[1], TREES, z=1)
    scatter_patches(L, rng, region, dirt, 3.0, 7.0, DIRT, z=1.5)


def _road(L: Layout, rng: np.random.Generator, behind: float, width: float, parking_p: float = 0.5):
    """A straight road parallel to the mean shore, with sidewalks and sometimes parked cars."""
    us = np.linspace(-L.R, L.R, 50)
    v = float(np.mean([L.shore(u) for u in np.linspace(-L.size_m / 2, L.size_m / 2, 21)])) + behind
    line = LineString([(-L.R - 10, v), (L.R + 10, v)])
    if not L.land.buffer(-width).contains(LineString([(us[20], v), (us[30], v)])):
        return None
    L.paint(line.buffer(width / 2 + 1.8, cap_style=2), SIDEWALK, z=2.8)
    road = L.paint(line.buffer(width / 2, cap_style=2), ASPHALT, z=3)
    if rng.random() < parking_p and not road.is_empty:
        side = -1.0 if rng.random() < 0.5 else 1.0
        add_street_parking(L, rng, line, side * (width / 2 - 1.2), float(rng.uniform(0.3, 0.8)), road)
    return line


def _path(L: Layout, rng: np.random.Generator, p0, p1, width: float, cls: int = DIRT, z: float = 2.0):
    line = wiggly_line(rng, p0, p1, amp=float(rng.uniform(1.0, 5.0)))
    return L.paint(line.buffer(width / 2), cls, z=z)


def _anchorage(L: Layout, rng: np.random.Generator, boats: int, types, free_buoys: int, underway: int,
               min_shore: float = 15.0) -> None:
    wind = float(rng.uniform(-180, 180))
    add_anchored(L, rng, boats, wind, types, min_shore=min_shore, buoy_p=float(rng.uniform(0.2, 0.7)))
    for u, v in open_water_points(L, rng, free_buoys, 8.0)[:free_buoys]:
        add_buoy(L, rng, u, v, {"role": "marker"})
    if underway:
        add_underway(L, rng, underway, ("runabout", "fishing_boat", "cabin_cruiser"))


def _pier_root_pad(L: Layout, u0: float, w: float, depth: float) -> None:
    v = L.shore(u0)
    L.paint(obox(u0, v + depth / 2 - 1.0, w, depth, 0.0), SIDEWALK, z=6)


def _fit_pier(L: Layout, rng: np.random.Generator, u0: float, want_len: float, min_len: float,
              angle_dev: float) -> float:
    """The walkway length that fits (leaves room for a T-head and boats at the outer end)."""
    run = water_run(L, u0, angle_dev)
    return max(0.0, min(want_len, run - 14.0)) if run - 14.0 >= min_len else 0.0


# ---------------------------------------------------------------- the levels


def simple_pier_a(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(3, 7)), tree_r=(5, 12), setback=8.0)
    u_lo, u_hi = L.shore_span(10.0)
    if rng.random() < 0.55:
        L.paint(L.band_along_shore(-L.R, L.R, -0.5, float(rng.uniform(2.5, 5.0)), wobble=0.8), ROCKS, z=4)
    else:
        a = float(rng.uniform(u_lo, u_hi))
        L.paint(L.band_along_shore(a - 20, a + 20, -0.5, float(rng.uniform(4, 9)), wobble=1.5), SAND, z=4)
    road = _road(L, rng, float(rng.uniform(28, 45)), float(rng.uniform(6.5, 9.0)))
    u0 = float(rng.uniform(-0.15, 0.15) * S)
    dev = float(rng.uniform(-8, 8))
    length = _fit_pier(L, rng, u0, float(rng.uniform(22, 45)), 10.0, dev)
    if length > 0:
        _pier_root_pad(L, u0, float(rng.uniform(5, 9)), float(rng.uniform(5, 8)))
        sides = [(1, -1), (1,), (-1,)][int(rng.integers(0, 3))]
        add_pier(L, PierSpec(u0, length, walk_w=float(rng.uniform(2.0, 3.0)), angle_dev_deg=dev,
                             finger_len=float(rng.uniform(6, 9)), finger_w=float(rng.uniform(1.0, 1.4)),
                             pitch=float(rng.uniform(4.2, 5.6)), sides=sides,
                             head_len=float(rng.uniform(10, 18)) if rng.random() < 0.5 else 0.0,
                             occupancy=float(rng.uniform(0.5, 0.85))), "pier_0", rng)
        if road is not None:
            _path(L, rng, (u0, L.shore(u0) + 4), (u0 + rng.uniform(-15, 15), road.coords[0][1]),
                  float(rng.uniform(1.2, 2.0)))
    _anchorage(L, rng, int(rng.integers(2, 6)), CRUISERS, int(rng.integers(1, 4)), int(rng.random() < 0.4))
    return {"pier_length_m": length}


def simple_pier_b(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(2, 6)), tree_r=(4, 10), setback=10.0)
    _u_lo, _u_hi = L.shore_span(5.0)
    qa, qb = float(rng.uniform(-0.35, -0.15) * S), float(rng.uniform(0.15, 0.35) * S)
    quay_w = float(rng.uniform(3.0, 6.0))
    L.paint(L.band_along_shore(-L.R, L.R, -0.5, float(rng.uniform(3, 6)), wobble=1.0), ROCKS, z=3.5)
    L.paint(L.band_along_shore(qa, qb, -0.5, quay_w), SIDEWALK, z=4)
    _road(L, rng, quay_w + float(rng.uniform(15, 30)), float(rng.uniform(6.5, 9.0)))
    gap = float(rng.uniform(28, 45))
    centre = float(rng.uniform(-0.08, 0.08) * S)
    piers = 0
    for k, u0 in enumerate((centre - gap / 2, centre + gap / 2)):
        if not (qa + 4 < u0 < qb - 4):
            continue
        dev = float(rng.uniform(-4, 4))
        if k == 0:
            length = _fit_pier(L, rng, u0, float(rng.uniform(25, 45)), 10.0, dev)
            side = 1 if rng.random() < 0.5 else -1
            spec = PierSpec(u0, length, walk_w=float(rng.uniform(2.2, 3.0)), angle_dev_deg=dev,
                            finger_len=float(rng.uniform(7, 11)), pitch=float(rng.uniform(4.5, 6.0)),
                            sides=(side,), head_len=float(rng.uniform(12, 20)) if rng.random() < 0.6 else 0.0,
                            occupancy=float(rng.uniform(0.55, 0.9)))
        else:
            length = _fit_pier(L, rng, u0, float(rng.uniform(15, 30)), 8.0, dev)
            spec = PierSpec(u0, length, walk_w=float(rng.uniform(1.8, 2.6)), angle_dev_deg=dev, sides=(),
                            occupancy=float(rng.uniform(0.4, 0.8)))
        if length > 0:
            add_pier(L, spec, f"pier_{k}", rng)
            piers += 1
    _anchorage(L, rng, int(rng.integers(1, 4)), CRUISERS, int(rng.integers(0, 3)), int(rng.random() < 0.3))
    return {"piers": piers, "quay_u": [qa, qb]}


def pier_parking(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(2, 5)), tree_r=(4, 9), setback=12.0)
    prom = float(rng.uniform(4.0, 7.0))
    L.paint(L.band_along_shore(-L.R, L.R, -0.5, float(rng.uniform(3, 6)), wobble=1.0), ROCKS, z=3.5)
    qa, qb = float(rng.uniform(-0.4, -0.2) * S), float(rng.uniform(0.2, 0.4) * S)
    L.paint(L.band_along_shore(qa, qb, -0.5, prom), SIDEWALK, z=4)
    lots = 0
    for _try in range(8):
        length = float(min(rng.uniform(40, 80), S * 0.6))
        depth = float(rng.choice([17.0, 34.0, 35.0]))
        cu = float(rng.uniform(-0.15, 0.15) * S)
        cv = L.shore(cu) + prom + float(rng.uniform(4, 10)) + depth / 2 + 2.0
        lot = add_parking(L, rng, cu, cv, length, depth, float(rng.uniform(-6, 6)),
                          float(rng.uniform(0.45, 0.92)), "lot_0")
        if lot is not None:
            lots = 1
            # an entrance from the promenade
            L.paint(obox(cu + length / 2 - 5.0, (L.shore(cu) + cv) / 2 + prom / 2, 6.0, cv - L.shore(cu), 0.0)
                    .intersection(L.band_along_shore(-L.R, L.R, prom, 200)), ASPHALT, z=5.5)
            break
    _road(L, rng, prom + float(rng.uniform(50, 60)), float(rng.uniform(7, 9)), parking_p=0.3)
    npiers = int(rng.integers(1, 3))
    placed = 0
    for k in range(npiers):
        u0 = float(rng.uniform(qa + 8, qb - 8))
        if any(abs(u0 - o.u) < 30 for o in L.objects if o.category == "pier"):
            continue
        dev = float(rng.uniform(-5, 5))
        length = _fit_pier(L, rng, u0, float(rng.uniform(25, 50)), 10.0, dev)
        if length <= 0:
            continue
        add_pier(L, PierSpec(u0, length, walk_w=float(rng.uniform(2.2, 3.0)), angle_dev_deg=dev,
                             finger_len=float(rng.uniform(6, 10)), pitch=float(rng.uniform(4.2, 5.8)),
                             sides=[(1, -1), (1,), (-1,)][int(rng.integers(0, 3))],
                             head_len=float(rng.uniform(10, 18)) if rng.random() < 0.5 else 0.0,
                             occupancy=float(rng.uniform(0.5, 0.9))), f"pier_{k}", rng)
        placed += 1
    _anchorage(L, rng, int(rng.integers(1, 5)), CRUISERS, int(rng.integers(0, 3)), int(rng.random() < 0.4))
    return {"lots": lots, "piers": placed}


def marina(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(2, 5)), tree_r=(4, 8), setback=14.0, dirt=1)
    prom = float(rng.uniform(4.0, 8.0))
    L.paint(L.band_along_shore(-L.R, L.R, -0.5, prom), SIDEWALK, z=4)
    u_lo, u_hi = L.shore_span(8.0)
    # a rock breakwater closing one side of the basin
    side = 1 if rng.random() < 0.5 else -1
    bw_u = (u_hi - 10.0) if side > 0 else (u_lo + 10.0)
    bw_len = water_run(L, bw_u, 0.0, margin=0.0) * float(rng.uniform(0.5, 0.9))
    bw_w = float(rng.uniform(6, 11))
    if bw_len > 20:
        v0 = L.shore(bw_u)
        arm = LineString([(bw_u, v0 + 3), (bw_u + side * rng.uniform(-4, 4), v0 - bw_len)]).buffer(bw_w / 2)
        L.add_land(arm, ROCKS)
        L.paint(LineString([(bw_u, v0 + 3), (bw_u, v0 - bw_len + bw_w)]).buffer(1.2), SIDEWALK, z=4.5)
    for _try in range(6):
        length = float(min(rng.uniform(50, 95), S * 0.6))
        cu = float(rng.uniform(-0.2, 0.2) * S)
        depth = 34.0
        cv = L.shore(cu) + prom + float(rng.uniform(3, 8)) + depth / 2 + 2.0
        occ = float(rng.uniform(0.55, 0.95))
        if add_parking(L, rng, cu, cv, length, depth, float(rng.uniform(-3, 3)), occ, "lot_0") is not None:
            break
    _road(L, rng, prom + float(rng.uniform(48, 60)), float(rng.uniform(7, 9)), parking_p=0.4)
    # main walkways with fingers on both sides, a fairway between neighbours
    walk_w = float(rng.uniform(2.4, 3.2))
    lo = u_lo + (15.0 if side < 0 else 6.0) + (bw_w if side < 0 else 0.0)
    hi = u_hi - (15.0 if side > 0 else 6.0) - (bw_w if side > 0 else 0.0)
    u = lo + float(rng.uniform(8, 14))
    k = 0
    while u < hi - 8:
        finger_len = float(rng.uniform(7, 13))
        finger_w = float(rng.uniform(1.0, 1.5))
        # slips wide enough for the beam of boats as long as the fingers (beam ~ length / 3)
        pitch = finger_w + max(float(rng.uniform(3.4, 6.5)), 0.33 * finger_len + 1.2)
        u_c = u + finger_len + walk_w / 2
        if u_c + finger_len + walk_w / 2 > hi:
            break
        length = _fit_pier(L, rng, u_c, float(rng.uniform(40, 90)), 12.0, 0.0)
        if length > 0:
            add_pier(L, PierSpec(u_c, length, walk_w=walk_w, finger_len=finger_len, pitch=pitch,
                                 finger_w=finger_w, sides=(1, -1),
                                 head_len=float(rng.uniform(14, 26)) if rng.random() < 0.5 else 0.0,
                                 occupancy=float(rng.uniform(0.78, 0.97)),
                                 double_p=float(rng.uniform(0.2, 0.6)),
                                 bow_in_p=0.7), f"pier_{k}", rng)
            k += 1
        u = u_c + walk_w / 2 + finger_len + 1.5 * finger_len * float(rng.uniform(1.0, 1.4)) + 4.0
    _anchorage(L, rng, int(rng.integers(0, 3)), CRUISERS, int(rng.integers(1, 3)), int(rng.random() < 0.5),
               min_shore=20.0)
    return {"walkways": k, "breakwater": bw_len > 20}


def lake_harbor(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(5, 10)), tree_r=(7, 18), setback=4.0, dirt=3)
    u_lo, u_hi = L.shore_span(15.0)
    a = float(rng.uniform(u_lo, u_hi))
    L.paint(L.band_along_shore(a - rng.uniform(12, 22), a + rng.uniform(12, 22), -0.5,
                               float(rng.uniform(8, 15)), wobble=2.0), SAND, z=4)
    # boat ramp and its small parking lot
    ramp_u = float(np.clip(a + rng.choice([-1, 1]) * rng.uniform(30, 45), u_lo, u_hi))
    ramp_w = float(rng.uniform(4.5, 6.5))
    vr = L.shore(ramp_u)
    lot_depth = 17.0
    lot_len = float(rng.uniform(25, 45))
    lot_v = vr + float(rng.uniform(14, 20)) + lot_depth / 2
    lot = add_parking(L, rng, ramp_u + rng.uniform(-10, 10), lot_v, lot_len, lot_depth,
                      float(rng.uniform(-10, 10)), float(rng.uniform(0.3, 0.8)), "lot_0")
    L.paint(obox(ramp_u, (vr + lot_v) / 2 - 1.0, ramp_w, lot_v - vr + 2.0, 0.0), ASPHALT, z=5.5)
    _path(L, rng, (a, L.shore(a) + 6), (a + rng.uniform(-30, 30), L.shore(a) + 60),
          float(rng.uniform(1.2, 2.2)))
    placed, want = 0, int(rng.integers(1, 3))
    for _try in range(8):  # a harbour has at least one pier: retry where the shore does not allow one
        if placed >= want:
            break
        k = placed
        u0 = float(rng.uniform(u_lo + 10, u_hi - 10))
        if abs(u0 - ramp_u) < 12 or any(abs(u0 - o.u) < 25 for o in L.objects if o.category == "pier"):
            continue
        dev = float(rng.uniform(-12, 12))
        length = _fit_pier(L, rng, u0, float(rng.uniform(12, 28)), 6.0, dev)
        if length <= 0:
            continue
        _pier_root_pad(L, u0, 4.0, 4.0)
        add_pier(L, PierSpec(u0, length, walk_w=float(rng.uniform(1.5, 2.2)), angle_dev_deg=dev,
                             finger_len=float(rng.uniform(4.5, 7.0)), finger_w=float(rng.uniform(0.8, 1.1)),
                             pitch=float(rng.uniform(3.0, 4.2)),
                             sides=[(1, -1), (1,), (-1,)][int(rng.integers(0, 3))],
                             head_len=float(rng.uniform(6, 10)) if rng.random() < 0.3 else 0.0,
                             occupancy=float(rng.uniform(0.4, 0.85)), boat_types=LAKE_SLIP, double_p=0.5,
                             bow_in_p=0.5), f"pier_{k}", rng)
        placed += 1
    _anchorage(L, rng, int(rng.integers(2, 6)), ("dinghy", "runabout", "sailboat", "kayak"),
               int(rng.integers(1, 4)), int(rng.random() < 0.5), min_shore=10.0)
    return {"piers": placed, "lot": lot is not None}


def beach(L: Layout, rng: np.random.Generator, S: float) -> dict:
    L.paint(L.land, GRASS, z=0)
    sand_w = float(rng.uniform(18, 40))
    L.paint(L.band_along_shore(-L.R, L.R, -0.5, sand_w, wobble=3.0), SAND, z=4)
    dunes = _inland(L, sand_w, sand_w + 30)
    scatter_patches(L, rng, dunes, int(rng.integers(4, 9)), 4, 10, SAND, z=1)
    scatter_patches(L, rng, _inland(L, sand_w + 15), int(rng.integers(2, 6)), 6, 14, TREES, z=1.2)
    u_lo, u_hi = L.shore_span(10.0)
    for _ in range(int(rng.integers(2, 4))):
        u = float(rng.uniform(u_lo, u_hi))
        _path(L, rng, (u, L.shore(u) + sand_w * 0.6), (u + rng.uniform(-15, 15), L.shore(u) + sand_w + 45),
              float(rng.uniform(1.5, 3.0)), cls=DIRT, z=2)
    cu = float(rng.uniform(-0.2, 0.2) * S)
    cv = L.shore(cu) + sand_w + float(rng.uniform(12, 20)) + 17.0 / 2
    lot = add_parking(L, rng, cu, cv, float(min(rng.uniform(35, 70), S * 0.5)), 17.0,
                      float(rng.uniform(-5, 5)), float(rng.uniform(0.4, 0.95)), "lot_0")
    _road(L, rng, sand_w + float(rng.uniform(42, 55)), float(rng.uniform(7, 9)), parking_p=0.5)
    # a line of swim-area buoys offshore, parallel to the beach
    off = float(rng.uniform(25, 40))
    a, b = sorted(rng.uniform(u_lo, u_hi, 2))
    if b - a < 30:
        a, b = (a + b) / 2 - 20, (a + b) / 2 + 20
    spacing = float(rng.uniform(7, 12))
    for u in np.arange(a, b, spacing):
        add_buoy(L, rng, float(u), L.shore(float(u)) - off + rng.normal(0, 0.4), {"role": "swim_line"})
    # kayaks and dinghies close to the beach, bigger boats at anchor further out
    add_anchored(L, rng, int(rng.integers(1, 4)), float(rng.uniform(-180, 180)), SMALL, min_shore=6.0,
                 buoy_p=0.0)
    _anchorage(L, rng, int(rng.integers(2, 7)), CRUISERS, int(rng.integers(0, 3)), int(rng.random() < 0.5),
               min_shore=off + 12)
    return {"sand_width_m": sand_w, "lot": lot is not None, "swim_line_offset_m": off}


def rocky_shore(L: Layout, rng: np.random.Generator, S: float) -> dict:
    _base_land(L, rng, trees=int(rng.integers(4, 9)), tree_r=(6, 15), setback=6.0, dirt=3)
    rock_w = float(rng.uniform(4, 12))
    L.paint(L.band_along_shore(-L.R, L.R, -0.5, rock_w, wobble=2.5), ROCKS, z=4)
    scatter_patches(L, rng, _inland(L, rock_w, rock_w + 25), int(rng.integers(2, 6)), 2, 6, ROCKS, z=1.8)
    u_lo, u_hi = L.shore_span(15.0)
    groyne = False
    if rng.random() < 0.7:
        gu = float(rng.uniform(u_lo + 10, u_hi - 10))
        run = water_run(L, gu, 0.0, margin=0.0)
        g_len = min(float(rng.uniform(15, 35)), run * 0.6)
        if g_len > 8:
            v0 = L.shore(gu)
            L.add_land(LineString([(gu, v0 + 2), (gu + rng.uniform(-6, 6), v0 - g_len)])
                       .buffer(float(rng.uniform(2.5, 4.5))), ROCKS)
            groyne = True
    road = _road(L, rng, rock_w + float(rng.uniform(15, 35)), float(rng.uniform(6.5, 9.0)), parking_p=0.8)
    placed = 0
    if rng.random() < 0.6:
        u0 = float(rng.uniform(u_lo + 5, u_hi - 5))
        dev = float(rng.uniform(-10, 10))
        length = _fit_pier(L, rng, u0, float(rng.uniform(15, 30)), 8.0, dev)
        if length > 0:
            _pier_root_pad(L, u0, 5.0, rock_w + 2.0)
            add_pier(L, PierSpec(u0, length, walk_w=float(rng.uniform(1.8, 2.6)), angle_dev_deg=dev, sides=(),
                                 head_len=float(rng.uniform(8, 14)) if rng.random() < 0.5 else 0.0,
                                 occupancy=float(rng.uniform(0.3, 0.8))), "pier_0", rng)
            placed = 1
            if road is not None:
                _path(L, rng, (u0, L.shore(u0) + rock_w), (u0 + rng.uniform(-10, 10), road.coords[0][1]), 1.5)
    _anchorage(L, rng, int(rng.integers(2, 6)), CRUISERS, int(rng.integers(1, 4)), int(rng.random() < 0.4),
               min_shore=18.0)
    return {"rock_width_m": rock_w, "groyne": groyne, "piers": placed}


# name -> (builder, size range (m), land setback v0 as a fraction of S, shore amplitude (m), wavelength (m),
#          terrain overrides)
Range = tuple[float, float]
PresetDef = tuple[Callable[[Layout, np.random.Generator, float], dict], Range, Range, Range, Range, dict]

PRESET_DEFS: dict[str, PresetDef] = {
    "simple_pier_a": (simple_pier_a, (120, 150), (0.06, 0.2), (1.5, 5.0), (70, 140), {}),
    "simple_pier_b": (simple_pier_b, (120, 160), (0.05, 0.18), (0.0, 0.8), (120, 200), {}),
    "pier_parking": (pier_parking, (150, 190), (0.05, 0.15), (0.5, 2.5), (120, 220), {}),
    "marina": (marina, (170, 220), (0.1, 0.2), (0.0, 0.5), (150, 250), {}),
    "lake_harbor": (lake_harbor, (150, 200), (0.0, 0.15), (6.0, 14.0), (90, 180),
                    {"max_depth_m": (3.0, 7.0), "depth_scale_m": (20.0, 50.0)}),
    "beach": (beach, (150, 200), (0.05, 0.2), (2.0, 8.0), (120, 250), {"max_depth_m": (4.0, 9.0)}),
    "rocky_shore": (rocky_shore, (130, 180), (0.0, 0.15), (4.0, 10.0), (40, 90), {}),
}


def build_layout(preset: str, rng: np.random.Generator, catalog: dict[str, AssetDims],
                 size_m: float | None = None,
                 mix: Mix = BENCHMARK_MIX) -> tuple[Layout, TruthTerrainParams, dict]:
    """Lay out one level: returns the layout (local frame), its truth-terrain parameters and the
    drawn level parameters (for the provenance)."""
    fn, size_rng, v0_rng, amp_rng, wl_rng, terr = PRESET_DEFS[preset]
    S = even(size_m if size_m is not None else rng.uniform(*size_rng))
    theta = float(rng.uniform(-180, 180))
    v0 = float(rng.uniform(*v0_rng) * S)
    amp, wl = float(rng.uniform(*amp_rng)), float(rng.uniform(*wl_rng))
    slope = float(rng.uniform(-0.05, 0.05))
    us, vs = shore_curve(rng, S * 0.8, v0, amp, wl, slope)
    L = Layout(S, theta, us, vs, catalog, rng, mix)
    tp = terrain_params(rng, **{k: float(rng.uniform(*v)) for k, v in terr.items()})
    info = {"size_m": S, "rotation_deg": theta, "shore_offset_m": v0, "shore_amplitude_m": amp,
            "shore_wavelength_m": wl, **fn(L, rng, S)}
    return L, tp, info
