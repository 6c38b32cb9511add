"""The default, weight-free terrain model (DESIGN.md §4): shore-aware profiles from the class map.

Every pixel gets its distance to the shoreline (the edge between land and water pixels) and a
soft mix of the four shore types it is near: sand → beach (Dean's equilibrium profile under water,
a beach face rising to a berm on land), rocks → steep revetment, asphalt/sidewalk → vertical quay
wall with a dredged berth in front, grass/dirt/trees → natural bank. The mix weights come from the
distance to the nearest shore pixel *of each type*, through a soft-min whose width grows offshore,
so types blend smoothly along the coast and there is no step where two coasts' zones of influence
meet. Water pixels are always below the water level and land pixels above it (a beach may dip
``intertidal_m`` below it): the invariants hold by construction, not by clipping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..classes import ASPHALT, DIRT, GRASS, N_CLASSES, PAVED, ROCKS, SAND, SIDEWALK, TREES, WATER
from ..config import TerrainConfig
from ..errors import ConfigError, InputError
from ..rng import stage_rng
from ..types import ClassMap, GeoImage, HeightMap

SHORE_TYPES: tuple[str, ...] = ("beach", "revetment", "quay", "bank")
BEACH, REVETMENT, QUAY, BANK = range(4)

# shore type of a land class where it meets the water (-1: water itself)
CLASS_SHORE = np.full(N_CLASSES, -1, dtype=np.int8)
CLASS_SHORE[[ASPHALT, SIDEWALK]] = QUAY
CLASS_SHORE[[GRASS, TREES, DIRT]] = BANK
CLASS_SHORE[ROCKS] = REVETMENT
CLASS_SHORE[SAND] = BEACH

# how strongly land of each class rises inland (paved areas and beaches stay low and flat)
CLASS_RISE = np.zeros(N_CLASSES, dtype=np.float32)
CLASS_RISE[[ASPHALT, SIDEWALK]] = 0.4
CLASS_RISE[GRASS] = 1.0
CLASS_RISE[TREES] = 1.3
CLASS_RISE[DIRT] = 0.9
CLASS_RISE[ROCKS] = 1.2
CLASS_RISE[SAND] = 0.3

_FAR_PX = 1.0e6  # "no shoreline in the image": distances treated as effectively infinite


@dataclass(frozen=True, eq=False)
class ShoreField:
    """Where the shore is and what kind it is, on the class map's grid.

    ``dist_m``: distance to the shoreline in metres (pixel centres; ≥ half a pixel);
    ``water``: bool mask; ``weights``: (4, H, W) float32 soft mix of SHORE_TYPES (sums to 1);
    ``dominant``: (H, W) int8 index of the strongest type, -1 when the image has no shoreline.
    """

    dist_m: np.ndarray
    water: np.ndarray
    weights: np.ndarray
    dominant: np.ndarray
    gsd_m: float
    has_shore: bool

    @property
    def signed_m(self) -> np.ndarray:
        """Signed distance: positive offshore (water), negative inland."""
        return np.where(self.water, self.dist_m, -self.dist_m)

    def present(self) -> tuple[int, ...]:
        """Shore types that dominate at least one shoreline pixel."""
        if not self.has_shore:
            return ()
        near = self.dist_m <= 0.51 * self.gsd_m + 1e-9
        return tuple(int(t) for t in np.unique(self.dominant[near]) if t >= 0)


def dean_a(d50_mm: float) -> float:
    """Dean's shape parameter A (m^1/3) from the median grain size D50 in millimetres."""
    return 0.21 * float(d50_mm) ** 0.48


def dean_depth(d_m, d50_mm: float):
    """Dean's equilibrium beach profile: depth h = A d^(2/3) at distance d offshore."""
    d = np.maximum(np.asarray(d_m, dtype=np.float64), 0.0)
    return dean_a(d50_mm) * np.cbrt(d) ** 2


def smooth(a: np.ndarray, sigma_px: float) -> np.ndarray:
    """A Gaussian-like blur from three box passes: constant time per pixel whatever the width."""
    import cv2

    w = int(round(np.sqrt(4.0 * sigma_px * sigma_px + 1.0)))
    if w < 2:
        return a.astype(np.float32, copy=True)
    w = min(w | 1, 2 * max(a.shape) + 1)
    out = a.astype(np.float32, copy=True)
    for _ in range(3):
        out = cv2.blur(out, (w, w), borderType=cv2.BORDER_REFLECT)
    return out


def _edt(zero_mask: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (pixels) from every pixel to the nearest True pixel of ``zero_mask``."""
    import cv2

    if not zero_mask.any():
        return np.full(zero_mask.shape, _FAR_PX, dtype=np.float32)
    src = np.where(zero_mask, 0, 1).astype(np.uint8)
    # DIST_MASK_PRECISE is the exact EDT (Felzenszwalb), ~3x faster than scipy's on 2 cores; its last bits
    # vary between calls in one process, so snap to the exact value (squared distances are integers)
    d = cv2.distanceTransform(src, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float64)
    np.multiply(d, d, out=d)
    np.rint(d, out=d)
    return np.sqrt(d).astype(np.float32)


def _pool_any(mask: np.ndarray, f: int) -> np.ndarray:
    """Any-pooling by f (thin features survive the coarser grid)."""
    import cv2

    if f <= 1:
        return mask
    h, w = mask.shape
    hc, wc = -(-h // f), -(-w // f)
    pad = np.zeros((hc * f, wc * f), dtype=np.uint8)
    pad[:h, :w] = mask
    pad *= 255  # an area average of ≥ 1 pixel in f*f (f ≤ 4) stays > 0 after rounding
    return cv2.resize(pad, (wc, hc), interpolation=cv2.INTER_AREA) > 0


def _upsample(a: np.ndarray, f: int, shape: tuple[int, int], nearest: bool = False) -> np.ndarray:
    """Undo ``_pool_any``'s grid: coarse cell centres land on the centres of their fine blocks."""
    import cv2

    if f <= 1:
        return a
    hc, wc = a.shape
    interp = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
    return cv2.resize(a, (wc * f, hc * f), interpolation=interp)[: shape[0], : shape[1]]


def analyse_shore(ids: np.ndarray, gsd_m: float, config: TerrainConfig) -> ShoreField:
    """Distance to the shoreline and the soft shore-type mix for a class-id raster."""
    import cv2

    if ids.ndim != 2 or ids.size == 0:
        raise InputError(f"class map must be a non-empty (H, W) array of class ids, got shape {ids.shape}")
    if not (gsd_m > 0 and np.isfinite(gsd_m)):
        raise InputError(f"class map gsd_m = {gsd_m!r} must be a positive number of metres per pixel")
    ids = np.asarray(ids)
    if ids.max(initial=0) >= N_CLASSES or ids.min(initial=0) < 0:
        raise InputError(f"class map holds id {int(ids.max())}, outside 0..{N_CLASSES - 1}; "
                         "pass a raster of the eight terrain class ids")
    water = ids == WATER
    land = ~water
    h, w = ids.shape
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    near_water = cv2.dilate(water.view(np.uint8), cross).astype(bool)
    shore = land & near_water  # land pixels sharing an edge with water
    has_shore = bool(shore.any())
    d_px = _edt(shore) if has_shore else np.full((h, w), _FAR_PX, np.float32)
    # the shoreline runs between pixel centres: half a pixel beyond the shore-land pixels
    d_px += np.where(water, np.float32(-0.5), np.float32(0.5))
    d_px *= np.float32(gsd_m)
    dist_m = d_px

    weights = np.zeros((len(SHORE_TYPES), h, w), dtype=np.float32)
    if not has_shore:
        weights[BANK] = 1.0  # no coast in view: plain land / open water, profile shape is moot
        return ShoreField(dist_m, water, weights, np.full((h, w), -1, np.int8), gsd_m, False)
    stype = np.where(shore, CLASS_SHORE[ids], np.int8(-1))
    present = [int(t) for t in np.unique(stype[shore])]
    if len(present) == 1:
        weights[present[0]] = 1.0
        return ShoreField(dist_m, water, weights, np.full((h, w), present[0], np.int8), gsd_m, True)
    # The mix is smooth on the scale of shore_blend_m, so it is computed on a grid up to 4x coarser.
    tau0 = np.float32(max(config.shore_blend_m, 1e-3))
    f = int(np.clip(tau0 / gsd_m // 3, 1, 4))
    g = np.float32(gsd_m * f)
    dk = [_edt(_pool_any(stype == t, f)) * g for t in present]
    dmin = dk[0].copy()
    for a in dk[1:]:
        np.minimum(dmin, a, out=dmin)
    # soft-min over per-type distances; its width grows offshore/inland so far zones blend gently
    tau = tau0 + np.float32(0.5) * dmin
    total = np.zeros_like(dmin)
    best = np.zeros(dmin.shape, np.int8)
    for i, a in enumerate(dk):
        a -= dmin
        a /= -tau
        np.exp(a, out=a)
        total += a
        if i:
            best[a >= np.float32(1.0 - 1e-6)] = i  # exp(0): this type is (one of) the nearest
    for i, t in enumerate(present):
        weights[t] = _upsample(dk[i] / total, f, (h, w))
    dominant = _upsample(np.asarray(present, dtype=np.int8)[best], f, (h, w), nearest=True)
    return ShoreField(dist_m, water, weights, np.ascontiguousarray(dominant), gsd_m, True)


def _noise_field(shape: tuple[int, int], gsd_m: float, seed: int) -> np.ndarray:
    """Smooth seeded variation in (-1, 1): three octaves of upsampled white noise (2, 6 and 20 m)."""
    import cv2

    rng = stage_rng(seed, "terrain")
    h, w = shape
    total = np.zeros(shape, dtype=np.float32)
    for cell_m, amp in ((2.0, 0.25), (6.0, 0.35), (20.0, 0.4)):
        cell_px = max(cell_m / gsd_m, 1.0)
        gh, gw = int(np.ceil(h / cell_px)) + 2, int(np.ceil(w / cell_px)) + 2
        g = rng.standard_normal((gh, gw)).astype(np.float32)
        size = (int(round(gw * cell_px)), int(round(gh * cell_px)))
        up = cv2.resize(g, size, interpolation=cv2.INTER_CUBIC)
        total += amp * up[:h, :w]
    std = float(total.std()) or 1.0
    return np.tanh(total / (1.5 * std)).astype(np.float32)


def _smooth_coarse(a: np.ndarray, sigma_px: float) -> np.ndarray:
    """``smooth`` for wide kernels, on a grid ~sigma/8 coarser, upsampled (same result, ~50x less work)."""
    import cv2

    k = int(max(1, sigma_px // 8))
    if k == 1:
        return smooth(a, sigma_px)
    h, w = a.shape
    small = cv2.resize(a.astype(np.float32), (max(1, w // k), max(1, h // k)), interpolation=cv2.INTER_AREA)
    sm = smooth(small, sigma_px * small.shape[1] / w)
    return cv2.resize(sm, (w, h), interpolation=cv2.INTER_LINEAR)


def water_depth(d: np.ndarray, wts: dict[int, np.ndarray], c: TerrainConfig) -> np.ndarray:
    """Positive depth below the water level at distance ``d`` (m) offshore, mixed over shore types."""
    f32 = np.float32
    M = f32(c.max_depth_m)
    general = M * -np.expm1(d / -f32(c.depth_scale_m))  # smooth approach to the maximum depth offshore
    depth = np.zeros_like(d)
    for t, w in wts.items():
        if t == BEACH:
            dean = np.cbrt(d)
            dean *= dean
            dean *= f32(dean_a(c.d50_mm))
            prof = dean * M / np.sqrt(np.sqrt(dean ** 4 + M ** 4))  # Dean's curve, soft-capped at M
        elif t == QUAY:
            prof = np.maximum(general, f32(c.berth_depth_m))  # the dredged berth starts right at the wall
        elif t == REVETMENT:
            toe = f32(min(c.revetment_toe_m, c.max_depth_m))
            prof = np.maximum(general, toe * -np.expm1(d * (-f32(c.revetment_slope) / toe)))
        else:
            prof = general
        depth += w * prof
    return depth


def land_profile(d: np.ndarray, wts: dict[int, np.ndarray], c: TerrainConfig) -> np.ndarray:
    """Height above the water level of the shore profile at distance ``d`` (m) inland, mixed over types."""
    f32 = np.float32
    z = np.zeros_like(d)
    for t, w in wts.items():
        if t == QUAY:
            z += w * f32(c.quay_height_m)  # a flat deck from the wall's edge
            continue
        top, slope = {BEACH: (c.beach_height_m, c.beach_slope), REVETMENT: (c.revetment_height_m,
                      c.revetment_slope), BANK: (c.bank_height_m, c.bank_slope)}[t]
        z += w * (f32(top) * -np.expm1(d * (-f32(slope) / f32(top))))
    return z


def heights_from_shore(ids: np.ndarray, sf: ShoreField, config: TerrainConfig, seed: int) -> np.ndarray:
    """Heights (float32 metres) from the shore field: profiles per type, mixed by the weights."""
    c = config
    f32 = np.float32
    water = sf.water
    land = ~water
    used = [t for t in range(len(SHORE_TYPES)) if sf.weights[t].any()]
    z = np.empty(ids.shape, np.float32)
    it = f32(c.intertidal_m)

    # water and land pixels are evaluated separately: each needs only its own profile family
    dw = sf.dist_m[water]
    ww = {t: sf.weights[t][water] for t in used}
    zw = -water_depth(dw, ww, c)
    if it > 0 and BEACH in ww:
        zw -= it * ww[BEACH]  # keeps the beach continuous with a waterline at -intertidal_m
    z[water] = zw
    del dw, ww, zw

    # land: the shore profile plus a gentle inland rise whose strength depends (smoothly) on the class
    factor = _smooth_coarse(CLASS_RISE[ids] * land, 10.0 / sf.gsd_m)
    den = _smooth_coarse(land.astype(np.float32), 10.0 / sf.gsd_m)
    dl = sf.dist_m[land]
    wl = {t: sf.weights[t][land] for t in used}
    zl = land_profile(dl, wl, c)
    fl = factor[land] / np.maximum(den[land], f32(1e-6))
    zl += f32(c.land_rise_m) * fl * -np.expm1(dl / -f32(c.land_rise_scale_m))
    if it > 0 and BEACH in wl:
        # tidal flats: sand at the waterline dips to -intertidal_m and climbs back over the beach face
        sand = ids[land] == SAND
        zl -= np.where(sand, it * wl[BEACH] * np.exp(dl * (-f32(c.beach_slope) / it)), f32(0))
    z[land] = zl
    del dl, wl, zl

    # small natural variation: never on paved areas or dredged berths, and never enough to flip a sign
    if c.noise_m > 0:
        import cv2

        paved = np.isin(ids, PAVED)
        k = max(3, int(round(2.0 / sf.gsd_m)) | 1)
        near_paved = cv2.blur(paved.astype(np.float32), (k, k), borderType=cv2.BORDER_REFLECT)
        mask = np.clip(1.0 - 2.0 * near_paved, 0.0, 1.0)
        mask[paved] = 0.0
        if QUAY in used:
            mask[water] = 1.0 - sf.weights[QUAY][water]
        else:
            mask[water] = 1.0
        nm = f32(c.noise_m)
        amp = np.minimum(nm, np.abs(z) * f32(0.1))  # ≤ 10 % of the local height above/below water
        amp *= mask
        amp *= _noise_field(ids.shape, sf.gsd_m, seed)
        z += amp
    return z


class DefaultTerrain:
    """Shore-aware height model from the class map alone (no weights)."""

    name = "default"

    def __init__(self, config: TerrainConfig, **opts) -> None:
        if opts:
            raise InputError(f"the default terrain backend takes no options, got {sorted(opts)}; "
                             "remove them (weights are for --backend onnx)")
        _check_config(config)
        self.config = config

    def analyse(self, class_map: ClassMap) -> ShoreField:
        return analyse_shore(class_map.ids, class_map.grid.gsd_m, self.config)

    def estimate_from_shore(self, class_map: ClassMap, shore: ShoreField, seed: int) -> HeightMap:
        z = heights_from_shore(np.asarray(class_map.ids), shore, self.config, seed)
        return HeightMap(z_m=z, grid=class_map.grid)

    def estimate(self, class_map: ClassMap, image: GeoImage | None, seed: int) -> HeightMap:
        return self.estimate_from_shore(class_map, self.analyse(class_map), seed)


def _check_config(c: TerrainConfig) -> None:
    """Reject values that would break the profiles, naming the key and a sensible range."""
    positive = ("max_depth_m", "depth_scale_m", "berth_depth_m", "quay_height_m", "d50_mm", "beach_height_m",
                "revetment_slope", "bank_slope", "beach_slope", "revetment_height_m", "revetment_toe_m",
                "bank_height_m",
                "land_rise_scale_m", "shore_blend_m", "seam_m", "optical_max_depth_m")
    for key in positive:
        v = getattr(c, key)
        if not (np.isfinite(v) and v > 0):
            raise ConfigError(f"terrain.{key} = {v!r} must be a positive number; "
                              f"fix it with --set terrain.{key}=...")
    for key in ("intertidal_m", "noise_m", "land_rise_m"):
        v = getattr(c, key)
        if not (np.isfinite(v) and v >= 0):
            raise ConfigError(f"terrain.{key} = {v!r} must be ≥ 0; fix it with --set terrain.{key}=...")
