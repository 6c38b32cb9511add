"""What segmentation writes beside the scene.

- ``classes.png``: uint8 class ids (DESIGN.md §2), the scene grid.
- ``classes_preview.png``: the class palette blended over the image, for people.
- ``weights/<class>.png``: one 8-bit weight map per class (Unreal landscape paint layers). Borders are
  softened by a Gaussian of ``segment.weight_blur_m`` metres; at every pixel the eight maps sum to
  exactly 255 (the rounding remainder goes to the pixel's own class).
- ``biome.png`` + ``biome.json``: a map for vegetation/scatter rules, with the legend below. "Shore"
  means within ``segment.biome_shore_m`` of the waterline; "shallow" water is within
  ``segment.biome_shallow_m`` of land (where seaweed grows).

  ====  ===============  ==============================================
  id    name             from
  ====  ===============  ==============================================
  0     deep_water       water farther than biome_shallow_m from land
  1     shallow_water    water near land (seaweed)
  2     beach            sand
  3     rocky_shore      rocks near the waterline (revetments, riprap)
  4     rocky_ground     rocks inland
  5     shore_grass      grass near the waterline (dune/bank grass)
  6     inland_grass     other grass
  7     woodland         trees
  8     paved            asphalt and sidewalk (no vegetation)
  9     bare_ground      dirt
  ====  ===============  ==============================================
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..classes import ASPHALT, CLASS_NAMES, DIRT, GRASS, N_CLASSES, ROCKS, SAND, SIDEWALK, TREES, WATER, colorize
from ..config import SegmentConfig
from ..fsio import atomic_write_text, write_png
from ..types import ClassMap, GeoImage

BIOMES: tuple[tuple[int, str, str], ...] = (
    (0, "deep_water", "water farther than biome_shallow_m from land"),
    (1, "shallow_water", "water within biome_shallow_m of land (seaweed)"),
    (2, "beach", "sand"),
    (3, "rocky_shore", "rocks within biome_shore_m of the waterline"),
    (4, "rocky_ground", "rocks inland"),
    (5, "shore_grass", "grass within biome_shore_m of the waterline"),
    (6, "inland_grass", "grass inland"),
    (7, "woodland", "trees"),
    (8, "paved", "asphalt and sidewalk"),
    (9, "bare_ground", "dirt"),
)
BIOME_IDS = {name: i for i, name, _d in BIOMES}


def preview(rgb: np.ndarray, ids: np.ndarray, alpha: float = 0.55) -> np.ndarray:
    """The class palette blended over the image (uint8 RGB)."""
    col = colorize(ids).astype(np.float32)
    return np.clip((1.0 - alpha) * rgb.astype(np.float32) + alpha * col + 0.5, 0, 255).astype(np.uint8)


def weight_maps(ids: np.ndarray, gsd_m: float, blur_m: float) -> np.ndarray:
    """(H, W, 8) uint8 paint-layer weights with soft borders; each pixel sums to exactly 255."""
    h, w = ids.shape
    sigma = max(0.0, blur_m / gsd_m)
    out = np.zeros((h, w, N_CLASSES), np.uint8)
    total = np.zeros((h, w), np.int32)
    for c in np.unique(ids):
        one = (ids == c).astype(np.float32)
        if sigma > 0.3:
            # a Gaussian is a partition of unity, so the blurred one-hot maps still sum to 1
            one = cv2.GaussianBlur(one, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        q = np.floor(one * 255.0 + 1e-4).astype(np.int32)
        np.clip(q, 0, 255, out=q)
        out[..., c] = q.astype(np.uint8)
        total += q
    rest = 255 - total  # 0..7 from flooring: give it to the pixel's own class
    own = np.take_along_axis(out, ids[..., None].astype(np.intp), axis=2)[..., 0].astype(np.int32) + rest
    np.put_along_axis(out, ids[..., None].astype(np.intp), np.clip(own, 0, 255).astype(np.uint8)[..., None], axis=2)
    return out


def biome_map(ids: np.ndarray, gsd_m: float, shore_m: float = 15.0, shallow_m: float = 20.0) -> np.ndarray:
    """Biome ids (uint8) for vegetation rules; see the module docstring for the legend."""
    from scipy import ndimage as ndi

    h, w = ids.shape
    # distances need no more than ~0.5 m precision: work on a reduced grid for big images
    f = max(1, int(min(0.5 / gsd_m, max(h, w) / 1024)) if gsd_m < 0.5 else 1)
    small = ids[::f, ::f]
    water = small == WATER
    g = gsd_m * f
    if water.any() and (~water).any():
        d_to_water = ndi.distance_transform_edt(~water) * g  # on land: distance to the waterline
        d_to_land = ndi.distance_transform_edt(water) * g
    else:
        d_to_water = np.full(small.shape, np.inf)
        d_to_land = np.full(small.shape, np.inf)
    b = np.full(small.shape, BIOME_IDS["paved"], np.uint8)
    b[water] = BIOME_IDS["deep_water"]
    b[water & (d_to_land <= shallow_m)] = BIOME_IDS["shallow_water"]
    b[small == SAND] = BIOME_IDS["beach"]
    shore = d_to_water <= shore_m
    b[(small == ROCKS) & shore] = BIOME_IDS["rocky_shore"]
    b[(small == ROCKS) & ~shore] = BIOME_IDS["rocky_ground"]
    b[(small == GRASS) & shore] = BIOME_IDS["shore_grass"]
    b[(small == GRASS) & ~shore] = BIOME_IDS["inland_grass"]
    b[small == TREES] = BIOME_IDS["woodland"]
    b[(small == ASPHALT) | (small == SIDEWALK)] = BIOME_IDS["paved"]
    b[small == DIRT] = BIOME_IDS["bare_ground"]
    if f > 1:
        b = cv2.resize(b, (w, h), interpolation=cv2.INTER_NEAREST)
    return b


def write_segmentation(out_dir: str | Path, class_map: ClassMap, image: GeoImage | None = None,
                       config: SegmentConfig | None = None, backend: str = "") -> dict:
    """Write classes.png, classes_preview.png (if ``image``), weights/<class>.png, biome.png, biome.json
    and segmentation.json into ``out_dir`` (atomically). Returns name → path and the class fractions."""
    cfg = config or SegmentConfig()
    out = Path(out_dir)
    ids = np.ascontiguousarray(class_map.ids, dtype=np.uint8)
    gsd = class_map.grid.gsd_m
    paths: dict[str, str] = {}
    paths["classes"] = str(write_png(out / "classes.png", ids))
    if image is not None:
        paths["preview"] = str(write_png(out / "classes_preview.png", preview(image.rgb, ids)))
    wm = weight_maps(ids, gsd, cfg.weight_blur_m)
    for c, name in enumerate(CLASS_NAMES):
        paths[f"weights/{name}"] = str(write_png(out / "weights" / f"{name}.png", np.ascontiguousarray(wm[..., c])))
    del wm
    biome = biome_map(ids, gsd, cfg.biome_shore_m, cfg.biome_shallow_m)
    paths["biome"] = str(write_png(out / "biome.png", biome))
    legend = {
        "format": "coastforge.biome/1",
        "raster": "biome.png",
        "shore_m": cfg.biome_shore_m,
        "shallow_m": cfg.biome_shallow_m,
        "legend": [{"id": i, "name": n, "from": d} for i, n, d in BIOMES],
    }
    paths["biome_legend"] = str(atomic_write_text(out / "biome.json", json.dumps(legend, indent=1)))
    counts = np.bincount(ids.ravel(), minlength=N_CLASSES)
    fractions = {n: float(counts[i] / max(ids.size, 1)) for i, n in enumerate(CLASS_NAMES)}
    meta = {
        "format": "coastforge.segmentation/1",
        "backend": backend,
        "gsd_m": gsd,
        "size_px": [int(ids.shape[1]), int(ids.shape[0])],
        "class_fractions": fractions,
        "files": {k: Path(v).relative_to(out).as_posix() for k, v in paths.items()},
    }
    paths["meta"] = str(atomic_write_text(out / "segmentation.json", json.dumps(meta, indent=1)))
    return {"paths": paths, "class_fractions": fractions}
