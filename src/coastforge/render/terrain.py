"""Procedural terrain and water shading for the top-down renderer.

Everything is vectorised over the output grid with numpy/OpenCV. Noise is defined in scene metres
(a random lattice upsampled with cubic interpolation), so the same scene rendered at two GSDs shows
the same texture; lattice cells smaller than a pixel are not drawn (they would alias) but folded into
per-pixel grain instead.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..classes import ASPHALT, DIRT, GRASS, ROCKS, SAND, SIDEWALK, TREES, WATER
from ..rng import stage_rng
from .objects import PixelGrid

F32 = np.float32


class NoiseBank:
    """Seeded value noise on the scene frame; one lattice per (name, cell, angle)."""

    def __init__(self, grid: PixelGrid, seed: int):
        self.grid = grid
        self.seed = seed
        self._cache: dict = {}

    def field(self, name: str, cell_m: float, angle_deg: float = 0.0, stretch: float = 1.0) -> np.ndarray:
        """Zero-mean, roughly unit-std noise with feature size ``cell_m`` (``stretch`` > 1 elongates it
        along ``angle_deg``). Cells below ~1.5 px come back as zeros (see ``grain``)."""
        g = self.grid
        cu, cv = cell_m * stretch, cell_m
        if cv < 1.5 * g.gsd:
            return np.zeros((g.H, g.W), F32)
        th = np.deg2rad(angle_deg)
        c, s = np.cos(th), np.sin(th)
        diag = float(np.hypot(g.w_m, g.h_m))
        gu, gv = int(diag / cu) + 5, int(diag / cv) + 5
        rng = stage_rng(
            self.seed, "render", "noise", name, f"{cell_m:.4f}", f"{angle_deg:.2f}", f"{stretch:.3f}"
        )
        lat = rng.standard_normal((gv, gu)).astype(F32)
        # dst pixel (col,row) -> world (x,y) -> rotated (x',y') -> lattice (u,v)
        # big cells are smooth at pixel scale: evaluate on a coarser grid and upsample linearly (much faster)
        f = int(np.clip(cv / g.gsd / 6.0, 1, 8))
        Wc, Hc = -(-g.W // f), -(-g.H // f)
        xa, xb, xc = g.gx * f, 0.0, g.x0 + 0.5 * g.gx * f
        ya, yb, yc = 0.0, -g.gy * f, g.y0 - 0.5 * g.gy * f
        M = np.array(
            [
                [(c * xa + s * ya) / cu, (c * xb + s * yb) / cu, (c * xc + s * yc) / cu + gu / 2.0],
                [(-s * xa + c * ya) / cv, (-s * xb + c * yb) / cv, (-s * xc + c * yc) / cv + gv / 2.0],
            ]
        )
        # cells of a few pixels: linear interpolation (2x faster) looks the same; larger cells need cubic
        interp = cv2.INTER_LINEAR if (f == 1 and cv < 4.0 * g.gsd) else cv2.INTER_CUBIC
        out = cv2.warpAffine(
            lat, M, (Wc, Hc), flags=interp | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT
        )
        if f > 1:
            # align coarse pixel centres: coarse (i + 0.5) * f == fine (j + 0.5)
            Mu = np.array([[1.0 / f, 0.0, 0.5 / f - 0.5], [0.0, 1.0 / f, 0.5 / f - 0.5]])
            out = cv2.warpAffine(
                out,
                Mu,
                (g.W, g.H),
                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_REPLICATE,
            )
        out *= (
            1.35 if interp == cv2.INTER_CUBIC else 1.6
        )  # interpolation smooths white noise: restore ~unit std
        return out  # not cached: each field is used once, and a 2048² field is 16 MB

    def fbm(self, name: str, cell_m: float, octaves: int = 3, gain: float = 0.5) -> np.ndarray:
        out = np.zeros((self.grid.H, self.grid.W), F32)
        amp, tot = 1.0, 0.0
        for k in range(octaves):
            out += amp * self.field(f"{name}{k}", cell_m / 2**k, angle_deg=17.0 * k)
            tot += amp * amp
            amp *= gain
        return out / np.sqrt(tot)

    _PAD = 61

    def grain(self, name: str) -> np.ndarray:
        """Per-pixel white noise (read-only). One seeded field, seen through a different offset per name:
        drawing millions of normals per layer would be the most expensive step otherwise."""
        g = self.grid
        if "__grain" not in self._cache:
            rng = stage_rng(self.seed, "render", "grain")
            base = rng.standard_normal((g.H + self._PAD, g.W + self._PAD), dtype=F32)
            base.flags.writeable = False
            self._cache["__grain"] = base
        k = stage_rng(self.seed, "render", "grain", name).integers(0, self._PAD, 2)
        return self._cache["__grain"][k[0] : k[0] + g.H, k[1] : k[1] + g.W]


def class_lut(values, cls: np.ndarray) -> np.ndarray:
    """``values[cls]`` for a per-class float table and a uint8 class map (cv2.LUT: ~5x numpy indexing)."""
    lut = np.zeros(256, F32)
    v = np.asarray(values, F32)
    lut[: len(v)] = v
    return cv2.LUT(cls, lut)


def srgb(c) -> np.ndarray:
    return np.asarray(c, F32) / 255.0


# per class: base colour, and how strongly large / mid / small noise and pixel grain modulate it
_BASE = (
    np.array(
        [
            (150, 142, 112),  # water: the seabed (silty sand) seen through the water column
            (100, 98, 96),  # asphalt
            (178, 176, 168),  # sidewalk / concrete
            (92, 128, 58),  # grass
            (46, 78, 38),  # trees (canopy)
            (128, 104, 76),  # dirt
            (122, 116, 106),  # rocks
            (206, 188, 146),  # sand
        ],
        F32,
    )
    / 255.0
)
_AMP = np.array(
    [  # large, mid, small, fine, grain
        (0.05, 0.05, 0.03, 0.02, 0.02),
        (0.05, 0.05, 0.03, 0.025, 0.08),
        (0.03, 0.04, 0.03, 0.03, 0.04),
        (0.10, 0.08, 0.07, 0.08, 0.06),
        (0.08, 0.08, 0.06, 0.05, 0.05),
        (0.08, 0.07, 0.07, 0.07, 0.06),
        (0.07, 0.07, 0.06, 0.06, 0.07),
        (0.04, 0.04, 0.03, 0.04, 0.04),
    ],
    F32,
)
# colour drift with the large noise (e.g. grass yellowing in patches)
_DRIFT = np.array(
    [
        (0, 0, 0),
        (0.01, 0.01, 0.015),
        (0.01, 0.01, 0.0),
        (0.05, 0.03, -0.004),
        (0.02, 0.03, 0.0),
        (0.03, 0.015, 0.0),
        (0.02, 0.015, 0.0),
        (0.025, 0.02, 0.0),
    ],
    F32,
)


def _smooth_upsample(classes: np.ndarray, grid: PixelGrid) -> np.ndarray:
    """Class map on the output grid. When the output is finer than the class grid, each class's indicator
    is interpolated bilinearly and the strongest wins: diagonal edges come out straight, not as stairs."""
    h, w = classes.shape
    if grid.W < 1.5 * w and grid.H < 1.5 * h:
        return cv2.resize(classes, (grid.W, grid.H), interpolation=cv2.INTER_NEAREST)
    present = np.flatnonzero(np.bincount(classes.ravel(), minlength=256))
    if len(present) == 1:
        return np.full((grid.H, grid.W), present[0], np.uint8)
    best = np.zeros((grid.H, grid.W), np.uint8)
    out = np.zeros((grid.H, grid.W), np.uint8)
    for k in present:
        ind = cv2.resize(
            (classes == k).astype(np.uint8) * 255, (grid.W, grid.H), interpolation=cv2.INTER_LINEAR
        )
        win = ind > best
        out[win] = k
        np.maximum(best, ind, out=best)
    return out


def resample_classes(classes: np.ndarray, grid: PixelGrid, noise: NoiseBank) -> np.ndarray:
    """Nearest-neighbour class lookup with a slight noise warp so borders between natural classes are
    not staircases when the render is finer than the class grid."""
    h, w = classes.shape
    cols = (np.arange(grid.W, dtype=F32) + 0.5) * (w / grid.W) - 0.5
    rows = (np.arange(grid.H, dtype=F32) + 0.5) * (h / grid.H) - 0.5
    mx, my = np.meshgrid(cols, rows)
    src_gsd = grid.w_m / w
    amp = 0.45 * max(src_gsd, grid.gsd) / src_gsd  # in source pixels
    mx += amp * noise.field("warpx", max(4 * src_gsd, 0.8))
    my += amp * noise.field("warpy", max(4 * src_gsd, 0.8))
    warped = cv2.remap(classes, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
    if amp < 0.05:
        return warped
    # built edges (quays, roads, pavements) stay straight: warp only where both sides are natural classes
    # (water counts as natural: beaches and rocky shores get irregular water lines)
    plain = _smooth_upsample(classes, grid)
    is_built = np.zeros(256, np.uint8)
    is_built[[ASPHALT, SIDEWALK]] = 1
    built = (cv2.LUT(plain, is_built) | cv2.LUT(warped, is_built)).astype(bool)
    return np.where(built, plain, warped)


def resample_height(height: np.ndarray, grid: PixelGrid) -> np.ndarray:
    h = np.asarray(height, F32)
    if h.shape == (grid.H, grid.W):
        return h.copy()
    interp = cv2.INTER_LINEAR if grid.W >= h.shape[1] else cv2.INTER_AREA
    return cv2.resize(h, (grid.W, grid.H), interpolation=interp)


def hillshade(z: np.ndarray, grid: PixelGrid, sun: np.ndarray) -> np.ndarray:
    """max(0, n·sun) (H, W) of a height field (x east = cols, y north = -rows), without forming normals."""
    dzdx = cv2.Sobel(z, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
    dzdx *= F32(1.0 / (8.0 * grid.gx))
    dzdy = cv2.Sobel(z, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
    dzdy *= F32(-1.0 / (8.0 * grid.gy))  # rows point south
    num = dzdx * F32(-sun[0])
    num -= dzdy * F32(sun[1])
    num += F32(sun[2])
    dzdx *= dzdx
    dzdy *= dzdy
    dzdx += dzdy
    dzdx += F32(1.0)
    num /= np.sqrt(dzdx, out=dzdx)
    return np.maximum(num, F32(0.0), out=num)


def dominant_edge_angle(mask: np.ndarray) -> float:
    """Dominant orientation (radians, scene frame, modulo 90°) of a mask's edges, from the gradient
    structure on a downsampled copy: a rectilinear layout (slabs, lines) aligned with it looks built."""
    h, w = mask.shape
    k = max(1, int(max(h, w) / 512))
    small = cv2.resize(mask.astype(F32), (max(w // k, 1), max(h // k, 1)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), 1.0)
    gx = cv2.Sobel(small, cv2.CV_32F, 1, 0, ksize=3)
    gy = -cv2.Sobel(small, cv2.CV_32F, 0, 1, ksize=3)  # rows point south
    mag = np.hypot(gx, gy)
    if float(mag.sum()) < 1e-6:
        return 0.0
    ang = np.arctan2(gy, gx)
    z = (mag * np.exp(4j * ang)).sum()  # 4θ: edges at θ and θ + 90° vote together
    return float(np.angle(z) / 4.0)


def _cells(grid: PixelGrid, mask: np.ndarray, spacing_m: float, rng: np.random.Generator):
    """Random seed points (jittered lattice in metres) inside ``mask``'s bounding box; returns for each
    pixel of the box the offset (dx, dy) in metres to the nearest seed and that seed's index."""
    rr, cc = np.nonzero(mask)
    r0, r1, c0, c1 = rr.min(), rr.max() + 1, cc.min(), cc.max() + 1
    h, w = r1 - r0, c1 - c0
    sp_px = spacing_m / grid.gsd
    ny, nx = int(h / sp_px) + 2, int(w / sp_px) + 2
    gy, gx = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    py = (gy + rng.uniform(0.1, 0.9, gy.shape)) * sp_px
    px = (gx + rng.uniform(0.1, 0.9, gx.shape)) * sp_px
    py, px = py.ravel(), px.ravel()
    keep = (py < h) & (px < w)
    py, px = py[keep], px[keep]
    seeds = np.ones((h, w), np.uint8)
    iy, ix = py.astype(int), px.astype(int)
    seeds[iy, ix] = 0
    _, lab = cv2.distanceTransformWithLabels(seeds, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    # labels are numbered in scan order of the zero pixels
    order = np.flatnonzero(seeds.ravel() == 0)
    lut_y = np.zeros(len(order) + 1, F32)
    lut_x = np.zeros(len(order) + 1, F32)
    lut_y[1:], lut_x[1:] = order // w + 0.5, order % w + 0.5
    yy, xx = np.mgrid[0:h, 0:w].astype(F32)
    dy_px = lut_y[lab] - (yy + 0.5)
    dx_px = lut_x[lab] - (xx + 0.5)
    sl = (slice(r0, r1), slice(c0, c1))
    return sl, -dx_px * grid.gx, dy_px * grid.gy, lab  # offsets pixel -> seed, in metres (x east, y north)


def _domes(grid, mask, spacing_m, radius_m, rng, sun, flat_top=0.0):
    """Shading of rounded crowns (trees) or boulders: returns (slice, shade (h,w), inside (h,w), label)."""
    sl, dx, dy, lab = _cells(grid, mask, spacing_m, rng)
    nlab = int(lab.max()) + 1
    rad = (radius_m * rng.uniform(0.7, 1.3, nlab)).astype(F32)[lab]
    d2 = dx * dx + dy * dy
    inside = np.clip(1.0 - d2 / (rad * rad), 0.0, 1.0)
    hz = np.sqrt(inside) + flat_top
    # normal of a sphere cap: points away from the centre (centre is at +dx, +dy from the pixel)
    nx, ny = -dx / rad, -dy / rad
    nz = np.maximum(hz, 0.05)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    shade = (nx * sun[0] + ny * sun[1] + nz * sun[2]) / norm
    return sl, np.clip(shade, 0, 1).astype(F32), inside.astype(F32), lab


def terrain_albedo(
    cls: np.ndarray, grid: PixelGrid, noise: NoiseBank, seed: int, sun: np.ndarray, water_mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel albedo (3, H, W) (planar) of land and seabed, and a per-pixel extra shading factor (H, W) for
    texture relief that the height map does not hold (tree crowns, boulders, ripples)."""
    g = grid
    nl = noise.field("large", 28.0)
    nm = noise.fbm("mid", 7.0, 2)
    ns = noise.field("small", 1.6)
    nf = noise.field("fine", 0.35)
    gr = noise.grain("grain")
    # features below the pixel size average out, but the pixel-to-pixel variation they cause remains
    fine_w = np.clip(0.35 / (1.5 * g.gsd), 0.0, 1.0)
    layers = (nl, nm, ns, nf, gr * F32(1.0 - 0.5 * fine_w))
    mod = np.ones(cls.shape, F32)
    for k, layer in enumerate(layers):
        mod += class_lut(_AMP[:, k], cls) * layer
    relief = np.ones(cls.shape, F32)
    blue = None  # extra blue-channel factor (wet sand)
    rng = stage_rng(seed, "render", "features")

    # seabed: dark patches of seagrass / weed and silt
    m = cls == WATER
    if m.any():
        weed = np.clip((noise.field("weed", 6.0) + 0.5 * noise.field("weed2", 1.5) - 0.9) * 1.5, 0, 1)
        mod[m] *= 1.0 - 0.55 * weed[m]

    # asphalt: darker patches (repairs, wear) and oil stains
    m = cls == ASPHALT
    if m.any():
        patch = np.clip((noise.field("apatch", 11.0) - 1.3) * 4.0, 0, 1)  # resurfaced patches, crisp edges
        stain = np.clip(noise.field("astain", 1.5) - 2.0, 0, 1) * np.clip(noise.field("astain2", 20.0), 0, 1)
        f = 1.0 - 0.10 * patch - 0.3 * stain
        # aggregate: a few bright stones, visible only when pixels are small enough to resolve them
        stones = np.clip(noise.grain("stones") - 1.6, 0, 1) * F32(0.25 * fine_w)
        f += stones
        mod[m] *= f[m]

    # concrete: slabs with joints and per-slab tone
    m = cls == SIDEWALK
    if m.any():
        slab = float(rng.uniform(1.6, 3.2))
        rows, cols = np.nonzero(m)
        x, y = g.xy(rows, cols)
        th = dominant_edge_angle(m)  # lay the slabs along the quay / kerb, not along the image axes
        x, y = x * np.cos(th) + y * np.sin(th), -x * np.sin(th) + y * np.cos(th)
        ix, iy = np.floor(x / slab), np.floor(y / slab)
        tone = 1.0 + 0.05 * np.sin(ix * 12.9898 + iy * 78.233 + seed) * np.cos(ix * 4.1 - iy * 7.7)
        dj = np.minimum(np.abs(x / slab - np.round(x / slab)), np.abs(y / slab - np.round(y / slab))) * slab
        jw = 0.02
        # a 2 cm joint darkens a coarse pixel only by the fraction of it that it covers
        cover = np.clip((0.5 * (jw + g.gsd) - dj) / g.gsd, 0, 1) * min(1.0, 2.5 * jw / g.gsd)
        mod[rows, cols] *= (tone * (1.0 - 0.45 * cover)).astype(F32)

    # grass: mowing stripes and dry patches
    m = cls == GRASS
    if m.any():
        ang = float(rng.uniform(0, np.pi))
        rows, cols = np.nonzero(m)
        x, y = g.xy(rows, cols)
        stripe = np.sign(np.sin((x * np.cos(ang) + y * np.sin(ang)) * np.pi / 2.2)) * 0.04
        mod[rows, cols] *= (1.0 + stripe).astype(F32)

    # tree canopy: rounded crowns with gaps between them
    m = cls == TREES
    if m.any():
        sl, shade, inside, lab = _domes(g, m, 3.0, 2.1, rng, sun)
        crown_tone = (1.0 + 0.15 * rng.standard_normal(int(lab.max()) + 1)).astype(F32)[lab]
        leafy = 1.0 + 0.18 * noise.field("leaf", 0.45)[sl] + 0.1 * noise.field("leaf2", 1.1)[sl]
        # soft crown rims (leaves thin out), dark understorey in the gaps between crowns
        rim = np.clip(inside * 4.0, 0.0, 1.0)
        f = (0.45 + 0.9 * shade) * crown_tone * leafy * rim + 0.4 * (1.0 - rim)
        mm = m[sl]
        relief[sl][mm] = f[mm]

    # rocks: boulders with dark cracks between them
    m = cls == ROCKS
    if m.any():
        sl, shade, inside, lab = _domes(g, m, 1.3, 1.0, rng, sun, flat_top=0.3)
        tone = (1.0 + 0.15 * rng.standard_normal(int(lab.max()) + 1)).astype(F32)[lab]
        edge = cv2.morphologyEx(lab.astype(F32), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
        f = (0.5 + 0.8 * shade) * tone * np.where(edge, 0.55, 1.0)
        mm = m[sl]
        relief[sl][mm] = f[mm]

    # dirt: small pebbles and tyre-track-like streaks
    m = cls == DIRT
    if m.any():
        peb = np.clip(noise.field("pebble", 0.25) - 1.5, 0, 1)
        streak = noise.field("streak", 1.0, angle_deg=float(rng.uniform(0, 180)), stretch=6.0)
        f = 1.0 + 0.25 * peb + 0.05 * streak
        mod[m] *= f[m]

    # sand: wind ripples, and wet darker sand near the water line
    m = cls == SAND
    if m.any():
        ang = float(rng.uniform(0, np.pi))
        rows, cols = np.nonzero(m)
        x, y = g.xy(rows, cols)
        wl = 0.7
        warp = 0.6 * noise.field("sandwarp", 3.0)[rows, cols]
        rip = np.sin(2 * np.pi * ((x * np.cos(ang) + y * np.sin(ang)) / wl + warp))
        rip *= np.clip(0.5 + noise.field("sandrip", 4.0)[rows, cols], 0, 1)  # ripples come and go
        rip_amp = 0.03 * float(np.clip((wl / g.gsd - 2.0) / 3.0, 0, 1))
        relief[rows, cols] = 1.0 + rip_amp * rip
    if water_mask.any() and (m.any() or (cls == DIRT).any()):
        dist = cv2.distanceTransform((~water_mask).astype(np.uint8), cv2.DIST_L2, 5) * g.gsd
        wet_w = float(rng.uniform(1.0, 4.0))
        wet = np.exp(-dist / F32(wet_w)) * ((cls == SAND) | (cls == DIRT))
        mod *= 1.0 - 0.35 * wet
        blue = 1.0 + 0.06 * wet
    nl = np.clip(nl, F32(-0.8), F32(2.0))  # colour drift: yellowed patches, never a cast towards teal
    alb = np.empty((3,) + cls.shape, F32)  # planar: per-channel arithmetic stays fast
    for ch in range(3):
        np.multiply(class_lut(_BASE[:, ch], cls), mod, out=alb[ch])
        alb[ch] += class_lut(_DRIFT[:, ch], cls) * nl
    if blue is not None:
        alb[2] *= blue
    return alb, relief


def water_body(depth: np.ndarray, idx: np.ndarray, lighting, noise: NoiseBank):
    """Colour of the water column (3, N) at flat pixel indices ``idx`` for depths ``depth`` (N,), and the
    seabed transmittance (N,)."""
    turb = float(np.clip(lighting.turbidity, 0.0, 1.0))
    shallow = srgb(lighting.water_shallow_rgb)
    deep = srgb(lighting.water_deep_rgb)
    silt = srgb((112, 104, 70))
    shallow = shallow * (1 - 0.6 * turb**1.5) + silt * 0.6 * turb**1.5
    d0 = 1.2 + 6.0 * (1.0 - turb)  # depth over which the body goes from shallow to deep colour
    vis = 0.4 + 3.5 * (1.0 - turb) ** 1.5  # depth at which the seabed fades to ~1/e
    # patchy turbidity (plumes) so open water is not a flat colour
    plume = (
        noise.field("plume", 40.0).reshape(-1)[idx] * 0.5 + noise.field("plume2", 12.0).reshape(-1)[idx] * 0.3
    )
    dd = np.maximum(depth, 0.0) * (1.0 + 0.25 * plume)
    t = (1.0 - np.exp(-dd / F32(d0)))[None]
    body = shallow[:, None] + (deep - shallow)[:, None] * t
    trans = np.exp(-dd / F32(vis)).astype(F32)
    return body.astype(F32), trans


def water_surface(idx: np.ndarray, grid: PixelGrid, noise: NoiseBank, lighting, sun: np.ndarray, seed: int):
    """Ripple normals → (sky reflection brightness (N,), glint (N,)) at flat pixel indices. The wind
    direction is seeded; ripples are elongated across it."""
    rng = stage_rng(seed, "render", "wind")
    wind = float(rng.uniform(0, 180))
    h = (
        0.6 * noise.field("wave1", 2.2, wind, 3.0)
        + 0.3 * noise.field("wave2", 0.9, wind + 25, 2.5)
        + 0.2 * noise.field("wave3", 0.35, wind - 20, 2.0)
        + 0.12 * noise.field("wave4", 5.0, wind + 8, 4.0)
    )
    calm = 0.55 + 0.45 * np.clip(noise.field("calm", 35.0).reshape(-1)[idx] * 0.7 + 0.6, 0, 1)  # wind slicks
    amp = 0.05 * calm
    gx = cv2.Sobel(h, cv2.CV_32F, 1, 0, ksize=3).reshape(-1)[idx] * (amp / F32(8 * grid.gx))
    gy = cv2.Sobel(h, cv2.CV_32F, 0, 1, ksize=3).reshape(-1)[idx] * (amp / F32(-8 * grid.gy))
    # small ripples below the pixel size still tilt facets: a pixel-scale random slope keeps glitter
    fine = float(np.clip(0.3 / grid.gsd, 0.0, 1.0))
    gx += noise.grain("glx").reshape(-1)[idx] * (0.05 * (1.1 - fine) * calm)
    gy += noise.grain("gly").reshape(-1)[idx] * (0.05 * (1.1 - fine) * calm)
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    nx, ny, nz = -gx * inv, -gy * inv, inv
    hv = sun + np.array([0.0, 0.0, 1.0])
    hv /= np.linalg.norm(hv)
    u = 1.0 - np.clip(nx * F32(hv[0]) + ny * F32(hv[1]) + nz * F32(hv[2]), 0, 1)  # ~ angle² / 2
    # sharp sun glitter on facets that mirror the sun, plus a broad sheen around the specular point
    glint = F32(lighting.glint) * (6.0 * np.exp(-900.0 * u) + 0.12 * np.exp(-60.0 * u))
    # reflected sky: tilted facets see more of the brighter horizon sky
    cw, sw = np.cos(np.deg2rad(wind)), np.sin(np.deg2rad(wind))
    sky = (1.0 - nz) * 3.0 + 0.02 * (1 + (nx * F32(cw) + ny * F32(sw)) * 2)
    return sky.astype(F32), glint.astype(F32)
