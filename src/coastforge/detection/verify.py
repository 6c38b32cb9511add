"""Checks of the boxes after refinement: ``refine.refine_boxes`` drops the boxes that fail them.

Buoy boxes on sun glints / whitecaps (small, streaked, faint; or the water's own colour brightened with
no shadow beside it, ``is_glint``) and boat boxes on dark water (weed, submerged rocks: darker water of
the same chromaticity) or on mostly water (broken wakes, weed patches with water between them) are
dropped; so are boat boxes on a piece of a pier (a uniform core continuing past one end, water on both
sides: ``is_structure_piece``), on a boat's foam wake (``drop_wakes``), vehicle boxes on blank ground
(``is_blank_ground``) and weaker vehicle boxes on the empty bay beside a car (``drop_shifted_cars``).
"""

from __future__ import annotations

import math

import numpy as np

from ..types import Detection
from .crops import LabCache, background_modes, box_core, crop_box, lab_window, sq_dist

BUOY_MAX_ASPECT, BUOY_MIN_AREA_M2, BUOY_MIN_PEAK = 1.4, 0.25, 24.0  # see ``is_buoy``
# sun glints (``is_glint``): the ring (m from the centre) where a buoy darkens the water, how dark its
# 10th percentile must get (Lab L) and how close to the water's chromaticity a glint's colour stays
GLINT_RING_M, GLINT_MAX_SHADOW, GLINT_MAX_TINT = (0.6, 0.95), -1.4, 0.1
# ... white glints on a wavy sea have another tint than the water, but where the ring lies at least
# GLINT_RING_MIN_PX from the centre (finer than 0.15 m/px: the blur does not spill the blob into it) a
# ring brighter than the water by GLINT_BRIGHT_RING on average, with no shadow, is a field of glints:
# synthetic seeds 0-3 at 0.1 m/px, the 88 true buoys' rings -0.2 and darker, the 2 such glints' +2.4
GLINT_RING_MIN_PX, GLINT_BRIGHT_RING = 4.0, 1.0
DARK_WATER_SHADOW, DARK_WATER_CONTRAST = 0.8, 0.8  # see ``is_dark_water``
# ... unless its ring is clearly darker (mean, 10th percentile) and its colour its own (tint), when 0.8 of
# the area and peak will do (synthetic seeds 0-2: 2 of the 3 true buoys the shape checks dropped kept,
# none of 99 glints; every such glint was smaller, or had a brighter ring or the water's tint)
BUOY_SURE_SHAPE, BUOY_SURE_RING, BUOY_SURE_TINT = 0.8, (-1.0, -3.0), 0.1
# wakes (``drop_wakes``): a boat box in line behind a boat (axes within WAKE_MAX_DEG, centre within half
# its width of the boat's axis, at most WAKE_GAP_M or half the boat's length beyond its stern) whose
# core is partly water (>= WAKE_MIN_WATER) and far less contrasted than the boat's (WAKE_REL_CONTRAST)
WAKE_MAX_DEG, WAKE_GAP_M, WAKE_REL_CONTRAST, WAKE_MIN_WATER = 20.0, 2.0, 0.3, 0.25
# pier pieces (``is_structure_piece``): the colour (Lab distance of medians) beyond one end within
# PIECE_END_DE of the core's, beside both sides at least PIECE_SIDE_DE from it, a core more uniform than
# PIECE_MAX_STD_L (Lab L); bands from PIECE_BAND_M[0] to PIECE_BAND_M[1] metres outside the box
PIECE_END_DE, PIECE_SIDE_DE, PIECE_MAX_STD_L, PIECE_BAND_M = 4.0, 15.0, 10.0, (0.5, 2.0)
# a vehicle box beside a clearly stronger one (score ratio >= SHIFTED_SCORE_RATIO), parallel (axes
# within SHIFTED_MAX_DEG), level with it (centres within half a length along the axis) and at most
# SHIFTED_MAX_LAT widths to the side, with a uniform core (Lab L std < SHIFTED_MAX_STD_L), is that
# car seen shifted onto its shadow or the empty bay beside it (``drop_shifted_cars``)
SHIFTED_SCORE_RATIO, SHIFTED_MAX_DEG, SHIFTED_MAX_LAT, SHIFTED_MAX_STD_L = 1.3, 15.0, 1.3, 4.0
# vehicle boxes on blank ground (``is_blank_ground``)
BLANK_MAX_CONTRAST, BLANK_MIN_SAME = 0.8, 0.5
# ... and a box whose core is more than this share water-coloured (within this Lab distance)
CORE_WATER_MAX, CORE_WATER_DE = 0.5, 8.0
# ... dark hulls: a box at least this long (m) must be darker water on nearly all its core to go
DARK_HULL_MIN_M, DARK_HULL_MIN_PX, DARK_HULL_SHADOW = 7.5, 20.0, 0.95  # ... seen this many pixels long


def core_evidence(rgb: np.ndarray, det: Detection, gsd_m: float) -> dict[str, float]:
    """How much the middle of a box looks like an object rather than background: ``contrast`` (the
    core's median colour distance to the nearest background mode over the background's own spread)
    and ``shadow`` (the fraction of the core that is darker than the background with its
    chromaticity: a dark patch of water, weed, a shadow) and ``water`` (the fraction of the core within
    ``CORE_WATER_DE`` of the median colour around the box)."""
    L, W = det.length_px, det.width_px
    scale = max(1.0, min(4.0, 12.0 / max(W, 1.0)))
    pad = max(3.0, 0.6 / gsd_m)
    half_u, half_v = 0.5 * L * 1.35 + 2 * pad, 0.5 * W * 1.6 + 2 * pad
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, scale)
    nv, nu = crop.shape[:2]
    U = np.abs((np.arange(nu) - (nu - 1) / 2.0) / scale)[None, :]
    V = np.abs((np.arange(nv) - (nv - 1) / 2.0) / scale)[:, None]
    ring = (U > 0.6 * L + 1.5 * pad) | (V > 0.65 * W + 1.5 * pad)
    core = (U <= 0.35 * L) & (V <= 0.3 * W)
    found = background_modes(crop[ring], crop[core], max_in_core=1.01)
    if not found or not core.any():
        return {"contrast": 0.0, "shadow": 1.0, "water": 1.0}
    modes = [m for m, _ in found]
    dist = np.stack([np.sqrt(sq_dist(crop, m)) for m in modes]).min(0)
    spread = max(2.0, float(np.percentile(dist[ring], 50)))
    shadow = np.zeros(dist.shape, bool)
    for m in modes:
        ratio = np.clip((crop[..., 0] + 16.0) / (m[0] + 16.0), 0.0, 1.0)  # Lab: f(kY) = k^(1/3) f(Y)
        ab_dev = np.hypot(crop[..., 1] - m[1] * ratio, crop[..., 2] - m[2] * ratio)
        shadow |= (crop[..., 0] < m[0] - 3.0 * spread) & (ab_dev < max(6.0, 1.5 * spread))
    # the share of the core coloured like the water around the box (its ring's median colour)
    water = float((np.sqrt(sq_dist(crop[core], np.median(crop[ring], 0))) < CORE_WATER_DE).mean())
    return {"contrast": float(np.median(dist[core])) / spread, "shadow": float(shadow[core].mean()),
            "water": water}


def buoy_features(rgb: np.ndarray, det: Detection, gsd_m: float) -> dict[str, float]:
    """Shape and contrast of the blob at a buoy box, measured on a 4 m square resampled to 5 cm:
    ``peak`` (Lab distance from the water around, 95th percentile within 0.6 m), ``area`` (m², of the
    blob brighter than half the peak within 1 m), ``aspect`` (long/short axis from its moments), and
    for ``is_glint``: ``ring_p10`` and ``ring_mean`` (10th percentile and mean of the lightness minus
    the water's in the annulus ``GLINT_RING_M`` around the blob) and ``tint`` (how far the blob's
    chromaticity is from the water's, over the water's chroma)."""
    sample = 0.05
    win = lab_window(rgb, det.cx_px, det.cy_px, 2.5 / gsd_m + 3)
    crop = crop_box(win, det.cx_px, det.cy_px, 0.0, 2.0 / gsd_m, 2.0 / gsd_m, gsd_m / sample)
    n0, n1 = crop.shape[:2]
    yy, xx = np.mgrid[:n0, :n1]
    rr = np.hypot(yy - (n0 - 1) / 2.0, xx - (n1 - 1) / 2.0) * sample
    bg = np.median(crop[rr > 1.2], 0)
    dist = np.sqrt(sq_dist(crop, bg))
    peak = float(np.percentile(dist[rr < 0.6], 95))
    blob = (dist > 0.5 * peak) & (rr < 1.0)
    ys, xs = np.nonzero(blob)
    aspect = math.inf
    if len(xs) > 3:
        ev = np.linalg.eigvalsh(np.cov(np.stack([xs, ys]).astype(float)))
        aspect = float(math.sqrt(ev[1] / max(ev[0], 1e-6)))
    dl = crop[..., 0] - bg[0]
    r0, r1 = GLINT_RING_M
    ring = (rr >= r0) & (rr < r1)
    # the blob's colour: the core weighted by how much brighter than the water it is
    w = np.clip(dl, 0.0, None) * (rr < 0.3)
    ab = (crop[..., 1:] * w[..., None]).sum((0, 1)) / w.sum() if w.sum() > 1e-6 else bg[1:]
    chroma = float(math.hypot(bg[1], bg[2]))
    tint = (float(math.hypot(ab[0] - bg[1], ab[1] - bg[2])) - 1.5) / max(chroma, 1e-6)
    return {"peak": peak, "area": float(blob.sum() * sample * sample), "aspect": aspect,
            "ring_p10": float(np.percentile(dl[ring], 10)) if ring.any() else 0.0,
            "ring_mean": float(dl[ring].mean()) if ring.any() else 0.0, "tint": tint}


def is_glint(f: dict[str, float], gsd_m: float | None = None) -> bool:
    """``buoy_features`` of a sun glint: a glint is the water's own colour made brighter, and the
    ripples around it catch some of the sun too, so the water around it is, if anything, brighter; a
    floating buoy stands out in its own colour and darkens the water beside it (its shadow, its
    waterline). On the synthetic levels (seeds 0 and 1) every glint left by the shape checks had a
    10th percentile of the ring at -1.15 or more, a brighter ring on average and a tint <= 0.06; the
    true buoys' ring reached -1.61 or less at both resolutions (so each test alone separates them;
    a glint must pass all three). White glints on a wavy sea differ in tint but show their field of
    glints in a well resolved ring (``GLINT_BRIGHT_RING``, ``gsd_m`` given)."""
    if f["ring_p10"] <= GLINT_MAX_SHADOW or f["ring_mean"] <= 0.0:
        return False
    if f["tint"] <= GLINT_MAX_TINT:
        return True
    return gsd_m is not None and GLINT_RING_M[0] / gsd_m >= GLINT_RING_MIN_PX and f["ring_mean"] > GLINT_BRIGHT_RING


def is_buoy(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A buoy is a bright, round float at least ~0.5 m across. Sun glints and whitecaps, which the
    learned detector takes for buoys, are small, streaked along the wind and fainter (on the
    synthetic levels: 0.1 m/px all 25 buoys kept, 64 of 65 glints dropped; 0.2 m/px 25/26 and 21/27);
    the glints left are told apart by their surroundings and colour (``is_glint``: 0.2 m/px, seeds 0
    and 1, the last 6 of 6 dropped, no buoy)."""
    f = buoy_features(rgb, det, gsd_m)
    if f["aspect"] <= BUOY_MAX_ASPECT and f["area"] >= BUOY_MIN_AREA_M2 and f["peak"] >= BUOY_MIN_PEAK:
        return not is_glint(f, gsd_m)
    # a float casting a clear shadow in its own colour (far from any glint) may be a little smaller,
    # fainter or less round than the shape checks want: at 0.2 m/px a 1 m buoy is 5 px, blurred
    return (f["area"] >= BUOY_SURE_SHAPE * BUOY_MIN_AREA_M2 and f["peak"] >= BUOY_SURE_SHAPE * BUOY_MIN_PEAK
            and f["ring_mean"] <= BUOY_SURE_RING[0] and f["ring_p10"] <= BUOY_SURE_RING[1]
            and f["tint"] >= BUOY_SURE_TINT)


def is_dark_water(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A boat box whose middle is only darker water (weed, a submerged rock, a cloud or tree shadow:
    darker than the water around with its chromaticity), or hardly differs from it. Hulls and decks
    seen from above are brighter or of another colour; a yacht-sized box needs a darker core
    throughout (``DARK_HULL_*``: dark hulls are large, weed patches on the synthetic levels small). On
    the synthetic levels this drops 13 of 22 false boats and no true one."""
    # fast path (speed): a core clearly brighter than the box's surroundings is no dark patch
    win = lab_window(rgb, det.cx_px, det.cy_px, 0.5 * math.hypot(det.length_px, det.width_px) + 2 * max(
        3.0, 0.6 / gsd_m) + 3)
    lab = win[0]
    h, w = lab.shape[:2]
    dh, dw = max(1, h // 8), max(1, w // 8)
    mid = lab[h // 2 - dh:h // 2 + dh + 1, w // 2 - dw:w // 2 + dw + 1]
    if float(np.median(mid[..., 0])) > float(np.median(lab[..., 0])) + 15.0:
        return False
    e = core_evidence(rgb, det, gsd_m)
    if e["contrast"] < DARK_WATER_CONTRAST:
        return True
    if e["water"] > CORE_WATER_MAX:
        # a hull or deck covers the middle of its box; weed patches seen with gaps of water between
        # them, and foam trails, leave at least half of it the water's colour (synthetic seeds 0-2:
        # true boats at most 0.47, the kayaks whose boxes are wider than they are)
        return True
    # dark patches on the synthetic levels are small (2-7 m, weed and rocks); a yacht-sized dark box
    # with contrast is a dark hull (real marina: 2 of 2 such true boats, 0 false at 7.5 m and up)
    # (seen large enough: not a satellite speck)
    big = det.length_px * gsd_m >= DARK_HULL_MIN_M and det.length_px >= DARK_HULL_MIN_PX
    return e["shadow"] >= (DARK_HULL_SHADOW if big else DARK_WATER_SHADOW)


def is_blank_ground(rgb: np.ndarray | LabCache, det: Detection, gsd_m: float) -> bool:
    """A vehicle box on nothing: its core has the colour of the ground around it (at least
    ``BLANK_MIN_SAME`` of it within ``CORE_WATER_DE``) and no contrast with it (``core_evidence``
    contrast below ``BLANK_MAX_CONTRAST``): sand, a lawn, an empty bay. Dark cars on dark asphalt have
    as little contrast but their own colour (synthetic seeds 0-3: the 2 lowest-contrast true cars, 0.71
    and 0.74, shared none of their core with the ground; the 3 such false boxes 0.58-0.88 of it)."""
    e = core_evidence(rgb, det, gsd_m)
    return e["contrast"] < BLANK_MAX_CONTRAST and e["water"] >= BLANK_MIN_SAME


def core_std_l(rgb: np.ndarray | LabCache, det: Detection) -> float:
    """The std of the Lab lightness (0-100) in the box's core (within 0.35 of its length and 0.3 of
    its width from the centre)."""
    L, W = det.length_px, det.width_px
    crop, u, v = box_core(rgb, det, 0.35 * L + 1.0, 0.3 * W + 1.0)
    core = crop[(np.abs(u) <= 0.35 * L) & (np.abs(v) <= 0.3 * W)]
    return float(core[:, 0].std()) if len(core) >= 4 else math.inf


def drop_shifted_cars(rgb: np.ndarray | LabCache, dets: list[Detection]) -> list[Detection]:
    """Vehicle boxes that are a stronger neighbour's car seen shifted sideways onto its shadow or the
    empty bay beside it (``SHIFTED_*``): parallel, level with it, touching it and scored well below
    it, with a uniform core (asphalt or shadow: no roof edge, no glass). Overlapping ones are merged
    by the learned backend already (``learned.VEHICLE_MAX_IOA``); these only touch. Synthetic seeds
    0-2: 4 of 4 such false cars (core std 1.9-3.3, score ratio 1.35-1.61, 1.0-1.26 widths aside);
    true neighbours that close scored alike (ratio <= 1.1) or had a varied core (std >= 8)."""
    cars = [i for i, d in enumerate(dets) if d.category == "vehicle"]
    if len(cars) < 2:
        return dets
    cs = np.array([[dets[i].cx_px, dets[i].cy_px] for i in cars])
    drop: set[int] = set()
    for k, i in enumerate(cars):
        d = dets[i]
        r = math.radians(d.yaw_deg)
        f, lft = (math.cos(r), -math.sin(r)), (-math.sin(r), -math.cos(r))
        near = np.hypot(*(cs - cs[k]).T) <= SHIFTED_MAX_LAT * d.width_px + 0.5 * d.length_px + 1.0
        for m in np.nonzero(near)[0]:
            e = dets[cars[m]]
            if m == k or e.score < SHIFTED_SCORE_RATIO * d.score:
                continue
            if abs((e.yaw_deg - d.yaw_deg + 90.0) % 180.0 - 90.0) > SHIFTED_MAX_DEG:
                continue
            du, dv = e.cx_px - d.cx_px, e.cy_px - d.cy_px
            u, v = du * f[0] + dv * f[1], du * lft[0] + dv * lft[1]
            if abs(u) > 0.25 * (d.length_px + e.length_px) or abs(v) > SHIFTED_MAX_LAT * 0.5 * (d.width_px + e.width_px):
                continue
            if core_std_l(rgb, d) < SHIFTED_MAX_STD_L:
                drop.add(i)
                break
    return [d for i, d in enumerate(dets) if i not in drop]


def is_structure_piece(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A boat box on a piece of a longer structure (a pier finger, a walkway's end, a pier head): its
    uniform core continues in the same colour past one end while both its sides are another colour
    (water). A hull ends in the water or at the pier it is moored to, which is coloured otherwise, and
    shows a cabin, a cockpit, a deck line (a less uniform core). On the synthetic levels (seeds 0-1)
    this drops 4 pier decks and a streak of water between weed patches taken for boats (end within
    2.7 of the core's colour, sides 20-37 away, core std 3.9-7.7), no true boat (the nearest: end 4.6
    but sides 12.3, or end 5.4 and core std 15-18); on held-out seed 2, 3 pier decks and no true boat."""
    L, W = det.length_px, det.width_px
    if L < 4 or W < 2:
        return False
    a, b = PIECE_BAND_M[0] / gsd_m, PIECE_BAND_M[1] / gsd_m
    crop, u, v = box_core(rgb, det, 0.5 * L + b, 0.5 * W + b)
    core = crop[(np.abs(u) <= 0.35 * L) & (np.abs(v) <= 0.3 * W)]
    if len(core) < 4 or float(core[:, 0].std()) >= PIECE_MAX_STD_L:
        return False
    cm = np.median(core, 0)

    def de(band: np.ndarray) -> float:
        return float(np.linalg.norm(np.median(crop[band], 0) - cm)) if band.any() else math.inf

    ends = [de((sg * u >= 0.5 * L + a) & (sg * u <= 0.5 * L + b) & (np.abs(v) <= 0.3 * W)) for sg in (-1, 1)]
    if min(ends) >= PIECE_END_DE:
        return False
    sides = [de((sg * v >= 0.5 * W + a) & (sg * v <= 0.5 * W + b) & (np.abs(u) <= 0.35 * L)) for sg in (-1, 1)]
    return min(sides) > PIECE_SIDE_DE


def _in_line_behind(b: Detection, a: Detection, gsd_m: float) -> bool:
    """Whether box ``b`` lies in line behind boat ``a`` (either end when ``a``'s heading is unknown):
    axes within ``WAKE_MAX_DEG``, centre within half ``a``'s width of its axis, at most ``WAKE_GAP_M``
    (or half ``a``'s length) beyond its end and not overlapping it by more than a quarter of ``b``."""
    turn = abs((b.yaw_deg - a.yaw_deg + 90.0) % 180.0 - 90.0)
    if turn > WAKE_MAX_DEG:
        return False
    r = math.radians(a.yaw_deg)
    du, dv = b.cx_px - a.cx_px, b.cy_px - a.cy_px
    u, v = du * math.cos(r) - dv * math.sin(r), -du * math.sin(r) - dv * math.cos(r)
    if abs(v) > 0.5 * a.width_px or (a.heading_known and u > 0):
        return False
    gap = abs(u) - 0.5 * (a.length_px + b.length_px)
    return -0.25 * b.length_px <= gap <= max(WAKE_GAP_M / gsd_m, 0.5 * a.length_px)


def drop_wakes(rgb: np.ndarray, dets: list[Detection], gsd_m: float) -> list[Detection]:
    """Boat boxes that are a boat's wake: in line behind it (``_in_line_behind``), their core partly the
    water's colour (foam over water) and far less contrasted than the boat's (``WAKE_*``). The learned
    detector takes the foam trail of a moving boat for a second boat (synthetic seeds 0-1: 2 false
    boats, core contrast 0.14-0.17 of their boat's); boats moored stern to stern across a finger are
    as contrasted as each other (0.5 and up)."""
    boats = [i for i, d in enumerate(dets) if d.category == "boat"]
    if len(boats) < 2:
        return dets
    drop: set[int] = set()
    evidence: dict[int, dict[str, float]] = {}

    def ev(i: int) -> dict[str, float]:
        if i not in evidence:
            evidence[i] = core_evidence(rgb, dets[i], gsd_m)
        return evidence[i]

    cs = np.array([[dets[i].cx_px, dets[i].cy_px] for i in boats])
    longest = max(dets[i].length_px for i in boats)
    for k, i in enumerate(boats):
        b = dets[i]
        # only boats close enough to be ``_in_line_behind`` are looked at (speed)
        near = np.hypot(*(cs - cs[k]).T) <= 0.5 * b.length_px + longest + WAKE_GAP_M / gsd_m + 1.0
        for m in np.nonzero(near)[0]:
            j = boats[m]
            if j == i or not _in_line_behind(b, dets[j], gsd_m):
                continue
            e = ev(i)
            if e["water"] >= WAKE_MIN_WATER and e["contrast"] < WAKE_REL_CONTRAST * ev(j)["contrast"]:
                drop.add(i)
                break
    return [d for i, d in enumerate(dets) if i not in drop]
