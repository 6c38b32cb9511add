"""The learned segmenter: a small U-Net trained by coastforge on its own synthetic renders and on real
labelled photos (``python -m coastforge.train.seg_train``; the card ``segmenter.json`` beside
``coastforge/data/models/segmenter.onnx`` lists the data sets), run with onnxruntime (no torch at run time).

The image is resampled to the model's working GSD (0.3 m/px), run in overlapping tiles (bounded
memory on large images; only tile centres are kept) with a mirrored pass averaged in, land specks
are merged, and the class probabilities are upsampled bilinearly to the image grid (smooth borders
rather than blocks of working pixels).

Classes are decided from evidence, not by a switch (``fuse_votes``): the classical segmenter runs too;
its water model (large-scale rules that know rafted boats, pier clusters and the gaps between them) votes in
the network's water log-odds, so a confident network keeps its call and an unsure one follows the rules;
among land classes the two distributions are mixed. Both are weighted by GSD (``classical_weight``: the
classical segmenter at fine GSDs, where the network's land classes have seen only renders; the network at
coarse ones, where it has seen real labelled photos and the classical fine-texture cues vanish). The class
map carries a per-pixel confidence (the fused probability of the chosen class) and which
source decided each pixel; both are written beside the scene and shown in the report. Outside the
network's GSD range the classical segmenter is used.
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
OVERLAP_PX = 48  # context kept around each tile centre (> half the network's useful receptive field);
# a model's card may ask for more ("overlap_px": deeper networks see further)
WATER_MODES = ("fused", "classical", "net")
# the classical water model's vote in the network's water log-odds (fused mode): a factor of e^3 ~ 20 in the
# odds, so a network surer than ~0.95 keeps its call and an unsure one follows the rules (which know rafted
# boats and pier clusters; the network knows water colours they do not). Chosen a priori, not tuned on any
# validation image.
CLASSICAL_WATER_VOTE = 3.0
# the classical segmenter (developed on 0.1-0.3 m/px images: fine texture over ~0.6 m, a 0.4 m working
# raster) is trusted fully at GSDs up to the first value and not at all from the second; the network's
# real labels are at ~0.4-1.2 m/px (Dubai, harbour photos) while at finer GSDs its land classes have seen
# only renders
CLASSICAL_GSD_M = (0.3, 0.6)
# which source decided a pixel (ClassMap.source; shown in the report)
SOURCE_BOTH, SOURCE_NETWORK, SOURCE_CLASSICAL, SOURCE_DETECTIONS = 0, 1, 2, 3
SOURCE_NAMES = ("both agree", "network", "classical rules", "detections")  # the last: consistency.water_from_boats


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


def _tiles(n: int, tile: int, overlap: int, multiple: int = 1) -> list[tuple[int, int, int, int]]:
    """1-D windows (start, stop, keep_from, keep_to) covering 0..n; each keeps its centre part, with at least
    ``overlap`` of context on each inner side. As few windows of at most ``tile`` as that allows, all of one
    size (rounded up to ``multiple``, the network's): evenly spread, no window mostly repeats its neighbour."""
    if n <= tile:
        return [(0, n, 0, n)]
    if tile <= 2 * overlap:
        raise InputError(f"segmenter tiles of {tile} px cannot keep {overlap} px of context on each side; "
                         "the model card's overlap_px must be less than half the tile")
    k = -(-(n - 2 * overlap) // (tile - 2 * overlap))
    size = -(-(n + 2 * overlap * (k - 1)) // k)
    size = min(tile, -(-size // multiple) * multiple)
    starts = [i * (n - size) // (k - 1) for i in range(k)]
    keeps = [0] + [(s + e) // 2 for s, e in zip(starts[1:], (s + size for s in starts[:-1]))] + [n]
    return [(s, s + size, keeps[i], keeps[i + 1]) for i, s in enumerate(starts)]


def tiled_logits(rgb: np.ndarray, run, channels: int, tile: int, overlap: int, multiple: int) -> np.ndarray:
    """A fully convolutional network's output (h, w, ``channels``) float32 over an RGB uint8 image, window by window
    (``_tiles``: each keeps its centre, with ``overlap`` of context): ``run`` maps one window (1, 3, H, W) in 0..1,
    reflect-padded to ``multiple``, to its (1, channels, H, W) output."""
    h, w = rgb.shape[:2]
    out = np.empty((h, w, channels), np.float32)
    for r0, r1, kr0, kr1 in _tiles(h, tile, overlap, multiple):
        for c0, c1, kc0, kc1 in _tiles(w, tile, overlap, multiple):
            win = rgb[r0:r1, c0:c1]
            th, tw = win.shape[:2]
            ph, pw = (-th) % multiple, (-tw) % multiple
            if ph or pw:  # reflect-pad to the network's multiple (small images: at least 1 px real)
                win = cv2.copyMakeBorder(win, 0, ph, 0, pw, cv2.BORDER_REFLECT_101 if min(th, tw) > 1
                                         else cv2.BORDER_REPLICATE)
            x = np.ascontiguousarray(win.transpose(2, 0, 1)[None], dtype=np.float32) / 255.0
            lg = run(x)[0, :, :th, :tw].transpose(1, 2, 0)
            out[kr0:kr1, kc0:kc1] = lg[kr0 - r0:kr1 - r0, kc0 - c0:kc1 - c0]
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
        name = sess.get_inputs()[0].name

        def run(x: np.ndarray) -> np.ndarray:
            logits = 0.0
            for axes in flips:  # test-time flips: averaged logits are steadier at class borders
                xi = np.ascontiguousarray(np.flip(x, axes)) if axes else x
                try:
                    res = sess.run(None, {name: xi})[0]
                except Exception as exc:
                    raise BackendUnavailable(f"learned segmenter {self.weights} failed on a {x.shape[3]}x{x.shape[2]} "
                                             f"tile ({exc})") from exc
                if res.ndim != 4 or res.shape[1] != N_CLASSES:
                    raise InputError(f"{self.weights} outputs shape {res.shape}; expected (1, {N_CLASSES}, H, W)")
                logits = logits + (np.flip(res, axes) if axes else res)
            return logits / len(flips)

        return tiled_logits(rgb, run, N_CLASSES, TILE_PX, int(self.meta.get("overlap_px", OVERLAP_PX)),
                            int(self.meta.get("multiple", 16)))

    def segment(self, image: GeoImage, seed: int = 0) -> ClassMap:
        rgb = image.rgb
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise InputError(f"learned segmentation needs an (H, W, 3) uint8 RGB image, got {rgb.shape} {rgb.dtype}")
        from .classical import ClassicalSegmenter

        cfg = self.config
        mode = getattr(cfg, "learned_water", "fused")
        if mode not in WATER_MODES:
            raise InputError(f"segment.learned_water = {mode!r}; use one of {', '.join(WATER_MODES)}")
        H, W = rgb.shape[:2]
        gsd = float(image.grid.gsd_m)
        lo, hi = self.meta.get("gsd_range_m", GSD_RANGE_M)
        if not lo <= gsd <= hi:
            # far outside the scales it was trained on the network sees things it never saw (and
            # upsampling a coarse image to the working GSD would be huge); the classical rules work at any GSD
            cm = ClassicalSegmenter(cfg).segment(image, seed)
            return ClassMap(cm.ids, cm.grid, confidence=None, source=np.full((H, W), SOURCE_CLASSICAL, np.uint8))
        s = gsd / float(self.meta["work_gsd_m"])
        w, h = max(16, int(round(W * s))), max(16, int(round(H * s)))
        small = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        p = self.proba_small(small)
        net_ids = p.argmax(axis=2).astype(np.uint8)
        lw = classical_weight(gsd)
        votes = None  # "net", or "fused" where the classical rules get no weight
        if mode == "classical" or (mode == "fused" and lw > 0):
            votes = self._classical_votes(image, seed, (h, w))
            vote = CLASSICAL_WATER_VOTE * lw if mode == "fused" else 30.0  # "classical": its water always wins
            fuse_votes(p, votes, vote, lw)
        min_px = float(getattr(cfg, "learned_min_region_m2", 12.0)) / float(self.meta["work_gsd_m"]) ** 2
        ids_small = _merge_specks(p, min_px)
        conf = (255.0 * p.max(axis=2)).astype(np.uint8)
        src = source_map(net_ids, ids_small, votes)
        if (w, h) == (W, H):
            return ClassMap(ids_small, image.grid, confidence=conf, source=src)
        ids = _upsample_argmax(p, H, W)
        conf = cv2.resize(conf, (W, H), interpolation=cv2.INTER_LINEAR)
        src = cv2.resize(src, (W, H), interpolation=cv2.INTER_NEAREST)
        return ClassMap(ids, image.grid, confidence=conf, source=src)

    def _classical_votes(self, image: GeoImage, seed: int, shape: tuple[int, int]) -> np.ndarray:
        """The classical segmenter's class map as the share of each class in each working pixel, (h, w, 8)
        float32 on a grid of ``shape``. Its water model knows rafted boats, pier clusters and the gaps
        between them; its land classifier adapts to each image (self-training on its confident pixels)."""
        from .classical import ClassicalSegmenter

        h, w = shape
        ids = ClassicalSegmenter(self.config).segment(image, seed).ids
        out = np.empty((h, w, N_CLASSES), np.float32)
        for c in range(N_CLASSES):
            one = (ids == c).astype(np.float32)
            out[..., c] = cv2.resize(one, (w, h), interpolation=cv2.INTER_AREA if one.shape[1] > w
                                     else cv2.INTER_LINEAR)
        return out


def classical_weight(gsd_m: float) -> float:
    """How much the classical segmenter is trusted against the network at this GSD: 1 up to
    CLASSICAL_GSD_M[0], 0 from CLASSICAL_GSD_M[1], linear between. It scales the water vote and weighs the
    land classes."""
    lo, hi = CLASSICAL_GSD_M
    return float(np.clip((hi - gsd_m) / (hi - lo), 0.0, 1.0))


def fuse_votes(p: np.ndarray, votes: np.ndarray, water_vote: float, land_weight: float) -> None:
    """Combine the network's probabilities ``p`` (h, w, 8) with the classical segmenter's class shares
    ``votes`` (h, w, 8), in place.

    Water against land: the classical share of water votes in the network's water log-odds (``water_vote``
    for a pixel it calls water, ``-water_vote`` for land), so a confident network outvotes it and an unsure
    one follows it. Among land classes: a geometric mix of the two distributions, the classical one
    weighted ``land_weight`` (``classical_weight``); where the classical map has no land class (its
    water), the network's land classes stand."""
    pw = np.clip(p[..., WATER], 1e-6, 1 - 1e-6)
    logit = np.log(pw) - np.log1p(-pw) + water_vote * (2.0 * votes[..., WATER] - 1.0)
    pw2 = (1.0 / (1.0 + np.exp(-logit))).astype(np.float32)
    land = p[..., 1:] / (1.0 - pw)[..., None]
    if land_weight > 0:
        q = votes[..., 1:]
        qs = q.sum(axis=2, keepdims=True)
        q = q / np.maximum(qs, 1e-6)
        q = 0.98 * q + 0.02 / (N_CLASSES - 1)  # a floor: the network can still say what the rules never do
        lw = land_weight * np.clip(qs, 0.0, 1.0)  # as much as the rules saw land there
        logl = (1.0 - lw) * np.log(np.clip(land, 1e-6, 1.0)) + lw * np.log(q)
        logl -= logl.max(axis=2, keepdims=True)
        land = np.exp(logl)
        land /= land.sum(axis=2, keepdims=True)
    p[..., WATER] = pw2
    p[..., 1:] = land * (1.0 - pw2)[..., None]


def source_map(net_ids: np.ndarray, ids: np.ndarray, votes: np.ndarray | None) -> np.ndarray:
    """Which source decided each pixel (SOURCE_*): both agreed, the network outvoted the classical
    segmenter, or the classical segmenter outvoted the network."""
    out = np.full(ids.shape, SOURCE_BOTH, np.uint8)
    if votes is None:
        out[:] = SOURCE_NETWORK
        return out
    cls, final, net = votes.argmax(axis=2), ids, net_ids
    out[(final != cls) & (final == net)] = SOURCE_NETWORK
    out[(final == cls) & (final != net)] = SOURCE_CLASSICAL
    return out


def _softmax(logits: np.ndarray) -> np.ndarray:
    """Softmax over the last axis of (h, w, C) logits, as float32."""
    top = logits[..., 0].copy()
    for c in range(1, logits.shape[2]):  # a running maximum: ~8x faster than max(axis=2), same values
        np.maximum(top, logits[..., c], out=top)
    e = logits - top[..., None]
    np.exp(e, out=e)
    e /= e.sum(axis=2, keepdims=True)
    return e.astype(np.float32, copy=False)


def _merge_specks(p: np.ndarray, min_px: float) -> np.ndarray:
    """Land specks under ``min_px`` working pixels take the class of the nearest larger region (in place, as
    one-hot probabilities, so the later bilinear upsampling keeps smooth borders); water stays as it is.
    Returns the class ids after the merge."""
    from .classical import merge_small

    ids = p.argmax(axis=2).astype(np.uint8)
    merged = merge_small(ids, int(round(min_px)), fixed=ids == WATER)
    ch = merged != ids
    if ch.any():
        p[ch] = 0.0
        p[ch, merged[ch]] = 1.0
    return merged


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
