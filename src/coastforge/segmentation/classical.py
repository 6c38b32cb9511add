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

Step 1 is ``features``, step 3's land classes ``land``; water (step 2), the final clean-up and the
segmenter that runs them all are here.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
from scipy import ndimage as ndi

from ..classes import ASPHALT, DIRT, N_CLASSES, ROCKS, SAND, SIDEWALK, TREES, WATER
from ..config import SegmentConfig
from ..errors import InputError
from ..rng import stage_seed
from ..types import ClassMap, GeoImage
from .features import (Features, box_std, compute_features, disk, fine_texture, labels_in, odd_px,
                       outline_share)
from .land import (CAR_BANK_M, CAR_ROW, LAND, fold_rows, greenness, land_seeds, parked_cars,
                   refine_land_edges, shaded_continuation, shaded_crowns, train_predict)

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
# fragments of a crown standing in pavement: at least this share of them trees, this share of their
# outline asphalt or sidewalk
CROWN_TREE_SHARE = 0.3
CROWN_PAVED_RING = 0.5


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
    Lo = cv2.morphologyEx(F.L, cv2.MORPH_OPEN, disk(0.6 / F.gsd_m))
    return box_std(Lo, odd_px(1.2 / F.gsd_m)), box_std(Lo, odd_px(4.0 / F.gsd_m))


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
    k = odd_px(10.0 / gsd)
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
        water = labels_in(lab2, ids2[ids2 > 0], n2)
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
    _h, _w = water.shape
    r = cfg.water_close_m / gsd
    if r >= 0.75:
        closed = cv2.morphologyEx(water.astype(np.uint8), cv2.MORPH_CLOSE, disk(r),
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
    opened = cv2.morphologyEx(land, cv2.MORPH_OPEN, disk(cfg.pier_open_m / gsd))
    n, lab, st, _c = cv2.connectedComponentsWithStats(opened, connectivity=8)
    big_ids = np.flatnonzero(st[:, cv2.CC_STAT_AREA] * gsd * gsd > cfg.water_hole_max_m2)
    big = labels_in(lab, big_ids[big_ids > 0], n)
    cand = (land > 0) & ~big
    n, lab, st, _c = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=8)
    out = water.copy()
    k = disk(3.0 / gsd)
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
    absorb = (area <= max_m2) & (outline_share(lab, n, np.isin(ids, ring_classes)) >= 0.6)
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
    paved = outline_share(lab, n, (ids == ASPHALT) | (ids == SIDEWALK))
    ok = (area >= min_px) & (trees >= CROWN_TREE_SHARE * area) & (paved >= CROWN_PAVED_RING)
    ok[0] = False
    return ok[lab] & small


def merge_small(ids: np.ndarray, min_px: int, fixed: np.ndarray) -> np.ndarray:
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
            small |= labels_in(lab, tiny, n)
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
    kk = odd_px(6.0 / F.gsd_m)
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
                classes, proba = train_predict(X[m], train.ravel()[m], X[land.ravel()],
                                                stage_seed(seed, "segment", "classical"))
                if classes[-1] == CAR_ROW:
                    classes, proba = fold_rows(classes, proba)
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
        ids = merge_small(ids, min_px, fixed=water)
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
