"""Matching: each detection → the library asset it shows, by shape at metric scale, appearance and size.

A detection is cropped rotation-normalised (front along +x), embedded with the library's embedder and
compared with every asset of its category. With shape re-ranking (``match.shape``, the default) each
candidate's top views are also fitted to the crop at metric scale over a small search of scale, shift
and both headings, on paint-invariant orientation fields (``ShapeMatcher``): car and small-boat paint is
arbitrary, their outline and structure are not. The fit's correlation, the embedding's cosine, a prior on
the instance's scale and the detected length/width against the fitted asset make the score; the fit at
both headings (each at its own best place), a grey-level comparison with the asset's mean view and the
detector's heading confidence as a prior (both weighted more on objects of few pixels) decide bow from
stern. Without it the embedding and a size likelihood decide and, if the detector was unsure, an NCC of
the crop against the chosen asset's top view at both headings. ``best`` takes the top candidate,
``sample`` (the paper's behaviour) a seeded random one within a score margin. Every decision (candidates, scores, choice, fitted
scale and centre offset) is recorded.
"""

from __future__ import annotations

import contextlib
import dataclasses

import math
from dataclasses import dataclass

import numpy as np

from .config import MatchConfig
from .errors import LibraryError
from .frames import wrap_deg
from .rng import stage_rng
from .types import Detection, GeoImage

ASSET_CATEGORIES_FOR = {"boat": ("boat",), "vehicle": ("vehicle",), "buoy": ("buoy",)}
SIZE_SIGMA_LENGTH = 0.22  # log-ratio spread of a detected length around the true one
SIZE_SIGMA_WIDTH = 0.35  # widths are noisier (shadows, fenders, side-by-side boats)


@dataclass(frozen=True)
class Candidate:
    asset_id: str
    appearance: float  # the embedding's cosine
    size: float  # size likelihood of the detected length/width against dims_m
    score: float
    shape: float | None = None  # orientation-field correlation of the best fit (shape re-ranking)
    fit_scale: float | None = None  # the asset's scale at that fit


@dataclass(frozen=True)
class MatchDecision:
    index: int  # into the detections given
    asset_id: str
    score: float
    yaw_deg: float
    heading_source: str  # detector | library | unresolved
    flip_evidence: float  # library: NCC(same heading) - NCC(flipped) (+ grey cue); > 0 supports the yaw
    candidates: tuple[Candidate, ...]
    fit_scale: float | None = None  # the chosen asset's scale that fitted the crop best (shape re-ranking)
    fit_offset_m: tuple[float, float] = (0.0, 0.0)  # fitted centre - box centre, along the final yaw and to its left
    confidence: float = 1.0  # the score as a confidence in [0, 1] (``match_confidence``): the scene objects' score

    def to_dict(self) -> dict:
        out = {"index": self.index, "asset_id": self.asset_id, "score": round(self.score, 4),
               "confidence": round(self.confidence, 4),
               "yaw_deg": round(self.yaw_deg, 3), "heading_source": self.heading_source,
               "flip_evidence": round(self.flip_evidence, 4),
               "candidates": [{"asset_id": c.asset_id, "appearance": round(c.appearance, 4),
                               "size": round(c.size, 4), "score": round(c.score, 4),
                               **({"shape": c.shape, "fit_scale": c.fit_scale} if c.shape is not None else {})}
                              for c in self.candidates]}
        if self.fit_scale is not None:
            out["fit_scale"] = self.fit_scale
            out["fit_offset_m"] = [round(v, 3) for v in self.fit_offset_m]
        return out


def crop_rotated(rgb: np.ndarray, cx: float, cy: float, yaw_deg: float, out_w_px: int, out_h_px: int,
                 scale: float = 1.0) -> np.ndarray:
    """A crop centred on (cx, cy) rotated so that direction ``yaw_deg`` points to the crop's right (+x),
    resampled by ``scale`` (output pixels per input pixel). Borders replicate the surroundings."""
    import cv2

    # rotating the content counter-clockwise by -yaw brings the front to image-right
    m = cv2.getRotationMatrix2D((float(cx), float(cy)), -float(yaw_deg), float(scale))
    m[0, 2] += out_w_px / 2.0 - cx
    m[1, 2] += out_h_px / 2.0 - cy
    return cv2.warpAffine(rgb, m, (int(out_w_px), int(out_h_px)), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REFLECT)


def detection_crop(image: GeoImage, det: Detection, pad: float = 1.5, max_px: int = 256) -> tuple[np.ndarray, float]:
    """Square, rotation-normalised crop of a detection and its metres-per-pixel."""
    side_in = max(det.length_px, det.width_px) * pad + 4
    scale = min(1.0, max_px / side_in)
    side = int(math.ceil(side_in * scale))
    crop = crop_rotated(image.rgb, det.cx_px, det.cy_px, det.yaw_deg, side, side, scale)
    return crop, image.grid.gsd_m / scale


def size_likelihood(length_m: float, width_m: float, dims_m) -> float:
    L, W = max(dims_m[0], 1e-3), max(dims_m[1], 1e-3)
    a = math.log(max(length_m, 1e-3) / L) / SIZE_SIGMA_LENGTH
    b = math.log(max(width_m, 1e-3) / W) / SIZE_SIGMA_WIDTH
    return math.exp(-0.5 * (a * a + b * b))


def _gray_norm(a: np.ndarray) -> np.ndarray:
    g = a.astype(np.float32).mean(axis=2) if a.ndim == 3 else a.astype(np.float32)
    g -= g.mean()
    n = np.linalg.norm(g)
    return g / n if n > 0 else g


def heading_evidence(crop: np.ndarray, crop_gsd: float, view: np.ndarray, view_gsd: float,
                     length_m: float, width_m: float) -> float:
    """NCC(crop, view) - NCC(crop rotated 180°, view) over the object's box (both front at +x)."""
    import cv2

    s = view_gsd / crop_gsd
    v = cv2.resize(view, (max(1, round(view.shape[1] * s)), max(1, round(view.shape[0] * s))),
                   interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    w = max(4, int(round(length_m * 1.1 / crop_gsd)))
    h = max(4, int(round(width_m * 1.1 / crop_gsd)))

    def centre(a):
        cy, cx = a.shape[0] // 2, a.shape[1] // 2
        hh, ww = min(h, a.shape[0]) // 2, min(w, a.shape[1]) // 2
        return a[cy - hh:cy + hh, cx - ww:cx + ww]

    c, v = centre(crop), centre(v)
    hh, ww = min(c.shape[0], v.shape[0]), min(c.shape[1], v.shape[1])
    if hh < 3 or ww < 3:
        return 0.0

    def mid(a):
        oy, ox = (a.shape[0] - hh) // 2, (a.shape[1] - ww) // 2
        return a[oy:oy + hh, ox:ox + ww]

    c, v = _gray_norm(mid(c)), _gray_norm(mid(v))
    return float((c * v).sum() - (c[::-1, ::-1] * v).sum())


_VIEW_CACHE: dict = {}


def asset_top_view(library, asset_id: str, background: str) -> tuple[np.ndarray, float]:
    """The asset seen from above at yaw 0 (front at +x) and its metres per pixel, rendered once and cached."""
    key = (id(library), asset_id, background)
    if key not in _VIEW_CACHE and hasattr(library, "top_view"):
        _VIEW_CACHE[key] = library.top_view(asset_id, background)
    if key not in _VIEW_CACHE:
        from .render import render_mesh_view, standard_view_lightings

        mesh = library.mesh(asset_id)
        ext = mesh.extents
        gsd = max(float(max(ext[0], ext[1])) * 1.3 / 160.0, 0.01)
        view = render_mesh_view(mesh, gsd, 160, standard_view_lightings()[0], background)
        _VIEW_CACHE[key] = (view, gsd)
    return _VIEW_CACHE[key]


def _warn_library(exc: Exception) -> None:
    """Matching goes on without an unreadable view or model, but says so (once per message)."""
    import warnings

    from .errors import CoastforgeWarning

    warnings.warn(f"{exc}; matching used the embedding and the size only for this asset", CoastforgeWarning,
                  stacklevel=3)


def shape_matcher(library) -> ShapeMatcher:
    """The library's shape matcher (its templates are cached across calls, e.g. over the tiles of a scene)."""
    sm = getattr(library, "_shape_matcher", None)
    if sm is None or sm.library is not library:
        sm = ShapeMatcher(library)
        # a library-like object that takes no attributes: no cache across calls
        with contextlib.suppress(AttributeError):
            library._shape_matcher = sm
    return sm


def _scale_sigma(config: MatchConfig, category: str) -> float:
    return {"boat": config.shape_scale_sigma_boat, "vehicle": config.shape_scale_sigma_vehicle}.get(
        category, config.shape_scale_sigma_buoy)


def _logit(p: float) -> float:
    p = min(max(float(p), 0.5), 0.99)  # below 0.5 the detector would have said the other way
    return math.log(p / (1.0 - p))


def _pixel_scaling(config: MatchConfig, det: Detection) -> float:
    """``heading_prior_ref_px`` / the object's length in the pixels the shape fit compares (at most
    ``ShapeMatcher.MAX_LEN_PX``): the fit's heading evidence is noisier on objects of few pixels, so the
    other cues count more there."""
    if config.heading_prior_ref_px <= 0:
        return 1.0
    return config.heading_prior_ref_px / max(min(det.length_px, ShapeMatcher.MAX_LEN_PX), 4.0)


def heading_prior(config: MatchConfig, det: Detection) -> float:
    """The detector's heading belief in units of the shape fit's heading evidence (NCC difference):
    ``heading_prior_weight`` x logit(confidence) x the pixel scaling (``_pixel_scaling``)."""
    return config.heading_prior_weight * _logit(det.heading_confidence) * _pixel_scaling(config, det)


def mean_view(library, asset_id: str, background: str) -> tuple[np.ndarray, float]:
    """The mean of the asset's stored views on ``background`` (lightings, repainted copies; front at +x) and
    its metres per pixel: what every paint shares (dark glass, the cabin's outline) stays. Cached with the
    library's shape matcher."""
    cache = shape_matcher(library)._mean_views
    key = (asset_id, background)
    if key not in cache:
        if hasattr(library, "views_on"):
            views = library.views_on(asset_id, background)
            gsd = float(library.asset(asset_id).view_gsd_m)
            cache[key] = (np.mean([v.astype(np.float32) for v in views], axis=0), gsd)
        else:
            cache[key] = asset_top_view(library, asset_id, background)
    return cache[key]


# default-embedder blocks the matcher leaves out of its crops' vectors (see ``_without_context_blocks``); the
# ring clutter and the background too: within one category they only split crowded from isolated views
# (synthetic levels, truth boxes: 0.954 right with the clutter, 0.944 with both at the background's weight
# 1.2; 0.956 without)
DROP_BLOCKS = ("edge_extent", "clutter", "background")


def _without_context_blocks(library, vecs: np.ndarray) -> np.ndarray:
    """The crops' vectors without the default embedder's blocks that describe the crop around the object
    (``DROP_BLOCKS``), renormalised. The edge extent measures everything with edges in a crop, which around
    a detection (a car in a row, a boat at a crowded berth) is its neighbours too; here the box and the shape
    fit measure the object. A zero block drops out of every cosine alike. (Synthetic levels of seeds 0-2,
    truth boxes: 0.942 of the assets right with the edge extent, 0.956 without.)"""
    slices = getattr(getattr(library, "embedder", None), "block_slices", {})
    sls = [slices[k] for k in DROP_BLOCKS if k in slices]
    if not sls or not len(vecs):
        return vecs
    vecs = vecs.copy()
    for sl in sls:
        vecs[:, sl] = 0.0
    return vecs / np.maximum(np.linalg.norm(vecs, axis=1, keepdims=True), 1e-12)


def match_detections(image: GeoImage, dets: list[Detection], library, config: MatchConfig, seed: int,
                     heading_min_evidence: float = 0.03, heading_trust: float = 0.7,
                     fallback=None) -> list[MatchDecision]:
    """Choose an asset and a final yaw for every boat, vehicle and buoy detection.

    With ``config.shape`` (the default) every asset of the category is fitted to the crop by shape (see
    ``ShapeMatcher``) at both headings; the score adds the embedding's cosine, a prior on the instance's
    scale and the detected length/width against the fitted asset. The heading: the chosen asset's fit at
    both headings plus a grey-level cue, against the detector's confidence as a prior (``heading_prior``).
    Without it: embedding + size likelihood, heading from NCC."""
    todo = [(i, d) for i, d in enumerate(dets) if d.category in ASSET_CATEGORIES_FOR]
    if not todo:
        return []
    if fallback is not None:  # categories the library lacks are matched against ``fallback`` (the starter kit)
        have = {a.category for a in library.assets}
        lacking = {d.category for _, d in todo if not have.intersection(ASSET_CATEGORIES_FOR[d.category])}
        if lacking:
            out = []
            for lib, want in ((library, False), (fallback, True)):
                idx = [i for i, d in enumerate(dets) if (d.category in lacking) == want]
                out += [dataclasses.replace(m, index=idx[m.index]) for m in match_detections(
                    image, [dets[i] for i in idx], lib, config, seed, heading_min_evidence, heading_trust)]
            return sorted(out, key=lambda m: m.index)
    if config.mode not in ("best", "sample"):
        raise LibraryError(f"match.mode = {config.mode!r}; valid modes: best, sample")
    crops, gsds = [], []
    for _, d in todo:
        c, g = detection_crop(image, d)
        crops.append(c)
        gsds.append(g)
    vecs = _without_context_blocks(library, np.asarray(library.embed(crops, gsds), dtype=np.float32))
    by_cat: dict[str, list] = {}
    for a in library.assets:
        by_cat.setdefault(a.category, []).append(a)
    sm = shape_matcher(library) if config.shape else None
    gsd_img = image.grid.gsd_m
    # one index search per category for all its detections (a search per detection costs ~1 ms in calls)
    pools: dict[str, list] = {}
    hits_of: dict[int, list] = {}
    for cat in dict.fromkeys(d.category for _, d in todo):
        cats = ASSET_CATEGORIES_FOR[cat]
        pools[cat] = pool = [a for c in cats for a in by_cat.get(c, [])]
        if not pool:
            raise LibraryError(
                f"the asset library has no {'/'.join(cats)} asset to match a detected {cat}; add one to the "
                "library (coastforge library build) or use the starter kit")
        rows = [row for row, (_, d) in enumerate(todo) if d.category == cat]
        for row, h in zip(rows, library.search(vecs[rows], k=len(pool), category=cats[0])):
            hits_of[row] = h
    decisions = []
    for row, (i, d) in enumerate(todo):
        pool = pools[d.category]
        hits = hits_of[row]
        appearance = dict(hits)
        L, W = d.length_px * gsd_img, d.width_px * gsd_img
        bg = "ground" if d.category == "vehicle" else "water"
        shapes = {}
        if sm is not None:
            sig = _scale_sigma(config, d.category)
            scales = tuple(s for s in ShapeMatcher.SCALES if abs(math.log(s)) <= 2.5 * sig + 1e-9) or (1.0,)
            order = [aid for aid, _s in hits] + [a.id for a in pool if a.id not in appearance]
            try:
                shapes = sm.score(image.rgb, d, gsd_img, order, bg, scales=scales)
            except LibraryError as exc:  # views or meshes unreadable: the embedding and size still decide
                _warn_library(exc)
                shapes = {}
            if any(a.id not in shapes for a in pool):  # one scale for all candidates, or none
                shapes = {}
        # the detector's belief in its heading, as a bonus for fits at that heading
        hp = heading_prior(config, d) if d.heading_known else 0.0
        cands, fits = [], {}
        for a in pool:
            app = float(appearance.get(a.id, -1.0))
            sz = size_likelihood(L, W, a.dims_m)
            sh = shapes.get(a.id)
            if sh is None:
                cands.append(Candidate(a.id, app, sz, (1 - config.size_weight) * app + config.size_weight * sz))
                continue
            keep = (sh.ncc if not sh.flipped else sh.ncc_other_heading) + hp / 2
            flip = (sh.ncc if sh.flipped else sh.ncc_other_heading) - hp / 2
            s = sh.scale
            dl = math.log(max(L, 1e-3) / (a.dims_m[0] * s)) / config.shape_length_sigma
            dw = math.log(max(W, 1e-3) / (a.dims_m[1] * s)) / config.shape_width_sigma
            size_log = -0.5 * (config.shape_scale_weight * (math.log(s) / sig) ** 2
                               + config.shape_length_weight * dl * dl + config.shape_width_weight * dw * dw)
            score = max(keep, flip) + config.shape_appearance_weight * app + size_log
            fits[a.id] = (flip > keep, sh)
            cands.append(Candidate(a.id, app, sz, score, round(sh.ncc, 4), s))
        cands.sort(key=lambda c: -c.score)
        chosen = cands[0]
        if config.mode == "sample":
            near = [c for c in cands if c.score >= cands[0].score - config.sample_margin]
            chosen = near[int(stage_rng(seed, "match", i).integers(len(near)))]
        yaw, source, evidence = float(d.yaw_deg), "detector", 0.0
        fit_scale, offset = None, (0.0, 0.0)
        if chosen.asset_id in fits:
            # heading from the fit: the chosen asset at both headings, the detector's confidence as a prior, and
            # the grey levels against the asset's mean view (what the paint-invariant fit cannot see)
            sh = fits[chosen.asset_id][1]
            ncc_keep = sh.ncc_other_heading if sh.flipped else sh.ncc
            ncc_flip = sh.ncc if sh.flipped else sh.ncc_other_heading
            lib_ev = ncc_keep - ncc_flip  # the library's evidence for the detector's heading
            if config.heading_appearance_weight > 0:
                try:
                    view, view_gsd = mean_view(library, chosen.asset_id, bg)
                    grey = heading_evidence(crops[row], gsds[row], view, view_gsd, L, W)
                except LibraryError as exc:  # views unreadable: the fit and the detector decide
                    _warn_library(exc)
                    grey = 0.0
                lib_ev += config.heading_appearance_weight * _pixel_scaling(config, d) * grey
            flipped = lib_ev + hp < 0  # as in the candidates' scores when the grey cue is off
            evidence = -lib_ev if flipped else lib_ev
            if flipped:
                yaw = float(wrap_deg(yaw + 180.0))
            if abs(lib_ev) >= heading_min_evidence or flipped:
                source = "library"
            elif not d.heading_known:
                source = "unresolved"
            fit_scale = sh.scale
            ox, oy = sh.offset_m
            # offsets were measured in the box's frame; after a flip the box frame turned by 180 degrees
            offset = (-ox, -oy) if flipped else (ox, oy)
        elif not d.heading_known or d.heading_confidence < heading_trust:
            # Heading without the shape fit: compare the crop (front at +x by the detector's guess) with the top
            # views of the best candidates at both headings (~90 % right on true boxes).
            top = [chosen] + [c for c in cands[:3] if c.asset_id != chosen.asset_id][:2]
            wsum = esum = 0.0
            for j, c in enumerate(top):
                view, view_gsd = asset_top_view(library, c.asset_id, bg)
                w = 1.0 if j == 0 else 0.5
                esum += w * heading_evidence(crops[row], gsds[row], view, view_gsd, L, W)
                wsum += w
            evidence = esum / wsum
            if abs(evidence) >= heading_min_evidence or not d.heading_known:
                if evidence < 0:
                    yaw = float(wrap_deg(yaw + 180.0))
                source = "library" if abs(evidence) >= heading_min_evidence else "unresolved"
                evidence = abs(evidence)
        decisions.append(MatchDecision(i, chosen.asset_id, chosen.score, float(wrap_deg(yaw)), source, evidence,
                                       tuple(cands[: min(5, len(cands))]), fit_scale, offset,
                                       match_confidence(chosen, config)))
    return decisions


def match_confidence(c: Candidate, config: MatchConfig) -> float:
    """A candidate's score as a confidence in [0, 1]. The score ranks candidates and is not bounded by 1: with
    the shape fit it is a correlation (<= 1) plus ``shape_appearance_weight`` x the embedding's cosine minus a
    size penalty (so up to 1 + that weight; scenes showed 1.15), without it a weighted mean of cosine and size
    likelihood (<= 1). Dividing by the largest score the formula can give keeps the ranking and makes 1 the
    perfect match; negative scores (anti-correlated fits) are no confidence at all."""
    top = 1.0 + max(0.0, config.shape_appearance_weight) if c.shape is not None else 1.0
    return float(min(1.0, max(0.0, c.score / top)))


# --------------------------------------------------------------------------------------------------
# shape re-ranking: the crop against each candidate's top views at metric scale

def orientation_field(img: np.ndarray, sigma: float = 0.8, norm_sigma: float = 2.0) -> np.ndarray:
    """Paint-invariant structure: the colour structure tensor's double-angle vector (Jxx - Jyy, 2 Jxy),
    divided by the local gradient energy. Unchanged by contrast polarity (a black car and a white one
    give the same edges) and, locally, by contrast strength; (H, W, 2) float32 in [-1, 1]."""
    import cv2

    f = img.astype(np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)
    if f.ndim == 3:  # channel sums with cv2.transform: numpy's reduction over a length-3 axis is slow
        ones = np.ones((1, f.shape[2]), np.float32)
        jxx, jyy, jxy = cv2.transform(gx * gx, ones), cv2.transform(gy * gy, ones), cv2.transform(gx * gy, ones)
    else:
        jxx, jyy, jxy = gx * gx, gy * gy, gx * gy
    a = cv2.GaussianBlur(jxx - jyy, (0, 0), sigma)
    b = cv2.GaussianBlur(2.0 * jxy, (0, 0), sigma)
    t = cv2.GaussianBlur(jxx + jyy, (0, 0), norm_sigma)
    # flat areas (sensor noise, water ripples) must not be amplified into structure
    eps = 0.05 * float(cv2.mean(t)[0]) + 25.0
    return np.stack([a / (t + eps), b / (t + eps)], axis=2).astype(np.float32)


@dataclass(frozen=True)
class ShapeScore:
    asset_id: str
    ncc: float  # best correlation of orientation fields (normalised as in ``score``)
    scale: float  # the asset's scale at the best fit
    flipped: bool  # best fit with the front at the crop's left (yaw + 180)
    ncc_other_heading: float  # best correlation at the other heading (heading evidence)
    offset_m: tuple[float, float] = (0.0, 0.0)  # fitted centre minus box centre: along the box's yaw, to its left


class ShapeMatcher:
    """Compares rotation-normalised crops with the library's top views of a few candidates over a small
    search of scale, shift and both headings, on orientation fields (paint-invariant). Templates are
    made once per (asset, metres per pixel, scale) and cached on the matcher."""

    # scales and working resolutions on one lattice (2^(1/12) and 2^(3/12) steps): a template depends only on
    # gsd / scale, so templates made for one object serve others of other sizes
    SCALES = tuple(2.0 ** (k / 12.0) for k in range(-3, 4))  # 0.84 .. 1.19
    MAX_LEN_PX = 64  # objects are compared at most this long (finer detail costs time, adds little)
    SHIFT_ALONG = 0.10  # search +- this fraction of the length along, and of the width across
    SHIFT_ACROSS = 0.15
    MAX_VIEWS = 10  # views averaged per template (the lightings first, then repainted copies)
    LENGTH_TOLERANCE = 1.5  # scaled asset lengths beyond detected x/÷ this are not tried

    def __init__(self, library):
        self.library = library
        self._views: dict = {}
        self._tpl: dict = {}
        self._mean_views: dict = {}  # see ``mean_view``

    @staticmethod
    def work_gsd(image_gsd: float, length_m: float, max_len_px: int) -> float:
        """The image's metres per pixel, coarsened in steps of 2^(1/4) for long objects (so templates of
        similar objects share a cache entry)."""
        g = float(image_gsd)
        need = length_m / max_len_px
        if need > g:
            g = g * 2.0 ** (math.ceil(4 * math.log2(need / g)) / 4.0)
        return g

    def _asset_views(self, asset_id: str, background: str):
        """The asset's views on ``background`` and its silhouette, cut to the object plus a margin, symmetric
        about the view centre (= the footprint centre); float32, at the views' metres per pixel."""
        key = (asset_id, background)
        if key not in self._views:
            lib = self.library
            a = lib.asset(asset_id)
            if hasattr(lib, "views_on"):
                views = lib.views_on(asset_id, background)[: self.MAX_VIEWS]
            else:
                views = [lib.top_view(asset_id, background)[0]]
            gsd = float(a.view_gsd_m)
            n = views[0].shape[0]
            sil = _silhouette(lib, asset_id, n, gsd, views[0])
            ys, xs = np.nonzero(sil)
            h = n // 2
            if len(xs):
                hx = min(h, int(max(h - xs.min(), xs.max() + 1 - h)) + 6)
                hy = min(h, int(max(h - ys.min(), ys.max() + 1 - h)) + 6)
            else:
                hx = hy = h
            cut = (slice(h - hy, h + hy), slice(h - hx, h + hx))
            self._views[key] = ([np.ascontiguousarray(v[cut], np.float32) for v in views], gsd,
                                np.ascontiguousarray(sil[cut]))
        return self._views[key]

    def template(self, asset_id: str, background: str, gsd: float, scale: float) -> _Template:
        """The orientation field x silhouette mask of the asset scaled by ``scale`` and seen at ``gsd``, front
        at +x, footprint centre at the template centre; the field is the mean over the asset's views (the
        lightings and repainted copies: edges that every paint shows count most)."""
        import cv2

        key = (asset_id, background, round(1200.0 * math.log2(gsd / scale)))
        if key in self._tpl:
            return self._tpl[key]
        views, vgsd, sil = self._asset_views(asset_id, background)
        f = vgsd * scale / gsd
        vh, vw = sil.shape
        mw, mh = max(4, int(round(vw * f))), max(4, int(round(vh * f)))
        interp = cv2.INTER_AREA if f < 1 else cv2.INTER_LINEAR
        field = None
        for v in views:
            fv = orientation_field(cv2.resize(v, (mw, mh), interpolation=interp))
            field = fv if field is None else field + fv
        field /= len(views)
        mask = cv2.resize(sil, (mw, mh), interpolation=cv2.INTER_AREA) > 0.3
        mask = cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(np.float32)
        ys, xs = np.nonzero(mask)
        if not len(xs):
            ys, xs = np.array([mh // 2]), np.array([mw // 2])
        cx, cy = (mw - 1) / 2.0, (mh - 1) / 2.0
        # symmetric about the centre (= the footprint centre), so the template centre is the object's
        hx = int(math.ceil(max(cx - xs.min(), xs.max() - cx)))
        hy = int(math.ceil(max(cy - ys.min(), ys.max() - cy)))
        x0, x1 = max(0, int(round(cx - hx))), int(round(cx + hx)) + 1
        y0, y1 = max(0, int(round(cy - hy))), int(round(cy + hy)) + 1
        fm = field[y0:y1, x0:x1] * mask[y0:y1, x0:x1, None]
        mk = mask[y0:y1, x0:x1]
        out = _Template({False: np.ascontiguousarray(fm), True: np.ascontiguousarray(fm[::-1, ::-1])},
                        {False: np.ascontiguousarray(mk), True: np.ascontiguousarray(mk[::-1, ::-1])},
                        float(np.sqrt((fm * fm).sum())), mk.shape,
                        np.stack([fm.ravel(), fm[::-1, ::-1].ravel()], 1),
                        np.stack([mk.ravel(), mk[::-1, ::-1].ravel()], 1))
        if len(self._tpl) > 4000:
            self._tpl.clear()
        self._tpl[key] = out
        return out

    def score(self, rgb: np.ndarray, det: Detection, image_gsd: float, asset_ids, background: str,
              headings=(False, True), scales: tuple[float, ...] | None = None) -> dict[str, ShapeScore]:
        """Per candidate, the best fit over scale, shift and heading (flipped = front at yaw + 180)."""
        import cv2

        if not asset_ids:
            return {}
        lib = self.library
        length_m = det.length_px * image_gsd
        dims = {a: lib.asset(a).dims_m for a in asset_ids}
        scales_all = tuple(scales) if scales else self.SCALES
        # compare at a resolution set by the object (a 3 m dinghy keeps its detail beside 18 m yachts)
        gsd = self.work_gsd(image_gsd, length_m * max(scales_all), self.MAX_LEN_PX)
        sx = max(2, int(math.ceil(self.SHIFT_ALONG * length_m / gsd)))
        sy = max(2, int(math.ceil(self.SHIFT_ACROSS * det.width_px * image_gsd / gsd)))
        plans = []
        for aid in asset_ids:
            # scales that fit the detected length (generously: boxes can be 30 % off); at least the nearest
            want = length_m / max(dims[aid][0], 1e-3)
            fit = [s for s in scales_all if 1.0 / self.LENGTH_TOLERANCE <= want / s <= self.LENGTH_TOLERANCE] \
                or [min(scales_all, key=lambda s: abs(math.log(want / s)))]
            for s in fit:
                tpl = self.template(aid, background, gsd, s)
                if tpl.norm > 0:
                    plans.append((aid, s, tpl, abs(math.log(want / s))))
        if not plans:
            return {}
        out_w = max(p[2].shape[1] for p in plans) + 2 * sx + 8
        out_h = max(p[2].shape[0] for p in plans) + 2 * sy + 8
        f = image_gsd / gsd
        if f < 0.999:  # crop at full resolution, then area-average (no aliasing)
            big_crop = crop_rotated(rgb, det.cx_px, det.cy_px, det.yaw_deg, int(math.ceil(out_w / f)) + 2,
                                    int(math.ceil(out_h / f)) + 2, 1.0)
            crop = cv2.resize(big_crop, (out_w, out_h), interpolation=cv2.INTER_AREA)
            # where the box centre landed (crop_rotated puts it at size / 2 in pixel-centre coordinates)
            ccx = (big_crop.shape[1] / 2.0 + 0.5) * out_w / big_crop.shape[1] - 0.5
            ccy = (big_crop.shape[0] / 2.0 + 0.5) * out_h / big_crop.shape[0] - 0.5
        else:
            crop = crop_rotated(rgb, det.cx_px, det.cy_px, det.yaw_deg, out_w, out_h, 1.0)
            ccx, ccy = out_w / 2.0, out_h / 2.0
        field = np.ascontiguousarray(orientation_field(crop))
        energy = np.ascontiguousarray((field * field).sum(2))
        ch, cw = field.shape[:2]
        # the structure the fit must explain: the box (10 % margin). The correlation is normalised by the
        # geometric mean of the crop's energy under the template and in the box: a short template must not win
        # on a long object by fitting only part of it (the plain masked NCC favours the shortest car at 0.2 m/px)
        bx, by = 0.55 * length_m / gsd, 0.55 * det.width_px * image_gsd / gsd
        box_norm = float(np.sqrt(energy[max(0, int(ccy - by)):int(math.ceil(ccy + by)) + 1,
                                        max(0, int(ccx - bx)):int(math.ceil(ccx + bx)) + 1].sum()))
        # 1. where is each candidate's best fit? Its template at the scale nearest the box, over the full shift
        #    range, at each heading searched: each heading gets its own best place. (Placing both at the box
        #    heading's best fit biased the heading toward the detector's: a car's cabin, fitted by shifting the
        #    template, then sits where only that heading explains it.)
        offsets = {}
        for aid in asset_ids:
            mine = [p for p in plans if p[0] == aid]
            if not mine:
                continue
            tpl = min(mine, key=lambda p: p[3])[2]
            th, tw = tpl.shape
            y0, x0 = (ch - th) // 2 - sy, (cw - tw) // 2 - sx
            fwin = field[y0:y0 + th + 2 * sy, x0:x0 + tw + 2 * sx]
            ewin = energy[y0:y0 + th + 2 * sy, x0:x0 + tw + 2 * sx]
            for flip in headings:
                num = cv2.matchTemplate(fwin, tpl.weighted[flip], cv2.TM_CCORR)
                den = cv2.matchTemplate(ewin, tpl.mask[flip], cv2.TM_CCORR)
                j = int(np.argmax(num / np.sqrt(np.maximum(den, 1e-6))))
                offsets[(aid, flip)] = (j // num.shape[1] - sy, j % num.shape[1] - sx)
        # 2. every candidate, scale and heading near that position (+-1 px): small matrix products over the
        #    3 x 3 windows (strided views, no per-window calls)
        fs, es = field.strides, energy.strides
        res: dict[str, list] = {}
        for aid, s, tpl, _d in plans:
            th, tw = tpl.shape
            for k, flip in enumerate((False, True)):
                if flip not in headings:
                    continue
                oy, ox = offsets[(aid, flip)]
                y0, x0 = (ch - th) // 2 + oy - 1, (cw - tw) // 2 + ox - 1
                y0, x0 = min(max(y0, 0), ch - th - 2), min(max(x0, 0), cw - tw - 2)
                win = np.ndarray((3, 3, th, tw, 2), np.float32, field, y0 * fs[0] + x0 * fs[1],
                                 (fs[0], fs[1], fs[0], fs[1], fs[2])).reshape(9, -1)
                win_e = np.ndarray((3, 3, th, tw), np.float32, energy, y0 * es[0] + x0 * es[1],
                                   (es[0], es[1], es[0], es[1])).reshape(9, -1)
                under = np.sqrt(np.sqrt(np.maximum(win_e @ tpl.flat_mask[:, k], 1e-6)))  # sqrt(|crop under it|)
                v = (win @ tpl.flat_weighted[:, k]) / (under * math.sqrt(max(box_norm, 1e-6)) * tpl.norm)  # (9,)
                j = int(np.argmax(v))
                val = float(v[j])
                r = res.setdefault(aid, [(-2.0, 1.0, 0.0, 0.0), (-2.0, 1.0, 0.0, 0.0)])
                if val > r[k][0]:
                    # the template centre's offset from the box centre, in metres (along the front, to the left),
                    # to a fraction of a pixel: a parabola through the peak and its neighbours
                    g3 = v.reshape(3, 3)
                    py, px = j // 3, j % 3
                    fx = _parabola_peak(g3[py, 0], g3[py, 1], g3[py, 2]) if px == 1 else 0.0
                    fy = _parabola_peak(g3[0, px], g3[1, px], g3[2, px]) if py == 1 else 0.0
                    dx = (x0 + px + fx + (tw - 1) / 2.0 - ccx) * gsd
                    dy = -(y0 + py + fy + (th - 1) / 2.0 - ccy) * gsd
                    r[k] = (val, s, dx, dy)
        out = {}
        for aid, (nf, fl) in res.items():
            flip = fl[0] > nf[0]
            b, o = (fl, nf) if flip else (nf, fl)
            out[aid] = ShapeScore(aid, b[0], b[1], flip, o[0], (b[2], b[3]))
        return out


@dataclass(frozen=True, eq=False)
class _Template:
    weighted: dict  # flipped (bool) -> orientation field x mask, (h, w, 2) float32
    mask: dict  # flipped -> (h, w) float32
    norm: float  # |field x mask|
    shape: tuple[int, int]
    flat_weighted: np.ndarray  # (h w 2, 2): both headings, flattened
    flat_mask: np.ndarray  # (h w, 2)


def _parabola_peak(a: float, b: float, c: float) -> float:
    """Sub-pixel position (-0.5 .. 0.5) of the maximum of a parabola through (-1, a), (0, b), (1, c)."""
    den = a - 2.0 * b + c
    return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < -1e-9 else 0.0


def _silhouette(library, asset_id: str, n: int, gsd: float, view: np.ndarray) -> np.ndarray:
    """The asset's footprint seen from above, aligned with its views (n x n at ``gsd``), float32 0/1: the
    library's stored mask, else rasterised from the mesh, else (thumbnail-only assets) segmented from the view."""
    stored = library.silhouette(asset_id) if hasattr(library, "silhouette") else None
    if stored is not None and stored.shape == (n, n):
        return stored
    a = library.asset(asset_id)
    if getattr(a, "mesh_path", None) is not None:
        from .assets.meshes import footprint_mask

        return footprint_mask(library.mesh(asset_id), n, gsd).astype(np.float32)
    from .assets.embed import object_mask  # thumbnail-only asset: no shadows in its views

    return object_mask(view).astype(np.float32)
