"""The kit's boats, from a dinghy to a motor yacht: hulls lofted from deck outlines, superstructure tiers."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .shapes import (ANTIFOUL_BLUE, ANTIFOUL_RED, BLACK, CREAM, CUSHION, DARK_GREY, GLASS, MID_GREY, OAR,
                     OFFWHITE, STEEL, TEAK, WHITE, Colour, Model, at_z, band, box, cabin_ring, cap, circle,
                     cylinder, ellipsoid, hull_ring, loft, rect, rrect, sweep)


def _hull(m: Model, length: float, beam: float, x_stern: float, freeboard: float, draft: float,
          hull: Colour, deck: Colour | None, bottom: Colour, *, shoulder=0.5, bow_power=1.8, transom=0.85,
          keel_beam=0.2, y0: float = 0.0, deck_cap: bool = True) -> np.ndarray:
    """A hull: bottom (keel to waterline) in antifouling, topsides, a deck cap; returns the sheer ring."""
    kw = dict(shoulder=shoulder, bow_power=bow_power, transom=transom, y0=y0)
    keel = hull_ring(length * 0.86, beam * keel_beam, x_stern + length * 0.03, **kw)
    wl = hull_ring(length * 0.95, beam * 0.88, x_stern + length * 0.01, **kw)
    sheer = hull_ring(length, beam, x_stern, **kw)
    m.add(loft([at_z(keel, -draft), at_z(wl, 0.0)], bottom=True, top=False), bottom)
    m.add(loft([at_z(wl, 0.0), at_z(sheer, freeboard)], bottom=False, top=False), hull)
    if deck_cap:
        m.add(cap(at_z(sheer, freeboard)), deck if deck is not None else hull)
    return sheer


def _gunwale(m: Model, length, beam, x_stern, z, width, height, colour, **kw) -> None:
    outer = hull_ring(length, beam, x_stern, **kw)
    inner = hull_ring(length - 2.2 * width, beam - 2 * width, x_stern + width, **kw)
    m.add(band(outer, inner, z, z + height), colour)


def _tier(m: Model, x0, x1, width, z0, bands: Sequence[tuple[float, Colour]], slope=0.0, inset=0.0,
          chamfer=0.0, nose=0.4, roof: Colour | None = None, y0: float = 0.0) -> float:
    """A superstructure tier: stacked coloured bands (hull-white, window-dark, ...) with a raked front;
    returns the roof height."""
    z = z0
    def ring(zz):
        dz = zz - z0
        r = cabin_ring(x0 + inset * dz, x1 - slope * dz, width - 2 * inset * dz, chamfer, nose)
        r[:, 1] += y0
        return at_z(r, zz)
    for i, (h, colour) in enumerate(bands):
        last = i == len(bands) - 1
        m.add(loft([ring(z), ring(z + h)], bottom=(i == 0), top=last and roof is None), colour)
        z += h
    if roof is not None:
        m.add(cap(ring(z)), roof)
    return z


def build_dinghy() -> Model:
    m = Model()
    grey, orange = ((128, 132, 136), "rubber"), ((235, 105, 25), "rubber")
    r, half = 0.23, 0.55  # tube radius, tube centreline half-width
    zc = 0.16  # tube centre above the waterline
    # side tubes (grey) from the stern to the start of the bow curve, bow curve orange
    sx, bx, a = -1.22, 0.0, 1.3
    m.add(sweep(np.array([[sx, -half, zc], [bx, -half, zc]]), r, 10), grey)
    m.add(sweep(np.array([[bx, half, zc], [sx, half, zc]]), r, 10), grey)
    # the bow tubes converge to a point (taper like a hull: half-width = 1 - u^1.6 along the bow)
    s = np.sin(np.linspace(-np.pi / 2, np.pi / 2, 13))
    u = (1 - np.abs(s)) ** (1 / 1.6)
    bow = np.column_stack([bx + a * u, half * s, zc + 0.12 * u])
    m.add(sweep(bow, r, 10), orange)
    # floor between the tubes and the transom board
    m.add(loft([at_z(hull_ring(2.2, 2 * half, sx, shoulder=0.62, bow_power=2.2, transom=1.0), -0.12),
                at_z(hull_ring(2.35, 2 * half, sx, shoulder=0.62, bow_power=2.2, transom=1.0), 0.0)]),
          DARK_GREY)
    m.add(box(sx - 0.04, sx + 0.06, -half, half, -0.1, 0.36), MID_GREY)
    # outboard motor on the transom: cowling, shaft, skeg below the water
    m.add(box(sx - 0.36, sx - 0.04, -0.17, 0.17, 0.22, 0.62), BLACK)
    m.add(box(sx - 0.24, sx - 0.12, -0.05, 0.05, -0.32, 0.22), DARK_GREY)
    # thwart (seat) and a fuel tank: deck detail seen from above
    m.add(box(-0.25, 0.05, -half, half, 0.2, 0.26), MID_GREY)
    m.add(box(-1.0, -0.7, -0.2, 0.12, 0.0, 0.22), ((200, 30, 30), "paint"))
    return m


def build_kayak() -> Model:
    m = Model()
    yellow, red = ((250, 200, 20), "paint"), ((215, 50, 30), "paint")
    L, B = 4.0, 0.62
    kw = dict(shoulder=0.45, bow_power=1.5, transom=0.32)
    x0 = -L / 2
    keel = hull_ring(L * 0.9, B * 0.35, x0 + L * 0.05, **kw)
    wl = hull_ring(L * 0.96, B * 0.92, x0 + L * 0.02, **kw)
    sheer = hull_ring(L, B, x0, **kw)
    ridge = hull_ring(L * 0.9, B * 0.45, x0 + L * 0.05, **kw)
    m.add(loft([at_z(keel, -0.13), at_z(wl, 0.0)], top=False), yellow)
    m.add(loft([at_z(wl, 0.0), at_z(sheer, 0.2)], bottom=False, top=False), yellow)
    m.add(loft([at_z(sheer, 0.2), at_z(ridge, 0.3)], bottom=False, top=True), yellow)
    # cockpit aft of centre: black coaming, dark seat; deck lines and a red stern hatch
    ck = circle(-0.25, 0.0, 1.0, 12)
    outer = ck * [0.48, 0.25] + [-0.25 * 0.52, 0]
    inner = ck * [0.40, 0.19] + [-0.25 * 0.6, 0]
    m.add(band(outer, inner, 0.26, 0.36), BLACK)
    m.add(cap(at_z(inner, 0.33)), DARK_GREY)
    m.add(loft([at_z(circle(-1.05, 0, 0.14, 10), 0.28), at_z(circle(-1.05, 0, 0.14, 10), 0.34)]), red)
    m.add(loft([at_z(circle(0.95, 0, 0.12, 10), 0.28), at_z(circle(0.95, 0, 0.12, 10), 0.34)]), red)
    m.add(box(0.45, 1.6, -0.01, 0.01, 0.3, 0.33), BLACK)  # bungee line on the fore deck
    m.add(box(-1.98, -1.86, -0.015, 0.015, -0.22, 0.22), BLACK)  # rudder blade at the stern
    return m


def build_runabout() -> Model:
    m = Model()
    red = ((200, 30, 40), "paint")
    L, B, fb, d = 5.6, 2.4, 0.85, 0.42
    xs = -2.6
    kw = dict(shoulder=0.42, bow_power=1.6, transom=0.9)
    _hull(m, L, B, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, **kw)
    # coloured stripe: a red band on the topsides just under the sheer, and a red rub rail
    sheer_lo = hull_ring(L * 0.995, B * 1.005, xs + 0.01, **kw)
    sheer_hi = hull_ring(L * 1.0, B * 1.01, xs, **kw)
    m.add(loft([at_z(sheer_lo, fb - 0.35), at_z(sheer_hi, fb - 0.15)]), red)
    _gunwale(m, L, B, xs, fb, 0.12, 0.06, red, **kw)
    # cockpit floor (light grey) aft of the windscreen, bench seats, console
    m.add(box(xs + 0.2, 0.9, -0.95, 0.95, fb, fb + 0.02), ((190, 190, 185), "matte"))
    m.add(box(xs + 0.25, xs + 0.85, -1.0, 1.0, fb, fb + 0.45), ((210, 200, 180), "matte"))  # stern bench
    m.add(box(-0.7, -0.15, -0.85, -0.25, fb, fb + 0.5), ((210, 200, 180), "matte"))  # helm seat
    m.add(box(-0.7, -0.15, 0.25, 0.85, fb, fb + 0.5), ((210, 200, 180), "matte"))
    m.add(box(0.1, 0.75, -0.9, -0.2, fb, fb + 0.7), WHITE)  # console
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
        m.add(loft([at_z(ring, fb), at_z(ring - [0.25, 0], fb + 0.45)]), GLASS)
    # outboard engine aft of the transom
    m.add(box(xs - 0.42, xs - 0.02, -0.28, 0.28, 0.35, 1.1), ((30, 30, 32), "paint"))
    m.add(box(xs - 0.3, xs - 0.12, -0.06, 0.06, -0.55, 0.35), DARK_GREY)
    # bow cleat and a sun pad on the fore deck
    m.add(box(1.6, 2.4, -0.55, 0.55, fb, fb + 0.08), ((210, 200, 180), "matte"))
    m.add(box(2.7, 2.85, -0.04, 0.04, fb, fb + 0.06), STEEL)
    return m


def build_cabin_cruiser() -> Model:
    m = Model()
    navy = ((25, 45, 95), "paint")
    L, B, fb, d = 9.5, 3.5, 1.3, 0.9
    xs = -4.5
    kw = dict(shoulder=0.45, bow_power=1.7, transom=0.9)
    _hull(m, L, B, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.14, 0.25, navy, **kw)
    # swim platform (teak) aft of the transom
    m.add(box(-5.0, xs + 0.02, -1.4, 1.4, 0.3, 0.4), TEAK)
    # cockpit (teak) aft, cabin superstructure amidships with raked dark windscreen
    m.add(box(xs + 0.2, -1.5, -1.5, 1.5, fb, fb + 0.02), TEAK)
    top = _tier(m, -1.5, 2.9, 2.9, fb, [(0.6, WHITE), (0.55, GLASS), (0.2, WHITE)], slope=0.9, inset=0.12,
                chamfer=0.9, nose=0.45, roof=OFFWHITE)
    # radar arch / mast on the roof and a fore-deck hatch
    m.add(box(-0.9, -0.6, -0.9, 0.9, top, top + 0.35), WHITE)
    m.add(cylinder([-0.75, 0, top + 0.35], [-0.75, 0, top + 0.8], 0.05, 6), STEEL)
    m.add(box(3.3, 3.9, -0.35, 0.35, fb, fb + 0.1), ((150, 160, 170), "glass"))
    # cockpit bench across the stern
    m.add(box(xs + 0.3, xs + 0.8, -1.4, 1.4, fb, fb + 0.45), ((215, 205, 185), "matte"))
    return m


def build_sailboat() -> Model:
    m = Model()
    navy = ((20, 35, 80), "paint")
    blue = ((30, 80, 160), "matte")
    L, B, fb, d = 9.0, 3.0, 1.0, 0.45
    xs = -4.5
    kw = dict(shoulder=0.4, bow_power=1.5, transom=0.8)
    _hull(m, L, B, xs, fb, d, navy, CREAM, ANTIFOUL_RED, **kw)
    _gunwale(m, L, B, xs, fb, 0.1, 0.08, navy, **kw)
    # fin keel and rudder below the canoe body
    fin = [at_z(rect(-0.5, 0.6, -0.1, 0.1), -1.7), at_z(rect(-0.8, 0.9, -0.12, 0.12), -0.3)]
    m.add(loft(fin), ANTIFOUL_RED)
    m.add(box(-4.0, -3.6, -0.04, 0.04, -1.2, -0.2), ANTIFOUL_RED)
    # cockpit: teak sole with white coamings, a wheel
    cockpit = rrect(-4.25, -1.2, 1.9, 0.2)
    inner = rrect(-4.15, -1.3, 1.7, 0.15)
    m.add(cap(at_z(cockpit, fb + 0.01)), TEAK)
    m.add(band(cockpit, inner, fb, fb + 0.3), WHITE)
    m.add(box(-3.6, -3.5, -0.45, 0.45, fb, fb + 0.9), BLACK)
    # cabin trunk with dark ports and a hatch
    top = _tier(m, -1.2, 2.2, 2.0, fb, [(0.25, CREAM), (0.12, GLASS), (0.12, CREAM)], slope=0.35, inset=0.1,
                chamfer=0.8, nose=0.5, roof=WHITE)
    m.add(box(0.8, 1.3, -0.3, 0.3, top, top + 0.06), ((120, 140, 160), "glass"))
    # mast, boom with a blue sail cover, forestay region pulpit
    mx = 1.2
    m.add(cylinder([mx, 0, top], [mx, 0, fb + 12.5], 0.09, 8), STEEL)
    bz = top + 1.1
    m.add(cylinder([mx, 0, bz], [-3.3, 0, bz], 0.06, 6), STEEL)
    m.add(sweep(np.array([[mx - 0.1, 0, bz + 0.15], [0.0, 0, bz + 0.2], [-3.2, 0, bz + 0.12]]),
                np.array([0.2, 0.22, 0.12]), 8), blue)
    m.add(cylinder([3.8, 0, fb + 0.05], [4.35, 0, fb + 0.05], 0.04, 6), STEEL)  # bow roller/pulpit
    return m


def build_catamaran() -> Model:
    m = Model()
    L, hb, fb, d = 12.0, 1.4, 1.2, 0.7
    xs = -6.0
    kw = dict(shoulder=0.55, bow_power=1.6, transom=0.85, keel_beam=0.25)
    yh = 2.4
    for sgn in (-1, 1):
        _hull(m, L, hb, xs, fb, d, WHITE, WHITE, ANTIFOUL_BLUE, y0=sgn * yh, **kw)
    # bridge deck aft, trampoline (dark net) forward, saloon with dark windows, mast and boom
    m.add(box(-5.6, 1.8, -yh, yh, fb - 0.25, fb + 0.05), WHITE)
    m.add(box(1.8, 3.9, -yh + 0.5, yh - 0.5, fb - 0.05, fb), ((45, 48, 52), "matte"))
    m.add(box(3.85, 4.05, -yh, yh, fb - 0.15, fb + 0.05), WHITE)  # front beam
    m.add(box(-5.6, -3.0, -1.8, 1.8, fb + 0.05, fb + 0.07), ((190, 190, 185), "matte"))  # cockpit sole
    top = _tier(m, -3.0, 1.6, 4.6, fb + 0.05, [(0.6, WHITE), (0.6, GLASS), (0.15, WHITE)], slope=0.6,
                inset=0.15, chamfer=0.8, nose=0.6, roof=OFFWHITE)
    mx = 1.4
    m.add(cylinder([mx, 0, top], [mx, 0, 17.0], 0.11, 8), STEEL)
    bz = top + 0.5
    m.add(cylinder([mx, 0, bz], [-5.0, 0, bz], 0.07, 6), STEEL)
    m.add(sweep(np.array([[mx - 0.1, 0, bz + 0.15], [-1.5, 0, bz + 0.2], [-4.8, 0, bz + 0.12]]),
                np.array([0.2, 0.24, 0.12]), 8), ((200, 200, 195), "matte"))
    return m


def build_yacht() -> Model:
    m = Model()
    L, B, fb, d = 17.2, 5.0, 2.0, 1.4
    xs = -8.2
    kw = dict(shoulder=0.45, bow_power=1.7, transom=0.92)
    _hull(m, L, B, xs, fb, d, ((28, 35, 55), "paint"), WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.15, 0.7, WHITE, **kw)  # bulwark
    m.add(box(-9.0, xs + 0.02, -2.2, 2.2, 0.3, 0.45), TEAK)  # swim platform
    m.add(box(xs + 0.2, -4.5, -2.3, 2.3, fb, fb + 0.02), TEAK)  # aft deck
    # main deck saloon, then the flybridge tier, hardtop; dark window bands and raked windscreens
    z1 = _tier(m, -4.5, 4.5, 4.2, fb, [(0.9, WHITE), (0.95, GLASS), (0.35, WHITE)], slope=0.9, inset=0.08,
               chamfer=1.6, nose=0.45, roof=WHITE)
    z2 = _tier(m, -2.6, 2.4, 3.6, z1, [(0.25, WHITE), (0.75, GLASS), (0.2, WHITE)], slope=1.0, inset=0.1,
               chamfer=1.2, nose=0.5, roof=OFFWHITE)
    m.add(box(-1.2, 0.2, -1.2, 1.2, z2, z2 + 0.3), MID_GREY)  # radar arch base
    m.add(ellipsoid([-0.5, 0, z2 + 0.5], [0.35, 0.35, 0.25], 3, 8), WHITE)  # radome
    # fore-deck sun pads and a tender on the aft deck roof overhang
    m.add(box(5.0, 6.6, -1.2, 1.2, fb, fb + 0.18), ((215, 205, 180), "matte"))
    m.add(box(7.5, 7.8, -0.1, 0.1, fb, fb + 0.15), STEEL)  # anchor windlass
    return m


def build_fishing_boat() -> Model:
    m = Model()
    blue = ((28, 70, 150), "paint")
    L, B, fb, d = 12.0, 4.2, 1.4, 1.3
    xs = -6.0
    kw = dict(shoulder=0.5, bow_power=1.5, transom=0.95)
    _hull(m, L, B, xs, fb, d, blue, ((105, 110, 105), "matte"), ANTIFOUL_RED, **kw)
    _gunwale(m, L, B, xs, fb, 0.16, 0.85, blue, **kw)  # bulwarks: a blue outline from above
    # wheelhouse forward: white, dark window band, orange roof with a mast and radar
    z = _tier(m, 0.8, 4.2, 3.0, fb, [(1.1, WHITE), (0.8, GLASS), (0.25, WHITE)], slope=0.3, inset=0.05,
              chamfer=0.6, nose=0.6, roof=((235, 110, 30), "paint"))
    m.add(cylinder([2.0, 0, z], [2.0, 0, z + 2.2], 0.08, 6), STEEL)
    m.add(box(1.55, 2.45, -0.1, 0.1, z + 1.6, z + 1.7), DARK_GREY)  # radar scanner
    # work deck aft: net drum, fish boxes, a stern gantry
    m.add(cylinder([-1.5, -1.3, fb + 0.65], [-1.5, 1.3, fb + 0.65], 0.65, 10), ((40, 110, 60), "matte"))
    orange = ((240, 130, 20), "matte")
    for i, (x, y) in enumerate([(-3.6, -1.2), (-3.6, -0.55), (-4.3, -1.2), (0.0, 1.2), (-0.6, 1.2)]):
        m.add(box(x, x + 0.6, y, y + 0.45, fb, fb + 0.35 + 0.3 * (i % 2)), orange)
    yellow = ((240, 200, 30), "paint")
    for sgn in (-1, 1):
        m.add(cylinder([-5.6, sgn * 1.7, fb], [-5.3, sgn * 1.5, fb + 3.0], 0.1, 6), yellow)
    m.add(cylinder([-5.3, -1.6, fb + 3.0], [-5.3, 1.6, fb + 3.0], 0.1, 6), yellow)
    return m


def build_rowboat() -> Model:
    m = Model()
    wood = ((128, 84, 50), "matte")
    green = ((70, 120, 95), "paint")
    L, B, fb, d = 3.6, 1.4, 0.45, 0.2
    xs = -L / 2
    kw = dict(shoulder=0.45, bow_power=1.5, transom=0.75)
    _hull(m, L, B, xs, fb, d, wood, green, ((60, 45, 35), "matte"), **kw)  # open boat: painted interior
    _gunwale(m, L, B, xs, fb, 0.07, 0.05, wood, **kw)
    for x0 in (-1.35, -0.3, 0.7):  # thwarts (seats)
        half = 0.5 if x0 < 0.5 else 0.42
        m.add(box(x0, x0 + 0.22, -half, half, fb - 0.02, fb + 0.04), wood)
    # a pair of oars shipped along the sides
    for sgn in (-1, 1):
        m.add(cylinder([-1.3, sgn * 0.5, fb + 0.08], [1.0, sgn * 0.55, fb + 0.08], 0.03, 6), OAR)
    return m


def build_center_console() -> Model:
    m = Model()
    hull = ((150, 190, 215), "paint")
    canvas = ((28, 48, 92), "matte")
    L, B, fb, d = 6.9, 2.6, 1.0, 0.5
    xs = -3.1
    kw = dict(shoulder=0.4, bow_power=1.5, transom=0.9)
    _hull(m, L, B, xs, fb, d, hull, WHITE, ANTIFOUL_BLUE, **kw)
    _gunwale(m, L, B, xs, fb, 0.12, 0.12, WHITE, **kw)
    m.add(box(xs + 0.2, 2.2, -1.05, 1.05, fb, fb + 0.02), ((200, 200, 195), "matte"))  # non-skid sole
    m.add(box(-0.6, 0.6, -0.45, 0.45, fb, fb + 1.05), WHITE)  # console
    screen = [at_z(rect(0.45, 0.75, -0.45, 0.45), fb + 1.05), at_z(rect(0.35, 0.5, -0.42, 0.42), fb + 1.45)]
    m.add(loft(screen), GLASS)
    for x in (-0.9, 0.7):  # T-top frame and canvas
        for y in (-0.55, 0.55):
            m.add(cylinder([x, y, fb], [x, y, fb + 2.15], 0.03, 6), STEEL)
    m.add(box(-1.1, 0.9, -0.95, 0.95, fb + 2.15, fb + 2.25), canvas)
    m.add(box(xs + 0.3, xs + 0.8, -1.1, 1.1, fb, fb + 0.45), CUSHION)  # leaning post / bench
    m.add(box(2.0, 2.9, -0.75, 0.75, fb, fb + 0.35), CUSHION)  # bow seating
    for y in (-0.45, 0.45):  # twin outboards
        m.add(box(xs - 0.45, xs - 0.02, y - 0.27, y + 0.27, 0.4, 1.2), BLACK)
        m.add(box(xs - 0.32, xs - 0.14, y - 0.06, y + 0.06, -0.6, 0.4), DARK_GREY)
    return m
