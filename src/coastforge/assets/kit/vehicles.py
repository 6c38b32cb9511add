"""The kit's vehicles: cars from one parametric body, vans, a bus, a box truck."""

from __future__ import annotations

import numpy as np

from .shapes import (BLACK, DARK_GREY, GLASS, HEAD_LAMP, MID_GREY, TAIL_LAMP, Colour, Model, at_z, band, box,
                     cylinder, loft, rect, rrect)


def _car(m: Model, paint: Colour, *, L, W, body_top, roof_z, gh_x, roof_x, chamfer=0.25, belt_inset=0.1,
         roof_inset=0.2, wheel_r=0.33, wheelbase=2.7, clearance=0.18, rear_lamps=True) -> None:
    """A car: chamfered lower body (hood and trunk in paint), dark-glass greenhouse whose windscreen
    (front) is longer than the rear window, painted roof, wheels, head and tail lamps."""
    x0, x1 = -L / 2, L / 2
    bottom = rrect(x0 + 0.1, x1 - 0.1, W - 0.1, chamfer)
    mid = rrect(x0, x1, W, chamfer)
    top = rrect(x0 + 0.05, x1 - 0.12, W - 0.06, chamfer)
    m.add(loft([at_z(bottom, clearance), at_z(mid, clearance + 0.3), at_z(top, body_top)]), paint)
    belt = rrect(gh_x[0], gh_x[1], W - 2 * belt_inset, 0.15)
    roof = rrect(roof_x[0], roof_x[1], W - 2 * roof_inset, 0.12)
    m.add(loft([at_z(belt, body_top), at_z(roof, roof_z - 0.04)], bottom=False, top=False), GLASS)
    m.add(loft([at_z(roof, roof_z - 0.04), at_z(roof, roof_z)], bottom=False), paint)
    for sx in (-1, 1):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.16)
            m.add(cylinder([sx * wheelbase / 2, y - 0.11, wheel_r], [sx * wheelbase / 2, y + 0.11, wheel_r],
                           wheel_r, 10), BLACK)
            lamp_x = x1 - 0.2 if sx > 0 else x0 + 0.08
            colour = HEAD_LAMP if sx > 0 else TAIL_LAMP
            if sx < 0 and not rear_lamps:
                continue
            m.add(box(lamp_x, lamp_x + 0.1, sy * (W / 2 - 0.3) - 0.14, sy * (W / 2 - 0.3) + 0.14,
                      body_top - 0.15, body_top + 0.01), colour)


def build_sedan() -> Model:
    m = Model()
    _car(m, ((165, 25, 32), "paint"), L=4.6, W=1.82, body_top=0.82, roof_z=1.45, gh_x=(-1.25, 0.95),
         roof_x=(-0.85, 0.2))
    return m


def build_suv() -> Model:
    m = Model()
    _car(m, ((32, 48, 92), "paint"), L=4.8, W=1.95, body_top=1.05, roof_z=1.8, gh_x=(-2.15, 0.95),
         roof_x=(-2.05, 0.35), wheel_r=0.38, wheelbase=2.85, clearance=0.25, chamfer=0.2)
    m.add(box(-1.7, 0.1, -0.75, -0.7, 1.8, 1.86), BLACK)  # roof rails
    m.add(box(-1.7, 0.1, 0.7, 0.75, 1.8, 1.86), BLACK)
    return m


def build_pickup() -> Model:
    m = Model()
    paint = ((175, 178, 183), "paint")
    L, W = 5.5, 2.0
    _car(m, paint, L=L, W=W, body_top=1.0, roof_z=1.85, gh_x=(-0.75, 1.05), roof_x=(-0.7, 0.45),
         wheel_r=0.39, wheelbase=3.4, clearance=0.26, chamfer=0.15)
    # open bed: black liner floor, painted walls, tailgate
    bx0, bx1 = -L / 2 + 0.08, -0.85
    m.add(box(bx0 + 0.08, bx1 - 0.05, -W / 2 + 0.12, W / 2 - 0.12, 1.0, 1.02), BLACK)
    outer = rect(bx0, bx1, -W / 2 + 0.03, W / 2 - 0.03)
    inner = rect(bx0 + 0.07, bx1 - 0.07, -W / 2 + 0.1, W / 2 - 0.1)
    m.add(band(outer, inner, 1.0, 1.3), paint)
    return m


def build_van() -> Model:
    m = Model()
    paint = ((240, 240, 238), "paint")
    L, W = 5.2, 2.0
    x0, x1 = -L / 2, L / 2
    m.add(loft([at_z(rrect(x0 + 0.05, x1 - 0.1, W - 0.08, 0.15), 0.22),
                at_z(rrect(x0, x1, W, 0.2), 0.55), at_z(rrect(x0, x1 - 0.05, W - 0.04, 0.25), 1.1)]), paint)
    # boxy cargo body behind a short, steep windscreen
    cargo = [at_z(rrect(x0, 1.55, W - 0.04, 0.12), 1.1), at_z(rrect(x0, 1.5, W - 0.1, 0.12), 2.3)]
    m.add(loft(cargo), paint)
    ws0 = rrect(1.45, 2.2, W - 0.16, 0.15)
    ws1 = rrect(1.45, 1.6, W - 0.2, 0.05)
    m.add(loft([at_z(ws0, 1.1), at_z(ws1, 2.12)]), GLASS)
    m.add(box(-0.8, 0.2, -0.35, 0.35, 2.3, 2.34), MID_GREY)  # roof vent
    for sx in (-1.65, 1.6):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.16)
            m.add(cylinder([sx, y - 0.11, 0.36], [sx, y + 0.11, 0.36], 0.36, 10), BLACK)
    for sy in (-1, 1):
        m.add(box(2.42, 2.52, sy * 0.7 - 0.14, sy * 0.7 + 0.14, 0.95, 1.11), ((245, 240, 215), "glass"))
        m.add(box(x0 + 0.02, x0 + 0.1, sy * 0.88 - 0.06, sy * 0.88 + 0.06, 1.2, 2.0), TAIL_LAMP)
    return m


def build_bus() -> Model:
    m = Model()
    yellow = ((240, 185, 25), "paint")
    L, W = 12.0, 2.55
    x0, x1 = -L / 2, L / 2
    def ring(zz, front):
        return at_z(rrect(x0 + 0.05, front, W - 0.02, 0.2), zz)
    m.add(loft([at_z(rrect(x0 + 0.2, x1 - 0.2, W - 0.1, 0.2), 0.3), ring(0.6, x1), ring(1.2, x1)],
               top=False), yellow)
    # raked windscreen: its dark glass shows from above at the front only
    m.add(loft([ring(1.2, x1), ring(2.55, x1 - 0.5)], bottom=False, top=False), GLASS)
    m.add(loft([ring(2.55, x1 - 0.5), ring(2.95, x1 - 0.62)], bottom=False), yellow)
    m.add(box(-2.0, 0.6, -0.8, 0.8, 2.95, 3.2), MID_GREY)  # roof air conditioning
    m.add(box(-4.8, -3.8, -0.5, 0.5, 2.95, 3.05), DARK_GREY)  # roof hatch
    for sx in (-3.4, 3.4):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.2)
            m.add(cylinder([sx, y - 0.14, 0.5], [sx, y + 0.14, 0.5], 0.5, 10), BLACK)
    return m


def build_hatchback() -> Model:
    m = Model()
    _car(m, ((40, 105, 70), "paint"), L=4.05, W=1.76, body_top=0.85, roof_z=1.48, gh_x=(-1.95, 0.75),
         roof_x=(-1.75, 0.05), wheelbase=2.55, chamfer=0.22)
    return m


def build_box_truck() -> Model:
    m = Model()
    cab_paint = ((170, 30, 30), "paint")
    box_paint = ((226, 226, 220), "paint")
    L, W = 7.5, 2.45
    x0, x1 = -L / 2, L / 2
    m.add(box(x0 + 0.3, x1 - 0.3, -0.6, 0.6, 0.45, 0.9), DARK_GREY)  # chassis
    # cab: short hood, raked windscreen, roof
    def cab(front, width, c, z):
        return at_z(rrect(1.9, front, width, c), z)
    m.add(loft([cab(x1, W - 0.15, 0.2, 0.55), cab(x1, W - 0.1, 0.25, 1.45)]), cab_paint)
    screen_top = cab(x1 - 0.65, W - 0.25, 0.15, 2.45)
    m.add(loft([cab(x1 - 0.15, W - 0.12, 0.2, 1.45), screen_top], top=False), GLASS)
    m.add(loft([screen_top, cab(x1 - 0.75, W - 0.3, 0.15, 2.6)], bottom=False), cab_paint)
    # the cargo box with roof ribs
    m.add(box(x0, 1.8, -W / 2, W / 2, 0.95, 3.4), box_paint)
    for x in np.linspace(x0 + 0.6, 1.2, 5):
        m.add(box(x - 0.04, x + 0.04, -W / 2 + 0.05, W / 2 - 0.05, 3.4, 3.43), ((200, 200, 195), "paint"))
    for sx in (-2.2, -1.1, 2.8):
        for sy in (-1, 1):
            y = sy * (W / 2 - 0.2)
            m.add(cylinder([sx, y - 0.14, 0.45], [sx, y + 0.14, 0.45], 0.45, 10), BLACK)
    for sy in (-1, 1):
        m.add(box(x1 - 0.12, x1 - 0.02, sy * 0.9 - 0.15, sy * 0.9 + 0.15, 1.2, 1.46), HEAD_LAMP)
    return m
