"""What segmentation writes beside the scene.

- ``classes.png``: uint8 class ids (DESIGN.md §2), the scene grid.
- ``classes_preview.png``: the class palette blended over the image, for people.
- ``confidence.png`` (when the backend gives one): uint8, 255 = sure of the pixel's class; and
  ``source.png``: which source decided each pixel (0 both agree, 1 the network, 2 the classical rules,
  3 moored boats made it water; legend in ``segmentation.json``).
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
from .learned import SOURCE_NAMES

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
    ids = np.ascontiguousarray(ids, dtype=np.uint8)
    lut = np.empty((1, 256, 3), np.uint8)  # ``classes.colorize`` as an OpenCV table (ids past the last clip)
    lut[0, :N_CLASSES] = colorize(np.arange(N_CLASSES))
    lut[0, N_CLASSES:] = lut[0, N_CLASSES - 1]
    col = cv2.LUT(cv2.merge([ids, ids, ids]), lut)
    img = np.ascontiguousarray(rgb[..., :3], dtype=np.uint8)
    if img.shape != col.shape:
        raise ValueError(f"preview: image {img.shape} and class map {ids.shape} differ in size")
    return cv2.addWeighted(img, 1.0 - alpha, col, alpha, 0.0)  # rounds and saturates in one uint8 pass


def _blur_factor(sigma_px: float) -> int:
    """How much coarser a Gaussian of ``sigma_px`` may be computed: a box-average down by f, the blur with
    sigma/f and a bilinear resize back add ~0.5 f px of blur, negligible while sigma/f ≥ 3."""
    return max(1, int(sigma_px // 3.0)) if sigma_px >= 6.0 else 1


def weight_maps(ids: np.ndarray, gsd_m: float, blur_m: float) -> np.ndarray:
    """(H, W, 8) uint8 paint-layer weights with soft borders; each pixel sums to exactly 255.

    A wide blur runs on a grid ``_blur_factor`` times coarser: every step (area average, Gaussian,
    bilinear resize) is linear and keeps constants, so the eight maps still sum to 1 before quantising,
    at a fraction of the cost of eight full-resolution Gaussians."""
    h, w = ids.shape
    ids = np.ascontiguousarray(ids, dtype=np.uint8)
    sigma = max(0.0, blur_m / gsd_m)
    f = _blur_factor(sigma)
    sw, sh = max(1, -(-w // f)), max(1, -(-h // f))
    planes = np.zeros((N_CLASSES, h, w), np.uint8)  # class-major: each map is one contiguous plane
    total = np.zeros((h, w), np.uint16)
    present = np.flatnonzero(np.bincount(ids.ravel(), minlength=N_CLASSES)[:N_CLASSES])
    for c in present:
        one = (ids == c).view(np.uint8).astype(np.float32)
        if sigma > 0.3:
            if f > 1:
                small = cv2.resize(one, (sw, sh), interpolation=cv2.INTER_AREA)
                small = cv2.GaussianBlur(small, (0, 0), sigma / f, borderType=cv2.BORDER_REFLECT)
                one = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
            else:
                # a Gaussian is a partition of unity, so the blurred one-hot maps still sum to 1
                one = cv2.GaussianBlur(one, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
        # floor(x * 255) (x is in [0, 1]: truncation is the floor); the sum per pixel stays ≤ 255
        cv2.multiply(one, 255.0, dst=one)
        np.add(one, 1e-4, out=one)
        q = one.astype(np.uint8)
        planes[c] = q
        total += q
    # 0..7 left from flooring: give it to the pixel's own class
    rest = (255 - total.astype(np.int16)).astype(np.uint8)
    for c in present:
        np.add(planes[c], rest, out=planes[c], where=ids == c)
    return np.moveaxis(planes, 0, -1)  # (H, W, 8) view; planes[c] stays contiguous for writing


def _distance_px(nonzero: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (px) of every nonzero pixel to the nearest zero pixel (OpenCV's precise
    transform: several times faster than scipy's ``distance_transform_edt``, same values)."""
    return cv2.distanceTransform(nonzero.view(np.uint8) if nonzero.dtype == bool else nonzero.astype(np.uint8),
                                 cv2.DIST_L2, cv2.DIST_MASK_PRECISE)


def biome_map(ids: np.ndarray, gsd_m: float, shore_m: float = 15.0, shallow_m: float = 20.0) -> np.ndarray:
    """Biome ids (uint8) for vegetation rules; see the module docstring for the legend."""
    h, w = ids.shape
    # distances need no more than ~0.5 m precision: work on a reduced grid for big images
    f = max(1, int(min(0.5 / gsd_m, max(h, w) / 1024)) if gsd_m < 0.5 else 1)
    small = np.ascontiguousarray(ids[::f, ::f], dtype=np.uint8)
    water = small == WATER
    g = gsd_m * f
    lut = np.full(256, BIOME_IDS["paved"], np.uint8)  # class -> biome before the distance rules
    lut[WATER] = BIOME_IDS["deep_water"]
    lut[SAND] = BIOME_IDS["beach"]
    lut[ROCKS] = BIOME_IDS["rocky_shore"]
    lut[GRASS] = BIOME_IDS["shore_grass"]
    lut[TREES] = BIOME_IDS["woodland"]
    lut[ASPHALT] = lut[SIDEWALK] = BIOME_IDS["paved"]
    lut[DIRT] = BIOME_IDS["bare_ground"]
    b = lut[small]
    if water.any() and (~water).any():
        inland = _distance_px(~water) * g > shore_m  # land farther than shore_m from the waterline
        b[water & (_distance_px(water) * g <= shallow_m)] = BIOME_IDS["shallow_water"]
    else:
        inland = ~water  # no waterline: all land is inland
    b[(small == ROCKS) & inland] = BIOME_IDS["rocky_ground"]
    b[(small == GRASS) & inland] = BIOME_IDS["inland_grass"]
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
    if class_map.confidence is not None:
        paths["confidence"] = str(write_png(out / "confidence.png", np.ascontiguousarray(class_map.confidence,
                                                                                          dtype=np.uint8)))
    if class_map.source is not None:
        paths["source"] = str(write_png(out / "source.png", np.ascontiguousarray(class_map.source, dtype=np.uint8)))
    wm = weight_maps(ids, gsd, cfg.weight_blur_m)
    for c, name in enumerate(CLASS_NAMES):
        paths[f"weights/{name}"] = str(write_png(out / "weights" / f"{name}.png", wm[..., c]))
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
        **({"confidence_mean": round(float(np.mean(class_map.confidence)) / 255.0, 4)}
           if class_map.confidence is not None else {}),
        **({"source_legend": {str(i): n for i, n in enumerate(SOURCE_NAMES)},
            "source_fractions": {n: float(np.mean(class_map.source == i)) for i, n in enumerate(SOURCE_NAMES)}}
           if class_map.source is not None else {}),
        "files": {k: Path(v).relative_to(out).as_posix() for k, v in paths.items()},
    }
    paths["meta"] = str(atomic_write_text(out / "segmentation.json", json.dumps(meta, indent=1)))
    return {"paths": paths, "class_fractions": fractions}
