"""Truth heights of a synthetic level from its class map (DESIGN.md §4), with its own parameters.

This is the *ground-truth* model of the benchmark, deliberately independent of the terrain stage's
estimator: the shore profile depends on the class that meets the water (sand → Dean's equilibrium
beach ``h = A d^(2/3)``, ``A = 0.21 D50^0.48`` with D50 in mm; rocks → a steep revetment; asphalt or
sidewalk → a vertical quay wall with berth depth in front; natural banks → a moderate slope), depth
grows smoothly offshore to a maximum, land rises gently inland, and every water pixel stays below
the water level and every land pixel above it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..classes import ASPHALT, ROCKS, SAND, SIDEWALK, WATER

MIN_DEPTH_M = 0.05  # water pixels are at least this deep, land pixels at least this high


@dataclass(frozen=True)
class TruthTerrainParams:
    max_depth_m: float = 8.0
    depth_scale_m: float = 40.0  # e-folding distance of the offshore deepening
    berth_depth_m: float = 4.0
    quay_height_m: float = 1.3
    d50_mm: float = 0.3
    beach_slope: float = 0.06  # dry beach rise per metre
    berm_height_m: float = 1.6
    revetment_slope: float = 0.65
    revetment_top_m: float = 2.2
    revetment_toe_m: float = 2.5  # depth at the foot of the rocks
    bank_slope: float = 0.18
    bank_top_m: float = 1.0
    land_rise_m: float = 3.0
    land_rise_scale_m: float = 120.0
    noise_m: float = 0.12
    seabed_noise_m: float = 0.25

    @property
    def dean_a(self) -> float:
        return 0.21 * self.d50_mm ** 0.48


def smooth_noise(shape: tuple[int, int], rng: np.random.Generator, cell_px: float) -> np.ndarray:
    """Smooth value noise in about [-1, 1] with features of ``cell_px`` pixels (cubic upsampling)."""
    import cv2

    h, w = shape
    gh, gw = max(2, int(h / cell_px) + 2), max(2, int(w / cell_px) + 2)
    g = rng.uniform(-1, 1, size=(gh, gw)).astype(np.float32)
    big = cv2.resize(g, (int(gw * cell_px), int(gh * cell_px)), interpolation=cv2.INTER_CUBIC)
    return np.clip(big[:h, :w], -1.5, 1.5)


def _masked_blur(z: np.ndarray, mask: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian blur of ``z`` using only pixels in ``mask`` (normalised convolution)."""
    if sigma_px <= 0.3:
        return z
    m = mask.astype(np.float32)
    num = ndimage.gaussian_filter(np.where(mask, z, 0.0).astype(np.float32), sigma_px)
    den = ndimage.gaussian_filter(m, sigma_px)
    return np.where(mask, num / np.maximum(den, 1e-6), z)


def _shore_type_weights(classes: np.ndarray, shore_land: np.ndarray, inds: np.ndarray,
                        gsd_m: float, sigma_m: float = 6.0) -> list[np.ndarray]:
    """Per-pixel weights of the four shore types (quay, rocks, sand, natural bank) from the shore
    pixels of each type nearby (a Gaussian kernel of ``sigma_m``), so that a short paved strip (a pier
    pad, a boat ramp) does not cast a wedge of berth depth across the water, and profiles blend
    smoothly where the shore type changes. Far from every shore the nearest type takes over."""
    import cv2

    h, w = classes.shape
    kinds = ((classes == ASPHALT) | (classes == SIDEWALK), classes == ROCKS, classes == SAND)
    kinds = kinds + (~(kinds[0] | kinds[1] | kinds[2]),)
    f = max(1, int(sigma_m / gsd_m / 4))  # blur on a coarser grid: a wide kernel at a small cost
    sh, sw = max(1, h // f), max(1, w // f)
    sig = sigma_m / (gsd_m * f)
    nearest = classes[inds[0], inds[1]]
    near_kinds = ((nearest == ASPHALT) | (nearest == SIDEWALK), nearest == ROCKS, nearest == SAND)
    near_kinds = near_kinds + (~(near_kinds[0] | near_kinds[1] | near_kinds[2]),)
    out = []
    for k, nk in zip(kinds, near_kinds):
        ind = (shore_land & k).astype(np.float32)
        small = cv2.resize(ind, (sw, sh), interpolation=cv2.INTER_AREA)
        # a near kernel for the local shore type plus a weak wide one, so far offshore the blend
        # still varies smoothly instead of jumping at the boundaries of the nearest-type regions
        near = cv2.GaussianBlur(small, (0, 0), sig) + 1e-3 * cv2.GaussianBlur(small, (0, 0), sig * 6)
        out.append(cv2.resize(near, (w, h), interpolation=cv2.INTER_LINEAR) + 1e-9 * nk)
    total = sum(out)
    return [o / total for o in out]


def truth_heights(classes: np.ndarray, gsd_m: float, p: TruthTerrainParams,
                  rng: np.random.Generator) -> np.ndarray:
    """Heights (float32 metres, z = 0 at the water level) for a class map on a grid of ``gsd_m``."""
    water = classes == WATER
    land = ~water
    h, w = classes.shape
    if not land.any():
        z = -np.full((h, w), p.max_depth_m, np.float32)
        return z
    if not water.any():
        return np.full((h, w), p.bank_top_m, np.float32)
    shore_land = land & ndimage.binary_dilation(water, iterations=1)
    dist, inds = ndimage.distance_transform_edt(~shore_land, sampling=gsd_m, return_indices=True)
    dist = dist.astype(np.float32)
    weights = _shore_type_weights(classes, shore_land, inds, gsd_m)  # quay, rocks, sand, bank

    # ---- water: a depth profile per shore type, blended by how much of each type is near
    d = np.maximum(dist, gsd_m * 0.5)
    deep = p.max_depth_m * (1.0 - np.exp(-d / p.depth_scale_m))
    # a quay's berth is dredged along the wall, then the seabed follows the general deepening
    berth = p.berth_depth_m * np.exp(-np.maximum(d - 15.0, 0.0) / 15.0)
    profiles = (
        np.maximum(berth, deep),
        np.maximum(np.minimum(0.3 + p.revetment_slope * d, p.revetment_toe_m), deep),
        p.dean_a * d ** (2.0 / 3.0),
        np.maximum(np.minimum(0.15 + p.bank_slope * d, 1.5), deep),
    )
    depth = sum(wt * prof for wt, prof in zip(weights, profiles))
    depth = np.minimum(depth, p.max_depth_m)
    depth = _masked_blur(depth, water, 1.0 / gsd_m)
    cell = max(4.0, 12.0 / gsd_m)
    depth = depth + p.seabed_noise_m * smooth_noise((h, w), rng, cell) * np.clip(depth / p.max_depth_m, 0, 1)
    z_water = -np.maximum(depth, MIN_DEPTH_M)

    # ---- land: shore profile by shore type, a gentle inland rise, natural roughness off the pavement
    rise = p.land_rise_m * (1.0 - np.exp(-dist / p.land_rise_scale_m))
    bases = (
        np.full_like(dist, p.quay_height_m),
        np.minimum(0.1 + p.revetment_slope * dist, p.revetment_top_m),
        np.minimum(0.05 + p.beach_slope * dist, p.berm_height_m),
        np.minimum(0.1 + p.bank_slope * dist, p.bank_top_m),
    )
    z_land = sum(wt * b for wt, b in zip(weights, bases)) + rise
    z_land = _masked_blur(z_land, land, 2.0 / gsd_m)
    paved = (classes == ASPHALT) | (classes == SIDEWALK)
    rough = np.where(classes == ROCKS, 2.5, 1.0) * ~paved
    z_land = z_land + p.noise_m * rough * smooth_noise((h, w), rng, max(3.0, 4.0 / gsd_m))
    if (classes == ROCKS).any():  # boulder-scale bumps on the riprap
        z_land = z_land + 0.15 * (classes == ROCKS) * smooth_noise((h, w), rng, max(2.0, 0.8 / gsd_m))
    z_land = np.maximum(z_land, MIN_DEPTH_M)
    return np.where(water, z_water, z_land).astype(np.float32)
