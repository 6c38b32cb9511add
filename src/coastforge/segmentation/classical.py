"""The default segmenter: no weights, a second or two per 2048 x 2048 image on two cores.

Pipeline (at a reduced working resolution, ~0.4 m/px by default, then upsampled):

1. Per-pixel colour (CIE Lab, saturation, excess green, blue dominance) and texture at two metric
   scales (std of lightness over ~1.2 m and ~4 m, gradient energy, gradient coherence, share of bright
   pixels), plus colour and texture averaged over ~8 m as context; when the image is finer than the
   working raster, also the std of lightness over ~0.6 m measured on the image itself (riprap's stones
   and a verge's tufts average out at ~0.4 m/px; paths and pavements stay smooth).
2. Water first, because everything downstream depends on it: connected regions that are smooth at both
   scales once sun glitter is taken out (a grey opening), cut at colour edges, water-coloured (blue,
   turquoise, green-teal, green-olive, very dark; neutral grey or murky olive-grey only when very
   large and very flat) and large in metres and pixels. Same-coloured smaller pieces join; water then
   grows into connected pixels of its local colour, pale teal shallows and cast shadows, but not into
   rough ground (riprap, whose dark gaps match a grey sea) nor dry sand. Gaps narrower than
   ~2 x ``water_close_m`` are closed, enclosed non-vegetated blobs up to ``water_hole_max_m2`` (boats,
   pier clusters: objects whose terrain is water) are filled unless they are rubble (a breakwater), as
   are fragmented narrow structures still tied to the shore (``pier_open_m``). At full resolution the
   open waterline is re-decided per pixel
   by comparing its colour with the local water and local land-class colours.
3. Land: colour/texture rules (after removing the image's colour cast) label the pixels they are sure
   of; a per-image Gaussian classifier (QDA) trained on those pixels (self-training) labels the rest,
   so thresholds only need to be right for the clear cases of each image (the asphalt / concrete
   lightness split follows the image when haze lifts it). Rows of parked cars are a class of their
   own while it learns; it then hands their probability to pavement where the pixel would otherwise be
   rocks, sand or dirt, and drops it elsewhere. Footpaths and quay walkways (smooth neutral strips
   under ~5 m wide, no darker than the asphalt, with unpaved ground around them) seed as sidewalk
   even when no lighter than a car park. Vegetation is measured
   against the image's own pavement (``greenness``: excess green of the mean colour over ~3 m minus
   the pavement's): canopies are greener, rows of dark parked cars and shadows on pavement are not;
   asphalt is not greener; unsure rough grey ground on the bank is a revetment.
4. Probabilities are box-smoothed (majority filter); priors: rocks are revetments near water, trees
   are textured and not a straight edge; rows of parked cars (textured, not green, beside pavement)
   are neither trees, dirt, sand, sidewalk nor (off the bank) rocks; car-sized blobs on pavement become
   asphalt (parked cars are transient); pixels within ``edge_refine_m`` of a class border are
   re-decided by their own colour against the local class colours (the classifier's 4-8 m windows
   spread classes past their borders); regions smaller than ``min_region_m2`` merge into their
   surroundings, except a crown in pavement split into such fragments, which stays trees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy import ndimage as ndi

from ..classes import ASPHALT, DIRT, GRASS, N_CLASSES, ROCKS, SAND, SIDEWALK, TREES, WATER
from ..config import SegmentConfig
from ..errors import InputError
from ..rng import stage_seed
from ..types import ClassMap, GeoImage

LAND = (ASPHALT, SIDEWALK, GRASS, TREES, DIRT, ROCKS, SAND)
# green-teal water (hue above ~149 deg in a*b*: b* < 0.6 |a*|) is bluer than lawns and canopies, whose
# yellow-green sits at ~120-140 deg (b* > 0.85 |a*|) in our renders and in photos
TEAL_MAX_B = 0.6
# turbid olive-grey water: chroma in Lab below MURKY_MAX_CHROMA, L* below MURKY_MAX_L (pavement under a
# yellow haze has the same hue, a little lighter)
MURKY_MAX_CHROMA = 14.0
MURKY_MAX_L = 40.0
MURKY_GREEN_A = -5.0  # ... or a* below this (greener than hazy pavement) and L* below MURKY_GREEN_MAX_L
MURKY_GREEN_MAX_L = 65.0
# water does not grow into rough ground: std of L* over ~1.2 m above ROUGH_T1, share of bright pixels
# below ROUGH_BRIGHT and gradient coherence below ROUGH_COH (riprap; a wall's shadow edge is coherent)
ROUGH_T1 = 3.0
# pale teal shallows (lighter than the water beside them) join the water whatever their contrast to it
SHALLOW_TEX = 2.0  # ... when smoother than this many times the image's flat texture
# water does not grow into light, yellow ground (dry sand): L* at least BEACH_MIN_L, b* above BEACH_MIN_B
BEACH_MIN_L = 60.0
BEACH_MIN_B = 9.0
# an enclosed blob this large and this much rough (riprap) is a breakwater: it is not filled as water
BREAKWATER_MIN_M2 = 300.0
BREAKWATER_ROUGH = 0.25
ROUGH_BRIGHT = 0.05
ROUGH_COH = 0.55
# riprap's stones are resolved as texture only on images finer than this (m/px)
FINE_GSD_M = 1.0
# a canopy's excess green over the pavement's (``greenness``, mean colour over ~3 m) is above this;
# dark car rows and shadows on pavement sit at or below 0
TREE_MIN_GREEN = 0.015
# ... and asphalt's is below this (the pavement reference is 0 by definition)
PAVED_MAX_GREEN = 0.03
# unsure grey ground this close to the water (m) and rougher than pavement (std of L* over ~1.2 m)
# seeds as rocks: a revetment's slope
BANK_ROCKS_M = 6.0
BANK_T1 = 4.0
# parked cars: std of L* over ~1.2 m above this (car bodies, glass and shadows against pavement) and
# greenness below this; they are not rocks unless this close to the water (a revetment beside a quay)
CAR_MIN_TEX = 6.0
CAR_MAX_GREEN = 0.01
CAR_BANK_M = 6.0
CAR_ROW = N_CLASSES  # the classifier's extra class for car rows (never in a class map)
# footpaths: smooth (std of L* over ~1.2 m below this) neutral strips narrower than PATH_MAX_W_M, at
# least PATH_MIN_M2 in area and PATH_MIN_LEN_M long
PATH_MAX_TEX = 4.0
PATH_MAX_W_M = 5.0
PATH_MIN_M2 = 15.0
PATH_MIN_LEN_M = 10.0
# shaded crowns (``shaded_crowns``): land darker than this share of the pavement's L*, wider than
# SHADE_MIN_W_M, touching a tree region of SHADE_MIN_TREE_M2, at most SHADE_MAX_M2, of these classes
SHADE_REL_L = 0.45
SHADE_MIN_W_M = 2.4
SHADE_MIN_TREE_M2 = 12.0
SHADE_MAX_M2 = 300.0
SHADE_MAX_GSD_M = 1.0  # crowns and their shade are resolved only on fine images
SHADE_FROM = (ASPHALT, SIDEWALK, DIRT)
PATH_RING_M = 2.5  # ... and at most a quarter of the ground this far around it is paved
ROCK_MIN_TEX = 5.0  # riprap's std of L* over ~1.2 m is above this
# fine texture: std of L* over ~FINE_TEX_M measured on the image itself (the working raster is ~0.4 m/px,
# where a riprap's 0.3-1 m stones average out), then averaged onto the working grid; a classifier feature,
# and paths and pavements are smooth at that scale (marina photo: sidewalk median 1.8, riprap 5.1)
FINE_TEX_M = 0.6
PATH_MAX_FINE = 4.0
# hazy images: asphalt and concrete split by lightness above this (see _paving_split)
PAVING_HAZE_L = 62.0
PAVING_SPLIT_SEP = 0.7
# fragments of a crown standing in pavement: at least this share of them trees, this share of their
# outline asphalt or sidewalk
CROWN_TREE_SHARE = 0.3
CROWN_PAVED_RING = 0.5
SPECK_SKEW = 4.0  # speckled sand: median minus mean L* over ~2 m above this


def _odd(n: float) -> int:
    k = max(3, int(round(n)))
    return k if k % 2 else k + 1


def _box_std(x: np.ndarray, k: int) -> np.ndarray:
    m = cv2.blur(x, (k, k))
    sq = cv2.blur(x * x, (k, k))
    return np.sqrt(np.maximum(sq - m * m, 0.0))


@dataclass(frozen=True, eq=False)
class Features:
    """Per-pixel features at the working resolution (float32 arrays, H x W)."""

    L: np.ndarray  # CIE lightness 0..100
    a: np.ndarray  # green (-) .. red (+)
    b: np.ndarray  # blue (-) .. yellow (+)
    sat: np.ndarray  # HSV saturation 0..1
    exg: np.ndarray  # excess green on chromatic coordinates
    bdom: np.ndarray  # blue minus max(red, green), 0..1 units
    tex1: np.ndarray  # std of L over ~1.2 m
    tex2: np.ndarray  # std of L over ~4 m
    grad: np.ndarray  # mean gradient magnitude over ~1.2 m
    bright: np.ndarray  # share of bright pixels (L > 62) within ~3 m: car roofs, decks, not canopies
    coh: np.ndarray  # gradient coherence over ~2 m: 1 at straight edges, low in isotropic texture (canopies)
    ctx: np.ndarray  # (H, W, 4) L, a, b, tex1 averaged over ~8 m
    exg_m: np.ndarray  # excess green of the mean RGB over ~3 m (bright pixels weigh more than dark ones)
    gsd_m: float
    fine: np.ndarray | None = None  # std of L over ~FINE_TEX_M at the image's resolution (None: not finer)

    def stack(self) -> np.ndarray:
        """(H*W, F) matrix for the classifier."""
        # texture is heavy-tailed: its logarithm suits the Gaussian class models far better
        lg = np.log1p
        cols = [self.L, self.a, self.b, self.sat, self.exg, self.bdom, lg(self.tex1), lg(self.tex2), lg(self.grad),
                self.bright, self.coh, self.ctx[..., 0], self.ctx[..., 1], self.ctx[..., 2], lg(self.ctx[..., 3])]
        if self.fine is not None:
            cols.append(lg(self.fine))
        return np.stack([c.ravel() for c in cols], axis=1).astype(np.float32)


def _outline_share(lab: np.ndarray, n: int, hit: np.ndarray, radius_px: int = 1) -> np.ndarray:
    """Per label of ``lab`` (``n`` labels, 0 = background), the share of its outline (background pixels
    within ``radius_px``, square neighbourhood) where ``hit`` holds."""
    k = 2 * radius_px + 1
    lab_d = cv2.dilate(lab.astype(np.float32), np.ones((k, k), np.uint8)).astype(np.int32)
    ring = (lab_d > 0) & (lab == 0)
    ring_n = np.bincount(lab_d[ring], minlength=n).astype(np.float64)
    ring_h = np.bincount(lab_d[ring & hit], minlength=n).astype(np.float64)
    return ring_h / np.maximum(ring_n, 1.0)


def _labels_in(lab: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """``np.isin(lab, ids)`` for labels in [0, n), by a lookup table (several times faster)."""
    table = np.zeros(n, bool)
    table[ids] = True
    return table[lab]


def fine_texture(rgb: np.ndarray, gsd_m: float, shape: tuple[int, int]) -> np.ndarray:
    """Std of L* over ~``FINE_TEX_M`` on ``rgb`` (the full-resolution image), averaged onto a grid of
    ``shape`` (H, W): texture the working raster is too coarse to show (riprap's stones, a verge's tufts)."""
    # 8-bit Lab (L* x 255/100) is several times faster on a large image than float Lab, and its 0.4-unit
    # steps are far below the texture that matters here
    L = cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)[..., 0].astype(np.float32) * (100.0 / 255.0)
    t = _box_std(L, _odd(FINE_TEX_M / gsd_m))
    h, w = shape
    return t if t.shape == (h, w) else cv2.resize(t, (w, h), interpolation=cv2.INTER_AREA)


def compute_features(rgb: np.ndarray, gsd_m: float, fine: np.ndarray | None = None) -> Features:
    """Features of ``rgb`` at ``gsd_m``; ``fine``: ``fine_texture`` of the full-resolution image, when
    ``rgb`` is a downsampled copy."""
    f = rgb.astype(np.float32) * (1.0 / 255.0)
    lab = cv2.cvtColor(f, cv2.COLOR_RGB2LAB)
    L, a, b = lab[..., 0], lab[..., 1], lab[..., 2]
    # channel by channel (speed: numpy's reductions over a short last axis are slow), same values
    r, g, b_ = f[..., 0], f[..., 1], f[..., 2]
    mx, mn = np.maximum(np.maximum(r, g), b_), np.minimum(np.minimum(r, g), b_)
    sat = (mx - mn) / (mx + 1e-3)
    s = (r + g) + b_ + 1e-3  # f.sum(axis=2) adds in this order
    exg = (2.0 * f[..., 1] - f[..., 0] - f[..., 2]) / s
    bdom = f[..., 2] - np.maximum(f[..., 0], f[..., 1])
    k1, k2, kc = _odd(1.2 / gsd_m), _odd(4.0 / gsd_m), _odd(8.0 / gsd_m)
    tex1 = _box_std(L, k1)
    tex2 = _box_std(L, k2)
    gx = cv2.Sobel(L, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(L, cv2.CV_32F, 0, 1, ksize=3)
    grad = cv2.blur(np.sqrt(gx * gx + gy * gy), (k1, k1))
    ctx = cv2.blur(np.dstack([L, a, b, tex1]), (kc, kc))
    kb = _odd(3.0 / gsd_m)
    bright = cv2.blur((L > 62.0).astype(np.float32), (kb, kb))
    kh = _odd(2.0 / gsd_m)
    jxx, jyy, jxy = (cv2.blur(v, (kh, kh)) for v in (gx * gx, gy * gy, gx * gy))
    coh = np.sqrt((jxx - jyy) ** 2 + 4.0 * jxy * jxy) / (jxx + jyy + 1e-3)
    k3 = _odd(3.0 / gsd_m)
    fm = cv2.blur(f, (k3, k3))
    exg_m = (2.0 * fm[..., 1] - fm[..., 0] - fm[..., 2]) / (fm.sum(axis=2) + 1e-3)
    return Features(L, a, b, sat, exg, bdom, tex1, tex2, grad, bright, coh, ctx, exg_m, gsd_m, fine)


# ---------------------------------------------------------------------------------------------- water


def _disk(radius_px: float) -> np.ndarray:
    r = max(1, int(round(radius_px)))
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def _teal(F: Features) -> np.ndarray:
    """Clear shallow water over sand (bright turquoise) and green-teal seas: bluer than any lawn."""
    return (F.a < -6.0) & (F.b < np.maximum(6.0, TEAL_MAX_B * -F.a)) & (F.L < 85)


def water_colour(F: Features) -> np.ndarray:
    """Pixels whose colour water can have: blue/cyan/teal, dark olive-green, very dark, or dark neutral
    grey."""
    L, a, b = F.L, F.a, F.b
    # blue water: saturated blues have a* > 0, so allow red-green up to ~0.4 |b*| (not purple)
    bluish = ((b < -3.0) | (F.bdom > 0.015)) & (L < 88) & (a < 4.0 + 0.4 * np.maximum(-b, 0.0))
    cyan = _teal(F)
    # green-olive water (algae, turbid basins): green at least as strong as yellow, unlike dark forest
    olive = (a < -4.0) & (L < 52) & (b < 1.2 * (-a) + 1.0) & (b > -40.0)
    dark = (L < 20.0) & (a < 6.0)
    neutral = (np.hypot(a, b) < 9.0) & (L < 55.0) & (a < 4.0)
    return bluish | cyan | olive | dark | neutral


def _murky(L, a, b):
    """Murky olive-grey: low chroma, greener than neutral, and darker than pavement under a yellow haze
    (which has the same hue) unless clearly greener than it."""
    return (np.hypot(a, b) < MURKY_MAX_CHROMA) & (((a < -2.0) & (L < MURKY_MAX_L))
                                                   | ((a < MURKY_GREEN_A) & (L < MURKY_GREEN_MAX_L)))


def glint_free_texture(F: Features) -> tuple[np.ndarray, np.ndarray]:
    """``tex1``, ``tex2`` of the lightness after a grey opening over ~1.2 m: sun glitter and wave
    crests on choppy water are small bright specks; without them the water is as flat as calm water,
    while a lawn's or a roof's texture (dark and light alike) stays."""
    Lo = cv2.morphologyEx(F.L, cv2.MORPH_OPEN, _disk(0.6 / F.gsd_m))
    return _box_std(Lo, _odd(1.2 / F.gsd_m)), _box_std(Lo, _odd(4.0 / F.gsd_m))


def detect_water(F: Features, cfg: SegmentConfig, return_open: bool = False):
    """Bool mask of water at the working resolution (boats and piers over water included).

    With ``return_open`` also the open water alone (before boats, piers and gaps were filled)."""
    gsd = F.gsd_m
    px_m2 = gsd * gsd
    h, w = F.L.shape
    # Smoothness adapts a little to the image's own noise floor (JPEG, sensor): the 20th percentile of
    # fine texture is what "flat" looks like here.
    floor = float(np.percentile(F.tex1, 20))
    t1 = max(0.8, 2.5 * floor)
    t2 = max(1.5, 3.0 * floor)
    # smooth once sun glitter is taken out: choppy water sparkles
    s1, s2 = glint_free_texture(F)
    smooth = (s1 < t1) & (s2 < t2)
    colour = water_colour(F)
    # cut along colour edges too: water and asphalt of equal lightness meet without any texture
    ga = np.hypot(cv2.Sobel(F.a, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(F.a, cv2.CV_32F, 0, 1, ksize=3))
    gb = np.hypot(cv2.Sobel(F.b, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(F.b, cv2.CV_32F, 0, 1, ksize=3))
    cedge = (ga + gb) * 0.125 > 5.0
    # murky olive-grey (turbid lakes and rivers): confirmed below only as a very large, very flat region
    cand = (smooth & (colour | _murky(F.L, F.a, F.b)) & ~cedge).astype(np.uint8)
    n, lab, stats, _c = cv2.connectedComponentsWithStats(cand, connectivity=4)
    if n <= 1:
        return (np.zeros((h, w), bool),) * 2 if return_open else np.zeros((h, w), bool)
    areas_m2 = stats[1:, cv2.CC_STAT_AREA] * px_m2
    # a region confirms itself as water only when it is large in metres and in pixels (at 8 m/px a
    # few dark forest pixels cover 1500 m2); smaller pieces join later by matching a confirmed colour
    big = np.flatnonzero((areas_m2 >= cfg.water_min_m2) & (stats[1:, cv2.CC_STAT_AREA] >= 200)) + 1
    if big.size == 0:
        return (np.zeros((h, w), bool),) * 2 if return_open else np.zeros((h, w), bool)
    # Per-component colour statistics decide what each big smooth region is.
    idx = lab.ravel()
    cnt = np.bincount(idx, minlength=n).astype(np.float64)
    cnt[cnt == 0] = 1
    mean = lambda v: np.bincount(idx, weights=v.ravel().astype(np.float64), minlength=n) / cnt  # noqa: E731
    mL, ma, mb, mt2, mexg = mean(F.L), mean(F.a), mean(F.b), mean(s2), mean(F.exg)
    mchroma = np.hypot(ma, mb)
    image_m2 = h * w * px_m2
    keep = np.zeros(n, bool)
    for c in big:
        area = stats[c, cv2.CC_STAT_AREA] * px_m2
        lawn = mexg[c] > 0.3 and mchroma[c] > 20.0  # bright green: a lawn or a sports field
        cast = ((mb[c] < -3.0) or (ma[c] < -4.0 and mL[c] < 50 and mb[c] < 1.2 * -ma[c] + 1.0)
                or (mL[c] < 18 and mb[c] < 8.0) or (ma[c] < -6.0 and mb[c] < max(6.0, TEAL_MAX_B * -ma[c])))
        if cast and not lawn:
            keep[c] = True
        elif _murky(mL[c], ma[c], mb[c]):
            # Murky olive-grey (turbid water; pavement is not this green): very flat and a quarter of
            # the image, however small the image
            keep[c] = area >= max(cfg.water_min_m2, 0.25 * image_m2) and mt2[c] < 0.7 * t2
        elif mchroma[c] < 9.0:
            # Neutral grey: asphalt looks like this too. Only a region that is very large and very
            # flat is taken as (overcast or turbid) water.
            keep[c] = area >= max(20.0 * cfg.water_min_m2, 0.12 * image_m2) and mt2[c] < 0.7 * t2
    if keep.sum() > 1:
        # The largest region sets the scene's water colour. Another region on its own needs a similar
        # colour, or to be very flat: dark forest or hill shadow seen from orbit is dark and fairly
        # smooth too, and a false lake floods the terrain.
        ids_k = np.flatnonzero(keep)
        main = ids_k[np.argmax(stats[ids_k, cv2.CC_STAT_AREA])]
        for c in ids_k:
            de = math.sqrt((mL[c] - mL[main]) ** 2 + (ma[c] - ma[main]) ** 2 + (mb[c] - mb[main]) ** 2)
            if c != main and de >= 8.0 and mt2[c] >= 0.5 * t2:
                keep[c] = False
    if keep.any():
        # Water broken up by boats and piers leaves smaller smooth pieces: they join when they lie near
        # confirmed water (within ~40 m) and their colour matches it closely. Far inland, a dark
        # shadowed slope can match a dark sea's colour.
        ref = np.flatnonzero(keep)
        sized = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] * px_m2 >= 40.0)
        sized = sized[(sized > 0) & ~keep[sized]]
        if sized.size:
            d = np.sqrt((mL[sized, None] - mL[None, ref]) ** 2 + (ma[sized, None] - ma[None, ref]) ** 2
                        + (mb[sized, None] - mb[None, ref]) ** 2).min(axis=1)
            match = sized[d < 5.0]
            reach = max(40.0 / gsd, 6.0)
            for _ in range(4):  # pieces chain outwards from confirmed water, one reach at a time
                dist = cv2.distanceTransform((~keep[lab]).astype(np.uint8), cv2.DIST_L2, 3)
                touches = np.bincount(lab[dist <= reach].ravel(), minlength=n) > 0
                new = match[touches[match] & ~keep[match]]
                if new.size == 0:
                    break
                keep[new] = True
    water = keep[lab]
    if not water.any():
        return (water, water) if return_open else water
    # Grow into connected pixels of the local water colour that texture excluded (water beside boats,
    # piers and the shore, wakes): the reference colour is water's own, averaged over ~10 m, so a
    # bay and a darker basin in the same image each keep their colour.
    k = _odd(10.0 / gsd)
    wf = water.astype(np.float32)
    # shallows over sand or mud: pale, low-chroma green-grey; only ever joined next to water of
    # nearly the same colour (the ΔE test below), which keeps lawns (more chroma) and sand (warmer) out
    murky = (np.hypot(F.a, F.b) < 14.0) & (F.a < -2.0) & (F.L < 75.0) & (s1 < 4.0)  # glitter aside
    # each pass reaches ~5 m further (the reference is only defined near water): gradual shallows
    # (pale water over sand, up to ~45 m wide) need several passes; the water-colour gate keeps the
    # growth off beaches and lawns. Growth stops once a pass adds under 0.05 % of the image.
    # Riprap and rubble: rough isotropic texture (not the straight edge of a wall's shadow, low
    # coherence) with nothing bright nearby (boats, decks, foam). Its dark gaps match a grey or dark
    # sea's colour and would carry the water across the revetment. Stones are only resolved below
    # ~1 m/px; on coarser images every window is a few pixels wide and the test means nothing.
    if gsd <= FINE_GSD_M:
        rough = (F.tex1 > ROUGH_T1) & (F.bright < ROUGH_BRIGHT) & (F.coh < ROUGH_COH)
    else:
        rough = np.zeros(F.L.shape, bool)
    teal = _teal(F)
    # dry sand (light and yellow) is no water's colour: a gradual wet beach must not carry it inland
    beach = (F.L >= BEACH_MIN_L) & (F.b > BEACH_MIN_B) & (F.a > -3.0)
    for _ in range(9):
        before = int(water.sum())
        norm = cv2.blur(wf, (k, k))
        ok = norm > 1e-3
        Lr, ar, br = (cv2.blur(v * wf, (k, k)) / np.maximum(norm, 1e-3) for v in (F.L, F.a, F.b))
        de2 = (F.L - Lr) ** 2 + (F.a - ar) ** 2 + (F.b - br) ** 2
        # shadows cast on water (quay walls, piers, boats): darker, with the chroma scaled down alike
        sc = np.clip(F.L / np.maximum(Lr, 1e-3), 0.0, 1.0)
        shadow = (F.L < Lr - 3.0) & (F.L > 0.25 * Lr) & (np.abs(F.a - ar * sc) + np.abs(F.b - br * sc) < 6.0)
        # very flat pixels continuing the local water colour join whatever their hue (turbid green
        # shallows); a lawn is neither that flat nor that close to the water colour
        # pale teal shallows along a beach or bank: lighter than the water beside them, as smooth
        pale = teal & (F.L > Lr) & (F.tex1 < SHALLOW_TEX * t1)
        close = ok & (((de2 < 36.0) & (colour | murky | (F.tex1 < 1.5 * t1))) | shadow | pale)
        close &= ~rough & ~beach
        n2, lab2 = cv2.connectedComponents((close | water).astype(np.uint8), connectivity=8)
        ids2 = np.unique(lab2[water])
        water = _labels_in(lab2, ids2[ids2 > 0], n2)
        wf = water.astype(np.float32)
        if int(water.sum()) - before < 0.0005 * water.size:
            break
    # vegetation (yellow-green, textured, far from the water colour) keeps an enclosed blob land;
    # teal/cyan shadows between boats are not vegetation
    veg = (((F.exg > 0.12) & (F.b > 0.0)) | ((F.a < -8.0) & (F.b > 5.0))) & (de2 > 100.0) & (F.tex1 > 1.0)
    closed = close_water(water, F, cfg, veg, rough)
    return (closed, water) if return_open else closed


def close_water(water: np.ndarray, F: Features, cfg: SegmentConfig, veg: np.ndarray | None = None,
                rough: np.ndarray | None = None) -> np.ndarray:
    """Close narrow gaps (boats side by side, pier fingers, gangways) and fill enclosed blobs up to a
    pier-cluster size, unless they look vegetated (islands with trees or grass stay land).

    A blob cut by the image border counts as enclosed when most of its outline is water: pier clusters
    often run off the edge of a crop."""
    gsd = F.gsd_m
    h, w = water.shape
    r = cfg.water_close_m / gsd
    if r >= 0.75:
        closed = cv2.morphologyEx(water.astype(np.uint8), cv2.MORPH_CLOSE, _disk(r),
                                  borderType=cv2.BORDER_REPLICATE).astype(bool)
    else:
        closed = water.copy()
    if veg is None:
        veg = (F.a < -8.0) & (F.tex1 > 2.0)
    padded = np.pad(closed, 1, constant_values=True)
    holes = (ndi.binary_fill_holes(padded) & ~padded)[1:-1, 1:-1]
    if holes.any():
        n, lab, stats, _c = cv2.connectedComponentsWithStats(holes.astype(np.uint8), connectivity=4)
        idx = lab.ravel()
        cnt = np.maximum(np.bincount(idx, minlength=n), 1).astype(np.float64)
        vfrac = np.bincount(idx, weights=veg.ravel().astype(np.float64), minlength=n) / cnt
        area_m2 = stats[:, cv2.CC_STAT_AREA] * gsd * gsd
        # outline of each blob: how much of it is image border rather than water
        ring = cv2.dilate(holes.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~holes
        border = np.zeros_like(holes)
        border[0, :] = border[-1, :] = True
        border[:, 0] = border[:, -1] = True
        lab_d = cv2.dilate(lab.astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.int32)
        ring_w = np.bincount(lab_d[ring].ravel(), minlength=n).astype(np.float64)
        on_border = np.bincount(lab[border & holes].ravel(), minlength=n).astype(np.float64)
        water_share = ring_w / np.maximum(ring_w + on_border, 1.0)
        bright = np.bincount(idx, weights=(F.L > 65.0).ravel().astype(np.float64), minlength=n) / cnt
        # a blob mostly outlined by water, or a bright (boats, decks) strip along the border
        enclosed = (water_share >= 0.6) | ((water_share >= 0.4) & (bright >= 0.2))
        fill = (area_m2 <= cfg.water_hole_max_m2) & (vfrac < 0.3) & enclosed
        if rough is not None:
            # a breakwater cut off by the closing is rubble, a quarter or more of it rough; a pier
            # cluster's decks and hulls are smooth or straight-edged
            rfrac = np.bincount(idx, weights=rough.ravel().astype(np.float64), minlength=n) / cnt
            fill &= ~((area_m2 >= BREAKWATER_MIN_M2) & (rfrac >= BREAKWATER_ROUGH))
        fill |= (area_m2 <= 60.0) & (on_border == 0)  # anything boat-sized in open water is filled
        fill[0] = False
        closed |= fill[lab]
    return _absorb_structures(closed, F, cfg, veg)


def _absorb_structures(water: np.ndarray, F: Features, cfg: SegmentConfig, veg: np.ndarray) -> np.ndarray:
    """Pier clusters still tied to the shore (boats moored at the root close the gap) are water too.

    Land is opened with a disk of ``pier_open_m``: what does not belong to a large opened land mass
    is a narrow structure or a small island. Fragmented ones (fingers and boats with water between
    them, so closing them adds much area) become water; solid ones (breakwaters, jetties, islets) and
    vegetated ones stay land."""
    if cfg.pier_open_m <= 0 or water.all() or not water.any():
        return water
    gsd = F.gsd_m
    land = (~water).astype(np.uint8)
    opened = cv2.morphologyEx(land, cv2.MORPH_OPEN, _disk(cfg.pier_open_m / gsd))
    n, lab, st, _c = cv2.connectedComponentsWithStats(opened, connectivity=8)
    big_ids = np.flatnonzero(st[:, cv2.CC_STAT_AREA] * gsd * gsd > cfg.water_hole_max_m2)
    big = _labels_in(lab, big_ids[big_ids > 0], n)
    cand = (land > 0) & ~big
    n, lab, st, _c = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=8)
    out = water.copy()
    k = _disk(3.0 / gsd)
    for i in range(1, n):
        area = st[i, cv2.CC_STAT_AREA] * gsd * gsd
        if area < 20.0 or area > cfg.water_hole_max_m2:
            continue
        x, y, w, h = st[i, :4]
        pad = k.shape[0]
        y0, y1, x0, x1 = max(0, y - pad), min(lab.shape[0], y + h + pad), max(0, x - pad), min(lab.shape[1], x + w + pad)
        comp = (lab[y0:y1, x0:x1] == i).astype(np.uint8)
        if veg[y0:y1, x0:x1][comp > 0].mean() >= 0.3:
            continue
        solidity = comp.sum() / max(1, int(cv2.morphologyEx(comp, cv2.MORPH_CLOSE, k).sum()))
        if solidity < 0.95:
            out[y0:y1, x0:x1] |= comp > 0
    return out


# ------------------------------------------------------------------------------------------------ land


def colour_cast(F: Features, water: np.ndarray) -> tuple[float, float]:
    """The image's colour cast (a*, b*) estimated from land pixels that are nearly neutral (pavement,
    roofs): haze and white balance shift every colour, and the rules below want true neutrals at 0."""
    land = ~water
    # dark-to-mid neutrals (pavement, shadows); bright ones are often sand or concrete with a hue
    near = land & (np.hypot(F.a, F.b) < 12.0) & (F.L > 15) & (F.L < 60)
    if near.sum() < 200:
        return 0.0, 0.0
    a0, b0 = float(np.median(F.a[near])), float(np.median(F.b[near]))
    # a cast is small; anything larger means the "neutrals" are really a coloured surface
    return float(np.clip(a0, -5.0, 5.0)), float(np.clip(b0, -8.0, 8.0))


def pavement_exg(F: Features, water: np.ndarray) -> float:
    """Excess green of the image's smooth near-neutral land (pavement, roofs): the reference a canopy
    must be greener than. Haze and white balance shift excess green as they shift a*/b*; measuring
    vegetation against the pavement of the same image removes that shift."""
    near = ~water & (np.hypot(F.a, F.b) < 14.0) & (F.L > 15) & (F.L < 70) & (F.tex1 < 2.5) & (F.exg < 0.15)
    if near.sum() < 200:
        return 0.0
    return float(np.median(F.exg[near]))


def greenness(F: Features, water: np.ndarray) -> np.ndarray:
    """Excess green of the mean colour over ~3 m, relative to the pavement's (``pavement_exg``).

    The mean colour weighs pixels by their brightness, so a crown's dark shaded side takes the hue of
    its lit leaves (the chromaticity of a nearly black pixel is noise). A canopy is greener than the
    pavement; rows of dark parked cars and shadows on pavement (lit by the blue sky) are as green as
    the pavement or less: the cheapest feature that tells a car row from a row of trees."""
    return F.exg_m - pavement_exg(F, water)


def _paving_split(L, chroma, t1, a, water) -> tuple[float, float]:
    """Lightness below which smooth neutral ground seeds asphalt, and above which it seeds sidewalk:
    55 / 60, unless haze has lifted the image. Then its smooth neutral ground falls clearly into a
    darker and a lighter group (Otsu's split explains PAVING_SPLIT_SEP of the variance, each group at
    least a tenth) split above PAVING_HAZE_L: the thresholds move to that split."""
    m = (chroma < 8.0) & (t1 < 4.0) & (a > -5.0) & (L > 12) & ~water
    v = L[m]
    if v.size < 2000:
        return 55.0, 60.0
    lo, hi = np.percentile(v, [1, 99])
    v = v[(v >= lo) & (v <= hi)]
    v8 = np.clip((v - lo) / max(hi - lo, 1e-3) * 255, 0, 255).astype(np.uint8)
    thr, _ = cv2.threshold(v8.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    t = lo + thr / 255.0 * (hi - lo)
    dark, light = v[v < t], v[v >= t]
    if dark.size < 0.1 * v.size or light.size < 0.1 * v.size:
        return 55.0, 60.0
    between = dark.size * light.size / v.size ** 2 * (light.mean() - dark.mean()) ** 2
    if between < PAVING_SPLIT_SEP * max(float(v.var()), 1e-6) or not (PAVING_HAZE_L <= t <= 78.0):
        return 55.0, 60.0
    return t - 2.5, t + 2.5


def land_seeds(F: Features, water: np.ndarray, rocks_shore_m: float = 0.0,
               green: np.ndarray | None = None) -> np.ndarray:
    """Rule labels (int8, -1 = unsure) for pixels whose class is clear from colour and texture alone.

    ``green``: ``greenness(F, water)``, computed here when not given."""
    a0, b0 = colour_cast(F, water)
    if green is None:
        green = greenness(F, water)
    L, t1, t2 = F.L, F.tex1, F.tex2
    a, b = F.a - a0, F.b - b0
    chroma = np.hypot(a, b)
    hue_green = ((a < -5.0) & (b > -2.0)) | (F.exg > 0.08)
    # sand strewn with dark specks (debris, footprints, small shadows) is as textured as riprap, but
    # its median colour over ~2 m stays sand; riprap's median is its stones' grey. Only textured
    # pixels (where the riprap rule would fire) are judged so: smooth light dirt keeps the dirt rule
    sandy = _sandy(F, a0, b0) & (t1 > ROCK_MIN_TEX)
    l_asph, l_side = _paving_split(L, chroma, t1, a, water)
    rules = {
        # canopies are textured at the 4 m scale; in shade they are dark whatever their hue
        # ... and, lit or shaded, greener than the pavement (dark car rows and shadows are not)
        TREES: (((hue_green & (L < 48)) | (L < 30)) & (t2 > 6.0) & (t1 > 3.5) & (a < 8.0) & (F.bright < 0.03)
                & (green > TREE_MIN_GREEN)),
        GRASS: hue_green & (L > 20) & (t1 < 3.5) & (t2 < 7.0),
        # asphalt is no greener than the image's pavement (dry, pale grass can be as grey); light
        # concrete often has a tint of its own, so sidewalks are not held to this
        ASPHALT: ((chroma < 8.0) & (L > 12) & (L < l_asph) & (t1 < 4.0) & (a > -5.0)
                  & (green < PAVED_MAX_GREEN)),
        SIDEWALK: (chroma < 10.0) & (L >= l_side) & (t1 < 6.0) & (a > -5.0),
        # bare earth: warm (orange-yellow hue), some chroma, mid lightness; sand is the light version
        DIRT: (a > 1.0) & (b > 6.0) & (chroma > 7.0) & (L > 25) & (L < 60) & (t1 < 6.0),
        SAND: ((L >= 60) & (b > 9.0) & (a > -3.0) & (a < 10.0)) | (sandy & ~hue_green),
        # riprap: mid-grey, fine-grained texture, only a weak colour cast
        ROCKS: (chroma < 16.0) & (L > 33) & (L < 72) & (t1 > ROCK_MIN_TEX) & (a > -9.0) & (a < 6.0) & ~sandy,
    }
    seeds = np.full(L.shape, -1, np.int8)
    count = np.zeros(L.shape, np.uint8)
    for cid, m in rules.items():
        count += m
    for cid, m in rules.items():
        seeds[m & (count == 1)] = cid
    if rocks_shore_m > 0 and water.any():
        dist = ndi.distance_transform_edt(~water) * F.gsd_m
        seeds[(seeds == ROCKS) & (dist > rocks_shore_m)] = -1
        # on the bank itself, grey ground rougher than pavement and not vegetated is a revetment even
        # when darker or finer-grained than the riprap rule asks (wet or shaded stones)
        bank = ((dist <= BANK_ROCKS_M) & (chroma < 12.0) & (L > 20) & (L < 72) & (t1 > BANK_T1)
                & (green < TREE_MIN_GREEN) & (F.bright < 0.05))
        seeds[bank & (seeds < 0)] = ROCKS
    seeds[water] = -1
    # a footpath's pixels the rules took for asphalt (or were unsure of) are sidewalk
    path = footpaths(F, water, seeds, chroma, a)
    seeds[path & ((seeds < 0) | (seeds == ASPHALT))] = SIDEWALK
    if F.fine is not None:  # paths and pavements are smooth at the fine scale; light riprap is not
        seeds[(seeds == SIDEWALK) & (F.fine >= PATH_MAX_FINE)] = -1
    return seeds


def _sandy(F: Features, a0: float = 0.0, b0: float = 0.0) -> np.ndarray:
    """Pixels whose median colour over ~2 m is sand's (light, yellow; ``a0``, ``b0``: the colour cast)."""
    k = min(_odd(2.0 / F.gsd_m), 7)  # cv2.medianBlur takes float32 up to 5 px; uint8 beyond
    to8 = lambda v, lo, sc: np.clip((v - lo) * sc, 0, 255).astype(np.uint8)  # noqa: E731
    Lm = cv2.medianBlur(to8(F.L, 0.0, 2.55), k).astype(np.float32) / 2.55
    bm = cv2.medianBlur(to8(F.b - b0, -64.0, 2.0), k).astype(np.float32) / 2.0 - 64.0
    am = cv2.medianBlur(to8(F.a - a0, -64.0, 2.0), k).astype(np.float32) / 2.0 - 64.0
    # specks are dark outliers: they pull the mean below the median (textured dirt or riprap is more
    # symmetric about its median)
    skew = Lm - cv2.blur(F.L, (k, k))
    return (Lm >= 60.0) & (bm > 9.0) & (am > -3.0) & (am < 10.0) & (skew > SPECK_SKEW)


def footpaths(F: Features, water: np.ndarray, seeds: np.ndarray, chroma: np.ndarray,
              a: np.ndarray) -> np.ndarray:
    """Footpaths and quay walkways: smooth, neutral strips narrower than ``PATH_MAX_W_M`` and at least
    as light as the image's asphalt, that run between unpaved ground (lawn, bank, water) for most of
    their outline. Concrete paths are often no lighter than a sun-bleached car park, so colour alone
    cannot tell them apart; being a narrow strip that no pavement borders does (roads and lots are
    wider, and the slivers an opening cuts off their edges lie along pavement)."""
    gsd = F.gsd_m
    asph = seeds == ASPHALT
    if asph.sum() < 50:
        return np.zeros(F.L.shape, bool)
    l_ref = float(np.median(F.L[asph]))
    # (bright concrete is sidewalk by the lightness rule already; mostly-bright strips are roofs, decks)
    paved = (~water & (chroma < 10.0) & (a > -6.0) & (F.tex1 < PATH_MAX_TEX) & (F.L >= l_ref)
             & (F.bright < 0.5)).astype(np.uint8)
    r = PATH_MAX_W_M / (2.0 * gsd)
    if r < 1.0:
        return np.zeros(F.L.shape, bool)
    # any pavement, light or dark, counts as "paved" along a strip's outline
    pavement = ((seeds == ASPHALT) | (seeds == SIDEWALK) | (paved > 0)).astype(np.uint8)
    wide = cv2.morphologyEx(pavement, cv2.MORPH_OPEN, _disk(r)).astype(bool)
    narrow = (paved > 0) & ~wide
    n, lab, st, _c = cv2.connectedComponentsWithStats(narrow.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(F.L.shape, bool)
    # the outline is looked at PATH_RING_M out: a kerb between light and dark paving is textured, so
    # neither side's rule claims the pixels right at it
    paved_share = _outline_share(lab, n, pavement > 0, max(1, int(round(PATH_RING_M / gsd))))
    area_m2 = st[:, cv2.CC_STAT_AREA] * gsd * gsd
    long_side = np.maximum(st[:, cv2.CC_STAT_WIDTH], st[:, cv2.CC_STAT_HEIGHT]) * gsd
    ok = (area_m2 >= PATH_MIN_M2) & (long_side >= PATH_MIN_LEN_M) & (paved_share <= 0.25)
    ok[0] = False
    return ok[lab]


def parked_cars(F: Features, green: np.ndarray, seeds: np.ndarray, reach_m: float = 5.0) -> np.ndarray:
    """Where rows of parked cars likely are: strongly textured (painted metal, glass and their shadows
    against the pavement), no greener than the pavement, and beside pavement the rules are sure of
    (a car is ~4.5 m long, a double row of them ~10 m deep, so a car row's pixels are within
    ``reach_m`` of an aisle). The terrain under parked cars is pavement."""
    paved = ((seeds == ASPHALT) | (seeds == SIDEWALK)).astype(np.uint8)
    if not paved.any():
        return np.zeros(F.L.shape, bool)
    near = cv2.dilate(paved, _disk(reach_m / F.gsd_m)).astype(bool)
    return near & (F.tex1 > CAR_MIN_TEX) & (green < CAR_MAX_GREEN)


def _fold_rows(classes: np.ndarray, proba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hand the car-row class's probability to pavement where the pixel would otherwise be rocks, sand
    or dirt (what a car row is mistaken for); elsewhere (crowns, lawns, paths) drop it: there it only
    stood in for texture the other classes lack. Pavement means asphalt, or sidewalk where that is the
    likelier of the two."""
    j = classes.size - 1
    rest = proba[:, :j]
    alt = classes[:j][rest.argmax(axis=1)]
    row = np.where(np.isin(alt, (ROCKS, SAND, DIRT)), proba[:, j], 0.0)
    out = rest.copy()
    ia = np.flatnonzero(classes[:j] == ASPHALT)
    isw = np.flatnonzero(classes[:j] == SIDEWALK)
    if ia.size and isw.size:
        to_sw = out[:, isw[0]] > out[:, ia[0]]
        out[:, ia[0]] += np.where(to_sw, 0.0, row)
        out[:, isw[0]] += np.where(to_sw, row, 0.0)
    elif ia.size or isw.size:
        out[:, (ia if ia.size else isw)[0]] += row
    # a pixel that only the row class explains at all keeps no probability: the majority filter that
    # follows gives it its neighbours' class (pavement beside a car row, canopy inside a dark crown)
    out /= np.maximum(out.sum(axis=1, keepdims=True), 1e-12)
    return classes[:j], out


def _train_predict(X: np.ndarray, y: np.ndarray, Xall: np.ndarray, seed: int, per_class: int = 50000,
                   reg: float = 0.05):
    """Fit one full-covariance Gaussian per class (QDA) on up to ``per_class`` seed pixels of each
    class (no class prior, so unequal counts do not bias it; enough that which pixels were drawn hardly
    matters); return the classes and their posterior probabilities for ``Xall``. QDA predicts a
    megapixel in tens of milliseconds, where tree ensembles take seconds on two busy cores."""
    rng = np.random.default_rng(seed)
    mu_all = X.mean(axis=0)
    sd_all = X.std(axis=0) + 1e-3
    Z = (X - mu_all) / sd_all
    Zall = ((Xall - mu_all) / sd_all).astype(np.float32)
    classes, loglik = [], []
    eye = np.eye(X.shape[1], dtype=np.float64)
    for c in np.unique(y):
        idx = np.flatnonzero(y == c)
        if idx.size > per_class:
            idx = rng.choice(idx, per_class, replace=False)
        zc = Z[idx].astype(np.float64)
        mu = zc.mean(axis=0)
        cov = np.cov(zc, rowvar=False) if idx.size > 1 else eye.copy()
        cov = (1.0 - reg) * cov + reg * eye  # shrinkage keeps thin classes well posed
        chol = np.linalg.cholesky(cov)
        inv = np.linalg.inv(chol).astype(np.float32)
        d = Zall @ inv.T
        d -= (mu.astype(np.float32) @ inv.T)[None, :]
        ll = -0.5 * np.einsum("ij,ij->i", d, d) - float(np.log(np.diag(chol)).sum())
        classes.append(int(c))
        loglik.append(ll)
    ll = np.stack(loglik, axis=1)
    ll -= ll.max(axis=1, keepdims=True)
    p = np.exp(ll)
    p /= p.sum(axis=1, keepdims=True)
    return np.array(classes), p.astype(np.float32)


def refine_land_edges(ids: np.ndarray, F: Features, land: np.ndarray, band_m: float) -> np.ndarray:
    """Re-decide land pixels near a class border by their own fine features.

    The classifier sees texture and context averaged over 4-8 m, so a class spreads up to half that
    window past its true border (a crown's texture makes the lawn around it "trees"). Within
    ``band_m`` of a border, each pixel takes the class, among those present nearby, whose local mean
    colour (L*, a*, b* over ~4 x ``band_m``) it is nearest to, in units of that class's own colour
    spread in the image. Colour only: texture is itself a window statistic, high on both sides of
    every border."""
    gsd = F.gsd_m
    r = max(1, int(round(band_m / gsd)))
    # crowns and riprap are textured at every scale: a single pixel of either looks like any class,
    # so trees and rocks neither give nor take pixels here
    present = [c for c in LAND if c not in (TREES, ROCKS) and (ids[land] == c).any()]
    if len(present) < 2:
        return ids
    kb = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
    mx = cv2.dilate(ids, kb)
    mn = cv2.erode(ids, kb)
    band = land & (mx != mn) & (ids != TREES) & (ids != ROCKS)
    if not band.any():
        return ids
    feats = np.dstack([F.L, F.a, F.b]).astype(np.float32)
    k = _odd(4.0 * band_m / gsd)
    ys, xs = np.nonzero(band)
    px = feats[ys, xs]
    best = np.full(ys.size, np.inf, np.float32)
    out = ids.copy()
    for c in present:
        m = (ids == c) & land
        sd = feats[m].std(axis=0) + 1.0
        n = cv2.blur(m.astype(np.float32), (k, k))
        mean = cv2.blur(feats * m[..., None], (k, k)) / np.maximum(n, 1e-3)[..., None]
        d = (((px - mean[ys, xs]) / sd) ** 2).sum(axis=1)
        d[n[ys, xs] < 0.05] = np.inf  # only classes present nearby compete
        better = d < best
        best[better] = d[better]
        out[ys[better], xs[better]] = c
    return out


def shaded_crowns(ids: np.ndarray, F: Features, land: np.ndarray) -> np.ndarray:
    """Deep shade attached to a canopy is the canopy: the crown's own shaded side and the shadow right
    under it are nearly black, bluish (lit by the sky) and so no greener than the pavement, and the
    classifier calls them pavement. Dark land (below ``SHADE_REL_L`` of the pavement's lightness)
    wider than a car (an opening of ``SHADE_MIN_W_M`` removes dark cars) that touches a tree region of
    at least ``SHADE_MIN_TREE_M2`` becomes trees, up to ``SHADE_MAX_M2`` (a building's shadow stays)."""
    gsd = F.gsd_m
    trees = ids == TREES
    paved = land & (ids == ASPHALT)
    if gsd > SHADE_MAX_GSD_M or trees.sum() * gsd * gsd < SHADE_MIN_TREE_M2 or paved.sum() < 200:
        return ids
    l_ref = float(np.median(F.L[paved]))
    # the width test sees the whole dark blob, crown pixels included; only pavement-like pixels change
    paving = _labels_in(ids, np.array(SHADE_FROM), N_CLASSES)
    dark = land & (F.L < SHADE_REL_L * l_ref) & ((ids == TREES) | paving)
    dark = cv2.morphologyEx(dark.astype(np.uint8), cv2.MORPH_OPEN, _disk(SHADE_MIN_W_M / (2.0 * gsd)))
    if not dark.any():
        return ids
    n, lab, st, _c = cv2.connectedComponentsWithStats(dark, connectivity=8)
    # tree regions big enough to be crowns (not a car row the classifier took for trees)
    tn, tlab, tst, _tc = cv2.connectedComponentsWithStats(trees.astype(np.uint8), connectivity=8)
    crowns = _labels_in(tlab, np.flatnonzero(tst[:, cv2.CC_STAT_AREA] * gsd * gsd >= SHADE_MIN_TREE_M2), tn)
    crowns &= tlab > 0
    touch = cv2.dilate(crowns.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    hit = np.bincount(lab[touch & (lab > 0)], minlength=n) > 0
    hit &= st[:, cv2.CC_STAT_AREA] * gsd * gsd <= SHADE_MAX_M2
    hit[0] = False
    out = ids.copy()
    out[hit[lab] & paving] = TREES
    return out


def shaded_continuation(ids: np.ndarray, F: Features, land: np.ndarray, cls: int, into: tuple[int, ...],
                        reach_m: float = 6.0, tol: float = 4.0) -> np.ndarray:
    """Grow class ``cls`` into the shade on it: pixels of the classes ``into`` connected to ``cls`` that
    are darker than its local colour (averaged over ``reach_m``) with a* and b* scaled down alike (a
    shadow dims a surface without changing its hue) within ``tol``. A tree's mottled shade on a beach
    reads as riprap to the rules; riprap itself is grey, not dimmed sand. Only the classes the shade is
    mistaken for are taken: dirt has sand's hue at a lower lightness too, and stays."""
    gsd = F.gsd_m
    m = (ids == cls) & land
    if m.sum() < 20:
        return ids
    k = _odd(reach_m / gsd)
    mf = m.astype(np.float32)
    norm = cv2.blur(mf, (k, k))
    near = (norm > 0.05) & land & _labels_in(ids, np.array(into), N_CLASSES)
    if not near.any():
        return ids
    Lr, ar, br = (cv2.blur(v * mf, (k, k)) / np.maximum(norm, 1e-3) for v in (F.L, F.a, F.b))
    sc = np.clip(F.L / np.maximum(Lr, 1e-3), 0.0, 1.0)
    shade = near & (F.L < Lr - 3.0) & (F.L > 0.3 * Lr) & (np.abs(F.a - ar * sc) + np.abs(F.b - br * sc) < tol)
    n, lab = cv2.connectedComponents((shade | m).astype(np.uint8), connectivity=8)
    keep = np.zeros(n, bool)
    keep[np.unique(lab[m])] = True
    keep[0] = False
    out = ids.copy()
    out[shade & keep[lab]] = cls
    return out


def _absorb_into_asphalt(ids: np.ndarray, gsd_m: float, max_m2: float) -> np.ndarray:
    """Parked cars (and their rows) are transient objects on pavement: small blobs of rocks, dirt or
    sand mostly surrounded by pavement, and small sidewalk or car-sized dark "tree" blobs mostly
    surrounded by asphalt, become asphalt. Each class is taken on its own so a row of cars along a
    lot's kerb is not merged with the kerb."""
    if max_m2 <= 0:
        return ids
    out = ids.copy()
    paved = (ASPHALT, SIDEWALK)
    for cls, limit, ring_classes in ((ROCKS, max_m2, paved), (DIRT, max_m2, paved), (SAND, max_m2, paved),
                                     (SIDEWALK, max_m2, (ASPHALT,)), (TREES, min(max_m2, 12.0), (ASPHALT,))):
        out = _absorb(out, cls, limit, gsd_m, ring_classes)
    return out


def _absorb(ids: np.ndarray, cls: int, max_m2: float, gsd_m: float, ring_classes: tuple[int, ...]) -> np.ndarray:
    cand = (ids == cls).astype(np.uint8)
    n, lab, stats, _c = cv2.connectedComponentsWithStats(cand, connectivity=8)
    if n <= 1:
        return ids
    area = stats[:, cv2.CC_STAT_AREA] * gsd_m * gsd_m
    absorb = (area <= max_m2) & (_outline_share(lab, n, np.isin(ids, ring_classes)) >= 0.6)
    absorb[0] = False
    out = ids.copy()
    out[absorb[lab]] = ASPHALT
    return out


def _fragmented_crowns(ids: np.ndarray, small: np.ndarray, min_px: int) -> np.ndarray:
    """Pixels of crowns split into fragments each below the minimum region (lit canopy, its shaded side
    and gaps read as trees, grass and rocks) that together make a region of ``min_px``, with at least
    CROWN_TREE_SHARE of trees, standing in pavement (CROWN_PAVED_RING of the outline is asphalt or
    sidewalk): the trees of a car park's islands, which would otherwise melt into the pavement."""
    n, lab, stats, _c = cv2.connectedComponentsWithStats(small.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(ids.shape, bool)
    area = stats[:, cv2.CC_STAT_AREA].astype(np.float64)
    trees = np.bincount(lab[small], weights=(ids[small] == TREES).astype(np.float64), minlength=n)
    paved = _outline_share(lab, n, (ids == ASPHALT) | (ids == SIDEWALK))
    ok = (area >= min_px) & (trees >= CROWN_TREE_SHARE * area) & (paved >= CROWN_PAVED_RING)
    ok[0] = False
    return ok[lab] & small


def _merge_small(ids: np.ndarray, min_px: int, fixed: np.ndarray) -> np.ndarray:
    """Regions smaller than ``min_px`` take the class of the nearest larger region (``fixed`` kept),
    except crowns in pavement that were split into such regions (``_fragmented_crowns``)."""
    if min_px <= 1:
        return ids
    small = np.zeros(ids.shape, bool)
    for c in np.unique(ids):
        n, lab, stats, _ = cv2.connectedComponentsWithStats((ids == c).astype(np.uint8), connectivity=4)
        tiny = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < min_px)
        tiny = tiny[tiny > 0]
        if tiny.size:
            small |= _labels_in(lab, tiny, n)
    small &= ~fixed
    if not small.any() or small.all():
        return ids
    crowns = _fragmented_crowns(ids, small, min_px)
    out = ids
    if crowns.any():
        out = ids.copy()
        out[crowns] = TREES
        small = small & ~crowns
        if not small.any():
            return out
    _d, (ri, ci) = ndi.distance_transform_edt(small, return_indices=True)
    return out[ri, ci]


def refine_water_edge(rgb: np.ndarray, ids_small: np.ndarray, water_small: np.ndarray, F: Features,
                      band_small: int = 2, open_water: np.ndarray | None = None) -> np.ndarray:
    """Upsample the class ids to the image grid and sharpen the waterline at full resolution.

    Within ``band_small`` working pixels of the water edge, a full-resolution pixel is water when its
    colour is nearer the local water colour than the local land colour (both averaged over ~6 m at
    the working resolution). Land pixels turned to water become WATER; water turned land takes the
    nearest land class."""
    H, W = rgb.shape[:2]
    h, w = ids_small.shape
    ids = cv2.resize(ids_small, (W, H), interpolation=cv2.INTER_NEAREST)
    if not water_small.any() or water_small.all():
        return ids
    k = np.ones((2 * band_small + 1, 2 * band_small + 1), np.uint8)
    wu = water_small.astype(np.uint8)
    band_s = cv2.dilate(wu, k).astype(bool) & ~cv2.erode(wu, k).astype(bool)
    band = cv2.resize(band_s.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)
    ys, xs = np.nonzero(band)
    kk = _odd(6.0 / F.gsd_m)
    wf = water_small.astype(np.float32)
    nw = cv2.blur(wf, (kk, kk))
    nl = cv2.blur(1.0 - wf, (kk, kk))
    lab_s = np.dstack([F.L, F.a, F.b])
    mw = cv2.blur(lab_s * wf[..., None], (kk, kk)) / np.maximum(nw, 1e-3)[..., None]
    ml = cv2.blur(lab_s * (1.0 - wf)[..., None], (kk, kk)) / np.maximum(nl, 1e-3)[..., None]
    # sample the small maps at the band pixels (nearest working pixel is enough for ~6 m averages)
    sy = np.minimum((ys * h) // H, h - 1)
    sx = np.minimum((xs * w) // W, w - 1)
    ok = (nw[sy, sx] > 0.05) & (nl[sy, sx] > 0.05)
    ys, xs, sy, sx = ys[ok], xs[ok], sy[ok], sx[ok]
    if ys.size == 0:
        return ids
    # full-resolution colour of the band pixels, lightly smoothed against JPEG noise
    y0, y1, x0, x1 = max(0, ys.min() - 1), min(H, ys.max() + 2), max(0, xs.min() - 1), min(W, xs.max() + 2)
    sub = cv2.blur(rgb[y0:y1, x0:x1], (3, 3))
    px = sub[ys - y0, xs - x0].astype(np.float32).reshape(-1, 1, 3) * (1.0 / 255.0)
    lab = cv2.cvtColor(px, cv2.COLOR_RGB2LAB).reshape(-1, 3)
    # nearest land class at the working resolution: the land side is compared with the colour of that
    # class nearby (a dark revetment between water and a bright lawn is not judged by the lawn)
    land_s = ~water_small
    _d, (ri, ci) = ndi.distance_transform_edt(~land_s, return_indices=True)
    land_ids = ids_small[ri, ci]
    near_cls = land_ids[sy, sx]
    ml_px = ml[sy, sx].copy()
    for c in np.unique(near_cls):
        cf = (ids_small == c).astype(np.float32)
        nc = cv2.blur(cf, (kk, kk))
        mc = cv2.blur(lab_s * cf[..., None], (kk, kk)) / np.maximum(nc, 1e-3)[..., None]
        sel = (near_cls == c) & (nc[sy, sx] > 0.02)
        ml_px[sel] = mc[sy[sel], sx[sel]]
    dw = ((lab - mw[sy, sx]) ** 2).sum(axis=1)
    dl = ((lab - ml_px) ** 2).sum(axis=1)
    is_w = dw < dl
    cur_w = ids[ys, xs] == WATER
    to_w = is_w & ~cur_w
    to_l = ~is_w & cur_w
    if open_water is not None:
        # boats, piers and gaps filled as water stay water: only the open waterline is sharpened
        filled = (water_small & ~open_water).astype(np.uint8)
        to_l &= ~cv2.dilate(filled, k).astype(bool)[sy, sx]
    ids[ys[to_w], xs[to_w]] = WATER
    ids[ys[to_l], xs[to_l]] = land_ids[sy[to_l], sx[to_l]]
    return ids


class ClassicalSegmenter:
    """Colour/texture rules + a per-image classifier trained on its confident pixels (self-training)."""

    def __init__(self, config: SegmentConfig | None = None, **options):
        if options:
            raise InputError(
                f"the classical segmenter takes no options, got {', '.join(sorted(options))}; "
                "tune it with --set segment.KEY=VALUE instead"
            )
        self.config = config or SegmentConfig()

    def work_scale(self, width: int, height: int, gsd_m: float) -> float:
        cfg = self.config
        s = min(1.0, gsd_m / max(gsd_m, cfg.work_gsd_m))
        n = width * height * s * s
        if n > cfg.max_work_px:
            s *= math.sqrt(cfg.max_work_px / n)
        return s

    def segment_small(self, rgb: np.ndarray, gsd_m: float, seed: int, pre: tuple | None = None,
                      fine: np.ndarray | None = None):
        """Class ids, water mask, features and open-water mask at the resolution of ``rgb`` (the
        working resolution). ``pre`` = (features, water, open water) already computed for ``rgb``;
        ``fine``: ``fine_texture`` of the full-resolution image on this grid."""
        cfg = self.config
        if pre is not None:
            F, water, open_water = pre
            if fine is not None and F.fine is None:
                F = replace(F, fine=fine)
        else:
            F = compute_features(rgb, gsd_m, fine)
            water, open_water = detect_water(F, cfg, return_open=True)
        green = greenness(F, water)
        seeds = land_seeds(F, water, cfg.rocks_shore_m, green)
        h, w = water.shape
        land = ~water
        # rows of parked cars get a class of their own while the classifier learns: folded into
        # pavement they widen its spread, left out they are mistaken for rocks, sand or dirt
        cars = parked_cars(F, green, seeds)
        rows = cars & (seeds < 0) & land
        train = seeds
        if rows.sum() >= 20:
            train = seeds.copy()
            train[rows] = CAR_ROW
        ids = np.full((h, w), WATER, np.uint8)
        present = [c for c in LAND if (seeds == c).sum() >= 20]
        if land.any():
            if not present:
                # Nothing recognisable on land: call it dirt rather than guess a specific surface.
                ids[land] = DIRT
            elif len(present) == 1 or not cfg.self_training:
                ids[land] = self._rule_fill(seeds, land, present)
            else:
                X = np.concatenate([F.stack(), green.reshape(-1, 1)], axis=1)
                m = train.ravel() >= 0
                classes, proba = _train_predict(X[m], train.ravel()[m], X[land.ravel()],
                                                stage_seed(seed, "segment", "classical"))
                if classes[-1] == CAR_ROW:
                    classes, proba = _fold_rows(classes, proba)
                full = np.zeros((h * w, N_CLASSES), np.float32)
                full[np.ix_(land.ravel(), classes)] = proba
                full = full.reshape(h, w, N_CLASSES)
                k = 2 * max(0, int(cfg.smooth_px)) + 1
                if k > 1:
                    full = cv2.blur(full, (k, k))  # majority filter on probabilities
                d = ndi.distance_transform_edt(~water) * gsd_m if water.any() else None
                if d is not None and cfg.rocks_shore_m > 0:
                    # Rocks in a coastal scene are revetments and breakwaters along the water; inland,
                    # the same texture is usually rows of parked cars or gravel roofs.
                    full[..., ROCKS] *= np.where(d <= cfg.rocks_shore_m, 1.0, 0.05).astype(np.float32)
                # canopies are textured: a smooth dark lawn (shade, wet or lush grass) is not a tree
                # ... nor is the edge between a light and a dark patch of lawn (coherent gradients)
                notree = (F.tex2 < 7.5) | (F.tex1 < 3.0) | (F.coh > 0.6)
                full[..., TREES] *= np.where(notree, 0.05, 1.0).astype(np.float32)
                # parked cars stand on pavement: not trees, dirt, sand, sidewalk, nor rocks, except on
                # the bank itself (a revetment's stones beside a quay's pavement look like a car row)
                for c in (TREES, DIRT, SAND, SIDEWALK):
                    full[..., c] *= np.where(cars, 0.05, 1.0).astype(np.float32)
                if d is not None:
                    cars &= d > CAR_BANK_M
                full[..., ROCKS] *= np.where(cars, 0.05, 1.0).astype(np.float32)
                ids[land] = full.argmax(axis=2).astype(np.uint8)[land]
                if cfg.edge_refine_m > 0:
                    ids = refine_land_edges(ids, F, land, cfg.edge_refine_m)
                ids = _absorb_into_asphalt(ids, gsd_m, cfg.vehicle_area_max_m2)
                ids = shaded_crowns(ids, F, land)
                ids = shaded_continuation(ids, F, land, SAND, into=(ROCKS,))
        min_px = int(round(cfg.min_region_m2 / (gsd_m * gsd_m)))
        ids = _merge_small(ids, min_px, fixed=water)
        ids[water] = WATER
        ids[(ids == WATER) & ~water] = ASPHALT  # land that bordered nothing but water
        return ids, water, F, open_water

    @staticmethod
    def _rule_fill(seeds: np.ndarray, land: np.ndarray, present: list[int]) -> np.ndarray:
        known = seeds >= 0
        if not known.any():
            return np.full(int(land.sum()), present[0], np.uint8)
        _d, (ri, ci) = ndi.distance_transform_edt(~known, return_indices=True)
        return seeds[ri, ci].astype(np.uint8)[land]

    def segment(self, image: GeoImage, seed: int = 0, pre: tuple | None = None) -> ClassMap:
        """``pre``: (features, water, open water) at the working resolution, when the caller has them."""
        rgb = image.rgb
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise InputError(f"classical segmentation needs an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
        H, W = rgb.shape[:2]
        g = image.grid
        s = self.work_scale(W, H, g.gsd_m)
        fine = None
        if s < 0.999:
            w, h = max(8, int(round(W * s))), max(8, int(round(H * s)))
            small = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)
            fine = fine_texture(rgb, g.gsd_m, (h, w))
        else:
            w, h, small = W, H, rgb
        gsd_w = g.gsd_m * W / w
        ids, water, F, open_water = self.segment_small(small, gsd_w, seed, pre, fine)
        if (w, h) != (W, H):
            ids = refine_water_edge(rgb, ids, water, F, open_water=open_water)
        return ClassMap(ids=np.ascontiguousarray(ids, dtype=np.uint8), grid=g)
