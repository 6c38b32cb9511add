"""The learned segmenter: a small U-Net trained by coastforge on its own synthetic renders
(``python -m coastforge.train.seg_train``), shipped as ``coastforge/data/models/segmenter.onnx`` with
its ``segmenter.json`` and run with onnxruntime (no torch at run time).

The image is resampled to the model's working GSD (0.3 m/px), run in overlapping tiles (bounded
memory on large images; only tile centres are kept) with a mirrored pass averaged in, land specks
are merged, and the class probabilities are upsampled bilinearly to the image grid (smooth borders
rather than blocks of working pixels). Water comes from the classical water model (large-scale rules
that handle rafted boats and piers), or from the network when those rules find none at all and the
network is sure of a large body of water (a colour the rules do not know). A self-check guards
against photos unlike our renders: when the network disagrees with the classical colour rules on
their confident pixels, the classical segmenter is used instead (it is also used outside 0.04-0.6
m/px).
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from ..classes import CLASS_NAMES, N_CLASSES, WATER
from ..config import SegmentConfig
from ..errors import BackendUnavailable, InputError
from ..registry import require
from ..types import ClassMap, GeoImage

FORMAT = "coastforge.learned_segmenter/1"
TILE_PX = 768  # tile side at the working GSD (memory ~ 40 MB of activations per tile)
FLIPS = ((), (3,), (2,), (2, 3))  # test-time passes: as is, mirrored, flipped, both (numpy axes of NCHW)
GSD_RANGE_M = (0.04, 0.6)  # outside, the classical segmenter is used (see LearnedSegmenter.segment)
OVERLAP_PX = 48  # context kept around each tile centre (> half the network's useful receptive field)
# the network's water replaces the classical water model's only when that found at most this share of
# the image, the network's water covers at least NET_WATER_MIN_FRAC at a mean probability of at least
# NET_WATER_MIN_P, and its land agrees with the colour rules off that water (see _net_water_instead)
NET_WATER_MAX_CLASSICAL = 0.01
NET_WATER_MIN_FRAC = 0.05
NET_WATER_MIN_P = 0.9


def default_weights() -> Path:
    return Path(str(resources.files("coastforge") / "data" / "models" / "segmenter.onnx"))


def _read_meta(weights: Path, meta: dict | str | Path | None) -> dict:
    if isinstance(meta, dict):
        spec = meta
    else:
        p = Path(meta) if meta is not None else weights.with_suffix(".json")
        if not p.is_file():
            raise InputError(f"learned segmenter: metadata {p} not found; it is written beside the .onnx by "
                             "python -m coastforge.train.seg_train")
        try:
            spec = json.loads(p.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise InputError(f"learned segmenter: {p} is not valid JSON ({exc})") from exc
    if spec.get("format") != FORMAT or list(spec.get("classes", [])) != list(CLASS_NAMES):
        raise InputError(f"learned segmenter: metadata for {weights} must have format {FORMAT!r} and the "
                         f"classes {list(CLASS_NAMES)}")
    return spec


def _tiles(n: int, tile: int, overlap: int) -> list[tuple[int, int, int, int]]:
    """1-D windows (start, stop, keep_from, keep_to) covering 0..n; each keeps its centre part."""
    if n <= tile:
        return [(0, n, 0, n)]
    step = tile - 2 * overlap
    starts = list(range(0, n - tile, step)) + [n - tile]
    out, keep_from = [], 0
    for i, s in enumerate(starts):
        keep_to = n if i == len(starts) - 1 else s + tile - overlap
        out.append((s, s + tile, keep_from, keep_to))
        keep_from = keep_to
    return out


class LearnedSegmenter:
    """Run the shipped (or a given) learned segmentation model on one image."""

    def __init__(self, config: SegmentConfig | None = None, weights: str | Path | None = None,
                 meta: dict | str | Path | None = None, **options):
        if options:
            raise InputError(f"the learned segmenter takes weights=, meta=, not {', '.join(sorted(options))}")
        self.config = config or SegmentConfig()
        self.weights = Path(weights) if weights is not None else default_weights()
        if not self.weights.is_file():
            raise InputError(f"learned segmenter weights {self.weights} not found; train them with "
                             "python -m coastforge.train.seg_train or use --backend classical")
        self.meta = _read_meta(self.weights, meta)
        self.flips = max(1, min(len(FLIPS), int(getattr(self.config, "learned_flips", 2))))
        self._sess = None

    def _session(self):
        if self._sess is None:
            ort = require("onnxruntime", "onnx", "the learned segmenter")
            try:
                opts = ort.SessionOptions()
                # no busy-waiting between the tiles' runs: ~25 % less CPU for the same outputs (the
                # pipeline runs other stages beside this one: spinning threads only take their cores)
                opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
                self._sess = ort.InferenceSession(str(self.weights), opts, providers=["CPUExecutionProvider"])
            except Exception as exc:  # onnxruntime has its own exception types
                raise InputError(f"{self.weights} is not a loadable ONNX model ({exc})") from exc
        return self._sess

    def proba_small(self, rgb: np.ndarray) -> np.ndarray:
        """Class probabilities (h, w, 8) float32 of an image already at the working GSD (with the
        configured test-time flips)."""
        return _softmax(self.logits_small(rgb, FLIPS[:self.flips]))

    def logits_small(self, rgb: np.ndarray, flips=((),)) -> np.ndarray:
        """Logits (h, w, 8) averaged over the flipped passes ``flips`` (numpy axes of NCHW)."""
        sess = self._session()
        mult = int(self.meta.get("multiple", 16))
        h, w = rgb.shape[:2]
        out = np.empty((h, w, N_CLASSES), np.float32)
        name = sess.get_inputs()[0].name
        for r0, r1, kr0, kr1 in _tiles(h, TILE_PX, OVERLAP_PX):
            for c0, c1, kc0, kc1 in _tiles(w, TILE_PX, OVERLAP_PX):
                tile = rgb[r0:r1, c0:c1]
                th, tw = tile.shape[:2]
                ph, pw = (-th) % mult, (-tw) % mult
                if ph or pw:  # reflect-pad to the network's multiple (small images: at least 1 px real)
                    tile = cv2.copyMakeBorder(tile, 0, ph, 0, pw, cv2.BORDER_REFLECT_101 if min(th, tw) > 1
                                              else cv2.BORDER_REPLICATE)
                x = np.ascontiguousarray(tile.transpose(2, 0, 1)[None], dtype=np.float32) / 255.0
                logits = 0.0
                for axes in flips:  # test-time flips: averaged logits are steadier at class borders
                    xi = np.ascontiguousarray(np.flip(x, axes)) if axes else x
                    try:
                        res = sess.run(None, {name: xi})[0]
                    except Exception as exc:
                        raise BackendUnavailable(f"learned segmenter {self.weights} failed on a {tw}x{th} tile "
                                                 f"({exc})") from exc
                    if res.ndim != 4 or res.shape[1] != N_CLASSES:
                        raise InputError(f"{self.weights} outputs shape {res.shape}; expected (1, {N_CLASSES}, H, W)")
                    logits = logits + (np.flip(res, axes) if axes else res)
                lg = (logits / len(flips))[0, :, :th, :tw].transpose(1, 2, 0)
                out[kr0:kr1, kc0:kc1] = lg[kr0 - r0:kr1 - r0, kc0 - c0:kc1 - c0]
        return out

    def segment(self, image: GeoImage, seed: int = 0) -> ClassMap:
        rgb = image.rgb
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise InputError(f"learned segmentation needs an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
        from .classical import ClassicalSegmenter

        cfg = self.config
        mode = getattr(cfg, "learned_water", "classical")
        if mode not in ("classical", "net"):
            raise InputError(f"segment.learned_water = {mode!r}; use 'classical' or 'net'")
        H, W = rgb.shape[:2]
        gsd = float(image.grid.gsd_m)
        lo, hi = self.meta.get("gsd_range_m", GSD_RANGE_M)
        self.last_agreement = None
        if not lo <= gsd <= hi:
            # trained on 0.2-0.3 m renders: far outside, the network sees things it never saw (and
            # upsampling a coarse image to 0.3 m would be huge); the classical rules work at any GSD
            self.last_choice = "classical (GSD outside the network's range)"
            return ClassicalSegmenter(cfg).segment(image, seed)
        s = gsd / float(self.meta["work_gsd_m"])
        w, h = max(16, int(round(W * s))), max(16, int(round(H * s)))
        small = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        if mode == "net":
            p = self.proba_small(small)
            self.last_choice = "network"
            ids = p.argmax(axis=2).astype(np.uint8) if (w, h) == (W, H) else _upsample_argmax(p, H, W)
            return ClassMap(ids=ids, grid=image.grid)
        # one pass first: the self-check decides whether the flipped passes are worth running
        lg = self.logits_small(small, FLIPS[:1])
        p_net = _softmax(lg)
        p = p_net.copy()
        p[..., WATER] = -1.0  # land classes from the network, water from the classical model
        water = self._classical_water(rgb, gsd, p)
        if not isinstance(water, np.ndarray):  # the network disagrees with the image's clear cases
            net_water = self._net_water_instead(rgb, p_net, p, water)
            if net_water is None:
                self.last_choice = f"classical (agreement {self.last_agreement:.2f})"
                return ClassicalSegmenter(cfg).segment(image, seed, pre=water)
            water = net_water
            self.last_choice = (f"network land + network water: the classical water model found none "
                                f"(agreement {self.last_agreement:.2f})")
        else:
            self.last_choice = f"network land + classical water (agreement {self.last_agreement:.2f})"
        if self.flips > 1:
            n = self.flips
            lg = (lg + (n - 1) * self.logits_small(small, FLIPS[1:n])) / n
            p = _softmax(lg)
            p[..., WATER] = -1.0
        min_px = float(getattr(cfg, "learned_min_region_m2", 12.0)) / float(self.meta["work_gsd_m"]) ** 2
        _merge_specks(p, min_px)
        ids = p.argmax(axis=2).astype(np.uint8) if (w, h) == (W, H) else _upsample_argmax(p, H, W)
        ids[water] = WATER
        return ClassMap(ids=ids, grid=image.grid)

    def _classical_water(self, rgb: np.ndarray, gsd: float, land_p: np.ndarray) -> np.ndarray | tuple:
        """Water mask on the image grid from the classical water model (large-scale rules: rafted boats,
        pier clusters and gaps between them are water; the network, trained on sparse synthetic
        marinas, sees dense real rafts as pavement), its waterline sharpened at full resolution
        against the network's land classes.

        Returns the classical (features, water, open water) instead when the network's land classes
        agree with the classical colour rules' confident pixels (``land_seeds``) on less than
        ``segment.learned_min_agreement`` of them: on our renders the agreement is 0.8-0.95, on real
        photos unlike them it drops (0.57 on the DOTA marina), and then the classical segmenter is the
        better guess (it reuses the features and water computed here)."""
        from .classical import ClassicalSegmenter, compute_features, detect_water, land_seeds, refine_water_edge

        cfg = self.config
        H, W = rgb.shape[:2]
        sc = ClassicalSegmenter(cfg).work_scale(W, H, gsd)
        if sc < 0.999:
            wc, hc = max(8, int(round(W * sc))), max(8, int(round(H * sc)))
            small = cv2.resize(rgb, (wc, hc), interpolation=cv2.INTER_AREA)
        else:
            wc, hc, small = W, H, rgb
        F = compute_features(small, gsd * W / wc)
        water, open_water = detect_water(F, cfg, return_open=True)
        ids_c = _land_ids_at(land_p, hc, wc)
        seeds = land_seeds(F, water, cfg.rocks_shore_m)
        m = seeds >= 0
        self.last_agreement = float((ids_c[m] == seeds[m]).mean()) if m.sum() >= 200 else 1.0
        if self.last_agreement < float(getattr(cfg, "learned_min_agreement", 0.7)):
            return (F, water, open_water)  # reused by the classical fallback
        if (wc, hc) == (W, H):
            return water
        ids_c[water] = WATER
        return refine_water_edge(rgb, ids_c, water, F, open_water=open_water) == WATER

    def _net_water_instead(self, rgb: np.ndarray, p_net: np.ndarray, land_p: np.ndarray,
                           pre: tuple) -> np.ndarray | None:
        """Water on the image grid from the network, when the classical water model found (almost)
        none but the network sees a large body of water it is sure of (a colour the classical rules do
        not know, e.g. a silty olive-brown river, whose pixels the rules then seed as land, so the
        self-check fails on them) and the network's land classes agree with the rules' confident
        pixels everywhere else. Else None (the classical segmenter is used, as before).

        On real photos unlike our renders the network's water is not to be trusted (it calls half of a
        DOTA car park water, at ~0.7 probability): the confidence and the agreement off the water
        both guard against that."""
        from .classical import land_seeds

        cfg = self.config
        F, water_c, _open = pre
        if water_c.mean() > NET_WATER_MAX_CLASSICAL:
            return None
        wn = p_net.argmax(axis=2) == WATER
        if wn.mean() < NET_WATER_MIN_FRAC or float(p_net[..., WATER][wn].mean()) < NET_WATER_MIN_P:
            return None
        hc, wc = water_c.shape
        wn_c = cv2.resize(wn.astype(np.uint8), (wc, hc), interpolation=cv2.INTER_NEAREST).astype(bool)
        ids_c = _land_ids_at(land_p, hc, wc)
        seeds = land_seeds(F, wn_c, cfg.rocks_shore_m)
        m = seeds >= 0
        if m.sum() < 200:
            return None
        agreement = float((ids_c[m] == seeds[m]).mean())
        if agreement < float(getattr(cfg, "learned_min_agreement", 0.7)):
            return None
        self.last_agreement = agreement
        H, W = rgb.shape[:2]
        return _upsample_argmax(p_net, H, W) == WATER if p_net.shape[:2] != (H, W) else wn


def _softmax(logits: np.ndarray) -> np.ndarray:
    """Softmax over the last axis of (h, w, C) logits, as float32."""
    top = logits[..., 0].copy()
    for c in range(1, logits.shape[2]):  # a running maximum: ~8x faster than max(axis=2), same values
        np.maximum(top, logits[..., c], out=top)
    e = logits - top[..., None]
    np.exp(e, out=e)
    e /= e.sum(axis=2, keepdims=True)
    return e.astype(np.float32, copy=False)


def _merge_specks(p: np.ndarray, min_px: float) -> None:
    """Land specks under ``min_px`` working pixels take the class of the nearest larger region (in
    place, as one-hot probabilities, so the later bilinear upsampling keeps smooth borders)."""
    from .classical import _merge_small

    ids = p.argmax(axis=2).astype(np.uint8)
    merged = _merge_small(ids, int(round(min_px)), fixed=np.zeros(ids.shape, bool))
    ch = merged != ids
    if ch.any():
        p[ch] = 0.0
        p[ch, merged[ch]] = 1.0


def _land_ids_at(land_p: np.ndarray, h: int, w: int) -> np.ndarray:
    """The most likely land class per pixel of an h x w grid (``land_p``: land probabilities, any grid)."""
    if land_p.shape[:2] != (h, w):
        return _upsample_argmax(land_p, h, w)
    return land_p.argmax(2).astype(np.uint8)


def _upsample_argmax(p: np.ndarray, H: int, W: int, rows: int = 512) -> np.ndarray:
    """argmax of the bilinearly upsampled probabilities, in strips of ``rows`` output rows, so a large
    image never holds (H, W, 8) floats (smooth borders instead of blocks of working pixels)."""
    h, w = p.shape[:2]
    halves = [np.ascontiguousarray(p[..., i:i + 4]) for i in (0, 4)]  # cv2 remaps up to 4 channels fast
    xs = ((np.arange(W, dtype=np.float32) + 0.5) * (w / W) - 0.5).astype(np.float32)
    out = np.empty((H, W), np.uint8)
    for r0 in range(0, H, rows):
        r1 = min(H, r0 + rows)
        ys = ((np.arange(r0, r1, dtype=np.float32) + 0.5) * (h / H) - 0.5).astype(np.float32)
        mx = np.ascontiguousarray(np.broadcast_to(xs, (r1 - r0, W)))
        my = np.ascontiguousarray(np.broadcast_to(ys[:, None], (r1 - r0, W)))
        best = np.full((r1 - r0, W), -1.0, np.float32)
        better = np.empty((r1 - r0, W), bool)
        arg = out[r0:r1]
        for k, a in enumerate(halves):
            q = cv2.remap(a, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            for c, qc in enumerate(cv2.split(q)):  # in-place running argmax: faster than argmax(axis=2)
                np.greater(qc, best, out=better)
                np.copyto(arg, np.uint8(4 * k + c), where=better)
                np.maximum(best, qc, out=best)
    return out
