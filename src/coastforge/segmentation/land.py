"""The classical segmenter's land classes: colour and texture rules seed the pixels they are sure of
(footpaths, parked cars, revetments, sand), a per-image Gaussian classifier trained on them labels the
rest, and the class borders, shaded crowns and their shade are decided again afterwards."""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage as ndi

from ..classes import ASPHALT, DIRT, GRASS, N_CLASSES, ROCKS, SAND, SIDEWALK, TREES
from .features import Features, disk, labels_in, odd_px, outline_share

LAND = (ASPHALT, SIDEWALK, GRASS, TREES, DIRT, ROCKS, SAND)
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
PATH_MAX_FINE = 4.0  # paths and pavements are smooth at ``features.FINE_TEX_M``: fine texture below this
# hazy images: asphalt and concrete split by lightness above this (see _paving_split)
PAVING_HAZE_L = 62.0
PAVING_SPLIT_SEP = 0.7
SPECK_SKEW = 4.0  # speckled sand: median minus mean L* over ~2 m above this


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
    for m in rules.values():
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
    k = min(odd_px(2.0 / F.gsd_m), 7)  # cv2.medianBlur takes float32 up to 5 px; uint8 beyond
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
    wide = cv2.morphologyEx(pavement, cv2.MORPH_OPEN, disk(r)).astype(bool)
    narrow = (paved > 0) & ~wide
    n, lab, st, _c = cv2.connectedComponentsWithStats(narrow.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(F.L.shape, bool)
    # the outline is looked at PATH_RING_M out: a kerb between light and dark paving is textured, so
    # neither side's rule claims the pixels right at it
    paved_share = outline_share(lab, n, pavement > 0, max(1, int(round(PATH_RING_M / gsd))))
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
    near = cv2.dilate(paved, disk(reach_m / F.gsd_m)).astype(bool)
    return near & (F.tex1 > CAR_MIN_TEX) & (green < CAR_MAX_GREEN)


def fold_rows(classes: np.ndarray, proba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def train_predict(X: np.ndarray, y: np.ndarray, Xall: np.ndarray, seed: int, per_class: int = 50000,
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
    k = odd_px(4.0 * band_m / gsd)
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
    paving = labels_in(ids, np.array(SHADE_FROM), N_CLASSES)
    dark = land & (F.L < SHADE_REL_L * l_ref) & ((ids == TREES) | paving)
    dark = cv2.morphologyEx(dark.astype(np.uint8), cv2.MORPH_OPEN, disk(SHADE_MIN_W_M / (2.0 * gsd)))
    if not dark.any():
        return ids
    n, lab, st, _c = cv2.connectedComponentsWithStats(dark, connectivity=8)
    # tree regions big enough to be crowns (not a car row the classifier took for trees)
    tn, tlab, tst, _tc = cv2.connectedComponentsWithStats(trees.astype(np.uint8), connectivity=8)
    crowns = labels_in(tlab, np.flatnonzero(tst[:, cv2.CC_STAT_AREA] * gsd * gsd >= SHADE_MIN_TREE_M2), tn)
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
    k = odd_px(reach_m / gsd)
    mf = m.astype(np.float32)
    norm = cv2.blur(mf, (k, k))
    near = (norm > 0.05) & land & labels_in(ids, np.array(into), N_CLASSES)
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
