"""Evaluation against a truth scene (DESIGN.md §5, the paper's protocol made precise).

Objects: truth and predictions are matched one-to-one by the Hungarian assignment on centre distance,
with a gate of max(2 m, half the truth object's length). Only boats, vehicles and buoys count; pier
segments are checked for connectivity and for the deck area they share with the truth's piers instead.
Undefined figures (no matched pairs) are ``None``.

A truth object marked ``attrs["symmetry"] == "rotational"`` (a round buoy) looks the same at every yaw, so
its yaw error is undefined: it counts for XY, recall and precision but not for the rotation and orientation
RMSE (``n_yaw`` says how many pairs those use).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .classes import EVALUATED_CATEGORIES, N_CLASSES, WATER
from .frames import wrap_deg, wrap_half_deg
from .scene import Scene, SceneObject

MIN_GATE_M = 2.0


@dataclass(frozen=True)
class Match:
    truth: SceneObject
    pred: SceneObject
    distance_m: float


@dataclass(frozen=True)
class ObjectMetrics:
    n_truth: int
    n_pred: int
    n_matched: int
    xy_rmse_m: float | None
    rotation_rmse_deg: float | None
    orientation_rmse_deg: float | None
    recall: float | None
    match_precision: float | None
    match_precision_category: float | None
    detection_precision: float | None
    n_yaw: int = 0  # matched pairs whose yaw error is defined (see the module docstring)
    matches: tuple[Match, ...] = field(default=(), repr=False)

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in (
            "n_truth", "n_pred", "n_matched", "xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "recall",
            "match_precision", "match_precision_category", "detection_precision", "n_yaw")}


def match_objects(truth: list[SceneObject], pred: list[SceneObject]) -> list[Match]:
    """One-to-one Hungarian matching on centre distance, gated per truth object."""
    from scipy.optimize import linear_sum_assignment

    if not truth or not pred:
        return []
    t = np.array([[o.x_m, o.y_m] for o in truth])
    p = np.array([[o.x_m, o.y_m] for o in pred])
    d = np.linalg.norm(t[:, None, :] - p[None, :, :], axis=2)
    gate = np.maximum(MIN_GATE_M, 0.5 * np.array([o.length_m for o in truth]))[:, None]
    big = 1e9
    cost = np.where(d <= gate, d, big)
    rows, cols = linear_sum_assignment(cost)
    return [Match(truth[i], pred[j], float(d[i, j])) for i, j in zip(rows, cols) if cost[i, j] < big]


def is_yaw_symmetric(obj: SceneObject) -> bool:
    """True when the truth object is marked rotationally symmetric (its yaw carries no information)."""
    return str(obj.attrs.get("symmetry", "")).lower() == "rotational"


def _rmse(values: list[float]) -> float | None:
    return float(np.sqrt(np.mean(np.square(values)))) if values else None


def object_metrics(truth: list[SceneObject], pred: list[SceneObject]) -> ObjectMetrics:
    matches = match_objects(truth, pred)
    n_t, n_p, n_m = len(truth), len(pred), len(matches)
    xy = [m.distance_m for m in matches]
    oriented = [m for m in matches if not is_yaw_symmetric(m.truth)]
    rot = [float(wrap_deg(m.pred.yaw_deg - m.truth.yaw_deg)) for m in oriented]
    ori = [float(wrap_half_deg(m.pred.yaw_deg - m.truth.yaw_deg)) for m in oriented]
    same_asset = sum(m.pred.asset_id == m.truth.asset_id for m in matches)
    same_cat = sum(m.pred.category == m.truth.category for m in matches)
    return ObjectMetrics(
        n_truth=n_t, n_pred=n_p, n_matched=n_m, xy_rmse_m=_rmse(xy), rotation_rmse_deg=_rmse(rot),
        orientation_rmse_deg=_rmse(ori), recall=n_m / n_t if n_t else None,
        match_precision=same_asset / n_m if n_m else None,
        match_precision_category=same_cat / n_m if n_m else None,
        detection_precision=n_m / n_p if n_p else None, n_yaw=len(oriented), matches=tuple(matches),
    )


def _resample_nearest(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    if a.shape == shape:
        return a
    import cv2

    return cv2.resize(a, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)


def terrain_metrics(truth: Scene, pred: Scene) -> dict:
    """Class-map IoU per class and mIoU; height RMSE on land and on water (truth classes decide which)."""
    out: dict = {}
    if truth.classes is not None and pred.classes is not None:
        t = truth.classes
        p = _resample_nearest(pred.classes, t.shape)
        ious = {}
        from .classes import CLASS_NAMES

        for c in range(N_CLASSES):
            inter = np.count_nonzero((t == c) & (p == c))
            union = np.count_nonzero((t == c) | (p == c))
            if np.count_nonzero(t == c):  # classes absent from the truth do not count in the mean
                ious[CLASS_NAMES[c]] = inter / union if union else None
        vals = [v for v in ious.values() if v is not None]
        out["class_iou"] = ious
        out["miou"] = float(np.mean(vals)) if vals else None
    if truth.height is not None and pred.height is not None and truth.classes is not None:
        import cv2

        th = truth.height
        ph = pred.height if pred.height.shape == th.shape else cv2.resize(
            pred.height, (th.shape[1], th.shape[0]), interpolation=cv2.INTER_LINEAR)
        water = truth.classes == WATER if truth.classes.shape == th.shape else th < truth.water_level_m
        err = (ph - th).astype(np.float64)
        out["height_rmse_land_m"] = float(np.sqrt(np.mean(err[~water] ** 2))) if np.any(~water) else None
        out["height_rmse_water_m"] = float(np.sqrt(np.mean(err[water] ** 2))) if np.any(water) else None
    return out


def pier_connectivity(scene: Scene, tol_m: float = 0.75) -> dict:
    """Every pier segment must reach land or another pier segment, and every structure must reach land.

    A segment is a rectangle (centre, yaw, length, width). Two segments touch when their rectangles come within
    ``tol_m``; a segment touches land when any point of its footprint (grown by ``tol_m``) lies on a non-water
    class, or above the water level if there is no class map.
    """
    from shapely import STRtree
    from shapely.geometry import Polygon

    piers = [o for o in scene.objects if o.category == "pier"]
    if not piers:
        return {"n_segments": 0, "n_structures": 0, "segments_connected": None, "structures_on_land": None,
                "all_connected": None}
    polys = [Polygon(o.footprint_m()) for o in piers]
    n = len(piers)
    # pairs within tol_m from a spatial index (a marina has hundreds of segments: all pairs would be slow)
    src, dst = STRtree(polys).query(polys, predicate="dwithin", distance=tol_m)
    adj: list[list[int]] = [[] for _ in range(n)]
    for i, j in zip(src.tolist(), dst.tolist()):
        if i != j:
            adj[i].append(j)
    on_land = [touches_land(scene, p.buffer(tol_m)) for p in polys]
    # connected components of the touch graph = structures
    comp = [-1] * n
    k = 0
    for i in range(n):
        if comp[i] >= 0:
            continue
        stack = [i]
        comp[i] = k
        while stack:
            a = stack.pop()
            for b in adj[a]:
                if comp[b] < 0:
                    comp[b] = k
                    stack.append(b)
        k += 1
    structures_on_land = [any(on_land[i] for i in range(n) if comp[i] == s) for s in range(k)]
    seg_ok = [on_land[i] or bool(adj[i]) for i in range(n)]
    return {
        "n_segments": n, "n_structures": k,
        "segments_connected": sum(seg_ok) / n,
        "structures_on_land": sum(structures_on_land) / k,
        "all_connected": all(seg_ok) and all(structures_on_land),
        "disconnected_ids": [piers[i].id for i in range(n) if not seg_ok[i]
                             or not structures_on_land[comp[i]]],
    }


def pier_deck(truth: Scene, pred: Scene, tol_m: float = 0.5) -> dict:
    """How much of the truth's pier deck the prediction built, and how much of its deck is real: recall = the
    truth piers' area (union) within ``tol_m`` of a predicted pier, precision = the predicted piers' area within
    ``tol_m`` of a truth pier. Connectivity alone cannot see a pier that was never found, or deck built over
    open water; this can. ``None`` where a side has no pier."""
    from shapely import unary_union
    from shapely.geometry import Polygon

    def deck(scene: Scene):
        polys = [Polygon(o.footprint_m()) for o in scene.objects if o.category == "pier"]
        return unary_union(polys) if polys else None

    t, p = deck(truth), deck(pred)
    out: dict = {"truth_m2": float(t.area) if t is not None else 0.0,
                 "pred_m2": float(p.area) if p is not None else 0.0, "recall": None, "precision": None}
    if t is not None and t.area > 0:
        out["recall"] = float(t.intersection(p.buffer(tol_m)).area / t.area) if p is not None else 0.0
    if p is not None and p.area > 0:
        out["precision"] = float(p.intersection(t.buffer(tol_m)).area / p.area) if t is not None else 0.0
    return out


def touches_land(scene: Scene, poly) -> bool:
    grid = scene.grid
    minx, miny, maxx, maxy = poly.bounds
    # no land in the pixels of the bounding box (most segments of a marina stand in open water): no
    # sample inside the polygon can find any, so the point-in-polygon test is skipped
    box = _box_pixels(scene, minx, miny, maxx, maxy)
    if box is not None and not box.any():
        return False
    xs = np.linspace(minx, maxx, max(3, int((maxx - minx) / grid.gsd_m) + 1))
    ys = np.linspace(miny, maxy, max(3, int((maxy - miny) / grid.gsd_m) + 1))
    gx, gy = np.meshgrid(xs, ys)
    from shapely import contains_xy

    inside = contains_xy(poly, gx.ravel(), gy.ravel())
    if not inside.any():
        return False
    cols, rows = grid.to_pixel(gx.ravel()[inside], gy.ravel()[inside])
    ci = np.clip(np.floor(cols).astype(int), 0, grid.width_px - 1)
    ri = np.clip(np.floor(rows).astype(int), 0, grid.height_px - 1)
    if scene.classes is not None:
        return bool(np.any(scene.classes[ri, ci] != WATER))
    if scene.height is not None:
        return bool(np.any(scene.height[ri, ci] > scene.water_level_m))
    return False


def _box_pixels(scene: Scene, minx: float, miny: float, maxx: float, maxy: float) -> np.ndarray | None:
    """Is each pixel of the window spanning the box land (the pixels ``touches_land`` samples, clamped the
    same way)? None when the scene has no raster to tell."""
    grid = scene.grid
    cols, rows = grid.to_pixel(np.array([minx, maxx]), np.array([miny, maxy]))
    c0, c1 = np.clip(np.floor(np.sort(cols)).astype(int), 0, grid.width_px - 1)
    r0, r1 = np.clip(np.floor(np.sort(rows)).astype(int), 0, grid.height_px - 1)
    if scene.classes is not None:
        return scene.classes[r0:r1 + 1, c0:c1 + 1] != WATER
    if scene.height is not None:
        return scene.height[r0:r1 + 1, c0:c1 + 1] > scene.water_level_m
    return None


def check_same_ground(truth: Scene, pred: Scene) -> None:
    """Refuse to compare scenes of different extents: positions are metres from each scene's centre and the
    rasters are resampled onto the truth's grid, so two different places would give numbers, all wrong."""
    from .errors import InputError

    (tw, th), (pw, ph) = truth.extent_m, pred.extent_m
    tol = max(2.0 * max(truth.gsd_m, pred.gsd_m), 0.01 * max(tw, th))
    if abs(tw - pw) > tol or abs(th - ph) > tol:
        raise InputError(f"the truth covers {tw:g} x {th:g} m but the prediction {pw:g} x {ph:g} m: they are not "
                         "the same ground; evaluate a scene generated from the truth's own image (listed in its "
                         "inputs.json) at its GSD")


def evaluate_scenes(truth: Scene, pred: Scene) -> dict:
    """All metrics of DESIGN.md §5 as one JSON-ready dict. The two scenes must cover the same ground."""
    check_same_ground(truth, pred)
    t_objs = [o for o in truth.objects if o.category in EVALUATED_CATEGORIES]
    p_objs = [o for o in pred.objects if o.category in EVALUATED_CATEGORIES]
    overall = object_metrics(t_objs, p_objs)
    out = overall.to_dict()
    per = {}
    for c in EVALUATED_CATEGORIES:
        tc = [o for o in t_objs if o.category == c]
        pc = [o for o in p_objs if o.category == c]
        if tc or pc:
            per[c] = object_metrics(tc, pc).to_dict()
    out["per_category"] = per
    out["terrain"] = terrain_metrics(truth, pred)
    out["piers"] = pier_connectivity(pred)
    out["pier_deck"] = pier_deck(truth, pred)
    return out
