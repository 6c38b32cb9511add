"""``learned`` detect backend: coastforge's own small oriented-box detector, run with onnxruntime.

The model (trained by ``python -m coastforge.train.train_detector`` on synthetic renders only) is a
CenterNet-style network at a fixed working resolution (``work_gsd_m``, 0.2 m/px): the image is
resampled to it (so object sizes in pixels are the same at any GSD), cut into overlapping tiles, and
each tile gives per-class centre heatmaps (boat, vehicle, buoy), with, at stride 4, the sub-cell
offset, log length/width, the long axis as (cos 2θ, sin 2θ) and the front as (cos θ, sin θ).
Decoding: heatmap local maxima (3x3, inside the ONNX graph) above a threshold → boxes; the heading
is the axis direction the front vector agrees with, its confidence how strongly it agrees. By default
(``detect.flip_tta``) each tile also runs mirrored and the two passes' maps are averaged before decoding.
Piers are not detected by this backend (the classical backend does them).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..config import DetectConfig
from ..errors import InputError
from ..frames import wrap_deg, wrap_half_deg
from ..types import ClassMap, Detection, GeoImage
from .nms import centres_inside, rotated_nms

DEFAULT_META = {"classes": ["boat", "vehicle", "buoy"], "work_gsd_m": 0.2, "stride": 4, "thresholds": {},
                "thresholds_single_pass": {}, "edge_margin_px": 0}
# the flat colour of the margin a card's ``edge_margin_px`` adds around the picture (its network was trained
# with margins of random flat colours: ``train_detector --blank-p``)
EDGE_FILL = (128, 128, 128)
TILE_PX = 768  # tile size at the working GSD
TILE_OVERLAP_PX = 128  # > most objects' length (25 m boats); larger ones are merged by NMS
HEADING_KNOWN_CONF = 0.6  # |front · axis| >= 0.2
# boats are a few pixels at 1 m/px (the real harbour photos it was trained on reach 1.2 m/px); finer is only slower
MIN_GSD_M, MAX_GSD_M = 0.03, 1.25
# parked cars never overlap seen from above: a weaker vehicle box covering more than this share of a
# stronger one (intersection over the smaller) is the same car seen shifted onto its shadow or the
# empty bay beside it (synthetic seeds 0-2: true neighbours overlap at most 0.03, the two such
# duplicates, both on seed 2, 0.14 and 0.36)
VEHICLE_MAX_IOA = 0.1
# ``tta_axes``: the crop around an object is this many times its length (at least TTA_MIN_PX), in working
# pixels; a turned crop's box is the object's when its centre is within TTA_MATCH of the length
TTA_CROP, TTA_MIN_PX, TTA_MATCH = 1.2, 64, 0.3
# ``row_context``: boats are moored and vehicles parked in rows; a weak candidate beside a confident one of its
# class (axes within ROW_MAX_DYAW_DEG, abreast: offset along the axis at most ROW_MAX_ALONG of the longer one,
# across it between ROW_MIN_ACROSS and ROW_MAX_ACROSS of the wider one) gains ``detect.row_context`` per
# neighbour, for at most ROW_MAX_NEIGHBOURS of them
ROW_CATEGORIES = ("boat", "vehicle")
ROW_MAX_DYAW_DEG, ROW_MAX_ALONG, ROW_MIN_ACROSS, ROW_MAX_ACROSS, ROW_MAX_NEIGHBOURS = 20.0, 0.6, 0.5, 2.2, 2
# vehicles gained nothing once ``refine`` had fitted their mirror axis (docs/benchmarks.md) and are most of
# the objects in car parks: not worth the time
TTA_CATEGORIES = ("boat",)
# ``big_vessels``: boats of the shrunk pass at least BIG_MIN_LENGTH_M long (the renders' boats reach 22 m at
# the working scale; beyond it the normal pass sees a vessel's parts); boxes of the normal pass inside one
# are its parts unless two or more cross it (axes more than BIG_FRAGMENT_DYAW_DEG apart: boats abreast) or
# parallel ones fill BIG_ROW_SHARE of it (boats end to end)
BIG_MIN_LENGTH_M, BIG_FRAGMENT_DYAW_DEG = 20.0, 20.0
BIG_GROW = 1.25  # a part's centre lies in the big box grown as the benchmarks' matching rule grows labels
BIG_ROW_SHARE = 0.6  # two or more parallel boxes this long together are boats end to end, not parts
# a big box needs this score (over the boat threshold): rock groynes and breakwaters score up to about 0.5 in
# the shrunk view (a rendered groyne 0.47, the config probes' breakwater 0.51); the held-out renders' big
# vessels 0.41-0.78 (21 of 27 kept). ships_aerial training split, boxes of 20 m or more: at the boat threshold
# 13 of 19 true, at 0.55 9 of 10
BIG_MIN_SCORE = 0.55


def default_weights() -> Path:
    """The shipped model (``coastforge/data/models/detector.onnx``)."""
    return Path(__file__).resolve().parent.parent / "data" / "models" / "detector.onnx"


def decode(peaks: np.ndarray, reg: np.ndarray, threshold: float, stride: int = 4,
           max_det: int = 2000) -> np.ndarray:
    """Peak maps (C, h, w) and regression maps (8, h, w) → rows (N, 8):
    class, score, cx, cy, length, width (input pixels), yaw (degrees, scene convention: CCW with
    image-up positive; the front when the heading is known), heading confidence (0.5 … 1)."""
    peaks = np.asarray(peaks, np.float32)
    reg = np.asarray(reg, np.float32)
    if peaks.ndim != 3 or reg.ndim != 3 or reg.shape[0] != 8 or reg.shape[1:] != peaks.shape[1:]:
        raise InputError(f"learned detector outputs have shapes {peaks.shape} and {reg.shape}; "
                         "expected (C, h, w) and (8, h, w): is the weights file a coastforge detector?")
    cls, ii, jj = np.nonzero(peaks >= threshold)
    score = peaks[cls, ii, jj]
    if len(score) > max_det:
        keep = np.argsort(-score)[:max_det]
        cls, ii, jj, score = cls[keep], ii[keep], jj[keep], score[keep]
    r = reg[:, ii, jj]
    cx = (jj + r[0]) * stride
    cy = (ii + r[1]) * stride
    length = np.exp(np.clip(r[2], -3, 6)) * stride
    width = np.exp(np.clip(r[3], -3, 6)) * stride
    axis = 0.5 * np.arctan2(r[5], r[4])  # radians, mod pi
    proj = r[6] * np.cos(axis) + r[7] * np.sin(axis)
    yaw = np.where(proj < 0, axis + np.pi, axis)
    swap = width > length  # keep the long side as the length
    length, width = np.where(swap, width, length), np.where(swap, length, width)
    yaw = np.where(swap, yaw + np.pi / 2, yaw)
    yaw_deg = (np.degrees(yaw) + 180.0) % 360.0 - 180.0
    conf = np.where(swap, 0.5, 0.5 + 0.5 * np.clip(np.abs(proj), 0, 1))
    return np.stack([cls.astype(np.float32), score, cx, cy, length, width, yaw_deg, conf], 1).astype(np.float64)


def load_meta(weights: Path) -> dict:
    """The model's ``.json`` sidecar (classes, working GSD, stride); defaults when absent."""
    meta = dict(DEFAULT_META)
    side = weights.with_suffix(".json")
    if side.is_file():
        try:
            doc = json.loads(side.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise InputError(f"learned detector metadata {side} is not valid JSON ({exc}); "
                             "re-export the model with coastforge.train.train_detector") from exc
        for k in DEFAULT_META:
            if k in doc:
                meta[k] = doc[k]
    return meta


class LearnedDetector:
    """coastforge's learned oriented-box detector (boats, vehicles, buoys) from an ONNX file."""

    def __init__(self, config: DetectConfig | None = None, weights: str | os.PathLike | None = None,
                 threshold: float | None = None, **_opts):
        from ..registry import require

        self.config = config or DetectConfig()
        p = Path(weights) if weights is not None else default_weights()
        if not p.is_file():
            hint = ("the package's shipped model is missing: reinstall coastforge or train one with "
                    "python -m coastforge.train.train_detector" if weights is None
                    else "pass the path of a detector.onnx written by coastforge.train.train_detector")
            raise InputError(f"learned detector weights {p} do not exist; {hint}")
        ort = require("onnxruntime", "onnx", "the learned detect backend")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = min(2, os.cpu_count() or 1)
        # no busy-waiting between the tiles' runs: less CPU for the same outputs (other stages run beside)
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self.session = ort.InferenceSession(str(p), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:
            raise InputError(f"cannot load learned detector weights {p} ({type(exc).__name__}: {exc}); "
                             "the file is not a valid ONNX model: re-export or pass another --weights") from exc
        names = [o.name for o in self.session.get_outputs()]
        if not {"peaks", "reg"} <= set(names):
            raise InputError(f"ONNX model {p} has outputs {names}, not the learned detector's (peaks, reg); "
                             "use --backend onnx for other ONNX detectors")
        self.weights = p
        self.meta = load_meta(p)
        # per-class score thresholds tuned after training (sidecar), unless one is given
        base = float(threshold if threshold is not None else max(0.05, self.config.min_score))
        # the card's thresholds are for the default mirrored pair of passes (``flip_tta``); one pass's
        # scores are less steady and have their own, where the card gives them
        key = "thresholds" if self.config.flip_tta or not self.meta.get("thresholds_single_pass") \
            else "thresholds_single_pass"
        tuned = {} if threshold is not None else dict(self.meta.get(key) or {})
        self.class_threshold = {c: float(tuned.get(c, base)) for c in self.meta["classes"]}
        self.threshold = min([base, *self.class_threshold.values()])

    def is_confident(self, det: Detection) -> bool:
        """Whether a box passes its class's threshold (``detect(..., floor=...)`` also gives weaker ones)."""
        return det.score >= self.class_threshold.get(det.category, self.threshold)

    def run(self, work: np.ndarray, threshold: float | None = None, margin: int = 0) -> np.ndarray:
        """Decoded rows (see ``decode``) for one uint8 RGB image at the working GSD (tiled), down to
        ``threshold`` (default: the lowest class threshold). ``margin``: pixels of flat colour added along
        the tiles' sides that are the image's edges, so that the network can place an object the picture
        cuts whole, its centre perhaps outside (only for a network trained so: the card's
        ``edge_margin_px``)."""
        import cv2

        from .yolo import slice_windows

        h, w = work.shape[:2]
        stride = int(self.meta["stride"])
        rows = []
        for c0, r0, c1, r1 in slice_windows(w, h, TILE_PX, TILE_OVERLAP_PX):
            tile = work[r0:r1, c0:c1]
            left, top = (margin if c0 == 0 else 0), (margin if r0 == 0 else 0)
            right, bottom = (margin if c1 == w else 0), (margin if r1 == h else 0)
            if left or top or right or bottom:  # per tile: the image's tiling (and cost) stay as without
                tile = cv2.copyMakeBorder(tile, top, bottom, left, right, cv2.BORDER_CONSTANT, value=EDGE_FILL)
            th, tw = tile.shape[:2]
            ph, pw = (-th) % 32, (-tw) % 32  # whole cells at every level of the network
            if ph or pw:
                tile = cv2.copyMakeBorder(tile, 0, ph, 0, pw, cv2.BORDER_REFLECT_101 if min(th, tw) > 1
                                          else cv2.BORDER_REPLICATE)
            x = np.ascontiguousarray(tile.transpose(2, 0, 1)[None].astype(np.float32))
            if self.config.flip_tta:
                peaks, reg = self._run_flipped(x)
            else:
                peaks, reg = (o[0] for o in self.session.run(["peaks", "reg"], {"image": x}))
            d = decode(peaks, reg, self.threshold if threshold is None else threshold, stride)
            d = d[(d[:, 2] < tw) & (d[:, 3] < th)]  # nothing from the padding
            d[:, 2] += c0 - left
            d[:, 3] += r0 - top
            rows.append(d)
        return np.concatenate(rows, 0) if rows else np.zeros((0, 8))

    def _run_flipped(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Peaks and box maps of one tile (1, 3, H, W) as the mean of the network's pass on it and on its
        mirror image (columns reversed), mapped back: the mirror is lossless and its stride-4 cells line up
        with the tile's (H, W are multiples of 32), so the heatmaps average cell by cell. In a mirrored
        map the centre offset across is ``1 - r`` and the angles reflect (sin 2θ and cos θ change sign)."""
        from scipy.ndimage import maximum_filter

        heat_a, reg_a = self.session.run(["heat", "reg"], {"image": x})
        heat_b, reg_b = self.session.run(["heat", "reg"], {"image": np.ascontiguousarray(x[..., ::-1])})
        heat = 0.5 * (heat_a[0] + heat_b[0][..., ::-1])
        rb = reg_b[0][..., ::-1].copy()
        rb[0] = 1.0 - rb[0]
        rb[5] = -rb[5]
        rb[6] = -rb[6]
        reg = 0.5 * (reg_a[0] + rb)
        peaks = heat * (maximum_filter(heat, size=(1, 3, 3), mode="constant", cval=-1.0) == heat)
        return peaks, reg

    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0,
               floor: float | None = None) -> list[Detection]:
        """Boxes above each class's threshold; with ``floor``, also the weaker ones down to ``floor``
        after them, as they come from the network (overlapping ones are not merged): the hybrid
        detector uses them as evidence for the classical boxes (tell them apart with ``is_confident``)."""
        import cv2

        rgb = image.rgb
        h, w = rgb.shape[:2]
        gsd = float(image.grid.gsd_m)
        work_gsd = float(self.meta["work_gsd_m"])
        if not (math.isfinite(gsd) and MIN_GSD_M <= gsd <= MAX_GSD_M):
            raise InputError(f"the learned detector works on images of {MIN_GSD_M}-{MAX_GSD_M} m/px (it was "
                             f"trained at {work_gsd} m/px), got {gsd} m/px; use --backend classical, or "
                             "check --gsd")
        s = gsd / work_gsd
        nw, nh = max(8, int(round(w * s))), max(8, int(round(h * s)))
        work = rgb if (nw, nh) == (w, h) else cv2.resize(
            rgb, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        sx, sy = nw / w, nh / h
        classes = list(self.meta["classes"])
        cfg = self.config
        limits = {"boat": (cfg.min_boat_length_m * 0.6, cfg.max_boat_length_m),
                  "vehicle": (cfg.min_vehicle_length_m * 0.6, cfg.max_vehicle_length_m),
                  "buoy": (0.0, 4.0)}
        dets = []
        boost = max(0.0, float(cfg.row_context))
        reach = boost * ROW_MAX_NEIGHBOURS  # a candidate this far below its threshold may still reach it
        lowest = self.threshold - reach if floor is None else min(float(floor), self.threshold - reach)
        margin = int(self.meta.get("edge_margin_px") or 0)
        rows = self.run(work, max(1e-3, lowest), margin)
        for c, score, cx, cy, length, width, yaw, conf in rows:
            cat = classes[int(c)]
            thr = self.class_threshold[cat]
            low = thr - reach if cat in ROW_CATEGORIES else thr
            if score < (low if floor is None else min(floor, low)):
                continue
            lo, hi = limits.get(cat, (0.0, math.inf))
            if not (lo <= length * work_gsd <= hi):
                continue
            if margin and not (0.0 <= cx <= nw and 0.0 <= cy <= nh):  # centred in the margin: under half inside
                continue
            scale = 0.5 * (sx + sy)
            known = cat != "buoy" and conf >= HEADING_KNOWN_CONF
            dets.append(Detection(cat, float(score), float(cx / sx), float(cy / sy), float(length / scale),
                                  float(width / scale), float(yaw), heading_known=bool(known),
                                  heading_confidence=float(conf) if cat != "buoy" else 0.0))
        # tiles overlap: the same object seen twice, or cut by a tile edge, is merged; one object
        # is never two categories either
        # the network's front is kept even when weakly confident; for vehicles ``detect`` then adds the
        # windscreen cue of ``detection.heading.vehicle_fronts`` to it as log-odds (after refinement)
        strong = rotated_nms([d for d in dets if self.is_confident(d)], cfg.nms_iou, class_aware=False,
                             ioa_threshold=0.8)
        weak = [d for d in dets if not self.is_confident(d)]  # evidence only: not de-duplicated (speed)
        if boost > 0 and weak:  # weak ones abreast of the (de-duplicated) confident ones may join them
            weak = row_context(weak, strong, boost)
            if any(self.is_confident(d) for d in weak):
                strong = rotated_nms(strong + [d for d in weak if self.is_confident(d)], cfg.nms_iou,
                                     class_aware=False, ioa_threshold=0.8)
                weak = [d for d in weak if not self.is_confident(d)]
        weak = [] if floor is None else [d for d in weak if d.score >= floor]
        cars = rotated_nms([d for d in strong if d.category == "vehicle"], cfg.nms_iou,
                           ioa_threshold=VEHICLE_MAX_IOA)
        keep = {id(d) for d in cars}
        strong = [d for d in strong if d.category != "vehicle" or id(d) in keep]
        if cfg.axis_tta:
            strong = self.tta_axes(work, strong, sx, sy)
        if cfg.big_pass and cfg.big_pass > 1.0:  # after the axes' crops: at the working scale they see parts
            strong = self.big_vessels(work, strong, float(cfg.big_pass), sx, sy)
        return strong + weak

    def big_vessels(self, work: np.ndarray, dets: list[Detection], factor: float, sx: float = 1.0,
                    sy: float = 1.0) -> list[Detection]:
        """``dets`` with the big vessels the network finds on ``work`` shrunk ``factor`` times (there a 20-50 m
        vessel is as many pixels as the 5-15 m boats it knows best). Each big box (a boat of at least
        BIG_MIN_LENGTH_M scoring at least BIG_MIN_SCORE) replaces the boxes of the normal pass centred in it
        (grown BIG_GROW times): the parts of the vessel the normal pass saw. It is left out where those say that
        the shrunk view merged several things: a vehicle or buoy, a box as long as it, two or more crossing it
        (boats abreast), or parallel ones together BIG_ROW_SHARE of its length (boats end to end)."""
        import cv2

        work_gsd = float(self.meta["work_gsd_m"])
        nh, nw = work.shape[:2]
        small = cv2.resize(work, (max(8, int(round(nw / factor))), max(8, int(round(nh / factor)))),
                           interpolation=cv2.INTER_AREA)
        fx, fy = nw / small.shape[1], nh / small.shape[0]
        boat = list(self.meta["classes"]).index("boat")
        thr = max(self.class_threshold["boat"], BIG_MIN_SCORE)
        big = []
        for c, score, cx, cy, length, width, yaw, conf in self.run(small, thr):
            L = length * 0.5 * (fx + fy)
            if int(c) != boat or score < thr or not BIG_MIN_LENGTH_M <= L * work_gsd <= self.config.max_boat_length_m:
                continue
            big.append(Detection("boat", float(score), float(cx * fx / sx), float(cy * fy / sy),
                                 float(L / (0.5 * (sx + sy))), float(width * 0.5 * (fx + fy) / (0.5 * (sx + sy))),
                                 float(yaw), heading_known=bool(conf >= HEADING_KNOWN_CONF),
                                 heading_confidence=float(conf)))
        out = list(dets)
        for b in rotated_nms(big, self.config.nms_iou, class_aware=False, ioa_threshold=0.5):
            near = list(np.flatnonzero(centres_inside([b], out, BIG_GROW)[0]))
            parallel = [i for i in near if abs(wrap_half_deg(out[i].yaw_deg - b.yaw_deg)) <= BIG_FRAGMENT_DYAW_DEG]
            if any(out[i].category != "boat" or out[i].length_px >= b.length_px for i in near) \
                    or len(near) - len(parallel) > 1 \
                    or (len(parallel) > 1 and sum(out[i].length_px for i in parallel) >= BIG_ROW_SHARE * b.length_px):
                continue  # a vehicle, a row of boats abreast or end to end: not one vessel
            out = [d for i, d in enumerate(out) if i not in near] + [b]
        return out

    def tta_axes(self, work: np.ndarray, dets: list[Detection], sx: float = 1.0,
                 sy: float = 1.0) -> list[Detection]:
        """Each boat's long axis (``TTA_CATEGORIES``) as the score-weighted mean (of 2θ) of the tile's pass
        and the network run on a crop around it turned by 90, 180 and 270°. The turns are lossless, and the
        crop puts the object at another place on the network's stride-4 grid than its tile did: one pass's
        axis moves by a few degrees with both, the mean of four much less (docs/benchmarks.md). The front stays on the side the detector chose. ``work`` is the image at the working GSD, ``sx``,
        ``sy`` its scale from the detections' pixels."""
        import cv2

        todo = [i for i, d in enumerate(dets) if d.category in TTA_CATEGORIES]
        if not todo:
            return dets
        classes = list(self.meta["classes"])
        side = {i: int(max(TTA_MIN_PX, math.ceil(TTA_CROP * dets[i].length_px * sx / 32.0) * 32))
                for i in todo}
        pad = max(side.values())
        padded = cv2.copyMakeBorder(work, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
        out = list(dets)
        for i in todo:
            d, S = dets[i], side[i]
            cls = classes.index(d.category)
            cx, cy, length = d.cx_px * sx, d.cy_px * sy, d.length_px * sx
            c0, r0 = int(round(cx)) - S // 2, int(round(cy)) - S // 2
            crop = padded[r0 + pad:r0 + pad + S, c0 + pad:c0 + pad + S]
            acc = d.score * np.exp(2j * np.radians(d.yaw_deg))  # the tile's own pass is the first
            for k in range(1, 4):
                rows = self.run(np.ascontiguousarray(np.rot90(crop, k)), min(0.05, self.threshold))
                rows = rows[rows[:, 0] == cls]
                px, py = cx - c0, cy - r0
                for _ in range(k):  # where the centre lands in the crop turned by 90° (counter-clockwise)
                    px, py = py, S - 1 - px
                if not len(rows):
                    continue
                dist = np.hypot(rows[:, 2] - px, rows[:, 3] - py)
                j = int(np.argmin(dist))
                if dist[j] <= TTA_MATCH * length:
                    acc += rows[j, 1] * np.exp(2j * np.radians(rows[j, 6] - 90.0 * k))
            axis = math.degrees(np.angle(acc)) / 2.0
            turn = wrap_half_deg(axis - d.yaw_deg)  # to the nearer end of the mean axis
            out[i] = replace(d, yaw_deg=float(wrap_deg(d.yaw_deg + turn)))
        return out


def row_context(weak: list[Detection], sure: list[Detection], boost: float) -> list[Detection]:
    """``weak`` with each boat or vehicle raised by ``boost`` for each box of ``sure`` (the confident ones, one
    per object) of its class abreast of it: parallel, side by side, at most about two widths away (see
    ROW_*), for at most ROW_MAX_NEIGHBOURS of them. Moored boats and parked cars come in rows, so a weak peak
    in a gap of a row is more likely an object than the same peak alone; neighbours must be confident, so
    rows do not grow from weak ones. Chosen on the real training splits (docs/benchmarks.md)."""
    if not weak or not sure:
        return weak
    cat = np.array([d.category for d in sure])
    b = np.array([[d.cx_px, d.cy_px, d.length_px, d.width_px, d.yaw_deg] for d in sure], np.float64)
    a = np.deg2rad(b[:, 4])
    out = list(weak)
    for i, d in enumerate(weak):
        if d.category not in ROW_CATEGORIES:
            continue
        dx, dy = d.cx_px - b[:, 0], d.cy_px - b[:, 1]
        along = dx * np.cos(a) - dy * np.sin(a)  # image rows grow downwards: the axis is (cos, -sin)
        across = dx * np.sin(a) + dy * np.cos(a)
        dyaw = np.abs((d.yaw_deg - b[:, 4] + 90.0) % 180.0 - 90.0)
        longer, wider = np.maximum(d.length_px, b[:, 2]), np.maximum(d.width_px, b[:, 3])
        abreast = ((cat == d.category) & (dyaw <= ROW_MAX_DYAW_DEG) & (np.abs(along) <= ROW_MAX_ALONG * longer)
                   & (np.abs(across) > ROW_MIN_ACROSS * wider) & (np.abs(across) <= ROW_MAX_ACROSS * wider))
        n = min(int(abreast.sum()), ROW_MAX_NEIGHBOURS)
        if n:
            out[i] = replace(d, score=float(d.score + boost * n))
    return out
