"""Pier structures: walkway and finger boxes → chains of library pier segments, connected to land.

Each detected walkway/finger box is extended along its axis to reach land or the pier it attaches to
(within ``max_gap_m``); a structure that still floats gets a connecting walkway to the nearest land.
Each box then becomes ``n = ceil(length / segment length)`` segments scaled to fit exactly. The paper's
piers sometimes did not connect; here connectivity is checked and reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .classes import WATER
from .config import PierConfig
from .frames import wrap_half_deg
from .scene import SceneObject
from .types import ClassMap, Detection, Grid


@dataclass(frozen=True)
class PierBox:
    """A pier part in scene metres; ``yaw_deg`` is its axis (mod 180)."""

    role: str  # walkway | finger | connector
    x_m: float
    y_m: float
    length_m: float
    width_m: float
    yaw_deg: float
    score: float = 1.0

    @property
    def axis(self) -> np.ndarray:
        r = math.radians(self.yaw_deg)
        return np.array([math.cos(r), math.sin(r)])

    def ends(self) -> tuple[np.ndarray, np.ndarray]:
        c, u = np.array([self.x_m, self.y_m]), self.axis
        return c - u * self.length_m / 2, c + u * self.length_m / 2

    def polygon(self, grow: float = 0.0):
        from shapely.geometry import Polygon

        c, u = np.array([self.x_m, self.y_m]), self.axis
        n = np.array([-u[1], u[0]])
        hl, hw = self.length_m / 2 + grow, self.width_m / 2 + grow
        return Polygon([c + u * hl + n * hw, c - u * hl + n * hw, c - u * hl - n * hw, c + u * hl - n * hw])


def box_from_ends(a: np.ndarray, b: np.ndarray, width: float, role: str, score: float) -> PierBox:
    d = b - a
    c = (a + b) / 2
    return PierBox(role, float(c[0]), float(c[1]), float(np.linalg.norm(d)), width,
                   float(wrap_half_deg(math.degrees(math.atan2(d[1], d[0])))), score)


@dataclass(frozen=True)
class PierResult:
    objects: tuple[SceneObject, ...]
    boxes: tuple[PierBox, ...]  # after extension, before chaining
    structures: tuple[tuple[int, ...], ...]  # box indices per structure
    structure_on_land: tuple[bool, ...]
    extensions_m: tuple[float, ...]  # how far each box was extended
    report: dict = field(default_factory=dict)


class LandProbe:
    """Is a point on real land? Pier decks themselves are often classified as paving, so pixels inside
    pier boxes do not count as land."""

    def __init__(self, class_map: ClassMap, boxes: list[PierBox]):
        from shapely import contains_xy
        from shapely.ops import unary_union

        self.cm, self.grid = class_map, class_map.grid
        self.union = unary_union([b.polygon() for b in boxes]) if boxes else None
        self._contains = contains_xy

    def land_fraction(self, p: np.ndarray, radius_m: float) -> float:
        g = self.grid
        r = max(radius_m, g.gsd_m)
        n = max(3, int(2 * r / g.gsd_m))
        xs = np.linspace(p[0] - r, p[0] + r, n)
        gx, gy = np.meshgrid(xs, np.linspace(p[1] - r, p[1] + r, n))
        gx, gy = gx.ravel(), gy.ravel()
        keep = (gx - p[0]) ** 2 + (gy - p[1]) ** 2 <= r * r
        if self.union is not None:
            keep &= ~self._contains(self.union, gx, gy)
        if not keep.any():
            return 0.0
        col, row = g.to_pixel(gx[keep], gy[keep])
        inside = (col >= 0) & (col < g.width_px) & (row >= 0) & (row < g.height_px)
        if not inside.any():
            return 0.0
        ids = self.cm.ids[row[inside].astype(int), col[inside].astype(int)]
        return float(np.mean(ids != WATER))

    def is_land(self, p: np.ndarray, radius_m: float) -> bool:
        return self.land_fraction(p, radius_m) >= 0.3


def detections_to_boxes(dets: list[Detection], grid: Grid) -> list[PierBox]:
    out = []
    for d in dets:
        if d.category not in ("pier_walkway", "pier_finger"):
            continue
        x, y = grid.to_scene(d.cx_px, d.cy_px)
        out.append(PierBox("walkway" if d.category == "pier_walkway" else "finger", float(x), float(y),
                           d.length_px * grid.gsd_m, d.width_px * grid.gsd_m, float(wrap_half_deg(d.yaw_deg)),
                           float(d.score)))
    return out


def _extend(boxes: list[PierBox], probe: LandProbe, cfg: PierConfig, step: float) -> tuple[list[PierBox], list[float]]:
    """Extend each box end that floats along its axis until it meets land or another box."""
    out, ext = [], []
    polys = [b.polygon(grow=0.3) for b in boxes]
    from shapely.geometry import Point

    for i, b in enumerate(boxes):
        a, e = b.ends()
        u = b.axis
        new_ends = []
        grown = 0.0
        for end, sign in ((a, -1.0), (e, 1.0)):
            r = b.width_m / 2 + 0.5
            touching = probe.is_land(end, r) or any(
                polys[j].distance(Point(end)) <= 0.3 for j in range(len(boxes)) if j != i)
            if touching:
                new_ends.append(end)
                continue
            found = None
            for k in range(1, int(cfg.max_gap_m / step) + 1):
                q = end + sign * u * k * step
                if probe.is_land(q, b.width_m / 2) or any(
                        polys[j].contains(Point(q)) for j in range(len(boxes)) if j != i):
                    found = q + sign * u * min(0.5, step)  # a little overlap so the parts touch
                    break
            if found is None:
                new_ends.append(end)
            else:
                grown += float(np.linalg.norm(found - end))
                new_ends.append(found)
        out.append(box_from_ends(new_ends[0], new_ends[1], b.width_m, b.role, b.score))
        ext.append(grown)
    return out, ext


def _components(boxes: list[PierBox], tol: float = 0.4) -> list[list[int]]:
    n = len(boxes)
    polys = [b.polygon() for b in boxes]
    seen = [False] * n
    comps = []
    for i in range(n):
        if seen[i]:
            continue
        stack, comp = [i], []
        seen[i] = True
        while stack:
            a = stack.pop()
            comp.append(a)
            for j in range(n):
                if not seen[j] and polys[a].distance(polys[j]) <= tol:
                    seen[j] = True
                    stack.append(j)
        comps.append(sorted(comp))
    return comps


def _nearest_land(probe: LandProbe, start: np.ndarray, max_dist: float, step: float) -> np.ndarray | None:
    """The nearest land point from ``start`` within ``max_dist`` (search on rings of directions)."""
    for rad in np.arange(step, max_dist + step, step):
        angles = np.linspace(0, 2 * np.pi, max(16, int(2 * np.pi * rad / step)), endpoint=False)
        for t in angles:
            q = start + rad * np.array([np.cos(t), np.sin(t)])
            if probe.is_land(q, step):
                return q
    return None


def build_piers(dets: list[Detection], class_map: ClassMap, walkway_asset, finger_asset, config: PierConfig,
                water_level_m: float = 0.0) -> PierResult:
    """Chain library pier segments along detected walkways and fingers, connected to land."""
    grid = class_map.grid
    boxes = detections_to_boxes(dets, grid)
    if not boxes:
        return PierResult((), (), (), (), (), {"n_structures": 0, "n_segments": 0})
    probe = LandProbe(class_map, boxes)
    step = max(grid.gsd_m, 0.25)
    boxes, ext = _extend(boxes, probe, config, step)
    probe = LandProbe(class_map, boxes)
    comps = _components(boxes)
    # a structure that still does not reach land gets a connecting walkway to the nearest land
    for comp in list(comps):
        if any(probe.is_land(end, boxes[i].width_m / 2 + 0.5) for i in comp for end in boxes[i].ends()):
            continue
        best = None
        for i in comp:
            for end in boxes[i].ends():
                q = _nearest_land(probe, end, 4 * config.max_gap_m, step * 2)
                if q is not None and (best is None or np.linalg.norm(q - end) < best[0]):
                    best = (float(np.linalg.norm(q - end)), end, q, boxes[i].width_m)
        if best is not None:
            _, end, q, w = best
            u = (q - end) / max(np.linalg.norm(q - end), 1e-6)
            boxes.append(box_from_ends(end - u * 0.3, q + u * 0.5, max(w, 1.5), "connector", 0.5))
            ext.append(0.0)
    probe = LandProbe(class_map, boxes)
    comps = _components(boxes)
    on_land = tuple(any(probe.is_land(end, boxes[i].width_m / 2 + 0.5) for i in comp for end in boxes[i].ends())
                    for comp in comps)
    objects: list[SceneObject] = []
    for s, comp in enumerate(comps):
        for i in comp:
            b = boxes[i]
            asset = finger_asset if b.role == "finger" else walkway_asset
            objects.extend(_chain(b, asset, f"pier{s}_{i}", s, water_level_m))
    report = {
        "n_structures": len(comps), "n_boxes": len(boxes), "n_segments": len(objects),
        "structures_on_land": int(sum(on_land)), "connectors_added": sum(b.role == "connector" for b in boxes),
        "extended_m": [round(e, 2) for e in ext],
    }
    return PierResult(tuple(objects), tuple(boxes), tuple(tuple(c) for c in comps), on_land, tuple(ext), report)


def _chain(b: PierBox, asset, prefix: str, structure: int, water_level_m: float) -> list[SceneObject]:
    seg_len, seg_w, _ = asset.dims_m
    n = max(1, math.ceil(b.length_m / seg_len - 1e-6))
    piece = b.length_m / n
    sx = piece / seg_len
    sy = float(np.clip(b.width_m / seg_w, 0.5, 2.5))
    c, u = np.array([b.x_m, b.y_m]), b.axis
    start = c - u * b.length_m / 2
    out = []
    for k in range(n):
        p = start + u * (k + 0.5) * piece
        out.append(SceneObject(
            id=f"{prefix}_{k}", category="pier", asset_id=asset.id, x_m=float(p[0]), y_m=float(p[1]),
            z_m=float(water_level_m), yaw_deg=float(b.yaw_deg), scale=(float(sx), sy, 1.0), length_m=float(piece),
            width_m=float(seg_w * sy), source="pier", score=float(b.score),
            attrs={"structure": f"pier{structure}", "role": b.role, "segment": k, "of": n},
        ))
    return out
