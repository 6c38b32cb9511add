"""Bow versus stern (front versus back): which end of an oriented box is the front.

Cues, each giving a sign (+1: the front is along ``yaw_deg``, -1: opposite) and a confidence in [0.5, 1]:
- boats: the silhouette's width profile along the long axis. Bows taper to a point, sterns are square
  (transom), so the end whose outer fifth is narrower is the bow.
- vehicles (``glass_evidence``): seen from above, the windscreen is a long dark band in front of the
  (painted) roof, the rear window a short one or none (hatchbacks, SUVs, vans); so along the middle of
  the car more of the dark glass lies in the front half. An open pickup bed is dark too, but long and at
  the rear end: a dark run that long reaching an end of the body is left out. Glass need not be darker
  than the paint, though: on black cars the raked windscreen mirrors the sky and is lighter, on coloured
  ones it is grey against the hue, so ``glass_contrast`` counts glass as any lightness-or-colour departure
  from the paint. The detector's own belief (``heading_confidence``) and both cues are combined as
  log-odds with weights fitted on synthetic levels (``vehicle_fronts``).
- context: boats along one pier are usually moored the same way (all bow-in or all stern-in), so an
  unsure boat takes the majority of its confident neighbours at the same pier.
When the cues are weak ``heading_known`` stays False and the 180° ambiguity stays explicit.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..frames import direction_px, wrap_deg
from ..types import Detection

KNOWN_AT = 0.62  # confidence from which a heading counts as known


def _axes(det: Detection) -> tuple[np.ndarray, np.ndarray]:
    f = np.array(direction_px(det.yaw_deg))
    lft = np.array(direction_px(det.yaw_deg + 90.0))
    return f, lft


def box_coords(det: Detection, cols: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centres → (u along the front, v to the left) in pixels relative to the box centre."""
    f, lft = _axes(det)
    dc, dr = cols + 0.5 - det.cx_px, rows + 0.5 - det.cy_px
    return dc * f[0] + dr * f[1], dc * lft[0] + dr * lft[1]


def width_profile(mask: np.ndarray, origin: tuple[int, int], det: Detection, bins: int = 20) -> np.ndarray:
    """Width of the silhouette (pixels across the long axis) in ``bins`` slices from back (-L/2) to front."""
    rr, cc = np.nonzero(mask)
    u, _v = box_coords(det, cc + origin[0], rr + origin[1])
    half = det.length_px / 2.0
    k = np.clip(((u + half) / det.length_px * bins).astype(int), 0, bins - 1)
    ok = np.abs(u) <= half * 1.05
    prof = np.zeros(bins)
    np.add.at(prof, k[ok], 1.0)
    step = det.length_px / bins
    return prof / max(step, 1e-6)  # pixels per unit length = width


def silhouette_sign(mask: np.ndarray, origin: tuple[int, int], det: Detection) -> tuple[int, float]:
    """(+1 | -1, confidence) from the taper of the silhouette: the narrower end is the bow."""
    if mask is None or mask.sum() < 12 or det.length_px < 6:
        return 1, 0.5
    bins = 20
    prof = width_profile(mask, origin, det, bins)
    wmax = np.percentile(prof, 90)
    if wmax <= 0:
        return 1, 0.5
    n = 4  # outer fifth of each end
    back = prof[1:n + 1].mean() / wmax  # skip the very end slice (rounding at the box edge)
    front = prof[bins - n - 1:bins - 1].mean() / wmax
    tip_b, tip_f = prof[0] / wmax, prof[-1] / wmax
    asym = (back - front) + 0.5 * (tip_b - tip_f)
    sign = 1 if asym >= 0 else -1
    # ~0.15 of the max width difference is already a clear taper on real masks
    conf = 0.5 + 0.5 * float(np.tanh(abs(asym) / 0.15))
    elong = det.length_px / max(det.width_px, 1e-6)
    if elong < 1.4:  # round blobs have no bow
        conf = 0.5 + (conf - 0.5) * max(0.0, (elong - 1.0) / 0.4)
    return sign, conf


# glass cue (``glass_evidence``): chosen on the synthetic levels of seed 0 (seed 1 held out)
GLASS_NU, GLASS_NV = 48, 16  # samples along / across the box
GLASS_CORE_V = 0.3  # the middle strip (|v| < 0.3 W): no side windows, no cast shadow beside the car
GLASS_WIN_U = 0.35  # glass counted within |u| < 0.35 L: hood and boot tips and the box ends stay out
GLASS_PAINT_PCT = 75  # the paint's lightness: this percentile of the strip (glass is the minority)
GLASS_RUN_REL = 0.35  # a dark run: samples darker than the paint by this fraction of the darkest one
GLASS_BED_LEN, GLASS_BED_END = 0.2, 0.42  # a run this long (x L) reaching this far out is a bed, not glass
GLASS_WEIGHT = 4.0  # log-odds at full asymmetry (all dark glass in one half) ...
GLASS_FULL_DARK = 6.0  # ... once the glass is this much darker than the paint (Lab L, mean over the window)
GLASS_MIN_PX = 12.0  # shorter boxes show no windscreen


def _aligned_lab(rgb: np.ndarray, det: Detection, nu: int, nv: int) -> np.ndarray:
    """Lab (float, L 0-100) samples of the box on a (nv, nu) grid, u (columns) toward the front."""
    import cv2

    f, lft = _axes(det)
    su, sv = det.length_px / nu, det.width_px / nv
    a = np.stack([f * su, -lft * sv], 1)  # d(col, row) / d(j, i)
    o = np.array([det.cx_px - 0.5, det.cy_px - 0.5]) - a @ np.array([(nu - 1) / 2.0, (nv - 1) / 2.0])
    m = np.hstack([a, o[:, None]])
    crop = cv2.warpAffine(np.ascontiguousarray(rgb), m, (nu, nv),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT)
    return cv2.cvtColor(crop.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)


def _drop_beds(dev: np.ndarray, u: np.ndarray, on: np.ndarray) -> np.ndarray:
    """``dev`` with long runs of ``on`` samples that reach an end of the body set to 0 (open pickup beds,
    cargo floors: dark, long and at the rear, unlike glass)."""
    dev = dev.copy()
    k, nu = 0, len(u)
    while k < nu:
        if not on[k]:
            k += 1
            continue
        e = k
        while e + 1 < nu and on[e + 1]:
            e += 1
        if u[e] - u[k] >= GLASS_BED_LEN and (u[k] < -GLASS_BED_END or u[e] > GLASS_BED_END):
            dev[k:e + 1] = 0.0
        k = e + 1
    return dev


def glass_evidence(rgb: np.ndarray, det: Detection, lab: np.ndarray | None = None) -> float:
    """Vehicles: log-odds that the front is along ``yaw_deg`` (> 0) rather than opposite, from where the
    dark glass lies along the middle of the box (see the module doc); 0 when there is no such contrast
    (dark paint, a box of a few pixels)."""
    if det.length_px < GLASS_MIN_PX or det.width_px < 3:
        return 0.0
    nu, nv = GLASS_NU, GLASS_NV
    lab = _aligned_lab(rgb, det, nu, nv) if lab is None else lab
    u = (np.arange(nu) + 0.5) / nu - 0.5  # in box lengths, back to front
    v = (np.arange(nv) + 0.5) / nv - 0.5
    strip = lab[np.abs(v) < GLASS_CORE_V, :, 0]
    body = np.abs(u) < 0.45
    paint = float(np.percentile(strip[:, body], GLASS_PAINT_PCT))
    dark = np.clip(paint - strip.mean(0), 0.0, None) * body
    if dark.max() <= 0:
        return 0.0
    on = dark > GLASS_RUN_REL * dark.max()
    dark = _drop_beds(dark, u, on)
    dark = dark * on  # only clear glass counts: faint shading (roof vents, panel gradients) does not
    win = np.abs(u) < GLASS_WIN_U
    front, back = float(dark[win & (u > 0)].sum()), float(dark[win & (u < 0)].sum())
    asym = (front - back) / (front + back + 1e-6)
    strength = min(1.0, (front + back) / win.sum() / GLASS_FULL_DARK)
    return GLASS_WEIGHT * asym * strength


# glass contrast cue (``glass_contrast``) and the combination in ``vehicle_fronts``: fitted (logistic
# regression, no intercept, each car also mirrored) on the synthetic levels of seeds 0+1, seed 2 held out
CONTRAST_CORE_V = 0.3  # middle strip, as for the dark-glass cue
CONTRAST_WIN_U = 0.4  # lamps sit beyond 0.42 L at both ends and must stay out
CONTRAST_RUN_REL = 0.2  # a glass sample departs from the paint by this fraction of the largest departure
CONTRAST_FULL = 10.0  # full strength once the glass departs this much from the paint (mean Lab distance)
FRONT_W_NET, FRONT_W_DARK, FRONT_W_CONTRAST = 0.75, 1.2, 3.1  # log-odds weights: net, dark glass, contrast
FRONT_MAX_CUE = 4.0  # the image cues together never outweigh a detector sure of its front (logit > ~5)


def glass_contrast(rgb: np.ndarray, det: Detection, lab: np.ndarray | None = None) -> float:
    """Vehicles: in [-1, 1], > 0 when the glass lies more in the front half. Glass is what departs from
    the paint (Lab distance, lighter or darker, hue too) along the middle strip; the paint is the strip's
    median colour (hood, roof and boot outweigh the glass). 0 without contrast or on tiny boxes."""
    if det.length_px < GLASS_MIN_PX or det.width_px < 3:
        return 0.0
    nu, nv = GLASS_NU, GLASS_NV
    lab = _aligned_lab(rgb, det, nu, nv) if lab is None else lab
    u = (np.arange(nu) + 0.5) / nu - 0.5
    v = (np.arange(nv) + 0.5) / nv - 0.5
    strip = lab[np.abs(v) < CONTRAST_CORE_V]
    body = np.abs(u) < 0.45
    paint = np.median(strip[:, body].reshape(-1, 3), axis=0)
    dev = np.linalg.norm(strip.mean(0) - paint, axis=1) * body
    if dev.max() <= 0:
        return 0.0
    on = dev > CONTRAST_RUN_REL * dev.max()
    dev = _drop_beds(dev, u, on) * on
    win = np.abs(u) < CONTRAST_WIN_U
    front, back = float(dev[win & (u > 0)].sum()), float(dev[win & (u < 0)].sum())
    asym = (front - back) / (front + back + 1e-6)
    return asym * min(1.0, (front + back) / win.sum() / CONTRAST_FULL)


def cabin_sign(rgb: np.ndarray, det: Detection) -> tuple[int, float]:
    """Vehicles: (+1 | -1, confidence) from the glass cue (``glass_evidence``)."""
    lo = glass_evidence(rgb, det)
    return (1 if lo >= 0 else -1), float(1.0 / (1.0 + np.exp(-abs(lo))))


def _logit(conf: float) -> float:
    c = min(max(float(conf), 0.5), 0.999)
    return float(np.log(c / (1.0 - c)))


def vehicle_fronts(rgb: np.ndarray, dets: list[Detection]) -> list[Detection]:
    """Vehicles' fronts from a detector that gives its own heading (the learned network): its
    confidence and the two glass cues (``glass_evidence``, ``glass_contrast``) are added as weighted
    log-odds (``FRONT_W_*``: the net is over-confident, so its weight is below 1); other categories are
    returned unchanged. On the synthetic levels (hybrid backend, refined boxes) vehicle heading accuracy
    at 0.1 / 0.2 m/px went from 0.909 / 0.901 to 0.909 / 0.908 (seeds 0+1, fitted) and from 0.825 / 0.796
    to 0.845 / 0.827 (seed 2, held out); the dark-glass cue alone with weight 1 was the before.
    Most errors left are sedans whose rear window renders darker than the sky-lit windscreen.
    A vote of neighbouring cars (same row, same kerb) did not help: lots mix nose-in and nose-out."""
    out = []
    for d in dets:
        if d.category != "vehicle":
            out.append(d)
            continue
        big = d.length_px >= GLASS_MIN_PX and d.width_px >= 3
        lab = _aligned_lab(rgb, d, GLASS_NU, GLASS_NV) if big else None  # one resampling for both cues
        ev = glass_evidence(rgb, d, lab) if big else 0.0
        ct = glass_contrast(rgb, d, lab) if big else 0.0
        if ev == 0.0 and ct == 0.0:  # nothing to add: the detector's front and confidence stay as they are
            out.append(d)
            continue
        cue = float(np.clip(FRONT_W_DARK * ev + FRONT_W_CONTRAST * ct, -FRONT_MAX_CUE, FRONT_MAX_CUE))
        lo = FRONT_W_NET * _logit(d.heading_confidence) + cue
        out.append(apply_sign(d, 1 if lo >= 0 else -1, float(1.0 / (1.0 + np.exp(-abs(lo))))))
    return out


def apply_sign(det: Detection, sign: int, conf: float) -> Detection:
    yaw = det.yaw_deg if sign > 0 else wrap_deg(det.yaw_deg + 180.0)
    return replace(det, yaw_deg=float(yaw), heading_known=bool(conf >= KNOWN_AT),
                   heading_confidence=float(conf))


def patch_mask(rgb: np.ndarray, det: Detection, margin: float = 0.35) -> tuple[np.ndarray, tuple[int, int]]:
    """A silhouette inside the box for detectors that give none: pixels far (in Lab) from the ring
    around the box, by Otsu's threshold."""
    import cv2

    h, w = rgb.shape[:2]
    c = det.corners_px()
    pad = margin * det.width_px + 2
    c0, r0 = np.floor(c.min(0) - pad).astype(int)
    c1, r1 = np.ceil(c.max(0) + pad).astype(int)
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, w), min(r1, h)
    if c1 - c0 < 3 or r1 - r0 < 3:
        return np.zeros((max(r1 - r0, 1), max(c1 - c0, 1)), bool), (c0, r0)
    lab = cv2.cvtColor(np.ascontiguousarray(rgb[r0:r1, c0:c1]), cv2.COLOR_RGB2LAB).astype(np.float32)
    rr, cc = np.mgrid[r0:r1, c0:c1]
    u, v = box_coords(det, cc, rr)
    inbox = (np.abs(u) <= det.length_px / 2) & (np.abs(v) <= det.width_px / 2)
    ring = ~((np.abs(u) <= det.length_px / 2 + pad * 0.5) & (np.abs(v) <= det.width_px / 2 + pad * 0.5))
    if ring.sum() < 5:
        return inbox, (c0, r0)
    bg = np.median(lab[ring], axis=0)
    dl = lab[..., 0] - bg[0]
    dc = np.hypot(lab[..., 1] - bg[1], lab[..., 2] - bg[2])
    # the object is brighter or of another colour than its surroundings; its shadow is darker with
    # the same hue and must not count (it would fatten one side)
    dist = np.maximum(dl, np.where(dl > -15.0, dc * 1.5, 0.0))
    d8 = np.clip(dist * 2.0, 0, 255).astype(np.uint8)
    thr, _ = cv2.threshold(d8[inbox].reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = (d8 > max(thr, 12)) & inbox
    return mask, (c0, r0)


def resolve_heading(rgb: np.ndarray, det: Detection, mask: np.ndarray | None = None,
                    origin: tuple[int, int] | None = None) -> Detection:
    """Decide the front of one box (boats and vehicles; other categories are returned unchanged)."""
    if det.category == "boat":
        if mask is None:
            mask, origin = patch_mask(rgb, det)
        s, c = silhouette_sign(mask, origin, det)
        return apply_sign(det, s, c)
    if det.category == "vehicle":
        s1, c1 = cabin_sign(rgb, det)
        # car silhouettes are nearly symmetric: only an existing mask is worth the look
        s2, c2 = silhouette_sign(mask, origin, det) if mask is not None else (1, 0.5)
        c2 = 0.5 + (c2 - 0.5) * 0.5  # car silhouettes are nearly symmetric: a weak cue
        # combine the two as log-odds
        lo = s1 * np.log(c1 / (1 - c1 + 1e-9)) + s2 * np.log(c2 / (1 - c2 + 1e-9))
        conf = float(1.0 / (1.0 + np.exp(-abs(lo))))
        return apply_sign(det, 1 if lo >= 0 else -1, conf)
    return det


def pier_context(dets: list[Detection], radius_factor: float = 0.8) -> list[Detection]:
    """Boats along a pier moor the same way: give unsure boats the confident majority of their pier.

    For each boat, the nearest pier box within ``radius_factor`` boat lengths defines "toward the pier";
    boats whose axis crosses that pier vote with their confidence."""
    piers = [d for d in dets if d.category == "pier_walkway"]
    if not piers:
        piers = [d for d in dets if d.category == "pier_finger"]
    boats = [i for i, d in enumerate(dets) if d.category == "boat"]
    if not piers or not boats:
        return dets
    from shapely.geometry import Point, Polygon

    polys = [Polygon(p.corners_px()) for p in piers]
    link: dict[int, tuple[int, int]] = {}  # boat index -> (pier index, sign of "front toward pier")
    for i in boats:
        d = dets[i]
        pt = Point(d.cx_px, d.cy_px)
        dist = [pg.distance(pt) for pg in polys]
        j = int(np.argmin(dist))
        if dist[j] > radius_factor * d.length_px:
            continue
        # axis roughly perpendicular to the walkway (moored at it, not along it)
        rel = abs(wrap_deg(d.yaw_deg - piers[j].yaw_deg))
        rel = min(rel, 180 - rel)
        if rel < 50:
            continue
        near = polys[j].exterior.interpolate(polys[j].exterior.project(pt))
        f = np.array(direction_px(d.yaw_deg))
        to_pier = np.array([near.x - d.cx_px, near.y - d.cy_px])
        link[i] = (j, 1 if float(f @ to_pier) > 0 else -1)
    votes: dict[int, float] = {}
    for i, (j, s) in link.items():
        d = dets[i]
        if d.heading_known:
            votes[j] = votes.get(j, 0.0) + s * (d.heading_confidence - 0.5)
    out = list(dets)
    for i, (j, s) in link.items():
        d = dets[i]
        v = votes.get(j, 0.0)
        if d.heading_known or abs(v) < 0.5:  # need at least ~2 clear neighbours
            continue
        want = 1 if v > 0 else -1
        conf = min(0.75, 0.5 + 0.05 * abs(v) / 0.1)
        out[i] = apply_sign(d, 1 if want == s else -1, max(conf, d.heading_confidence))
    return out
