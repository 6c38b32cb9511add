"""Embedders: an image crop of one object (+ its metres per pixel) → an L2-normalised vector.

Protocol (every embedder): ``name``, ``settings`` (a JSON-able dict recorded in library.json),
``dim`` and ``embed(images, gsd_m) -> (n, dim) float32`` with unit rows.

``DefaultEmbedder`` needs no weights. Queries come at any yaw on water or ground, so it

1. segments the object from its background with a border colour model (the crop's outer ring is
   background; minority colours on the ring are parts of the object or of neighbours and are dropped),
   drops cast shadows (darker, bluer copies of the background) except inside the object's convex hull
   (grey parts of an object on grey ground) and sun glints on water (bright specks), grows faint parts by
   hysteresis and cuts neighbours joined by narrow bridges (cars parked side by side);
2. normalises rotation: the mask's principal axis becomes horizontal, the third moment picks which
   end points right (so both a library view and a query land in the same pose);
3. describes the object by blocks, each a unit vector times a weight, so the inner product of two
   embeddings is a weighted sum of per-block similarities:
   metric footprint (length, width, area in metres, as Gaussian soft-bins over log size, widened by a
   pixel's relative error so a 3 px object is not pinned to one size), integrated contrast (per Lab
   channel, the sum of pixel - background times the pixel area: about conserved when pixels are averaged,
   so it is what a 2 px object still shows; only on objects under ~16 px, where paint cannot be told from
   model)
   and its direction (the colour of the object whatever share of a pixel it covers),
   the edge extent (radii in metres from the crop's centre holding half and 85 % of the gradient energy above
   the background's: the object's size without a mask, where a white hull on light ground or a grey rock
   has no clear one),
   Lab colour (ab histogram, L histogram, a coarse colour layout along the body),
   silhouette (aspect, solidity, width profile along the length, rotation-invariant radial spectrum,
   Hu moments), gradients (HOG on the pose-normalised crop, rotation-invariant LBP histogram).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from ..errors import InputError

_VERSION = 8  # 4: integrated contrast in Lab (was a ratio to the background per RGB channel), edge parts
# 5: shadow test calibrated on renders (SHADOW_BLUE_MAX), speckle removed by area (SPECKLE_PX),
#   a part covering the crop's centre outranks parts that leave the crop (CENTRE_FRAC)
# 6: the integrated contrast's direction, the edge extent
# 7: the ring clutter and, faded in with it, the background's colour
# 8: sun glints are background (GLINTS)
SIZE_BINS = (96, 80, 80)  # Gaussian soft-bins over log length / width / area (sigma ~ 9 %, 9 %, 19 %)
# segmentation (tuned on the retrieval benchmark; recorded in the embedder settings)
THR_K = 7.0  # foreground = farther from every ring colour than median + THR_K robust sigmas
HYST = 0.7  # fainter pixels (x threshold) join when they touch clear foreground
MIN_SUPPORT = 0.2  # ring colours covering less of the ring are parts of the object or its neighbours
SEPARATE = True  # cut neighbours joined by narrow bridges (parked cars, adjacent berths)
RESTORE_DARK = True  # shadow-like pixels inside the object's convex hull are object parts (grey on grey)
DROP_EDGE_PARTS = True  # drop mask parts off the crop's central half that leave the crop (foam, wakes)
# A cast shadow is lit by the sky only, so it is a darker copy of the ground that is at most a little bluer:
# in renders of 33 lightings (30 random, the 3 library ones) on water and ground, its blue ratio was 0.81 to
# 1.13 x its red/green ratio. A looser bound also calls a navy car on dark ground a shadow and leaves only
# its windscreen as the object (docs/benchmarks.md).
SHADOW_BLUE_MAX = 1.25
# speckle (glints, noise) = foreground parts smaller than this many pixels at the work size; removed by area,
# not by an opening, which also erased thin rims (the 1-2 px white rim of a hull on light ground)
SPECKLE_PX = 8
CENTRE_FRAC = 0.1  # the crop's centre: a square of +- this fraction of its side (0: no centre rule)
# sun glints on water (see ``_glint_mask``): near-neutral pixels GLINT_DL brighter in L* than the ring's
# median (chroma below GLINT_CHROMA) and GLINT_TOPHAT brighter than a GLINT_PX opening, where at least
# GLINT_RING_SHARE of the ring shows them and the ring is otherwise plain (clutter share at most
# GLINT_MAX_CLUTTER: the white lines and roofs of a car park are not glitter); piers and buses on glittering
# water had glints in their masks (docs/benchmarks.md)
GLINTS = True
GLINT_DL, GLINT_CHROMA, GLINT_TOPHAT = 20.0, 20.0, 15.0
GLINT_PX = 7
GLINT_RING_SHARE, GLINT_MAX_CLUTTER = 0.005, 0.15
MIN_MASK_PX = 1  # a smaller mask falls back to the central disc (a tiny object is still itself, not a disc)
# integrated contrast (what tells a few-pixel object apart): soft-bins of arcsinh(sum / A0) per Lab channel.
# It is colour-specific, so it counts fully only on objects up to FULL_PX long and is gone at 2 x FULL_PX:
# a car or boat big enough to show its shape must still find its model in another paint (a library row with
# this block also loses cosine against queries without it, so it must stay off at the sizes paint views have).
# Lab, not a ratio to the background per RGB channel: on dark water a ratio of the red channel explodes and
# drowns the hue, and a difference of Lab (about perceptual, like the sRGB averaging of a coarse sensor or a
# resize) is about conserved when pixels are averaged (docs/benchmarks.md)
CONTRAST_A0 = (0.05, 0.02, 0.02)  # L*, a*, b* units x m^2
CONTRAST_BINS = 48
CONTRAST_FULL_PX = 8.0
SIZE_PX_UNCERTAINTY = 1.0  # the size code widens by this many pixels' relative error (tiny objects)
# the contrast's direction: the unit vector of the integrated contrast (L*, a*, b*), each component
# soft-binned. Its length mixes the object's colour with how much of its pixels it covers (a sparse tuft of
# blades, a solid clump); the direction is the colour alone (docs/benchmarks.md)
CONTRAST_DIR_BINS = 24
# edge extent: gradient energy (Lab, a* and b* at half weight) above this quantile of the crop ring's is the
# object's (its outline, its parts, its cast shadow); the radii holding 50 % and 85 % of it, soft-binned over
# log metres. The quantile keeps the ground's grain and the water's glitter out. It is what still measures a
# catamaran on light ground when the mask holds only its dark cabin (docs/benchmarks.md)
EDGE_QUANTILE = 0.9
EDGE_BINS = 48
# ring clutter: the share of the crop's ring farther than CLUTTER_DL (Lab) from its median colour,
# soft-binned. An isolated object's ring is plain background; around a car in a row or a boat in a berth,
# neighbours cut it. With the library's crowded views (LibraryConfig.crowded_views) it sends a crowded crop to
# crowded views and an isolated one to isolated views (without it, crowds of small cars drew isolated buses
# and box trucks; a high weight spoils the real crops: docs/benchmarks.md)
CLUTTER_DL = 12.0
CLUTTER_BINS = 21
CLUTTER_SIGMA = 0.05
# the background's colour (the ring's median Lab), faded in with the clutter (full from this share): an
# isolated object may lie on any ground in a query and the library renders every asset on water and on
# ground, but a crowded crop shows where it is (a car park, a marina) and the crowded views are rendered there
# (cars on ground, boats on water). Ungated it cost the isolated queries misses (docs/benchmarks.md)
BG_FULL = 0.2



def unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, np.float32).ravel()
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else v


@functools.lru_cache(maxsize=256)
def _crop_ring(h: int, w: int) -> np.ndarray:
    """The crop's outer ring (a twentieth of its side, at least 1 px), taken to show the background."""
    ring = max(1, min(h, w) // 20)
    edge = np.zeros((h, w), bool)
    edge[:ring], edge[-ring:], edge[:, :ring], edge[:, -ring:] = True, True, True, True
    edge.flags.writeable = False  # shared between calls
    return edge


@functools.lru_cache(maxsize=256)
def _radius_bins(h: int, w: int) -> np.ndarray:
    """Each pixel's distance from the centre of an h x w crop, in half pixels (rounded)."""
    yy, xx = np.mgrid[0:h, 0:w]
    return np.rint(2.0 * np.hypot(yy - (h - 1) / 2.0, xx - (w - 1) / 2.0)).astype(np.intp)


@functools.lru_cache(maxsize=64)
def _centres(lo: float, hi: float, n: int) -> np.ndarray:
    return np.linspace(lo, hi, n)


def _hist(x: np.ndarray, lo: float, hi: float, n: int) -> np.ndarray:
    """``np.histogram(x, n, (lo, hi))[0]`` as float32, without its overhead (values outside are dropped)."""
    x = np.asarray(x, np.float64).ravel()
    x = x[(x >= lo) & (x <= hi)]
    idx = np.minimum(((x - lo) * (n / (hi - lo))).astype(np.intp), n - 1)
    return np.bincount(idx, minlength=n).astype(np.float32)


def rbf(value: float, lo: float, hi: float, n: int, extra_sigma: float = 0.0) -> np.ndarray:
    """Gaussian soft-binning of a scalar: the inner product of two codes falls smoothly with distance.
    ``extra_sigma`` widens the bump for an uncertain value (in the units of ``value``)."""
    centres = _centres(lo, hi, n)
    sigma = math.hypot((hi - lo) / (n - 1), extra_sigma)
    v = float(np.clip(value, lo - sigma, hi + sigma))
    return np.exp(-0.5 * ((centres - v) / sigma) ** 2).astype(np.float32)


def rgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2Lab)


def as_rgb(image: np.ndarray, i: int) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise InputError(f"image {i} has shape {a.shape}; embedders need an RGB (H, W, 3) array")
    a = a[:, :, :3]
    if a.dtype != np.uint8:
        if np.issubdtype(a.dtype, np.floating) and a.size and float(np.nanmax(a)) <= 1.0:
            a = a * 255.0
        a = np.clip(np.nan_to_num(a), 0, 255).astype(np.uint8)
    if min(a.shape[:2]) < 4:
        raise InputError(f"image {i} is {a.shape[1]}x{a.shape[0]} px; crops must be at least 4x4 px")
    return np.ascontiguousarray(a)


def _background_centres(border: np.ndarray, radius: float = 10.0) -> np.ndarray:
    """A few colour centres for the crop's ring (leader clustering + one k-means step), minorities dropped.

    Minority ring colours are object parts touching the crop edge, not background.
    """
    step = max(1, len(border) // 400)
    pts = border[::step]
    centres = [pts[0]]
    dmin = ((pts - pts[0]) ** 2).sum(1)
    while len(centres) < 8:
        far = np.nonzero(dmin > radius * radius)[0]
        if not len(far):
            break
        centres.append(pts[far[0]])
        dmin = np.minimum(dmin, ((pts - pts[far[0]]) ** 2).sum(1))
    c = np.asarray(centres, np.float32)
    lab_d = ((pts[:, None, :] - c[None]) ** 2).sum(-1)
    near = lab_d.argmin(1)
    support = np.bincount(near, minlength=len(c)) / len(pts)
    c = np.asarray([pts[near == k].mean(0) if (near == k).any() else c[k] for k in range(len(c))], np.float32)
    keep = support >= MIN_SUPPORT
    return c[keep] if keep.any() else c[[int(support.argmax())]]


def object_mask(rgb: np.ndarray, work_px: int = 72) -> np.ndarray:
    """Foreground mask (bool, H x W); large crops are segmented at ``work_px`` and the mask upsampled."""
    import cv2

    h, w = rgb.shape[:2]
    f = work_px / max(h, w)
    if f >= 1.0:
        return _object_mask(rgb)
    small = cv2.resize(rgb, (max(4, round(w * f)), max(4, round(h * f))), interpolation=cv2.INTER_AREA)
    m = _object_mask(small).astype(np.float32)
    return cv2.resize(m, (w, h), interpolation=cv2.INTER_LINEAR) >= 0.5


def _ring_clutter(ring: np.ndarray) -> tuple[float, np.ndarray]:
    """The share of a crop's ring pixels (N x 3 Lab) farther than ``CLUTTER_DL`` from the ring's median
    colour, and that median."""
    med = np.median(ring, 0)
    return float((np.linalg.norm(ring - med, axis=1) > CLUTTER_DL).mean()), med


def _glint_mask(lab: np.ndarray, edge: np.ndarray) -> np.ndarray | None:
    """Sun glints on water (bright, near-neutral specks a few pixels across, see ``GLINT_DL``) or None
    when the crop's ring shows none. Glints joined to an object's outline made a pier or a bus on
    glittering water twice its width; a speck on the crop's very centre is the object (a white buoy)."""
    import cv2

    L = lab[:, :, 0]
    med = float(np.median(L[edge]))
    bright = (L > med + GLINT_DL) & (np.hypot(lab[:, :, 1], lab[:, :, 2]) < GLINT_CHROMA)
    if float(bright[edge].mean()) < GLINT_RING_SHARE or _ring_clutter(lab[edge])[0] > GLINT_MAX_CLUTTER:
        return None
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (GLINT_PX, GLINT_PX))
    tophat = L - cv2.morphologyEx(L, cv2.MORPH_OPEN, k)
    speck = (bright & (tophat > GLINT_TOPHAT)).astype(np.uint8)
    # with its halo: the fainter rim of each speck
    glint = ((cv2.dilate(speck, np.ones((3, 3), np.uint8)) > 0) & (L > med + 0.5 * GLINT_DL)).astype(np.uint8)
    h, w = L.shape
    r0 = max(1, int(round(CENTRE_FRAC * min(h, w))))
    cy, cx = (h - 1) // 2, (w - 1) // 2
    _n, lbl = cv2.connectedComponents(glint, connectivity=8)
    centre = np.unique(lbl[max(0, cy - r0 + 1): cy + r0 + 1, max(0, cx - r0 + 1): cx + r0 + 1])
    return (lbl > 0) & ~np.isin(lbl, centre[centre > 0])


def _object_mask(rgb: np.ndarray) -> np.ndarray:
    """Foreground mask (bool, H x W) of the object in a crop whose border shows its background.

    Background = colours near the ring's colour centres, or darker copies of them (cast shadows,
    which are lit only by the bluish sky). The components kept are the central and the large ones.
    """
    import cv2

    lab = rgb_to_lab(rgb)
    h, w = lab.shape[:2]
    edge = _crop_ring(h, w)
    border = lab[edge]
    centres = _background_centres(border)
    flat = lab.reshape(-1, 3)
    d2 = (flat ** 2).sum(1)[:, None] - 2.0 * flat @ centres.T + (centres ** 2).sum(1)[None, :]
    d = np.sqrt(np.maximum(d2, 0.0))
    nearest = d.argmin(1)
    dmin = d[np.arange(len(d)), nearest]
    bd = dmin.reshape(h, w)[edge]
    # robust spread of the ring's colours: glints and object pixels on the ring must not inflate it
    med = float(np.median(bd))
    thr = max(6.0, med + THR_K * 1.4826 * float(np.median(np.abs(bd - med))))
    fg = dmin > thr
    # cast shadows: a darker, slightly bluer copy of the background
    rgbf = rgb.reshape(-1, 3).astype(np.float32) + 2.0
    e_rgb, e_near = rgbf[edge.ravel()], nearest[edge.ravel()]
    cnt = np.bincount(e_near, minlength=len(centres)).astype(np.float32)
    bg_rgb = np.stack([np.bincount(e_near, weights=e_rgb[:, c], minlength=len(centres)) for c in range(3)], 1)
    bg_rgb = np.where(cnt[:, None] > 0, bg_rgb / np.maximum(cnt[:, None], 1), rgbf.mean(0)).astype(np.float32)
    ratio = rgbf / bg_rgb[nearest]
    k = ratio[:, :2].mean(1)
    slack = 6.0 / np.minimum(bg_rgb[nearest][:, 0], bg_rgb[nearest][:, 1])  # dark channels are noisy
    shadow = (k > 0.4) & (k < 0.97) & (np.abs(ratio[:, 0] - ratio[:, 1]) < 0.2 * k + slack) \
        & (ratio[:, 2] > 0.8 * k) & (ratio[:, 2] < SHADOW_BLUE_MAX * k + 0.05)
    fg_all = fg.reshape(h, w)
    fg = (fg & ~shadow).reshape(h, w)
    glint = _glint_mask(lab, edge) if GLINTS else None
    if glint is not None:
        fg &= ~glint
        fg_all = fg_all & ~glint
        shadow = shadow | glint.ravel()
    fg8 = fg.astype(np.uint8)
    if min(h, w) >= 40:  # drop speckle (glints, noise) by area (see SPECKLE_PX)
        nc, cl, cst, _ = cv2.connectedComponentsWithStats(fg8, connectivity=8)
        fg8 = ((cst[:, cv2.CC_STAT_AREA] >= SPECKLE_PX) & (np.arange(nc) > 0))[cl].astype(np.uint8)
    # hysteresis: faint parts (a white hull on light ground) join when they touch clearly different ones
    weak = ((dmin > HYST * thr) & ~shadow & ~edge.ravel()).reshape(h, w).astype(np.uint8) | fg8
    nw, wl = cv2.connectedComponents(weak, connectivity=8)
    if nw > 1 and fg8.any():
        grow = np.zeros(nw, bool)
        grow[np.unique(wl[fg8 > 0])] = True
        grow[0] = False
        fg8 = grow[wl].astype(np.uint8)
    n, lbl, stats, cents = cv2.connectedComponentsWithStats(fg8, connectivity=8)
    if n <= 1:
        weak = _weak_mask(dmin.reshape(h, w), thr)
        return weak if weak is not None else _fallback_mask(h, w)
    sizes = stats[1:, cv2.CC_STAT_AREA]
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    if DROP_EDGE_PARTS:
        # the crop is centred on the object: a part that does not reach the central half but runs out of the
        # crop is foam, a wake or a neighbour (a whitecap across the crop must not outvote a small tuft in
        # its middle); parts inside the crop may be the object's own detached parts (a bow) and stay
        central = np.zeros((h, w), bool)
        central[int(0.25 * h): int(math.ceil(0.75 * h)), int(0.25 * w): int(math.ceil(0.75 * w))] = True
        reach = np.zeros(n, bool)
        reach[np.unique(lbl[central])] = True
        reach[0] = False
        x0, y0 = stats[1:, cv2.CC_STAT_LEFT], stats[1:, cv2.CC_STAT_TOP]
        x1, y1 = x0 + stats[1:, cv2.CC_STAT_WIDTH], y0 + stats[1:, cv2.CC_STAT_HEIGHT]
        out = (x0 <= 0) | (y0 <= 0) | (x1 >= w) | (y1 >= h)
        if reach.any():
            sizes = np.where(reach[1:] | ~out, sizes, 0)
        # the same with the crop's very centre: when a part covers it, that part is the object, and parts that
        # leave the crop without covering it are neighbours (the next car in a row of parked cars)
        if CENTRE_FRAC > 0:
            r0 = max(1, int(round(CENTRE_FRAC * min(h, w))))
            core = np.zeros((h, w), bool)
            core[max(0, int(cy) - r0 + 1): int(math.ceil(cy)) + r0,
                 max(0, int(cx) - r0 + 1): int(math.ceil(cx)) + r0] = True
            hit = np.zeros(n, bool)
            hit[np.unique(lbl[core])] = True
            hit[0] = False
            if hit.any():
                sizes = np.where(hit[1:] | ~out, sizes, 0)
    big = sizes.max()
    keep = np.zeros(n, bool)
    for k in range(1, n):
        sz = sizes[k - 1]
        xx, yy = cents[k]
        near = abs(yy - cy) < 0.4 * h and abs(xx - cx) < 0.4 * w
        keep[k] = sz > 0 and sz >= 0.05 * big and (near or sz == big)
    mask = keep[lbl]
    if RESTORE_DARK:
        mask = _restore_dark_parts(mask, fg_all)
    mask = _fill_holes(mask)
    if SEPARATE:
        mask = _separate_neighbours(mask)
    if mask.sum() < MIN_MASK_PX:
        return _fallback_mask(h, w)
    return mask




def _restore_dark_parts(mask: np.ndarray, fg_all: np.ndarray) -> np.ndarray:
    """Give back the shadow-like pixels (darker, neutral copies of the background) that lie inside the
    convex hull of the object: grey stripes, dark outlines and hull parts of an object on grey ground,
    not a cast shadow (which falls outside the object, away from the sun)."""
    import cv2

    ys, xs = np.nonzero(mask)
    if len(xs) < 3:
        return mask
    hull = cv2.convexHull(np.stack([xs, ys], 1).astype(np.int32))
    inside = np.zeros(mask.shape, np.uint8)
    cv2.fillConvexPoly(inside, hull, 1)
    inside = cv2.erode(inside, np.ones((3, 3), np.uint8))  # not the shadow along the outline
    return mask | (fg_all & (inside > 0))


def _separate_neighbours(mask: np.ndarray) -> np.ndarray:
    """Cut off neighbours (cars parked side by side, boats in adjacent berths) joined to the object by
    narrow bridges: open with a disk a third of the blob's half-thickness, keep the parts centred in the
    crop (a tree's separate canopies stay), and grow them back inside the original mask."""
    import cv2

    h, w = mask.shape
    m8 = mask.astype(np.uint8)
    dt = cv2.distanceTransform(m8, cv2.DIST_L2, 3)
    r = int(round(0.35 * float(dt.max())))
    if r < 2:
        return mask
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    opened = cv2.morphologyEx(m8, cv2.MORPH_OPEN, disk)
    n, lbl, stats, cents = cv2.connectedComponentsWithStats(opened, connectivity=8)
    if n <= 2:
        return mask
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    sizes = stats[1:, cv2.CC_STAT_AREA]
    d = np.hypot((cents[1:, 0] - cx) / w, (cents[1:, 1] - cy) / h)
    central = d < 0.22
    if not central.any():
        central = d == d.min()
    big = sizes[central].max()
    keep = np.zeros(n, bool)
    keep[1:] = central & (sizes >= 0.25 * big)
    grown = cv2.dilate(keep[lbl].astype(np.uint8), disk)
    return mask & (grown > 0)




def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """Fill enclosed background (cv2 flood fill from a padded border: much faster than scipy here)."""
    import cv2

    h, w = mask.shape
    pad = np.zeros((h + 2, w + 2), np.uint8)
    pad[1:-1, 1:-1] = mask
    ff = pad.copy()
    cv2.floodFill(ff, np.zeros((h + 4, w + 4), np.uint8), (0, 0), 1)
    return (pad.astype(bool) | (ff == 0))[1:-1, 1:-1]


def _weak_mask(dmin: np.ndarray, thr: float) -> np.ndarray | None:
    """Tiny or faint objects: the most background-unlike pixels of the crop's centre."""
    h, w = dmin.shape
    centre = np.zeros((h, w), bool)
    centre[h // 4: h - h // 4 or h, w // 4: w - w // 4 or w] = True
    vals = np.where(centre, dmin, 0.0)
    if vals.max() <= 0.4 * thr:
        return None
    return vals > max(0.4 * thr, 0.5 * float(vals.max()))


def _fallback_mask(h: int, w: int) -> np.ndarray:
    """No contrast with the background: assume the object fills the central half of the crop."""
    yy, xx = np.mgrid[0:h, 0:w]
    return ((yy - (h - 1) / 2) / (h / 4)) ** 2 + ((xx - (w - 1) / 2) / (w / 4)) ** 2 <= 1.0


def integrated_contrast(rgb: np.ndarray, mask: np.ndarray, gsd: float, lab: np.ndarray | None = None
                        ) -> np.ndarray:
    """Per Lab channel, the sum over the object and a 2 px margin of pixel - background (the ring's median),
    times the pixel area: an object's contrast in Lab units x m^2. Averaging pixels about conserves it, so a
    tuft 2 px wide and its 40 px view agree, and a bright tuft differs from a faint one of the same size.
    ``lab``: the crop in Lab, when the caller has it already."""
    import cv2

    h, w = mask.shape
    edge = _crop_ring(h, w)
    lab = rgb_to_lab(rgb) if lab is None else lab
    bg = np.median(lab[edge], axis=0)
    region = cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))) > 0
    region &= ~edge
    return (lab[region] - bg).sum(0) * gsd * gsd


def normalise_pose(rgb: np.ndarray, mask: np.ndarray):
    """Rotate so the mask's major axis is horizontal (heavier end right); crop to the object.

    Returns ``(crop_rgb, crop_mask, angle_deg, elongation)`` with elongation = minor/major axis ratio.
    """
    import cv2

    m8 = mask.astype(np.uint8)
    mo = cv2.moments(m8, binaryImage=True)
    if mo["m00"] <= 0:
        return rgb, mask, 0.0, 1.0
    cx, cy = mo["m10"] / mo["m00"], mo["m01"] / mo["m00"]
    mu20, mu02, mu11 = mo["mu20"] / mo["m00"], mo["mu02"] / mo["m00"], mo["mu11"] / mo["m00"]
    theta = 0.5 * math.degrees(math.atan2(2 * mu11, mu20 - mu02))
    common = math.sqrt(max(0.0, ((mu20 - mu02) / 2) ** 2 + mu11 ** 2))
    l1, l2 = (mu20 + mu02) / 2 + common, (mu20 + mu02) / 2 - common
    elong = math.sqrt(max(l2, 0.0) / l1) if l1 > 0 else 1.0
    h, w = mask.shape
    side = int(math.ceil(math.hypot(h, w))) + 2
    # image angle is clockwise-positive for cv2 (row axis points down)
    rot = cv2.getRotationMatrix2D((cx, cy), theta, 1.0)
    rot[0, 2] += side / 2 - cx
    rot[1, 2] += side / 2 - cy
    mr = cv2.warpAffine(m8 * 255, rot, (side, side), flags=cv2.INTER_LINEAR) > 127
    ys, xs = np.nonzero(mr)
    if len(xs) == 0:
        return rgb, mask, 0.0, elong
    u = xs - xs.mean()
    skew = float((u ** 3).mean())
    if skew < 0:  # consistent end: heavier tail to the right
        theta += 180.0
        rot = cv2.getRotationMatrix2D((cx, cy), theta, 1.0)
        rot[0, 2] += side / 2 - cx
        rot[1, 2] += side / 2 - cy
        mr = cv2.warpAffine(m8 * 255, rot, (side, side), flags=cv2.INTER_LINEAR) > 127
        ys, xs = np.nonzero(mr)
    img_r = cv2.warpAffine(rgb, rot, (side, side), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    return img_r[y0:y1, x0:x1], mr[y0:y1, x0:x1], theta, elong


class DefaultEmbedder:
    """Hand-made, weight-free, rotation-invariant embedding (see the module docstring)."""

    name = "default"

    # Block weights (relative importance in the inner product); tuned on the retrieval benchmark
    # (docs/benchmarks.md). The size from the mask counts half since the edge extent also measures the object
    WEIGHTS: ClassVar[dict[str, float]] = {
        "size": 0.5, "colour_ab": 1.5, "colour_l": 0.5, "layout": 1.2,
        "shape": 0.6, "profile": 0.6, "radial": 0.6, "hog": 0.9, "lbp": 0.4, "contrast": 1.5,
        "contrast_dir": 1.0, "edge_extent": 1.5, "clutter": 0.7, "background": 1.0,
    }
    CANON = (32, 64)  # pose-normalised crop (rows across the width, columns along the length)
    MAX_WORK_PX = 128  # larger crops are downsampled first: finer detail does not change the blocks

    def __init__(self, weights: str | None = None, **overrides):
        if weights is not None:
            raise InputError(
                f"the default embedder uses no weights, but --weights {weights} was given; "
                "drop --weights or choose --embedder dinov3"
            )
        unknown = set(overrides) - set(self.WEIGHTS)
        if unknown:
            raise InputError(f"unknown default-embedder settings {sorted(unknown)}; valid: {sorted(self.WEIGHTS)}")
        self.weights = {**self.WEIGHTS, **{k: float(v) for k, v in overrides.items()}}
        self.block_slices: dict[str, slice] = {}
        self.dim = len(self._blocks(np.full((16, 16, 3), 128, np.uint8), 0.1, self.block_slices))

    @property
    def settings(self) -> dict:
        return {"version": _VERSION, "canon": list(self.CANON), "max_work_px": self.MAX_WORK_PX,
                "size_bins": list(SIZE_BINS), "weights": dict(self.weights),
                "size_px_uncertainty": SIZE_PX_UNCERTAINTY,
                "contrast": {"space": "lab", "a0": list(CONTRAST_A0), "bins": CONTRAST_BINS,
                             "full_px": CONTRAST_FULL_PX, "dir_bins": CONTRAST_DIR_BINS},
                "edge_extent": {"quantile": EDGE_QUANTILE, "bins": EDGE_BINS, "fractions": [0.5, 0.85]},
                "clutter": {"dl": CLUTTER_DL, "bins": CLUTTER_BINS, "sigma": CLUTTER_SIGMA},
                "background": {"full_share": BG_FULL, "bins": [11, 13, 13]},
                "segmentation": {"thr_k": THR_K, "hyst": HYST, "min_support": MIN_SUPPORT, "separate": SEPARATE,
                                 "restore_dark": RESTORE_DARK, "drop_edge_parts": DROP_EDGE_PARTS,
                                 "min_mask_px": MIN_MASK_PX, "shadow_blue_max": SHADOW_BLUE_MAX,
                                 "speckle_px": SPECKLE_PX, "centre_frac": CENTRE_FRAC,
                                 "glints": {"on": GLINTS, "dl": GLINT_DL, "chroma": GLINT_CHROMA,
                                            "tophat": GLINT_TOPHAT, "px": GLINT_PX,
                                            "ring_share": GLINT_RING_SHARE,
                                            "max_clutter": GLINT_MAX_CLUTTER}}}

    def embed(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray:
        images = list(images)
        gsds = [float(g) for g in gsd_m]
        if len(gsds) != len(images):
            raise InputError(f"embed got {len(images)} images but {len(gsds)} gsd values; give one gsd per image")
        out = np.zeros((len(images), self.dim), np.float32)
        for i, (img, g) in enumerate(zip(images, gsds)):
            if not (g > 0 and math.isfinite(g)):
                raise InputError(f"gsd {g!r} of image {i} must be a positive number of metres per pixel")
            out[i] = unit(self._blocks(as_rgb(img, i), g))
        return out

    # -- blocks ---------------------------------------------------------------------------------------
    def _blocks(self, rgb: np.ndarray, gsd: float, slices: dict | None = None) -> np.ndarray:
        """The weighted blocks, concatenated; ``slices`` (if given) receives each block's slice by name."""
        import cv2

        h, w = rgb.shape[:2]
        f = self.MAX_WORK_PX / max(h, w)
        if f < 1.0:
            rgb = cv2.resize(rgb, (max(4, round(w * f)), max(4, round(h * f))), interpolation=cv2.INTER_AREA)
            gsd = gsd * (w / rgb.shape[1])
        mask = object_mask(rgb)
        if not mask.any():  # a mask lost when upsampled from the work size: the object is the crop's centre
            mask = _fallback_mask(*mask.shape)
        crop, cmask, _theta, elong = normalise_pose(rgb, mask)
        if cmask.sum() == 0:
            crop, cmask = rgb, np.ones(rgb.shape[:2], bool)
        length_px, width_px = cmask.shape[1], cmask.shape[0]
        area_px = float(cmask.sum())
        lab = rgb_to_lab(crop)
        fg = lab[cmask]
        wt = self.weights
        blocks: list[tuple[str, np.ndarray]] = []
        # metric footprint
        # a mask a few pixels long is uncertain by about a pixel: widen the size code accordingly
        u_l, u_w = SIZE_PX_UNCERTAINTY / length_px, SIZE_PX_UNCERTAINTY / width_px
        size = np.concatenate([
            rbf(math.log(max(length_px * gsd, 1e-3)), math.log(0.1), math.log(400.0), SIZE_BINS[0], u_l),
            rbf(math.log(max(width_px * gsd, 1e-3)), math.log(0.05), math.log(80.0), SIZE_BINS[1], u_w),
            rbf(math.log(max(area_px * gsd * gsd, 1e-4)), math.log(0.005), math.log(2e4), SIZE_BINS[2], u_l + u_w),
        ])
        blocks.append(("size", wt["size"] * unit(size)))
        fade = float(np.clip(2.0 - length_px / CONTRAST_FULL_PX, 0.0, 1.0))
        lab_all = rgb_to_lab(rgb)  # the whole crop (``lab`` is the pose-normalised object)
        if fade > 0:
            contrast = integrated_contrast(rgb, mask, gsd, lab_all)
            blocks.append(("contrast", wt["contrast"] * fade * unit(self._contrast(contrast))))
            blocks.append(("contrast_dir", wt["contrast_dir"] * fade * unit(self._contrast_dir(contrast))))
        else:
            blocks.append(("contrast", np.zeros(3 * CONTRAST_BINS, np.float32)))
            blocks.append(("contrast_dir", np.zeros(3 * CONTRAST_DIR_BINS, np.float32)))
        blocks.append(("edge_extent", wt["edge_extent"] * unit(self._edge_extent(lab_all, gsd))))
        clutter, background = self._ring_context(lab_all)
        blocks.append(("clutter", wt["clutter"] * clutter))
        blocks.append(("background", wt["background"] * background))
        # colour: ab histogram (soft), L histogram
        ia = ((np.clip(fg[:, 1], -47.9, 47.9) + 48.0) * (8 / 96.0)).astype(np.intp)
        ib = ((np.clip(fg[:, 2], -47.9, 47.9) + 48.0) * (8 / 96.0)).astype(np.intp)
        ab = np.bincount(ia * 8 + ib, minlength=64).reshape(8, 8)
        ab = cv2.GaussianBlur(ab.astype(np.float32), (3, 3), 0.7)
        blocks.append(("colour_ab", wt["colour_ab"] * unit(np.sqrt(ab))))
        lh = _hist(fg[:, 0], 0.0, 100.0, 10)
        lh = np.convolve(lh, [0.25, 0.5, 0.25], mode="same")
        blocks.append(("colour_l", wt["colour_l"] * unit(np.sqrt(lh))))
        # colour layout along the body: 6 x 3 cells of mean Lab relative to the object's mean
        blocks.append(("layout", wt["layout"] * unit(self._layout(lab, cmask))))
        # silhouette scalars
        cnts, _ = cv2.findContours(cmask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        hull_area = sum(cv2.contourArea(cv2.convexHull(c)) for c in cnts) if cnts else area_px
        solidity = area_px / max(hull_area, 1.0)
        extent = area_px / max(length_px * width_px, 1)
        hu = cv2.HuMoments(cv2.moments(cmask.astype(np.uint8), binaryImage=True)).ravel()
        hu_l = [-math.copysign(1.0, v) * math.log10(abs(v)) if abs(v) > 1e-30 else 30.0 for v in hu[:3]]
        shape = np.concatenate([
            rbf(elong, 0.0, 1.0, 16), rbf(solidity, 0.3, 1.0, 12), rbf(extent, 0.3, 1.0, 12),
            rbf(hu_l[0], 0.6, 1.4, 10), rbf(hu_l[1], 1.0, 6.0, 10),
        ])
        blocks.append(("shape", wt["shape"] * unit(shape)))
        # width profile along the length (bow/stern shape)
        cols = cmask.sum(axis=0).astype(np.float32)
        prof = cv2.resize(cols[None, :], (16, 1), interpolation=cv2.INTER_AREA).ravel() / max(width_px, 1)
        blocks.append(("profile", wt["profile"] * unit(np.concatenate([prof, [1.0]]))))
        # rotation-invariant radial spectrum (round objects: trees, buoys, rocks)
        blocks.append(("radial", wt["radial"] * unit(self._radial(mask))))
        # gradients on the pose-normalised grey crop
        grey = lab[:, :, 0] * cmask + float(fg[:, 0].mean()) * (~cmask)
        canon = cv2.resize(grey.astype(np.float32), (self.CANON[1], self.CANON[0]), interpolation=cv2.INTER_AREA
                           if grey.shape[1] > self.CANON[1] else cv2.INTER_LINEAR)
        blocks.append(("hog", wt["hog"] * unit(np.sqrt(self._hog(canon)))))
        blocks.append(("lbp", wt["lbp"] * unit(np.sqrt(self._lbp(lab[:, :, 0], cmask)))))
        if slices is not None:
            start = 0
            for name, v in blocks:
                slices[name] = slice(start, start + len(v))
                start += len(v)
        return np.concatenate([v for _, v in blocks])

    @staticmethod
    def _contrast(contrast: np.ndarray) -> np.ndarray:
        code = np.arcsinh(contrast / np.asarray(CONTRAST_A0))
        return np.concatenate([rbf(float(c), -12.0, 12.0, CONTRAST_BINS) for c in code])

    @staticmethod
    def _contrast_dir(contrast: np.ndarray) -> np.ndarray:
        n = float(np.linalg.norm(contrast))
        if n <= 1e-9:
            return np.zeros(3 * CONTRAST_DIR_BINS, np.float32)
        return np.concatenate([rbf(float(c) / n, -1.0, 1.0, CONTRAST_DIR_BINS) for c in contrast])

    @staticmethod
    def _ring_context(lab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The crop's surroundings, as two unit codes: the share of its ring unlike the ring's median colour
        (neighbours, parked cars or boats in berths, cut the ring of a crowded crop; an isolated object's ring
        is plain background), and that median colour, faded in with the share (see ``BG_FULL``)."""
        share, med = _ring_clutter(lab[_crop_ring(*lab.shape[:2])])
        clutter = rbf(share, 0.0, 1.0, CLUTTER_BINS, CLUTTER_SIGMA)
        colour = np.concatenate([rbf(float(med[0]), 0.0, 100.0, 11), rbf(float(med[1]), -30.0, 30.0, 13),
                                 rbf(float(med[2]), -30.0, 30.0, 13)])
        return unit(clutter), min(1.0, share / BG_FULL) * unit(colour)

    @staticmethod
    def _edge_extent(lab: np.ndarray, gsd: float) -> np.ndarray:
        """Soft-binned log radii (metres, from the crop's centre) holding 50 % and 85 % of the gradient energy
        above the background's (see ``EDGE_QUANTILE``) in a Lab crop; zeros for a crop without any."""
        import cv2

        h, w = lab.shape[:2]
        gx = cv2.Sobel(lab, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(lab, cv2.CV_32F, 0, 1, ksize=3)
        mag = cv2.magnitude(gx.reshape(h, -1), gy.reshape(h, -1)).reshape(h, w, 3)
        grad = cv2.transform(mag, np.array([[1.0, 0.5, 0.5]], np.float32))
        edge = _crop_ring(h, w)
        excess = np.maximum(grad - float(np.quantile(grad[edge], EDGE_QUANTILE)), 0.0)
        excess[edge] = 0.0
        total = float(excess.sum())
        if total <= 1e-6:
            return np.zeros(2 * EDGE_BINS, np.float32)
        rbin = _radius_bins(h, w)  # distance from the crop's centre in half pixels
        cum = np.cumsum(np.bincount(rbin.ravel(), weights=excess.ravel())) / total
        code = []
        for frac in (0.5, 0.85):
            rad = (min(int(np.searchsorted(cum, frac)), len(cum) - 1) / 2.0 + 0.5) * gsd
            # a radius of a few pixels is uncertain by about a pixel (as the size code)
            code.append(rbf(math.log(rad), math.log(0.05), math.log(200.0), EDGE_BINS, gsd / rad))
        return np.concatenate(code)

    @staticmethod
    def _layout(lab: np.ndarray, cmask: np.ndarray) -> np.ndarray:
        import cv2

        m = cmask.astype(np.float32)
        mean = (lab * m[:, :, None]).sum((0, 1)) / max(m.sum(), 1.0)
        dev = (lab - mean) * m[:, :, None] / np.array([25.0, 15.0, 15.0], np.float32)
        cells_num = cv2.resize(dev, (6, 3), interpolation=cv2.INTER_AREA)
        cells_den = cv2.resize(m, (6, 3), interpolation=cv2.INTER_AREA)
        cells = cells_num / np.maximum(cells_den[:, :, None], 1e-3)
        cells = np.clip(cells, -3, 3) * np.minimum(cells_den[:, :, None] * 2, 1.0)
        return np.concatenate([cells.ravel(), cells_den.ravel(), [1.0]]).astype(np.float32)

    @staticmethod
    def _radial(mask: np.ndarray) -> np.ndarray:
        ys, xs = np.nonzero(mask)
        cy, cx = ys.mean(), xs.mean()
        ang = np.arctan2(ys - cy, xs - cx)
        r = np.hypot(ys - cy, xs - cx)
        bins = ((ang + np.pi) / (2 * np.pi) * 32).astype(int) % 32
        prof = np.zeros(32, np.float32)
        np.maximum.at(prof, bins, r.astype(np.float32))
        prof /= max(float(prof.max()), 1e-6)
        spec = np.abs(np.fft.rfft(prof))[:9]
        spec = spec / max(spec[0], 1e-6)
        return np.concatenate([[1.0], 3.0 * spec[1:]]).astype(np.float32)

    @staticmethod
    def _hog(canon: np.ndarray) -> np.ndarray:
        """8-orientation gradient histograms on 4 x 8 cells (unsigned), with per-cell L2 norm."""
        import cv2

        gx = cv2.Sobel(canon, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(canon, cv2.CV_32F, 0, 1, ksize=3)
        mag = np.hypot(gx, gy)
        ang = (np.arctan2(gy, gx) % np.pi) / np.pi * 8
        b0 = np.floor(ang).astype(int) % 8
        frac = ang - np.floor(ang)
        h, w = canon.shape
        cy, cx = 4, 8
        cell_r = (np.arange(h) * cy // h)[:, None].repeat(w, 1)
        cell_c = (np.arange(w) * cx // w)[None, :].repeat(h, 0)
        idx = (cell_r * cx + cell_c) * 8
        hist = np.zeros(cy * cx * 8, np.float32)
        np.add.at(hist, (idx + b0).ravel(), (mag * (1 - frac)).ravel())
        np.add.at(hist, (idx + (b0 + 1) % 8).ravel(), (mag * frac).ravel())
        hist = hist.reshape(cy * cx, 8)
        hist /= np.linalg.norm(hist, axis=1, keepdims=True) + 1e-3 + 0.1 * float(np.median(mag) + 1.0)
        return hist.ravel()

    @staticmethod
    def _lbp(grey: np.ndarray, cmask: np.ndarray) -> np.ndarray:
        """Rotation-invariant uniform LBP (8 neighbours) + gradient-magnitude histogram on the object."""
        import cv2

        g = grey.astype(np.float32)
        if min(g.shape) < 3:
            return np.ones(16, np.float32)
        c = g[1:-1, 1:-1]
        offs = [(-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1)]
        bits = np.stack([(g[1 + dy:g.shape[0] - 1 + dy, 1 + dx:g.shape[1] - 1 + dx] >= c + 2.0) for dy, dx in offs])
        transitions = (bits != np.roll(bits, 1, axis=0)).sum(0)
        ones = bits.sum(0)
        code = np.where(transitions <= 2, ones, 9)
        m = cmask[1:-1, 1:-1]
        lbp = np.bincount(code[m].ravel(), minlength=10)[:10].astype(np.float32)
        gm = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1))[cmask]
        gh = _hist(np.log1p(gm), 0.0, 6.0, 6)
        return np.concatenate([lbp / max(lbp.sum(), 1), gh / max(gh.sum(), 1)])
