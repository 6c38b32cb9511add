"""The default detector: no weights, colour and shape only (every threshold is in ``DetectConfig``).

1. Water: the class map's water when given; otherwise smooth, tinted (not grey), not-bright pixels in
   large connected regions (at satellite scale: the darkest large surface). A local water colour model
   (normalised convolution of Lab over the water, so it follows turbidity and sun gradients) gives
   every pixel its brightness and colour difference from the water around it.
2. Structures over/adjacent to water differ from that model. Piers are the long thin ones with water
   on both sides (``piers.py``); boats are bright or coloured cores grown by watershed into the weaker
   object pixels (boats moored side by side split at their dark gaps; squat blobs are re-seeded at
   distance-transform peaks; pieces of one boat on one axis are joined). Each segment becomes an
   oriented box filtered by size in metres and by contact with open water, its axis snapped to its
   pier's direction (or the perpendicular) when close. Lone specks in open water are buoys.
3. Vehicles: car-narrow bright/dark/coloured bodies (top-hat, black-hat, chroma top-hat) on land,
   standing on grey smooth ground, not on pier blocks and not beside tree canopies (shadows); blobs
   holding a row of cars are cut by the car-size prior.
4. Heading from the silhouette (``heading.py``) and the pier context.
Work is done at ``work_gsd_m`` (finer images are downsampled), so time grows with area only.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..classes import GRASS, TREES, WATER
from ..config import DetectConfig
from ..frames import wrap_half_deg, yaw_from_direction_px
from ..types import ClassMap, Detection, GeoImage
from . import heading as hd
from .piers import add_angles, component_axes, deck_spines, detect_piers, dominant_angles, labels_in


def _resize(a: np.ndarray, shape: tuple[int, int], nearest: bool = False) -> np.ndarray:
    import cv2

    h, w = shape
    if a.shape[:2] == (h, w):
        return a
    interp = cv2.INTER_NEAREST if nearest else cv2.INTER_AREA if a.shape[0] > h else cv2.INTER_LINEAR
    return cv2.resize(a, (w, h), interpolation=interp)


def _smooth_masked(values: np.ndarray, weight: np.ndarray, sigma_px: float) -> np.ndarray:
    """Normalised convolution: the weighted local mean of ``values`` (H, W, C) with a Gaussian of
    ``sigma_px``, computed on a coarse grid (a large blur) and brought back."""
    import cv2

    h, w = weight.shape
    f = max(1, int(sigma_px / 4))
    sh, sw = max(1, h // f), max(1, w // f)
    vs = cv2.resize(values * weight[..., None], (sw, sh), interpolation=cv2.INTER_AREA)
    ws = cv2.resize(weight, (sw, sh), interpolation=cv2.INTER_AREA)
    # where no water is near at all, fall back to the global water mean (area resizing keeps the sums)
    glob = vs.reshape(-1, values.shape[2]).sum(0) / max(float(ws.sum()), 1e-6) if ws.sum() > 0 else \
        np.zeros(values.shape[2], np.float32)
    s = sigma_px / f
    vs = cv2.GaussianBlur(vs, (0, 0), s)
    ws = cv2.GaussianBlur(ws, (0, 0), s)
    m = vs / np.maximum(ws, 1e-4)[..., None]
    m[ws < 1e-3] = glob
    return cv2.resize(m, (w, h), interpolation=cv2.INTER_LINEAR), ws


def _fill_holes(mask: np.ndarray, max_area_px: float) -> np.ndarray:
    """Fill holes (dark cockpits, windows) smaller than ``max_area_px`` in a uint8 mask."""
    import cv2

    inv = (mask == 0).astype(np.uint8)
    n, lbl, st, _ = cv2.connectedComponentsWithStats(inv, connectivity=4)
    small = np.zeros(n, bool)
    small[1:] = st[1:, cv2.CC_STAT_AREA] <= max_area_px
    return (mask.astype(bool) | small[lbl]).astype(np.uint8)


def _watershed(strength: np.ndarray, markers: np.ndarray, region: np.ndarray) -> np.ndarray:
    """Grow ``markers`` (int32 labels, 0 = unknown) over ``region`` along ``strength`` (higher = more
    object) with OpenCV's watershed; pixels outside the region stay 0, ridge pixels join a neighbour."""
    import cv2

    s = cv2.GaussianBlur(strength.astype(np.float32), (0, 0), 1.0)
    g = np.clip(255.0 - np.clip(s, 0, 255), 0, 255).astype(np.uint8)  # low = object centre
    img = cv2.merge([g, g, g])
    m = markers.astype(np.int32).copy()
    bg = int(m.max()) + 1
    m[~region] = bg
    cv2.watershed(img, m)
    m[(m == bg) | ~region] = 0
    ridge = m < 0
    if ridge.any():  # the 1-px ridges between basins: give them to the larger neighbour label
        m[ridge] = 0
        m = np.maximum(m, cv2.dilate(m.astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.int32) * ridge)
    return m


def _find_objects(labels: np.ndarray):
    """(label, (row slice, col slice)) of every positive label, like scipy.ndimage.find_objects."""
    rr, cc = np.nonzero(labels > 0)
    if rr.size == 0:
        return []
    lv = labels[rr, cc]
    n = int(lv.max()) + 1
    r0, c0 = np.full(n, 1 << 30), np.full(n, 1 << 30)
    r1, c1 = np.full(n, -1), np.full(n, -1)
    np.minimum.at(r0, lv, rr)
    np.minimum.at(c0, lv, cc)
    np.maximum.at(r1, lv, rr)
    np.maximum.at(c1, lv, cc)
    return [(k, (slice(int(r0[k]), int(r1[k]) + 1), slice(int(c0[k]), int(c1[k]) + 1)))
            for k in range(1, n) if r1[k] >= 0]


def _merge_fragments(dets: list[Detection], max_len_px: float, gap_px: float) -> list[Detection]:
    """Join the pieces of one boat split at a dark cockpit or canopy: two boxes on one axis, end to
    end (not side by side), whose union is no wider than the wider piece."""
    from ..frames import direction_px

    items = sorted(dets, key=lambda d: -d.length_px * d.width_px)
    changed = True
    while changed and len(items) > 1:
        changed = False
        xy = np.array([[d.cx_px, d.cy_px] for d in items])
        reach = np.array([d.length_px for d in items]) / 2
        dist = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
        near = dist <= reach[:, None] + reach[None, :] + gap_px
        used = np.zeros(len(items), bool)
        merged: list[Detection] = []
        for i in range(len(items)):
            if used[i]:
                continue
            a = items[i]
            f = np.array(direction_px(a.yaw_deg))
            lft = np.array([-f[1], f[0]])
            for j in np.nonzero(near[i])[0]:
                if j <= i or used[j]:
                    continue
                b = items[j]
                if abs(wrap_half_deg(a.yaw_deg - b.yaw_deg)) > 20.0:
                    continue
                bu = (b.corners_px() - [a.cx_px, a.cy_px]) @ f
                gap = max(0.0, bu.min() - a.length_px / 2, -a.length_px / 2 - bu.max())
                if gap > gap_px:
                    continue
                pts = np.vstack([a.corners_px(), b.corners_px()]) - [a.cx_px, a.cy_px]
                u, v = pts @ f, pts @ lft
                L, W = float(np.ptp(u)), float(np.ptp(v))
                if W > 1.2 * max(a.width_px, b.width_px) or L > max_len_px:
                    continue
                if a.length_px * a.width_px + b.length_px * b.width_px < 0.55 * L * W:
                    continue  # the pieces would leave a big hole: two boats, not one
                c = np.array([a.cx_px, a.cy_px]) + f * (u.max() + u.min()) / 2 + lft * (v.max() + v.min()) / 2
                a = replace(a, cx_px=float(c[0]), cy_px=float(c[1]), length_px=L, width_px=W,
                            score=max(a.score, b.score), mask=None, mask_origin_px=None)
                used[j] = True
                changed = True
                break
            used[i] = True
            merged.append(a)
        items = sorted(merged, key=lambda d: -d.length_px * d.width_px)
    return items


def _drop_contained(dets: list[Detection], ioa: float) -> list[Detection]:
    """Drop fragments: boxes lying mostly (``ioa`` of their area) inside a larger box."""
    from .nms import polygon_ioa

    order = sorted(dets, key=lambda d: -d.length_px * d.width_px)
    if not order:
        return []
    xy = np.array([[d.cx_px, d.cy_px] for d in order])
    half = np.array([d.length_px / 2 for d in order])
    corners = [d.corners_px() for d in order]
    kept: list[int] = []
    for i in range(len(order)):
        if kept:
            k = np.asarray(kept)
            close = np.abs(xy[k] - xy[i]).max(1) < half[k] + half[i] + 1
            if any(polygon_ioa(corners[i], corners[j]) > ioa for j in k[close]):
                continue
        kept.append(i)
    return [order[i] for i in kept]


def _ring_fraction(mask: np.ndarray, cx: float, cy: float, length: float, width: float, yaw: float,
                   off: float) -> float:
    """Fraction of ``mask`` on 24 points of a rectangle ``off`` pixels outside a box (work pixels)."""
    f = np.array([np.cos(np.deg2rad(yaw)), -np.sin(np.deg2rad(yaw))])
    lft = np.array([-f[1], f[0]])
    hl, hw = length / 2 + off, width / 2 + off
    t = np.linspace(-1, 1, 6)
    pts = np.concatenate([
        [[cx, cy] + f * hl * s + lft * hw * ti for ti in t] for s in (-1, 1)] + [
        [[cx, cy] + lft * hw * s + f * hl * ti for ti in t] for s in (-1, 1)])
    h, w = mask.shape
    c, r = pts[:, 0].astype(int), pts[:, 1].astype(int)
    ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
    return float(mask[r[ok], c[ok]].mean()) if ok.any() else 0.0


def _local_std(x: np.ndarray, k: int) -> np.ndarray:
    import cv2

    m = cv2.blur(x, (k, k))
    m2 = cv2.blur(x * x, (k, k))
    return np.sqrt(np.maximum(m2 - m * m, 0.0))


PIER_NET_P = 0.5  # a pixel the pier-deck network gives at least this probability is a deck
# (it runs on images no coarser than its card's max_gsd_m: ``PierNet.max_gsd_m``)
PIER_NET_CLOSE_M = 1.0  # gaps in the network's decks up to twice this are closed
PIER_NET_NOT_DECK_P = 0.1  # structure the network gives less than this is no deck


class ClassicalDetector:
    """Water model → piers (line openings) → boats (marker watershed) → vehicles (local contrast)."""

    def __init__(self, config: DetectConfig | None = None, work_gsd_m: float | None = None, debug: bool = False,
                 **_opts):
        self.config = config or DetectConfig()
        self.work_gsd_m = float(work_gsd_m if work_gsd_m is not None else self.config.work_gsd_m)
        self.debug = debug
        self.layers: dict[str, np.ndarray] = {}
        self._pier_net: Any = None

    def pier_net(self):
        """The pier-deck network (loaded once per detector)."""
        if self._pier_net is None:
            from .pier_net import PierNet

            self._pier_net = PierNet()
        return self._pier_net

    # ------------------------------------------------------------------------------------ water
    def water_mask(self, lab: np.ndarray, gsd: float, class_map: ClassMap | None) -> np.ndarray:
        shape = lab.shape[:2]
        if class_map is not None:
            return _resize(class_map.ids, shape, nearest=True) == WATER
        return self.photometric_water(lab, gsd)

    def photometric_water(self, lab: np.ndarray, gsd: float) -> np.ndarray:
        """Smooth, water-coloured, not bright, in large connected areas (OpenCV 8-bit Lab)."""
        import cv2

        L, a, b = lab[..., 0], lab[..., 1], lab[..., 2]
        cfg_chroma = self.config.water_min_chroma
        k = max(3, int(round(1.5 / gsd)) | 1)
        sd = _local_std(L, k)
        # water is smooth, not neutral grey (asphalt) and not bright (roofs, concrete, foam)
        chroma_dir = ((a < 124.0) | (b < 124.0)) & (np.hypot(a - 128.0, b - 128.0) > cfg_chroma)
        cand = (sd < 4.0) & chroma_dir & (L < 200.0)
        if gsd > 2.0:
            # satellite scale: waves make the sea textured; it is the darkest large surface there
            cand = (sd < 10.0) & (L < min(70.0, float(np.percentile(L, 30)) + 8.0)) & (np.hypot(a - 128.0, b - 128.0) < 25)
        n, lbl, st, _ = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=4)
        keep = np.zeros(n, bool)
        keep[1:] = st[1:, cv2.CC_STAT_AREA] * gsd * gsd >= self.config.min_water_area_m2
        return keep[lbl]

    # ------------------------------------------------------------------------------------ main
    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0,
               vehicles: bool = True) -> list[Detection]:
        """Piers, boats, buoys and (``vehicles=False``: not) vehicles; see the module doc. The hybrid
        detector takes its vehicles from the network and skips them here (speed)."""
        import cv2

        rgb_full = image.rgb
        H, W = rgb_full.shape[:2]
        gsd_full = image.grid.gsd_m
        scale = min(1.0, gsd_full / self.work_gsd_m)  # work pixels per image pixel
        wh, ww = max(8, int(round(H * scale))), max(8, int(round(W * scale)))
        scale_r, scale_c = wh / H, ww / W
        scale = (scale_r + scale_c) / 2.0
        gsd = gsd_full / scale
        rgb = _resize(rgb_full, (wh, ww))
        lab = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2LAB).astype(np.float32)

        water0 = self.water_mask(lab, gsd, class_map)
        self.water_work, self.work_scale = water0, scale  # kept for the hybrid detector's land check
        self._afloat = None
        dets: list[Detection] = []
        if water0.sum() * gsd * gsd >= self.config.min_water_area_m2:
            dets += self._water_objects(rgb, lab, water0, gsd, scale)
        afloat = self._afloat  # structures over water (boats, piers): no cars there
        if vehicles:
            land_cm = None
            if class_map is not None:
                land_cm = _resize(class_map.ids, (wh, ww), nearest=True)
            dets += self._vehicles(rgb, lab, water0, land_cm, gsd, scale, afloat)
        # heading on the full-resolution image (masks are in work pixels: rescale the boxes' masks)
        out = []
        for d in dets:
            if d.category in ("boat", "vehicle"):
                m, o = d.mask, d.mask_origin_px
                if m is not None and scale < 0.999:  # the work mask brought to image pixels
                    mh, mw = m.shape
                    m = cv2.resize(m.astype(np.uint8), (max(1, round(mw / scale)), max(1, round(mh / scale))),
                                   interpolation=cv2.INTER_NEAREST).astype(bool)
                    o = (int(round(o[0] / scale)), int(round(o[1] / scale)))
                    d = replace(d, mask=m, mask_origin_px=o)
                d = hd.resolve_heading(rgb_full, d, m, o)
            out.append(d)
        return hd.pier_context(out)

    # ------------------------------------------------------------------------------------ water objects
    def _water_objects(self, rgb, lab, water0, gsd, scale) -> list[Detection]:
        import cv2

        cfg = self.config
        wmodel, _wsupport = _smooth_masked(lab, water0.astype(np.float32), cfg.water_model_m / gsd)
        # a class map calls the water under boats and piers water (it is the terrain there): in a dense
        # marina the model then learns the boats' colour and the piers between them vanish. Refit once
        # on the pixels that look like the first model's water.
        out1 = (lab[..., 0] - wmodel[..., 0] > cfg.struct_dl) | (
            np.hypot(lab[..., 1] - wmodel[..., 1], lab[..., 2] - wmodel[..., 2]) > cfg.struct_dc)
        support = water0 & ~out1
        if support.sum() >= 0.5 * water0.sum():
            wmodel, _wsupport = _smooth_masked(lab, support.astype(np.float32), cfg.water_model_m / gsd)
        dL = lab[..., 0] - wmodel[..., 0]
        dc = np.hypot(lab[..., 1] - wmodel[..., 1], lab[..., 2] - wmodel[..., 2])
        dist_w = cv2.distanceTransform((~water0).astype(np.uint8), cv2.DIST_L2, 3) * gsd
        near = dist_w < max(cfg.near_water_m, 5 * gsd)  # at least a few pixels at satellite scale
        # 'structure': anything brighter or of another colour than the water; shadows (darker, same
        # hue) are not structure
        struct = ((dL > cfg.struct_dl) | ((dc > cfg.struct_dc) & (dL > -cfg.struct_dl))) & near
        buoys = self._buoys(struct, water0, dL, dc, gsd, scale)
        struct = cv2.morphologyEx(struct.astype(np.uint8), cv2.MORPH_OPEN, np.ones((2, 2), np.uint8)).astype(bool)
        # land: big structure blobs far from water are not piers or boats
        land = ~water0 & (dist_w > 0) & ~near
        # the pier-deck network's decks (a deck coloured like the water, dark timber) join the structure the piers
        # are searched in, and the structure it is sure is no deck (the boats moored alongside: merged with the
        # deck they make a blob too wide for one) leaves it (``detect.pier_net``)
        pier_struct = struct
        deck = None
        if cfg.pier_net and gsd <= self.pier_net().max_gsd_m:
            prob = self.pier_net().probability(rgb, gsd, struct.shape)
            deck = (prob >= PIER_NET_P) & near
            # a boat moored over a deck's edge breaks it for a metre or two: closed (fingers lie further apart)
            r = max(1, int(round(PIER_NET_CLOSE_M / gsd)))
            deck = cv2.morphologyEx(deck.astype(np.uint8), cv2.MORPH_CLOSE,
                                    cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))).astype(bool)
            pier_struct = deck | (struct & (prob >= PIER_NET_NOT_DECK_P))
        angles = dominant_angles(pier_struct & ~cv2.dilate(land.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool))
        if deck is not None:  # the network's decks give their own directions
            add_angles(angles, component_axes(deck, cfg.finger_min_m / gsd))
        # walkways on a coarser grid (line openings cost ~area x angles), fingers on the work grid
        pf = max(1, min(int(cfg.pier_gsd_m / gsd), 4))
        piers, pier_mask = detect_piers(pier_struct & ~land, gsd, scale, angles, water=water0,
                                        walkway_min_m=cfg.walkway_min_m, walkway_max_width_m=cfg.walkway_max_width_m,
                                        finger_min_m=cfg.finger_min_m, finger_max_width_m=cfg.finger_max_width_m,
                                        walk_factor=pf, longest_run=deck is not None)
        if deck is not None and cfg.deck_spines:
            # deck the straight openings did not explain (a curved walkway): walkways along its spine
            k = 2 * max(1, int(round(1.5 / gsd))) + 1
            covered = cv2.dilate(pier_mask.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
            spines = deck_spines(deck & ~land, covered, gsd, scale, water=water0,
                                 walkway_min_m=cfg.walkway_min_m, walkway_max_width_m=cfg.walkway_max_width_m)
            drawn = pier_mask.astype(np.uint8)
            for d in spines:
                cv2.fillPoly(drawn, [np.round(d.corners_px() * scale).astype(np.int32)], 1)
            pier_mask = drawn.astype(bool)
            piers = piers + spines
        # boats: bright or coloured cores, grown into the weaker object pixels
        pier_d = cv2.dilate(pier_mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        if cfg.boat_mask == "struct":
            core = struct & ~pier_d
        elif cfg.boat_mask == "region":
            core = ((dL > cfg.boat_region_dl) | ((dc > cfg.boat_region_dc) & (dL > -5))) & near & ~pier_d
        else:
            # on light water a white boat cannot be 70 brighter: cap the step by the headroom
            core_dl = np.minimum(cfg.boat_core_dl, cfg.boat_core_headroom * (255.0 - wmodel[..., 0]))
            core = ((dL > core_dl) | ((dc > cfg.boat_core_dc) & (dL > -5))) & near & ~pier_d
        r = int(round(cfg.boat_open_m / gsd))
        core = _fill_holes(core.astype(np.uint8), (cfg.min_boat_width_m / gsd) ** 2 * 2)
        if r >= 1:  # at satellite scale a ship is a few pixels wide: no opening
            se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
            core = cv2.morphologyEx(core, cv2.MORPH_OPEN, se)
        region = ((dL > cfg.boat_region_dl) | (dc > cfg.boat_region_dc)) & near & ~pier_mask
        region = (region | core.astype(bool))
        n, markers = cv2.connectedComponents(core, connectivity=8)
        # weak boundaries between touching boats: split by distance-transform peaks within big cores
        markers = self._split_markers(core, markers, n, gsd)
        labels = _watershed(dL + dc, markers, region)
        # water at object precision: near the water and like it (the rough mask has a halo round objects)
        water_fine = (water0 | (near & ~struct)) & ~((dL > cfg.struct_dl) | (dc > cfg.struct_dc * 1.5))
        dist_fine = cv2.distanceTransform((~water_fine).astype(np.uint8), cv2.DIST_L2, 3) * gsd
        mainland = self._mainland(water_fine, dist_fine, gsd)
        land_lbl = self._land_labels(labels, mainland)
        # what floats: structure near water that is not the mainland (pier blocks with their boats)
        afloat = struct & ~mainland
        k = max(3, int(round(2.0 / gsd)) | 1)
        self._afloat = cv2.dilate(afloat.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
        dets = self._boxes(labels, land_lbl, dL, gsd, scale, angles, dist_w)
        if self.debug:
            self.layers.update(water=water0, struct=struct, pier=pier_mask, core=core.astype(bool), labels=labels)
        dets = self._snap_to_piers(dets, [p for p in piers if p.category == "pier_walkway"], gsd / scale)
        return piers + dets + buoys

    def _buoys(self, struct, water0, dL, dc, gsd, scale) -> list[Detection]:
        """Buoys: tiny bright or coloured specks alone in open water."""
        import cv2

        cfg = self.config
        n, lbl, st, cen = cv2.connectedComponentsWithStats(struct.astype(np.uint8), connectivity=8)
        amin, amax = cfg.buoy_min_area_m2 / gsd ** 2, cfg.buoy_max_area_m2 / gsd ** 2
        # open water around: the rough water mask (which has a halo round every object) within a ring
        ring = max(2, int(round(cfg.buoy_clear_m / gsd)))
        out = []
        h, w = struct.shape
        for k in range(1, n):
            x, y, ww_, hh_, area = st[k]
            if not (max(1.0, amin) <= area <= amax) or max(ww_, hh_) * gsd > cfg.buoy_max_area_m2 ** 0.5 * 2:
                continue
            x0, y0, x1, y1 = max(0, x - ring), max(0, y - ring), min(w, x + ww_ + ring), min(h, y + hh_ + ring)
            win = struct[y0:y1, x0:x1] & (lbl[y0:y1, x0:x1] != k)
            if win.any():
                continue  # something else close by: part of a boat or pier
            wat = water0[y0:y1, x0:x1]
            if wat.mean() < 0.5:
                continue
            sl = lbl[y:y + hh_, x:x + ww_] == k
            contrast = float(max(dL[y:y + hh_, x:x + ww_][sl].max(), dc[y:y + hh_, x:x + ww_][sl].max()))
            if contrast < cfg.buoy_contrast:
                continue
            cx, cy = cen[k]
            size = max(ww_, hh_, 1.5)
            out.append(Detection("buoy", float(np.clip(0.3 + contrast / 200.0, 0, 0.9)), (cx + 0.5) / scale,
                                 (cy + 0.5) / scale, size / scale, size / scale, 0.0))
        return out

    def _snap_to_piers(self, boats: list[Detection], walkways: list[Detection], gsd_img: float) -> list[Detection]:
        """Boats moor parallel or perpendicular to their pier: snap each boat's axis to its nearest
        walkway's axis (or the perpendicular) when within ``snap_deg``."""
        if not walkways or not boats:
            return boats
        from shapely.geometry import LineString, Point

        lines = []
        for w in walkways:
            c = w.corners_px()
            lines.append(LineString([(c[0] + c[3]) / 2, (c[1] + c[2]) / 2]))
        out = []
        for b in boats:
            p = Point(b.cx_px, b.cy_px)
            dist = [ln.distance(p) for ln in lines]
            j = int(np.argmin(dist))
            if dist[j] > max(b.length_px, self.config.snap_radius_m / gsd_img):
                out.append(b)
                continue
            yaw = b.yaw_deg
            best, bd = yaw, self.config.snap_deg
            for a in (walkways[j].yaw_deg, walkways[j].yaw_deg + 90.0):
                d = abs(wrap_half_deg(yaw - a))
                if d < bd:
                    best, bd = float(wrap_half_deg(a)), d
            if best != yaw:
                b = self._refit(b, best)
            out.append(b)
        return out

    @staticmethod
    def _refit(b: Detection, yaw: float) -> Detection:
        """The box re-measured along a new axis: the extent of its old corners along that axis
        (a snap moves the axis by a few degrees, so this stays tight)."""
        f = np.array([np.cos(np.deg2rad(yaw)), -np.sin(np.deg2rad(yaw))])
        lft = np.array([-f[1], f[0]])
        if b.mask is not None and b.mask_origin_px is not None:
            rr, cc = np.nonzero(b.mask)
            pts = np.stack([cc + b.mask_origin_px[0] + 0.5, rr + b.mask_origin_px[1] + 0.5], 1)
            scale = b.length_px / max(1.0, float(np.ptp(pts @ np.array([np.cos(np.deg2rad(b.yaw_deg)),
                                                                          -np.sin(np.deg2rad(b.yaw_deg))]))) + 1.0)
            if not 0.8 < scale < 1.25:  # the mask is on another grid: keep the measured size
                return replace(b, yaw_deg=yaw)
        else:
            return replace(b, yaw_deg=yaw)
        rel = pts - [b.cx_px, b.cy_px]
        u, v = rel @ f, rel @ lft
        c = np.array([b.cx_px, b.cy_px]) + f * (u.max() + u.min()) / 2 + lft * (v.max() + v.min()) / 2
        return replace(b, cx_px=float(c[0]), cy_px=float(c[1]), length_px=float(np.ptp(u) + 1.0),
                       width_px=float(np.ptp(v) + 1.0), yaw_deg=yaw)

    def _split_markers(self, core, markers, n, gsd):
        """Cores larger than one boat are re-seeded at distance-transform maxima (side-by-side boats)."""
        import cv2

        cfg = self.config
        area_max = cfg.split_area_m2 / (gsd * gsd)
        out = markers.copy()
        nxt = n
        _n, _l, st, _c = cv2.connectedComponentsWithStats((markers > 0).astype(np.uint8), connectivity=8)
        half_w = cfg.min_boat_width_m / 2.0 / gsd
        ksz = max(3, int(2 * half_w * 1.6) | 1)
        for k in range(1, n):
            x, y, w, h, area = st[k] if k < len(st) else (0, 0, 0, 0, 0)
            if area < area_max:
                continue
            sl = (slice(y, y + h), slice(x, x + w))
            m = markers[sl] == k
            # one boat is elongated and fills its rectangle; rafted boats make squat or ragged blobs
            pts = np.stack(np.nonzero(m)[::-1], 1).astype(np.float32)
            (_c, (ra, rb), _a) = cv2.minAreaRect(pts)
            ra, rb = max(ra, rb) + 1, min(ra, rb) + 1
            if ra / rb >= cfg.split_max_aspect and ra * gsd < cfg.max_boat_length_m * 0.6:
                continue
            # pad with background: a blob filling its window would otherwise have no distance reference
            dt = cv2.distanceTransform(np.pad(m, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1]
            ksz = max(3, int(1.6 * float(dt.max())) | 1)
            peaks = (dt >= max(half_w, 0.6 * float(dt.max()))) & (dt >= cv2.dilate(dt, np.ones((ksz, ksz), np.uint8)) - 0.5)
            np_, pl = cv2.connectedComponents(peaks.astype(np.uint8), connectivity=8)
            np_ -= 1
            if np_ < 2:
                continue
            sub = out[sl]
            sub[m] = 0
            sub[pl > 0] = pl[pl > 0] + nxt
            nxt += np_
        return out

    def _mainland(self, water0, dist_w, gsd) -> np.ndarray:
        """Land proper: non-water regions (after cutting thin walkways) that reach far from the water.
        Pier-and-boat blocks are surrounded by water and never reach that far."""
        import cv2

        r = max(1, int(round(self.config.mainland_cut_m / gsd)))
        se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        nw = cv2.morphologyEx((~water0).astype(np.uint8), cv2.MORPH_OPEN, se)
        n, lbl = cv2.connectedComponents(nw, connectivity=4)
        far = dist_w > max(self.config.mainland_far_m, 6 * gsd)
        ids = np.unique(lbl[far & (lbl > 0)])
        return labels_in(lbl, ids[ids > 0], n)

    def _land_labels(self, labels, land) -> set[int]:
        """Segments that run onto land (shore, quays) are not boats."""
        if not land.any():
            return set()
        import cv2

        touch = cv2.dilate(land.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        ids, cnt = np.unique(labels[touch & (labels > 0)], return_counts=True)
        return {int(i) for i, c in zip(ids, cnt) if c > 3}

    def _boxes(self, labels, land_lbl, dL, gsd, scale, angles, dist_w) -> list[Detection]:
        import cv2

        cfg = self.config
        out: list[Detection] = []
        for k, sl in _find_objects(labels):
            if k in land_lbl:
                continue
            m = labels[sl] == k
            area = m.sum()
            if dist_w[sl][m].min() > max(cfg.boat_water_touch_m, 3 * gsd):
                continue  # a boat floats: some of it borders open water
            if area * gsd * gsd < cfg.min_boat_length_m * cfg.min_boat_width_m * 0.5:
                continue
            rr, cc = np.nonzero(m)
            pts = np.stack([cc + sl[1].start, rr + sl[0].start], 1).astype(np.float32)
            (cx, cy), (a, b), _ang = cv2.minAreaRect(pts)
            a, b = a + 1.0, b + 1.0
            length, width = max(a, b), min(a, b)
            # at satellite scale only large vessels are visible: the upper limit follows the pixel size
            if not (cfg.min_boat_length_m <= length * gsd <= max(cfg.max_boat_length_m, 40 * gsd)):
                continue
            if width * gsd < cfg.min_boat_width_m * 0.7 or not (cfg.min_boat_aspect <= length / width
                                                                <= cfg.max_boat_aspect):
                continue
            fill = area / (a * b)
            if fill < 0.45:
                continue
            # direction of the long side from the second moments (robust on blobby masks)
            yaw = self._axis_yaw(pts, (cx, cy))
            score = float(np.clip(0.4 + 0.3 * fill + 0.002 * np.median(dL[sl][m]), 0.0, 1.0))
            # length/width along the chosen axis
            f = np.array([np.cos(np.deg2rad(yaw)), -np.sin(np.deg2rad(yaw))])
            lft = np.array([-f[1], f[0]])
            rel = pts - [cx, cy]
            u, v = rel @ f, rel @ lft
            u0, u1 = u.min(), u.max()
            v0, v1 = v.min(), v.max()
            ccx, ccy = np.array([cx, cy]) + f * (u0 + u1) / 2 + lft * (v0 + v1) / 2
            length, width = u1 - u0 + 1.0, v1 - v0 + 1.0
            d = Detection("boat", score, (ccx + 0.5) / scale, (ccy + 0.5) / scale, length / scale, width / scale,
                          float(yaw), mask=m, mask_origin_px=(sl[1].start, sl[0].start))
            out.append(d)
        out = _merge_fragments(out, cfg.max_boat_length_m / (gsd * scale), cfg.merge_gap_m / (gsd * scale))
        return _drop_contained(out, 0.5)

    @staticmethod
    def _axis_yaw(pts: np.ndarray, c) -> float:
        rel = pts - np.asarray(c, dtype=np.float32)
        cov = rel.T @ rel / max(len(rel), 1)
        _w, v = np.linalg.eigh(cov)
        e = v[:, 1]
        return float(wrap_half_deg(yaw_from_direction_px(e[0], e[1])))

    # ------------------------------------------------------------------------------------ vehicles
    def _car_boxes(self, pts: np.ndarray, area: float, gsd: float) -> list[tuple]:
        """Car-sized boxes in one blob (work pixels): one car, or a row of cars parked side by side
        (the blob's short side is one car length) or nose to tail, split by the car-size prior."""
        import cv2

        cfg = self.config
        (cx, cy), (a_, b_), _ang = cv2.minAreaRect(pts)
        a_, b_ = a_ + 1.0, b_ + 1.0
        fill = area / (a_ * b_)
        if fill < 0.55:
            return []
        yaw = self._axis_yaw(pts, (cx, cy))  # along the blob's long side
        f = np.array([np.cos(np.deg2rad(yaw)), -np.sin(np.deg2rad(yaw))])
        lft = np.array([-f[1], f[0]])
        rel = pts - [cx, cy]
        u, v = rel @ f, rel @ lft
        u0, u1 = u.min(), u.max() + 1
        v0, v1 = v.min(), v.max() + 1
        c = np.array([cx, cy]) + f * (u0 + u1) / 2 + lft * (v0 + v1) / 2
        long_, short = (u1 - u0) * gsd, (v1 - v0) * gsd
        lo, hi = cfg.min_vehicle_length_m, cfg.max_vehicle_length_m
        if lo <= long_ <= min(hi, 6.5) and 1.3 <= short <= 2.8 and 1.5 <= long_ / short <= 3.6:
            return [(c[0], c[1], long_ / gsd, short / gsd, yaw, fill)]
        out = []
        if 3.4 <= short <= 6.0 and long_ >= 3.0:  # side by side: cut across the row
            n = int(round(long_ / cfg.vehicle_pitch_m))
            if n >= 2 and 1.4 <= long_ / n <= 3.0:
                step = (u1 - u0) / n
                for i in range(n):
                    p = c + f * ((i + 0.5) * step - (u1 - u0) / 2)
                    out.append((p[0], p[1], short / gsd, step * 0.85, float(wrap_half_deg(yaw + 90.0)), fill))
        elif 7.0 < long_ <= 16.0 and 1.3 <= short <= 2.8:  # two or three nose to tail (longer: a kerb)
            n = int(round(long_ / 5.0))
            if n >= 2 and lo <= long_ / n <= 6.0:
                step = (u1 - u0) / n
                for i in range(n):
                    p = c + f * ((i + 0.5) * step - (u1 - u0) / 2)
                    out.append((p[0], p[1], step * 0.9, short / gsd, yaw, fill))
        return out

    def _vehicles(self, rgb, lab, water0, class_ids, gsd, scale, afloat=None) -> list[Detection]:
        import cv2

        cfg = self.config
        if not cfg.vehicles:
            return []
        h, w = water0.shape
        dist_w = cv2.distanceTransform((~water0).astype(np.uint8), cv2.DIST_L2, 3) * gsd
        land = dist_w > cfg.vehicle_water_gap_m
        if afloat is not None:
            land &= ~afloat
        if class_ids is not None:
            land &= ~np.isin(class_ids, [WATER, GRASS, TREES])
        if land.sum() * gsd * gsd < 2.5:  # no room for a car
            return []
        # work inside the bounding box of the land (plus the filters' reach): harbours are mostly water
        reach = int(round(max(cfg.vehicle_hat_m, cfg.vehicle_shadow_m, 1.5) / gsd)) + 4
        rows, cols = np.nonzero(land.any(1))[0], np.nonzero(land.any(0))[0]
        y0, y1 = max(0, rows[0] - reach), min(h, rows[-1] + 1 + reach)
        x0, x1 = max(0, cols[0] - reach), min(w, cols[-1] + 1 + reach)
        land, lab = land[y0:y1, x0:x1], lab[y0:y1, x0:x1]
        L, a, b = lab[..., 0], lab[..., 1], lab[..., 2]
        # vegetation: greenish and textured
        veg = (a < 122.0) & (b > 130.0)
        # cars are narrower than ~2.5 m: a white top-hat / black-hat with a ~3 m disc keeps bright and
        # dark car bodies (even in tight rows, split at the gaps) and drops wide things (roofs, tree
        # shadows, lanes)
        L = lab[..., 0]
        rh = max(2, int(round(cfg.vehicle_hat_m / 2.0 / gsd)))
        se = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * rh + 1, 2 * rh + 1))  # separable: fast
        tophat = cv2.morphologyEx(L, cv2.MORPH_TOPHAT, se)
        blackhat = cv2.morphologyEx(L, cv2.MORPH_BLACKHAT, se)
        # coloured cars as bright as the asphalt (a red car): a top-hat of the chroma, on the same scale
        chroma = np.hypot(a - 128.0, b - 128.0).astype(np.float32)
        colourhat = cv2.morphologyEx(chroma, cv2.MORPH_TOPHAT, se) * (cfg.vehicle_dl / cfg.vehicle_dc)
        r = max(1, int(round(0.2 / gsd)))
        se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        # cars stand on paved ground: grey (low chroma) and smooth around them, unlike tree shadows on
        # grass, benches on dirt or details of sports courts
        ks = max(3, int(round(1.5 / gsd)) | 1)
        paved = (np.hypot(a - 128.0, b - 128.0) < cfg.vehicle_ground_chroma) & (_local_std(L, ks) < 20.0)
        out: list[Detection] = []
        cand_all = np.zeros(L.shape, bool)
        # dark blobs beside tree canopies are mostly their shadows
        kv = max(3, int(round(cfg.vehicle_shadow_m / gsd)) | 1)
        veg_near = cv2.dilate(veg.astype(np.uint8), np.ones((kv, kv), np.uint8)).astype(bool)
        for diff, extra in ((tophat, None), (blackhat, veg_near), (colourhat, None)):
            # bright and dark bodies separately: the gaps between bright cars are 'dark' and vice versa
            cand = (diff > cfg.vehicle_dl) & land & ~veg
            if extra is not None:
                cand &= ~extra
            cand = _fill_holes(cand.astype(np.uint8), (1.2 / gsd) ** 2)  # dark windows in a white body
            cand = cv2.morphologyEx(cand, cv2.MORPH_OPEN, se)
            cand_all |= cand.astype(bool)
            n, lbl, st, _cen = cv2.connectedComponentsWithStats(cand, connectivity=8)
            for k in range(1, n):
                x, y, ww_, hh_, area = st[k]
                if area * gsd * gsd < 2.5 or area * gsd * gsd > 400.0:  # up to a row of ~30 cars
                    continue
                m = lbl[y:y + hh_, x:x + ww_] == k
                rr, cc = np.nonzero(m)
                pts = np.stack([cc + x, rr + y], 1).astype(np.float32)
                contrast = float(np.median(diff[y:y + hh_, x:x + ww_][m]))
                for cx, cy, length, width, yaw, fill in self._car_boxes(pts, area, gsd):
                    if _ring_fraction(paved, cx, cy, length, width, yaw, 1.0 / gsd) < cfg.vehicle_ground_frac:
                        continue
                    score = float(np.clip(0.3 + 0.5 * fill * min(1.0, contrast / 60.0), 0, 1))
                    out.append(Detection("vehicle", score, (x0 + cx + 0.5) / scale, (y0 + cy + 0.5) / scale,
                                         length / scale, width / scale, yaw))
        from .nms import rotated_nms

        out = rotated_nms(out, 0.2, ioa_threshold=0.6)
        if self.debug:  # debug layers on the whole work grid
            cand = np.zeros((h, w), bool)
            cand[y0:y1, x0:x1] = cand_all
            diff = np.zeros((h, w), np.float32)
            diff[y0:y1, x0:x1] = np.maximum(tophat, blackhat)
            self.layers.update(vehicle_cand=cand, vehicle_diff=diff)
        return out
