"""Vegetation and rock scatter: per-class density rules, slope and water-level filters, Poisson-disk
spacing, clear of objects, piers and paved areas. Output: a compact table plus one 8-bit mask per rule
(Unreal PCG reads these as density maps)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .classes import DIRT, GRASS, ROCKS, SAND, TREES, WATER
from .config import VegetationConfig
from .rng import stage_rng
from .scene import SceneObject, Vegetation
from .types import Grid


@dataclass(frozen=True)
class Rule:
    name: str
    asset_category: str  # tree | bush | grass | rock | seaweed
    scene_category: str  # vegetation | rock (the Vegetation table's category)
    class_weights: dict  # class id -> density multiplier
    density_key: str  # VegetationConfig field with the density per 100 m²
    spacing_m: float
    land: bool = True  # land plants above the water level; seaweed below
    min_depth_m: float = 0.0
    max_depth_m: float = 0.0
    slope_limited: bool = False
    scale_range: tuple[float, float] = (0.8, 1.25)


RULES: tuple[Rule, ...] = (
    Rule("trees", "tree", "vegetation", {TREES: 1.0, GRASS: 0.04}, "tree_density_per_100m2", 4.0, slope_limited=True),
    Rule("bushes", "bush", "vegetation", {TREES: 0.6, GRASS: 0.15, DIRT: 0.1}, "bush_density_per_100m2", 1.8,
         slope_limited=True),
    Rule("grass", "grass", "vegetation", {GRASS: 1.0, DIRT: 0.2, TREES: 0.3}, "grass_density_per_100m2", 0.8),
    Rule("rocks", "rock", "rock", {ROCKS: 1.0, DIRT: 0.05, SAND: 0.02}, "rock_density_per_100m2", 1.5),
    Rule("seaweed", "seaweed", "vegetation", {WATER: 1.0}, "seaweed_density_per_100m2", 1.5, land=False,
         min_depth_m=0.5, max_depth_m=4.0),
)


@dataclass(frozen=True, eq=False)
class ScatterResult:
    vegetation: Vegetation
    masks: dict  # rule name -> (H, W) uint8 density mask
    counts: dict  # rule name -> instances


def slope_deg(height: np.ndarray, gsd_m: float) -> np.ndarray:
    gy, gx = np.gradient(height.astype(np.float32), gsd_m)
    return np.degrees(np.arctan(np.hypot(gx, gy)))


def footprint_mask(objects, grid: Grid, margin_m: float) -> np.ndarray:
    """Pixels covered by objects (oriented rectangles grown by ``margin_m``)."""
    import cv2

    mask = np.zeros(grid.shape, np.uint8)
    for o in objects:
        pts = o.footprint_m(grow_m=margin_m)
        col, row = grid.to_pixel(pts[:, 0], pts[:, 1])
        cv2.fillPoly(mask, [np.round(np.stack([col, row], 1)).astype(np.int32)], 1)
    return mask.astype(bool)


MAX_CANDIDATES = 4_000_000  # candidate cells per rule (about 100 MB of working arrays)


def _poisson_points(mask_density: np.ndarray, grid: Grid, density_per_100m2: float, spacing_m: float,
                    rng: np.random.Generator) -> np.ndarray:
    """Blue-noise points: one jittered candidate per cell of size ``spacing``, kept with the local density's
    probability, then thinned so no two are closer than ``spacing`` (KD-tree). Over an extent that would
    need more than ``MAX_CANDIDATES`` cells, the cells grow (never beyond one expected point per cell at
    full density), so memory stays bounded on a port of many km²."""
    from scipy.spatial import cKDTree

    w, h = grid.extent_m
    cell = spacing_m
    if density_per_100m2 > 0 and (w / cell) * (h / cell) > MAX_CANDIDATES:
        cell = max(spacing_m, min(float(np.sqrt(w * h / MAX_CANDIDATES)), float(np.sqrt(100.0 / density_per_100m2))))
    nx, ny = int(np.ceil(w / cell)), int(np.ceil(h / cell))
    if nx * ny == 0 or density_per_100m2 <= 0:
        return np.zeros((0, 2))
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny))
    x = -w / 2 + (gx.ravel() + rng.random(nx * ny)) * cell
    y = -h / 2 + (gy.ravel() + rng.random(nx * ny)) * cell
    inside = (x < w / 2) & (y < h / 2)  # the last row/column of cells may stick out of the scene
    x, y = x[inside], y[inside]
    col, row = grid.to_pixel(x, y)
    ci = np.clip(col.astype(int), 0, grid.width_px - 1)
    ri = np.clip(row.astype(int), 0, grid.height_px - 1)
    p = mask_density[ri, ci] * density_per_100m2 * cell * cell / 100.0
    keep = rng.random(p.size) < np.minimum(p, 1.0)
    pts = np.stack([x[keep], y[keep]], 1)
    if len(pts) < 2:
        return pts
    tree = cKDTree(pts)
    drop = np.zeros(len(pts), bool)
    for i, j in sorted(tree.query_pairs(spacing_m * 0.8)):
        if not drop[i] and not drop[j]:
            drop[j] = True
    return pts[~drop]


def scatter(classes: np.ndarray, height: np.ndarray | None, grid: Grid, assets_by_category: dict,
            objects: list[SceneObject] | tuple[SceneObject, ...], config: VegetationConfig, seed: int,
            water_level_m: float = 0.0) -> ScatterResult:
    """Scatter vegetation and rocks. ``assets_by_category`` maps an asset category (tree, bush, grass, rock,
    seaweed) to a list of asset ids; rules whose category has no asset are skipped."""
    import cv2

    if not config.enabled:
        return ScatterResult(Vegetation.empty(), {}, {})
    z = height if height is not None else np.where(classes == WATER, -2.0, 0.5).astype(np.float32)
    slope = slope_deg(z, grid.gsd_m)
    clear = ~footprint_mask(objects, grid, margin_m=1.0)
    rows: dict[str, list] = {k: [] for k in ("asset_id", "category", "x_m", "y_m", "z_m", "yaw_deg", "scale")}
    masks, counts, dens_of = {}, {}, {}
    for rule in RULES:
        ids = list(assets_by_category.get(rule.asset_category, ()))
        if not ids:
            continue
        dens = np.zeros(grid.shape, np.float32)
        for cid, wgt in rule.class_weights.items():
            dens[classes == cid] = wgt
        if rule.land:
            dens[z <= water_level_m + 0.2] = 0
        else:
            depth = water_level_m - z
            dens[(depth < rule.min_depth_m) | (depth > rule.max_depth_m)] = 0
        if rule.slope_limited:
            dens[slope > config.max_slope_deg_trees] = 0
        dens[~clear] = 0
        masks[rule.name] = np.clip(dens * 255, 0, 255).astype(np.uint8)
        dens_of[rule.name] = (rule, ids, dens)
    # where the rules together would scatter more than max_instances, every density is thinned by the same
    # factor first (the proportions stay), so a port of many km² never draws millions of points to drop them
    area_px = grid.gsd_m ** 2 / 100.0
    expected = sum(float(d.sum()) * area_px * getattr(config, r.density_key) for r, _i, d in dens_of.values())
    thin = min(1.0, config.max_instances / expected) if expected > 0 else 1.0
    for rule, ids, dens in dens_of.values():
        rng = stage_rng(seed, "vegetation", rule.name)
        spacing = max(rule.spacing_m, config.min_spacing_m if rule.asset_category == "tree" else rule.spacing_m)
        pts = _poisson_points(dens, grid, getattr(config, rule.density_key) * thin, spacing, rng)
        counts[rule.name] = len(pts)
        if not len(pts):
            continue
        col, row = grid.to_pixel(pts[:, 0], pts[:, 1])
        ci = np.clip(col.astype(int), 0, grid.width_px - 1)
        ri = np.clip(row.astype(int), 0, grid.height_px - 1)
        rows["asset_id"] += list(rng.choice(np.array(ids, dtype=object), len(pts)))
        rows["category"] += [rule.scene_category] * len(pts)
        rows["x_m"] += list(pts[:, 0])
        rows["y_m"] += list(pts[:, 1])
        rows["z_m"] += list(z[ri, ci].astype(float))
        rows["yaw_deg"] += list(rng.uniform(-180, 180, len(pts)))
        rows["scale"] += list(rng.uniform(*rule.scale_range, len(pts)))
    n = len(rows["x_m"])
    if n > config.max_instances:  # keep a uniform random subset, so density stays proportional
        keep = np.sort(stage_rng(seed, "vegetation", "cap").choice(n, config.max_instances, replace=False))
        rows = {k: [v[i] for i in keep] for k, v in rows.items()}
    veg = Vegetation(
        np.array(rows["asset_id"], dtype=object), np.array(rows["category"], dtype=object),
        *(np.round(np.array(rows[k], dtype=np.float64), 3) for k in ("x_m", "y_m", "z_m", "yaw_deg", "scale")),
    ) if rows["x_m"] else Vegetation.empty()
    # smooth the masks slightly: PCG samples them bilinearly and hard edges alias
    masks = {k: cv2.GaussianBlur(m, (0, 0), 1.0) for k, m in masks.items()}
    return ScatterResult(veg, masks, counts)
