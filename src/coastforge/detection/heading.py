"""Bow versus stern (front versus back): which end of an oriented box is the front.

Cues, each giving a sign (+1: the front is along ``yaw_deg``, -1: opposite) and a confidence in [0.5, 1]:
- boats: the silhouette's width profile along the long axis. Bows taper to a point, sterns are square
  (transom), so the end whose outer fifth is narrower is the bow.
- vehicles: the cabin (roof + glass) sits behind the centre because the bonnet is longer than the boot,
  and the windscreen is a dark band in front of the roof.
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
    u, v = box_coords(det, cc + origin[0], rr + origin[1])
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


def cabin_sign(rgb: np.ndarray, det: Detection) -> tuple[int, float]:
    """Vehicles: (+1 | -1, confidence) from the position of the dark glass/cabin along the long axis."""
    if det.length_px < 8:
        return 1, 0.5
    h, w = rgb.shape[:2]
    c = det.corners_px()
    c0, r0 = np.floor(c.min(0)).astype(int)
    c1, r1 = np.ceil(c.max(0)).astype(int)
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, w), min(r1, h)
    if c1 - c0 < 3 or r1 - r0 < 3:
        return 1, 0.5
    patch = rgb[r0:r1, c0:c1].astype(np.float32).mean(2)
    rr, cc = np.mgrid[r0:r1, c0:c1]
    u, v = box_coords(det, cc, rr)
    inside = (np.abs(u) < det.length_px * 0.45) & (np.abs(v) < det.width_px * 0.3)
    if inside.sum() < 10:
        return 1, 0.5
    val = patch[inside]
    uu = u[inside] / (det.length_px / 2.0)
    thr = np.percentile(val, 35)
    dark = val <= thr
    if dark.sum() < 3 or (~dark).sum() < 3:
        return 1, 0.5
    # glass/roof centroid lies behind the centre; the front windscreen is the darkest band
    shift = float(uu[dark].mean() - uu.mean())
    spread = float(np.ptp(val)) / 255.0
    sign = -1 if shift > 0 else 1
    conf = 0.5 + 0.35 * float(np.tanh(abs(shift) / 0.12)) * min(1.0, spread / 0.25)
    return sign, conf


def apply_sign(det: Detection, sign: int, conf: float) -> Detection:
    yaw = det.yaw_deg if sign > 0 else wrap_deg(det.yaw_deg + 180.0)
    return replace(det, yaw_deg=float(yaw), heading_known=bool(conf >= KNOWN_AT), heading_confidence=float(conf))


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
