"""Rotated non-maximum suppression (polygon IoU with shapely), used across image slices."""

from __future__ import annotations

import numpy as np

from ..types import Detection


def centres_inside(boxes: list[Detection], evidence: list[Detection], grow: float = 1.0) -> np.ndarray:
    """(len(boxes), len(evidence)) bool: evidence box j's centre lies inside box i grown ``grow`` times along
    and across."""
    pts = np.array([[e.cx_px, e.cy_px] for e in evidence], float).reshape(-1, 2)
    b = np.array([[d.cx_px, d.cy_px, d.length_px, d.width_px, d.yaw_deg] for d in boxes], float).reshape(-1, 5)
    r = np.deg2rad(b[:, 4])
    fx, fy = np.cos(r), -np.sin(r)  # forward in (col, row)
    dx = pts[None, :, 0] - b[:, None, 0]
    dy = pts[None, :, 1] - b[:, None, 1]
    u = dx * fx[:, None] + dy * fy[:, None]
    v = -dx * fy[:, None] + dy * fx[:, None]
    return (np.abs(u) <= grow * b[:, None, 2] / 2) & (np.abs(v) <= grow * b[:, None, 3] / 2)


def polygon_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two convex polygons given as (N, 2) corner arrays."""
    from shapely.geometry import Polygon

    pa, pb = Polygon(a), Polygon(b)  # boxes from corners_px are convex and valid
    inter = pa.intersection(pb).area
    union = pa.area + pb.area - inter
    return float(inter / union) if union > 0 else 0.0


def polygon_ioa(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over the smaller polygon's area (a box cut by a slice border lies inside the whole one)."""
    from shapely.geometry import Polygon

    pa, pb = Polygon(a), Polygon(b)
    small = min(pa.area, pb.area)
    return float(pa.intersection(pb).area / small) if small > 0 else 0.0


def rotated_nms(dets: list[Detection], iou_threshold: float = 0.3, class_aware: bool = True,
                ioa_threshold: float | None = None) -> list[Detection]:
    """Keep the highest-scoring box of every group overlapping by more than ``iou_threshold``.

    ``ioa_threshold`` also suppresses a box mostly contained in a better one (a half-object cut by a
    slice edge next to the whole object found in the neighbouring slice)."""
    if not dets:
        return []
    order = sorted(range(len(dets)), key=lambda i: -dets[i].score)
    corners = [dets[i].corners_px() for i in range(len(dets))]
    lo = np.array([c.min(0) for c in corners])
    hi = np.array([c.max(0) for c in corners])
    cats = np.array([d.category for d in dets])
    kept: list[int] = []
    for i in order:
        ok = True
        if kept:
            k = np.asarray(kept)
            touch = np.all(lo[k] <= hi[i], axis=1) & np.all(lo[i] <= hi[k], axis=1)  # bounds overlap
            if class_aware:
                touch &= cats[k] == cats[i]
            cand = k[touch].tolist()
        else:
            cand = []
        for j in cand:
            if polygon_iou(corners[i], corners[j]) > iou_threshold:
                ok = False
                break
            if ioa_threshold is not None and polygon_ioa(corners[i], corners[j]) > ioa_threshold:
                ok = False
                break
        if ok:
            kept.append(i)
    return [dets[i] for i in kept]
