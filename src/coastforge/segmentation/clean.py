"""Remove transient objects (boats, vehicles) from the image by inpainting.

Small holes (a car, a dinghy) are inpainted with OpenCV (Telea). Large ones (a yacht, a row of cars)
would come out as smears, so they are filled from their surroundings' statistics instead: a smooth
colour field interpolated from the ring of pixels around the hole (of the hole's surrounding class when
a class map is given: water under boats), plus texture — residual detail (pixel minus local mean)
copied from random places in that ring, so water keeps its ripples and asphalt its grain. In water the
colour and ripples come from open water nearby rather than the ring: between boats rafted along a pier
the ring is shadows, decks and slivers of hull. Pier walkways and fingers stay.

Detections come from ``coastforge detect`` or a JSON file in its format::

    {"gsd_m": 0.2, "image_size": [W, H],
     "detections": [{"category": "boat", "corners_px": [[c, r], [c, r], [c, r], [c, r]], "score": 0.9}, ...]}
"""

from __future__ import annotations

import json
from pathlib import Path
from collections.abc import Sequence

import cv2
import numpy as np

from .. import frames
from ..errors import InputError
from ..rng import stage_rng
from ..classes import DETECTION_CATEGORIES, N_CLASSES, WATER
from ..types import ClassMap, Detection, GeoImage

TRANSIENT = ("boat", "vehicle", "buoy")  # objects that move or are placed as assets; piers stay
PIERS = ("pier_walkway", "pier_finger")  # structure: kept even where a removed box's margin reaches over it
# A hole in water is filled from "open water": water pixels at least OPEN_WATER_CLEAR_M from any removed
# object, pier or land (past the shadows a boat casts and the glare at a quay), within OPEN_WATER_REACH_M
# of the hole; with fewer than OPEN_WATER_MIN_PX such pixels the ring right around the hole is used
OPEN_WATER_CLEAR_M = 2.0
OPEN_WATER_REACH_M = 15.0
OPEN_WATER_MIN_PX = 50


def detection_from_corners(category: str, corners, score: float = 1.0) -> Detection:
    """An oriented box from its 4 corners (col, row): centre, long side = length, yaw along it."""
    c = np.asarray(corners, dtype=np.float64)
    if c.shape != (4, 2) or not np.isfinite(c).all():
        raise InputError(f"a {category} detection needs 4 finite [col, row] corners, got {corners!r}")
    cx, cy = c.mean(axis=0)
    e1, e2 = c[1] - c[0], c[2] - c[1]
    l1, l2 = float(np.hypot(*e1)), float(np.hypot(*e2))
    long_e = e1 if l1 >= l2 else e2
    yaw = float(frames.yaw_from_direction_px(long_e[0], long_e[1]))
    return Detection(category=category, score=float(score), cx_px=float(cx), cy_px=float(cy),
                     length_px=max(l1, l2), width_px=min(l1, l2), yaw_deg=yaw)


def load_detections(path: str | Path, image_size: tuple[int, int] | None = None) -> list[Detection]:
    """Read a detections JSON (``coastforge detect`` format). Boxes are rescaled when the file's
    ``image_size`` differs from ``image_size`` (W, H) of the image being cleaned."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"detections file {p} does not exist; pass the JSON written by `coastforge detect`")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"detections file {p} is not a JSON text file (an image?); pass the JSON written by "
                         "`coastforge detect`") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"detections file {p} is not valid JSON: {exc}") from exc
    items = data.get("detections") if isinstance(data, dict) else data
    if not isinstance(items, list):
        raise InputError(f"detections file {p} needs a \"detections\" list")
    sx = sy = 1.0
    if image_size is not None and isinstance(data, dict) and data.get("image_size"):
        fw, fh = (float(v) for v in data["image_size"])
        W, H = image_size
        if fw <= 0 or fh <= 0:
            raise InputError(f"detections file {p} has an invalid image_size {data['image_size']}")
        sx, sy = W / fw, H / fh
        if abs(sx - sy) > 0.02 * max(sx, sy):
            raise InputError(f"detections file {p} is for a {fw:g}x{fh:g} image, which does not match the "
                             f"{W}x{H} image (different aspect ratio)")
    out = []
    for i, d in enumerate(items):
        if not isinstance(d, dict) or "category" not in d or "corners_px" not in d:
            raise InputError(f"detection {i} in {p} needs \"category\" and \"corners_px\"")
        if d["category"] not in DETECTION_CATEGORIES:
            raise InputError(f"detection {i} in {p} has category {d['category']!r}; valid: "
                             f"{', '.join(DETECTION_CATEGORIES)} (as `coastforge detect` writes them)")
        try:
            corners = np.asarray(d["corners_px"], dtype=np.float64) * [sx, sy]
            score = float(d.get("score", 1.0))
        except (TypeError, ValueError):
            raise InputError(f"detection {i} in {p}: corners_px = {d['corners_px']!r} must be 4 [col, row] pairs "
                             f"of numbers and score = {d.get('score', 1.0)!r} a number") from None
        out.append(detection_from_corners(str(d["category"]), corners, score))
    return out


def transient_mask(shape: tuple[int, int], detections: Sequence[Detection], categories=TRANSIENT,
                   margin_px: float = 0.0) -> np.ndarray:
    """Bool mask of the objects to remove: their masks if given, else their oriented boxes, grown by
    ``margin_px`` (shadows and anti-aliased edges)."""
    H, W = shape
    mask = np.zeros((H, W), np.uint8)
    for d in detections:
        if d.category not in categories:
            continue
        if d.mask is not None and d.mask_origin_px is not None:
            m = np.asarray(d.mask, bool)
            c0, r0 = d.mask_origin_px
            r1, c1 = min(H, r0 + m.shape[0]), min(W, c0 + m.shape[1])
            rr0, cc0 = max(0, r0), max(0, c0)
            if r1 > rr0 and c1 > cc0:
                mask[rr0:r1, cc0:c1] |= m[rr0 - r0:r1 - r0, cc0 - c0:c1 - c0].astype(np.uint8)
        else:
            pts = frames.box_corners_px(d.cx_px, d.cy_px, d.length_px, d.width_px, d.yaw_deg)
            cv2.fillPoly(mask, [np.round(pts).astype(np.int32)], 1)
    if margin_px >= 0.5 and mask.any():
        r = int(round(margin_px))
        mask = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    return mask.astype(bool)


def _typical(img: np.ndarray, ring: np.ndarray, k: float = 3.0) -> np.ndarray:
    """The ring pixels whose colour is typical of the ring (robust z-score below ``k``): keeps water
    and drops neighbouring boats, pier decks and their shadows from the fill statistics."""
    px = img[ring].astype(np.float32)
    if px.shape[0] < 10:
        return ring
    med = np.median(px, axis=0)
    mad = np.median(np.abs(px - med), axis=0) * 1.4826 + 2.0
    z = np.abs(px - med) / mad
    keep = (z < k).all(axis=1)
    if keep.sum() < max(10, 0.2 * px.shape[0]):
        return ring
    out = np.zeros_like(ring)
    ys, xs = np.nonzero(ring)
    out[ys[keep], xs[keep]] = True
    return out


def _texture_fill(img: np.ndarray, hole: np.ndarray, ring: np.ndarray, rng: np.random.Generator,
                  gsd_m: float) -> None:
    """Fill ``hole`` (in place) with a smooth field from ``ring`` plus ring texture."""
    f = img.astype(np.float32)
    valid = ring.astype(np.float32)
    # smooth base: normalised convolution at growing scales until every hole pixel is reached
    base = np.zeros_like(f)
    done = np.zeros(hole.shape, bool)
    k = max(3, int(round(2.0 / gsd_m)) | 1)
    # zeros outside the window: only ring pixels count, so the window need not reach past the ring
    while not done[hole].all() and k < 4 * max(hole.shape):
        num = cv2.blur(f * valid[..., None], (k, k), borderType=cv2.BORDER_CONSTANT)
        den = cv2.blur(valid, (k, k), borderType=cv2.BORDER_CONSTANT)
        ok = (den > 1e-3) & ~done
        base[ok] = num[ok] / den[ok][:, None]
        done |= ok
        k = k * 2 + 1
    # texture: residuals of the ring (pixel - local mean), copied from random ring pixels
    resid = f - cv2.blur(f, (5, 5))
    ry, rx = np.nonzero(ring)
    hy, hx = np.nonzero(hole)
    tex = _copy_texture(lambda oy, ox: resid[oy, ox], ry, rx, hy, hx, rng, resid.shape[:2])
    img[hy, hx] = np.clip(base[hy, hx] + tex + 0.5, 0, 255).astype(np.uint8)


def _copy_texture(resid_at, ry: np.ndarray, rx: np.ndarray, hy: np.ndarray, hx: np.ndarray,
                  rng: np.random.Generator, shape: tuple[int, int], b: int = 4):
    """Residual detail for the hole pixels (hy, hx), copied from random source pixels (ry, rx) in b x b
    blocks so that the grain keeps its spatial correlation (0 without sources). ``resid_at(oy, ox)``
    gives the residuals; ``shape`` (H, W) bounds the source coordinates."""
    if not ry.size:
        return 0.0
    by, bx = hy // b, hx // b
    keys = by.astype(np.int64) * 100_003 + bx
    uk, inv = np.unique(keys, return_inverse=True)
    pick = rng.integers(0, ry.size, uk.size)
    oy = np.clip(ry[pick][inv] + (hy % b) - b // 2, 0, shape[0] - 1)
    ox = np.clip(rx[pick][inv] + (hx % b) - b // 2, 0, shape[1] - 1)
    return resid_at(oy, ox)


class _OpenWater:
    """Water pixels well clear of removed objects, piers and land, with the smooth colour field they
    give (normalised box filters at two scales, on a grid 16 times coarser than the reach: the field is
    smooth, and this keeps it cheap on large images) and their ripples."""

    def __init__(self, rgb: np.ndarray, ids: np.ndarray, blocked: np.ndarray, gsd: float):
        self.reach_px = max(3, int(round(OPEN_WATER_REACH_M / gsd)))
        self.step = max(1, self.reach_px // 16)
        self._rgb, self._ids, self._blocked, self._gsd = rgb, ids, blocked, gsd
        self.mask: np.ndarray | None = None  # computed by ``prepare``, on the first hole in water
        self._base: np.ndarray | None = None  # coarse grid, NaN where no open water is within reach
        self._blur: np.ndarray | None = None

    def prepare(self) -> None:
        if self._base is not None:
            return
        rgb = self._rgb
        r = max(1, int(round(OPEN_WATER_CLEAR_M / self._gsd)))
        near = cv2.dilate((self._blocked | (self._ids != WATER)).astype(np.uint8),
                          cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
        self.mask = ~near.astype(bool)
        h, w = self.mask.shape
        base = self._smooth(self.mask)
        # "water" the detector missed (a boat, a buoy, a floating deck) or glare is far from the local
        # water colour: drop such pixels (robust z-score over the image) and smooth again
        full = cv2.resize(np.clip(np.nan_to_num(base) + 0.5, 0, 255).astype(np.uint8), (w, h),
                          interpolation=cv2.INTER_LINEAR)
        dev = cv2.absdiff(rgb, full)
        d = dev[::4, ::4][self.mask[::4, ::4]]
        if d.shape[0] >= OPEN_WATER_MIN_PX:
            thr = np.minimum(255, np.ceil(3.0 * (np.median(d, axis=0) * 1.4826 + 2.0)))
            over = cv2.subtract(dev, np.full(dev.shape, thr, np.uint8))
            self.mask &= (over[..., 0] | over[..., 1] | over[..., 2]) == 0
            base = self._smooth(self.mask)
        self._base, self._blur = base, cv2.blur(rgb, (5, 5))

    def _smooth(self, mask: np.ndarray) -> np.ndarray:
        h, w = mask.shape
        size = (max(1, w // self.step), max(1, h // self.step))
        m8 = mask.astype(np.uint8)
        ow = cv2.resize(m8.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        fw = cv2.resize(cv2.bitwise_and(self._rgb, self._rgb, mask=m8).astype(np.float32), size,
                        interpolation=cv2.INTER_AREA)
        r = max(1, self.reach_px // self.step)
        base = np.full(fw.shape, np.nan, np.float32)
        for k in (r | 1, (3 * r) | 1):  # the wider scale where the first has none
            den = cv2.blur(ow, (k, k))
            num = cv2.blur(fw, (k, k))
            ok = (den > 0.01) & np.isnan(base[..., 0])
            base = np.where(ok[..., None], num / np.maximum(den, 1e-6)[..., None], base)
        return base

    def colour_at(self, hy: np.ndarray, hx: np.ndarray) -> np.ndarray:
        """The smooth open-water colour at pixels (hy, hx), bilinear from the coarse grid (NaN: none)."""
        b = self._base
        gh, gw = b.shape[:2]
        fy = np.clip((hy + 0.5) / self.step - 0.5, 0, gh - 1)
        fx = np.clip((hx + 0.5) / self.step - 0.5, 0, gw - 1)
        y0, x0 = np.floor(fy).astype(np.intp), np.floor(fx).astype(np.intp)
        y1, x1 = np.minimum(y0 + 1, gh - 1), np.minimum(x0 + 1, gw - 1)
        wy, wx = (fy - y0)[:, None], (fx - x0)[:, None]
        return ((b[y0, x0] * (1 - wx) + b[y0, x1] * wx) * (1 - wy)
                + (b[y1, x0] * (1 - wx) + b[y1, x1] * wx) * wy)

    def ripples_at(self, oy: np.ndarray, ox: np.ndarray) -> np.ndarray:
        """Pixel minus its 5 x 5 mean at (oy, ox)."""
        return self._rgb[oy, ox].astype(np.int16) - self._blur[oy, ox]


def _fill_from_open_water(out: np.ndarray, lab: np.ndarray, i: int, box: tuple[int, int, int, int],
                          water: _OpenWater, rng: np.random.Generator) -> bool:
    """Fill hole ``i`` in water from open water within reach (False when there is too little of it).

    Right around boats in water are their shadows, pier decks and slivers of hull (boxes are never exact),
    and copying their colour and grain leaves dark, speckled patches where boats were rafted together."""
    water.prepare()
    x, y, w, h = box
    R = water.reach_px
    H, W = lab.shape
    X0, Y0, X1, Y1 = max(0, x - R), max(0, y - R), min(W, x + w + R), min(H, y + h + R)
    ry, rx = np.nonzero(water.mask[Y0:Y1, X0:X1])
    if ry.size < OPEN_WATER_MIN_PX:
        return False
    hy, hx = np.nonzero(lab[y:y + h, x:x + w] == i)
    hy, hx = hy + y, hx + x
    b = water.colour_at(hy, hx)
    if np.isnan(b).any():
        return False
    tex = _copy_texture(water.ripples_at, ry + Y0, rx + X0, hy, hx, rng, (H, W))
    out[hy, hx] = np.clip(b + tex + 0.5, 0, 255).astype(np.uint8)
    return True


def clean_image(image: GeoImage, detections: Sequence[Detection], class_map: ClassMap | None = None,
                seed: int = 0, categories: Sequence[str] = TRANSIENT, margin_m: float = 0.6,
                small_m2: float = 12.0, keep_categories: Sequence[str] = PIERS) -> np.ndarray:
    """The image with transient objects removed (uint8 RGB, same size).

    Holes up to ``small_m2`` use OpenCV Telea inpainting; larger ones a texture-aware fill from the
    surrounding pixels of the hole's surrounding class (``class_map``) or of all surroundings. A hole in
    water takes its colour and ripples from open water nearby (see ``OPEN_WATER_CLEAR_M``). Boxes of
    ``keep_categories`` stay as they are (pier walkways and fingers: a moored boat's margin must not erase
    them); other categories are ignored."""
    rgb = image.rgb
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise InputError(f"cleaning needs an RGB image, got shape {rgb.shape}")
    H, W = rgb.shape[:2]
    gsd = image.grid.gsd_m
    mask = transient_mask((H, W), detections, tuple(categories), margin_m / gsd)
    # piers stay: they are structure (the moored boats' boxes and margins often reach over the fingers)
    kept = transient_mask((H, W), detections, tuple(keep_categories))
    mask &= ~kept
    out = rgb.copy()
    if not mask.any():
        return out
    ids = None
    water: _OpenWater | None = None
    if class_map is not None:
        ids = class_map.ids
        if ids.shape != (H, W):
            ids = cv2.resize(ids, (W, H), interpolation=cv2.INTER_NEAREST)
        water = _OpenWater(rgb, ids, mask | kept, gsd)
    rng = stage_rng(seed, "clean")
    n, lab, stats, _c = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    ring_px = max(3, int(round(3.0 / gsd)))
    small_px = small_m2 / (gsd * gsd)
    for i in range(1, n):
        x, y, w, h, area = stats[i]
        if area <= small_px:
            continue  # inpainted below, all small holes in one pass
        pad = ring_px + 6  # the ring, the 5 px texture blur and the 4 px texture blocks
        x0, y0 = max(0, x - pad), max(0, y - pad)
        x1, y1 = min(W, x + w + pad), min(H, y + h + pad)
        hole = lab[y0:y1, x0:x1] == i
        k = np.ones((2 * ring_px + 1, 2 * ring_px + 1), np.uint8)
        ring = cv2.dilate(hole.astype(np.uint8), k).astype(bool) & ~mask[y0:y1, x0:x1]
        if ids is not None and ring.any():
            cls = np.bincount(ids[y0:y1, x0:x1][ring], minlength=8).argmax()
            same = ring & (ids[y0:y1, x0:x1] == cls)
            if same.sum() >= 0.2 * ring.sum():
                ring = same
            if cls == WATER and water is not None and _fill_from_open_water(out, lab, i, (x, y, w, h), water,
                                                                             rng):
                continue
        if not ring.any():
            ring = ~mask[y0:y1, x0:x1]
        if not ring.any():
            continue
        sub = out[y0:y1, x0:x1]
        ring = _typical(sub, ring)
        _texture_fill(sub, hole, ring, rng, gsd)
    small = (stats[lab, cv2.CC_STAT_AREA] <= small_px) & (lab > 0)
    if small.any():
        telea = small.astype(np.uint8)
        radius = max(3.0, 1.0 / gsd)
        bgr = np.ascontiguousarray(out[:, :, ::-1])
        filled = cv2.inpaint(bgr, telea, radius, cv2.INPAINT_TELEA)[:, :, ::-1]
        out[small] = filled[small]
    return out


def clean_file(image_path: str | Path, detections_path: str | Path, out_path: str | Path, *,
               gsd_m: float | None = None, size_m: tuple[float, float] | None = None, config=None,
               overwrite: bool = False, classes_path: str | Path | None = None) -> Path:
    """Read an image and a detections JSON, remove boats and vehicles, write the cleaned PNG."""
    from ..config import Config
    from ..fsio import check_writable_file, read_png, write_png
    from ..io import read_image

    from ..fsio import same_file
    from ..io import image_damage

    cfg = config or Config()
    if Path(out_path).suffix.lower() != ".png":
        raise InputError(f"--out {out_path} must end in .png (the cleaned image is written as PNG)")
    for what, p in (("the input image", image_path), ("--detections", detections_path), ("--classes", classes_path)):
        if p is not None and same_file(out_path, p):
            raise InputError(f"--out {out_path} is {what}; write the cleaned image to another file")
    out = check_writable_file(out_path, overwrite)
    image = read_image(image_path, gsd_m=gsd_m, size_m=size_m, config=cfg.io)
    dets = load_detections(detections_path, (image.grid.width_px, image.grid.height_px))
    cm = None
    if classes_path is not None:
        if not Path(classes_path).is_file():
            raise InputError(f"class map {classes_path} does not exist; pass the classes.png of `coastforge segment`")
        why = image_damage(classes_path)
        if why:
            raise InputError(f"class map {classes_path} is truncated or corrupt: {why}; run coastforge segment again")
        ids = read_png(classes_path)
        if ids.ndim != 2 or ids.dtype != np.uint8:
            raise InputError(f"class map {classes_path} must be a single-band PNG of class ids (classes.png)")
        if ids.shape != image.rgb.shape[:2]:
            raise InputError(f"class map {classes_path} is {ids.shape[1]}x{ids.shape[0]} px but {image_path} is "
                             f"{image.rgb.shape[1]}x{image.rgb.shape[0]} px; pass the classes.png segmented from "
                             "this image")
        if ids.max(initial=0) >= N_CLASSES:
            raise InputError(f"class map {classes_path} holds class id {int(ids.max())}, not one of 0..{N_CLASSES - 1}; "
                             "pass the classes.png of `coastforge segment` (not classes_preview.png)")
        cm = ClassMap(ids=ids, grid=image.grid)
    cleaned = clean_image(image, dets, cm, seed=cfg.seed)
    return write_png(out, cleaned)
