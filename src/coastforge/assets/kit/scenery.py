"""The kit's pier segments, buoys and vegetation (trees, bushes, rocks, grass, seaweed)."""

from __future__ import annotations

import math

import numpy as np

from ...rng import stage_rng
from .shapes import (DECIMALS, STEEL, WHITE, Model, at_z, box, circle, convex, cylinder, ellipsoid,
                     loft, sweep)

_KIT_SEED = 20261122  # the kit is a fixed artefact: one seed for its rocks and foliage jitter


# pier segments (modular along +x: piles every 2.5 m / 2 m continue across segment joints)
def _pier(length: float, width: float, pile_pitch: float, pile_r: float, seed_name: str) -> Model:
    m = Model()
    rng = stage_rng(_KIT_SEED, "kit", seed_name)
    deck_top, plank_t = 0.6, 0.05
    shades = [((152, 118, 82), "matte"), ((140, 106, 72), "matte"), ((163, 130, 92), "matte")]
    n_planks = int(round(length / 0.225))
    pitch = length / n_planks
    for i in range(n_planks):
        x = -length / 2 + i * pitch
        m.add(box(x + 0.012, x + pitch - 0.012, -width / 2, width / 2, deck_top - plank_t, deck_top),
              shades[int(rng.integers(0, len(shades)))])
    timber = ((95, 75, 55), "matte")
    wet = ((70, 58, 46), "matte")
    for y in np.linspace(-width / 2 + 0.15, width / 2 - 0.15, 3 if width > 2 else 2):
        m.add(box(-length / 2, length / 2, y - 0.06, y + 0.06, deck_top - plank_t - 0.2, deck_top - plank_t),
              timber)
    n_piles = int(round(length / pile_pitch))
    for i in range(n_piles):
        x = -length / 2 + (i + 0.5) * pile_pitch
        cap_top = deck_top - plank_t - 0.2  # pile cap beam under the stringers
        m.add(box(x - 0.1, x + 0.1, -width / 2, width / 2, cap_top - 0.2, cap_top), timber)
        for y in (-width / 2 + pile_r + 0.02, width / 2 - pile_r - 0.02):
            m.add(cylinder([x, y, -2.0], [x, y, deck_top - plank_t - 0.2], pile_r, 8), wet)
    return m


def build_pier_walkway() -> Model:
    return _pier(10.0, 2.5, 2.5, 0.16, "pier_walkway")


def build_pier_finger() -> Model:
    m = _pier(8.0, 1.2, 2.0, 0.12, "pier_finger")
    for x in (-3.0, 0.0, 3.0):  # mooring cleats along both edges
        for y in (-0.5, 0.5):
            m.add(box(x - 0.15, x + 0.15, y - 0.04, y + 0.04, 0.6, 0.7), STEEL)
    return m


# --------------------------------------------------------------------------------------------------
# buoy and vegetation


def build_buoy() -> Model:
    m = Model()
    body = np.array([[-0.42, 0.0], [-0.2, 0.42], [0.1, 0.5], [0.35, 0.44], [0.5, 0.26], [0.56, 0.0]])
    rings = [at_z(circle(0, 0, max(r, 0.05), 12), z) for z, r in body]
    blue = ((20, 80, 170), "paint")
    m.add(loft(rings[:3], top=False), WHITE)
    m.add(loft(rings[2:4], bottom=False, top=False), blue)
    m.add(loft(rings[3:], bottom=False), WHITE)
    m.add(cylinder([0, -0.03, 0.62], [0, 0.03, 0.62], 0.1, 8), STEEL)  # mooring eye
    return m


def build_conifer() -> Model:
    m = Model()
    rng = stage_rng(_KIT_SEED, "kit", "tree_conifer")
    m.add(cylinder([0, 0, 0], [0, 0, 2.6], 0.22, 8), ((95, 70, 50), "matte"))
    greens = [((28, 72, 40), "plant"), ((36, 84, 46), "plant")]
    layers = [(1.4, 4.8, 2.3), (3.4, 7.0, 1.85), (5.4, 8.8, 1.35), (7.2, 10.0, 0.8)]
    for i, (z0, z1, r) in enumerate(layers):
        n = 14
        jag = np.where(np.arange(n) % 2 == 0, 1.0, 0.72) * (0.92 + 0.16 * rng.random(n))
        base = circle(0, 0, 1.0, n, phase=0.25 * i) * (r * jag)[:, None]
        m.add(loft([at_z(base, z0), at_z(base * 0.06, z1)]), greens[i % 2])
    return m


def build_broadleaf() -> Model:
    m = Model()
    rng = stage_rng(_KIT_SEED, "kit", "tree_broadleaf")
    bark = ((100, 78, 55), "matte")
    trunk = np.array([[0, 0, 0], [0.05, 0, 2.0], [0.0, 0.05, 3.6]])
    m.add(sweep(trunk, np.array([0.3, 0.24, 0.2]), 8), bark)
    m.add(cylinder([0, 0, 2.6], [1.0, 0.5, 4.0], 0.11, 6), bark)
    m.add(cylinder([0, 0, 2.9], [-0.9, -0.6, 4.2], 0.1, 6), bark)
    greens = [((62, 112, 42), "plant"), ((78, 128, 50), "plant"), ((52, 98, 38), "plant")]
    blobs = [([0, 0, 5.6], 2.5), ([1.5, 0.9, 5.0], 1.8), ([-1.5, -0.9, 5.1], 1.8), ([-1.0, 1.4, 5.4], 1.7),
             ([1.2, -1.4, 5.5], 1.7), ([0.2, 0.1, 6.7], 1.35)]
    for i, (c, r) in enumerate(blobs):
        jit = 0.85 + 0.3 * rng.random((5, 10))
        m.add(ellipsoid(c, [r, r, r * 0.78], 5, 10, jit), greens[i % 3])
    return m


def build_palm() -> Model:
    m = Model()
    s = np.linspace(0, 1, 7)
    trunk = np.column_stack([0.9 * s ** 2, 0.3 * s ** 2, 8.6 * s])
    m.add(sweep(trunk, 0.26 - 0.08 * s, 8), ((135, 112, 82), "matte"))
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
        m.add(sweep(path, width, 6, flat=0.08), green[k % 2])
    m.add(ellipsoid(top + [0, 0, -0.15], [0.45, 0.45, 0.4], 3, 8), ((110, 85, 45), "matte"))  # coconuts
    return m


def _bush(name: str, blobs, greens) -> Model:
    m = Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    for i, (c, r) in enumerate(blobs):
        jit = 0.85 + 0.3 * rng.random((4, 9))
        m.add(ellipsoid(c, r, 4, 9, jit), greens[i % len(greens)])
    return m


def build_bush_round() -> Model:
    blobs = [([0, 0, 0.65], [0.72, 0.72, 0.6]), ([0.35, 0.25, 0.5], [0.45, 0.45, 0.42]),
             ([-0.3, -0.3, 0.5], [0.42, 0.42, 0.4]), ([0.05, -0.05, 1.0], [0.42, 0.42, 0.35])]
    return _bush("bush_round", blobs, [((40, 92, 38), "plant"), ((52, 104, 44), "plant")])


def build_bush_spreading() -> Model:
    blobs = [([0, 0, 0.45], [0.85, 0.75, 0.45]), ([0.7, 0.35, 0.35], [0.55, 0.5, 0.35]),
             ([-0.65, -0.3, 0.35], [0.55, 0.5, 0.33]), ([-0.25, 0.55, 0.32], [0.45, 0.4, 0.3]),
             ([0.3, -0.55, 0.3], [0.45, 0.4, 0.28])]
    narrow = np.array([0.78, 0.78, 1.0])  # a low, spreading shrub ~1.8 m across
    blobs = [(np.array(c) * narrow, np.array(r) * narrow) for c, r in blobs]
    return _bush("bush_spreading", blobs,
                 [((112, 130, 52), "plant"), ((128, 140, 60), "plant"), ((96, 118, 46), "plant")])


def _rock(name: str, size: tuple[float, float, float], shades) -> Model:
    """An irregular rock: convex hull of jittered points on an ellipsoid, bottom flattened into the ground."""
    m = Model()
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
    v, f = convex(np.round(pts, DECIMALS))
    pick = rng.integers(0, len(shades), len(f))
    for k, shade in enumerate(shades):
        sel = f[pick == k]
        if len(sel):
            m.add((v, sel), shade)
    return m


def build_rock_small() -> Model:
    return _rock("rock_small", (1.25, 0.95, 0.85), [((128, 122, 114), "matte"), ((112, 106, 100), "matte")])


def build_rock_medium() -> Model:
    return _rock("rock_medium", (2.1, 1.6, 1.3), [((140, 132, 120), "matte"), ((120, 114, 106), "matte"),
                                                  ((152, 146, 136), "matte")])


def build_rock_large() -> Model:
    return _rock("rock_large", (3.2, 2.4, 1.8), [((105, 100, 96), "matte"), ((92, 88, 84), "matte"),
                                                 ((124, 118, 110), "matte")])


def _grass(name: str, greens, height: float) -> Model:
    m = Model()
    rng = stage_rng(_KIT_SEED, "kit", name)
    n = 14
    for k in range(n):
        ang = 2 * np.pi * (k + 0.5 * rng.random()) / n
        r0 = 0.08 * rng.random()
        lean = 0.12 + 0.14 * rng.random()
        h = height * (0.7 + 0.3 * rng.random())
        d = np.array([math.cos(ang), math.sin(ang)])
        base = np.array([r0 * d[0], r0 * d[1]])
        tri = circle(0, 0, 0.025, 3, phase=rng.random()) + base
        tip = circle(0, 0, 0.004, 3) + base + lean * d
        mid = (tri + tip) / 2 + 0.3 * lean * d  # blades bow outwards
        m.add(loft([at_z(tri, 0.0), at_z(mid, h * 0.55), at_z(tip, h)]), greens[k % 2])
    return m


def build_grass_clump() -> Model:
    return _grass("grass_clump", [((88, 150, 52), "plant"), ((70, 132, 44), "plant")], 0.5)


def build_grass_dry() -> Model:
    return _grass("grass_dry", [((186, 170, 104), "plant"), ((160, 148, 90), "plant")], 0.55)


def build_buoy_channel() -> Model:
    """A red can (lateral mark): a floating cylinder with a dark top ring."""
    m = Model()
    red = ((200, 30, 30), "paint")
    m.add(loft([at_z(circle(0, 0, 0.38, 12), -0.55), at_z(circle(0, 0, 0.42, 12), 0.1)], top=False),
          ((60, 40, 35), "matte"))
    def ring(r, z):
        return at_z(circle(0, 0, r, 12), z)
    m.add(loft([ring(0.42, 0.1), ring(0.41, 0.75)], bottom=False, top=False), red)
    m.add(loft([ring(0.41, 0.75), ring(0.405, 0.88)], bottom=False, top=False), WHITE)  # reflective band
    m.add(loft([ring(0.405, 0.88), ring(0.4, 1.1), ring(0.34, 1.2)], bottom=False), red)
    m.add(cylinder([0, -0.02, 1.2], [0, 0.02, 1.2], 0.09, 8), STEEL)  # lifting eye
    return m


def _seaweed(name: str, n: int, height: float, spread: float, width: float, colours) -> Model:
    """Fronds/blades rising from one holdfast on the sea bed (z = 0 is the bed), swaying a little."""
    m = Model()
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
        m.add(sweep(path, w, 6, flat=0.12), colours[k % len(colours)])
    return m


def build_seaweed_kelp() -> Model:
    return _seaweed("seaweed_kelp", 7, 2.5, 1.1, 0.2, [((105, 92, 38), "plant"), ((122, 104, 44), "plant")])


def build_seaweed_eelgrass() -> Model:
    greens = [((62, 112, 52), "plant"), ((78, 124, 58), "plant")]
    return _seaweed("seaweed_eelgrass", 16, 0.8, 0.5, 0.025, greens)
