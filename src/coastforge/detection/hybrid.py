"""The ``hybrid`` detector: the learned network for boats, vehicles and buoys, the classical detector for piers.

The learned network (trained on coastforge's renders and the real sets' training splits) is far better on
rendered scenes (orientation 0.5-1.3° vs 25°) and on real harbour photos than the classical detector; it
does not detect piers. Its boats are not checked against the classical detector's own water mask: on real
harbour photos that mask misses much of the water and vetoed true boats (ships_aerial training split:
recall 0.53 with the check, 0.70 without). With a class map, ``coastforge.consistency`` decides boats
far from water (the segmenter's water, corrected by the boats themselves).

``union=True`` (``DetectConfig.hybrid_union``, on in the default preset) also keeps classical boats that no
learned box overlaps or mostly contains, when they pass these checks:

- **support**: the net also sees a boat there, if weakly (one of its boat peaks with a score of at least
  ``DetectConfig.hybrid_support`` lies inside the box). On the synthetic levels nearly every classical-only
  boat is a pier deck, a cabin or a sliver beside a boat, with no such peak; on the real marina the net's
  weak peaks confirm most of the true ones it missed (dark and unusual hulls).
- **not a deck** (``_not_decks``): wide pier heads and fingers of planks or concrete are uniform and
  coloured like the piers.
- **afloat** (``_afloat``, when a class map is given): the class map calls the box's core water, not the
  boulders of a riprap bank.

The net's boats and the classical pier boxes are checked against each other: an unsure boat over most of a
pier box gives way to it (``_off_piers``), a pier box more than a third under sure boats goes (``_piers_off_boats``).

On the real DOTA marina (also used to choose the union's rules) this takes recall from 0.63 to 0.89 at a
precision of 0.85 (0.97 outside the right strip DOTA labelled only partly; 0.92 at 0.87 with the class
map); on synthetic levels of seeds 0-2 it adds one or two false boats per resolution to the net's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..classes import WATER
from ..config import DetectConfig
from ..types import ClassMap, Detection, GeoImage
from .nms import centres_inside

PIERS = ("pier_walkway", "pier_finger")
UNION_IOA = 0.3
# classical-only boats (union): a core this uniform (std of OpenCV Lab L, 0-255) or coloured this close
# to the pier decks (Lab distance) is a deck, not a boat; see ``_not_decks``. Synthetic false ones:
# std 6-20 or distance <= 6.8; real marina true ones: std >= 40, distance >= 6.4
DECK_MAX_STD_L, DECK_MAX_DE = 20.0, 6.0
AFLOAT_MIN_WATER = 0.5  # see ``_afloat``
# a boat lying over more than this share of a pier box contradicts it; when the boat is also under
# SURE_BOAT_SCORE, the pier wins (see ``_off_piers``)
BOAT_OVER_PIER, SURE_BOAT_SCORE = 0.5, 0.5
# a pier box more than this share under sure boats is no pier (``_piers_off_boats``): boats moor beside
# fingers and walkways, so their boxes overlap a deck's edges only (a 2 m finger with boxes 0.3 m over it from
# both sides: 0.3); renders of seeds 0-1: no pier box more than 0.06 under sure boats
PIER_UNDER_BOATS = 1.0 / 3.0


def classical_part(image: GeoImage, class_map: ClassMap | None, config: DetectConfig, seed: int = 0,
                   detector=None) -> list[Detection]:
    """The classical detections the hybrid uses (module level: ``generate`` runs it in its side process while
    the network runs here, and hands the future to ``HybridDetector(classical_dets=...)``)."""
    from .classical import ClassicalDetector
    from .learned import MAX_GSD_M, MIN_GSD_M

    in_range = MIN_GSD_M <= image.grid.gsd_m <= MAX_GSD_M
    det = detector if detector is not None else ClassicalDetector(config)
    # in range, only the classical piers and boats are used: its vehicles are skipped (speed)
    return det.detect(image, class_map, seed, vehicles=not in_range)


class HybridDetector:
    def __init__(self, config: DetectConfig | None = None, weights: str | None = None, union: bool | None = None,
                 classical_dets=None, **_opts):
        """``classical_dets``: a future of ``classical_part`` for the same image, class map and seed."""
        from .classical import ClassicalDetector
        from .learned import LearnedDetector

        self.config = config or DetectConfig()
        self.learned = LearnedDetector(self.config, weights=weights)
        self.classical = ClassicalDetector(self.config)
        self.union = self.config.hybrid_union if union is None else bool(union)
        self._classical_dets = classical_dets

    def _classical(self, image: GeoImage, class_map: ClassMap | None, seed: int) -> list[Detection]:
        if self._classical_dets is not None:
            from concurrent.futures.process import BrokenProcessPool

            try:
                return self._classical_dets.result()
            except BrokenProcessPool:  # the process computing them died: compute them here
                pass
        return classical_part(image, class_map, self.config, seed, self.classical)

    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0) -> list[Detection]:
        from .learned import MAX_GSD_M, MIN_GSD_M
        from .nms import rotated_nms

        in_range = MIN_GSD_M <= image.grid.gsd_m <= MAX_GSD_M
        if not in_range:  # e.g. satellite ports at 10 m/px: outside what the network was trained on
            return self._classical(image, class_map, seed)
        support = float(self.config.hybrid_support)
        floor = support if self.union and support > 0 else None
        learned = self.learned.detect(image, class_map, seed, floor=floor)
        classical = self._classical(image, class_map, seed)  # after the network: it may be computing elsewhere
        strong = [d for d in learned if self.learned.is_confident(d)] if floor is not None else learned
        piers = [d for d in classical if d.category in PIERS]
        # a boat and a pier box over each other cannot both be right: the weaker evidence gives way
        objects = _off_piers(strong, piers)
        piers = _piers_off_boats(piers, objects)
        if not self.union:
            return objects + piers
        extra = [d for d in classical if d.category == "boat"]
        if floor is not None:
            # a classical boat is kept only where the net also sees a boat, if weakly (score >= support):
            # on the synthetic levels nearly every classical-only boat is a pier deck, a cabin or a
            # sliver beside a boat; on the real marina the net's weak peaks confirm most true ones
            weak = [d for d in learned if d.category == "boat"]
            extra = _defragment(_supported(extra, weak), weak)
        extra = _not_decks(image.rgb, extra, piers)
        extra = _off_big_vessels(extra, objects, image.grid.gsd_m)
        extra = _afloat(extra, class_map, image.grid.width_px, image.grid.height_px)
        if floor is not None:
            extra = _net_axes(extra, weak)
        # learned boxes first, so on overlap the learned box (better orientation and heading) survives;
        # a classical box lying mostly inside a learned one is a piece of the same boat (a cabin, a
        # deck split by shadow) and goes too (docs/benchmarks.md, "detection: hybrid merge")
        merged = rotated_nms([*objects, *[_demote(d) for d in extra]], self.config.nms_iou,
                             ioa_threshold=UNION_IOA)
        return merged + piers


def _off_piers(dets: list[Detection], piers: list[Detection]) -> list[Detection]:
    """``dets`` without the boats that lie over most of a pier box (BOAT_OVER_PIER of its area) while scoring
    under SURE_BOAT_SCORE: a deck cannot lie under a moored boat, so one of the two is wrong, and the boat is
    the weaker evidence (renders: a rock mole with its path, taken for a 55 m boat at 0.41, over the walkway
    the classical detector found on it; everything under a boat is later filled as water)."""
    if not piers:
        return dets
    from shapely.geometry import Polygon

    decks = [Polygon(p.corners_px()) for p in piers]
    out = []
    for d in dets:
        if d.category == "boat" and d.score < SURE_BOAT_SCORE:
            hull = Polygon(d.corners_px())
            if any(q.area > 0 and hull.intersection(q).area > BOAT_OVER_PIER * q.area for q in decks):
                continue
        out.append(d)
    return out


def _piers_off_boats(piers: list[Detection], dets: list[Detection]) -> list[Detection]:
    """``piers`` without the boxes lying more than PIER_UNDER_BOATS under boats scored SURE_BOAT_SCORE or more:
    the other side of ``_off_piers``, where the boats are the stronger evidence (a real marina of the
    ships_aerial training split: thin "walkways" drawn along the hulls of a moored row, 0.36-0.49 under boats
    scored 0.6-0.65, from which made-up connectors ran across the water to the breakwater)."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    hulls = [Polygon(d.corners_px()) for d in dets if d.category == "boat" and d.score >= SURE_BOAT_SCORE]
    if not piers or not hulls:
        return piers
    boats = unary_union(hulls)
    out = []
    for p in piers:
        deck = Polygon(p.corners_px())
        if deck.area > 0 and deck.intersection(boats).area > PIER_UNDER_BOATS * deck.area:
            continue
        out.append(p)
    return out


def _off_big_vessels(boxes: list[Detection], net: list[Detection], gsd_m: float) -> list[Detection]:
    """Classical boats not centred in a big vessel of the net (``detect.big_pass``; its box grown as there):
    the colour mask splits a big hull at its decks and superstructure."""
    from .learned import BIG_GROW, BIG_MIN_LENGTH_M

    big = [d for d in net if d.category == "boat" and d.length_px * gsd_m >= BIG_MIN_LENGTH_M]
    if not big or not boxes:
        return boxes
    hit = centres_inside(big, boxes, BIG_GROW).any(0)
    return [d for d, h in zip(boxes, hit) if not h]


def _supported_by(boxes: list[Detection], evidence: list[Detection]) -> list[Detection]:
    """The ``evidence`` boxes whose centre lies inside one of ``boxes``."""
    if not boxes or not evidence:
        return []
    hit = centres_inside(boxes, evidence).any(0)
    return [e for e, h in zip(evidence, hit) if h]


FRAGMENT_RATIO = 0.7  # a classical boat this much shorter than the net's box around it is a piece of it


def _defragment(boxes: list[Detection], net: list[Detection]) -> list[Detection]:
    """Classical boats whose centre lies in a (weak) net box at least 1 / ``FRAGMENT_RATIO`` times longer are
    pieces of that boat (its mask split at a dark deck or a shadow): the net's box replaces them."""
    if not boxes or not net:
        return boxes
    inside = centres_inside(net, boxes)  # (net, boxes)
    out = []
    for j, b in enumerate(boxes):
        around = [net[i] for i in np.flatnonzero(inside[:, j]) if b.length_px < FRAGMENT_RATIO * net[i].length_px]
        out.append(max(around, key=lambda d: d.score) if around else b)
    return out


def _net_axes(boxes: list[Detection], net: list[Detection]) -> list[Detection]:
    """A classical boat and a (weak) net box on the same boat (each one's centre inside the other, lengths
    within ``FRAGMENT_RATIO`` of each other) take the net's axis and front: the classical mask's axis
    tilts with a shadow or a neighbour's hull (real marina: two such boxes 24° and 30° off, the net's
    weak boxes there 1-2°), while its centre and size are the better ones where the net is unsure."""
    if not boxes or not net:
        return boxes
    mutual = centres_inside(net, boxes) & centres_inside(boxes, net).T  # (net, boxes)
    out = []
    for j, b in enumerate(boxes):
        same = [net[i] for i in np.flatnonzero(mutual[:, j])
                if FRAGMENT_RATIO <= b.length_px / net[i].length_px <= 1.0 / FRAGMENT_RATIO]
        if same:
            n = max(same, key=lambda d: d.score)
            b = replace(b, yaw_deg=n.yaw_deg, heading_known=n.heading_known,
                        heading_confidence=n.heading_confidence)
        out.append(b)
    return out


def _supported(boxes: list[Detection], evidence: list[Detection]) -> list[Detection]:
    """The boxes holding the centre of at least one ``evidence`` box."""
    if not boxes or not evidence:
        return []
    hit = centres_inside(boxes, evidence).any(1)
    return [b for b, h in zip(boxes, hit) if h]


def _core_pixels(img: np.ndarray, d: Detection, fu: float, fv: float) -> np.ndarray:
    """The pixels of ``img`` (H, W, C) within ``fu`` of the box's length and ``fv`` of its width
    from its centre (the box's core), as (N, C)."""
    h, w = img.shape[:2]
    c = d.corners_px()
    x0, y0 = np.clip(np.floor(c.min(0)).astype(int) - 1, 0, [w, h])
    x1, y1 = np.clip(np.ceil(c.max(0)).astype(int) + 2, 0, [w, h])
    if x1 <= x0 or y1 <= y0:
        return np.zeros((0, img.shape[2]), img.dtype)
    r = np.deg2rad(d.yaw_deg)
    f = np.array([np.cos(r), -np.sin(r)])
    yy, xx = np.mgrid[y0:y1, x0:x1]
    rx, ry = xx + 0.5 - d.cx_px, yy + 0.5 - d.cy_px
    u, v = rx * f[0] + ry * f[1], -rx * f[1] + ry * f[0]
    inside = (np.abs(u) <= fu * d.length_px) & (np.abs(v) <= fv * d.width_px)
    return img[y0:y1, x0:x1][inside]


def _not_decks(rgb: np.ndarray, boats: list[Detection], piers: list[Detection]) -> list[Detection]:
    """Classical boats that are no pier deck: a boat seen at 0.1-0.2 m/px shows a cabin, windows, a
    cockpit (its core's lightness varies by at least ``DECK_MAX_STD_L``), and it is not coloured like
    the piers (median Lab within ``DECK_MAX_DE`` of the pier boxes' median). Wide pier heads and
    fingers of planks are what the classical detector takes for boats next to the net's (synthetic
    levels, seeds 0 and 1: 26 of the 29 false classical-only boats left after the support check, not
    the one true one; on the real marina none of its 23 true ones)."""
    if not boats:
        return []
    lab = _lab_of_boxes(rgb, [*boats, *piers])
    cores = [c for c in (_core_pixels(lab, p, 0.45, 0.3) for p in piers) if len(c)]
    deck = np.median(np.concatenate(cores), 0).astype(np.float32) if cores else None
    out = []
    for b in boats:
        core = _core_pixels(lab, b, 0.35, 0.3).astype(np.float32)
        if len(core) < 4:
            continue
        if float(core[:, 0].std()) < DECK_MAX_STD_L:
            continue
        if deck is not None and float(np.linalg.norm(np.median(core, 0) - deck)) < DECK_MAX_DE:
            continue
        out.append(b)
    return out


def _afloat(boats: list[Detection], class_map: ClassMap | None, width_px: int, height_px: int) -> list[Detection]:
    """Classical-only boats whose core the class map calls water (at least ``AFLOAT_MIN_WATER``). The union's
    boats are the ones the net missed afloat; rough boulders of a riprap bank pass the other checks (seed-1
    synthetic levels: 5 false boats, their cores 65-100 % rocks), while the class map put water under every
    true one (real marina and synthetic). Without a class map nothing is dropped."""
    if class_map is None or not boats:
        return boats
    ids = class_map.ids
    h, w = ids.shape
    fx, fy = w / float(width_px), h / float(height_px)
    out = []
    for b in boats:
        c, r = int(b.cx_px * fx), int(b.cy_px * fy)
        rr = max(1, int(round(0.3 * b.width_px * fx)))
        core = ids[max(0, r - rr):r + rr + 1, max(0, c - rr):c + rr + 1]
        if core.size and float(np.mean(core == WATER)) >= AFLOAT_MIN_WATER:
            out.append(b)
    return out


def _lab_of_boxes(rgb: np.ndarray, boxes: list[Detection]) -> np.ndarray:
    """uint8 Lab (OpenCV scale) of the image, converted only inside the boxes' bounding rectangle."""
    import cv2

    h, w = rgb.shape[:2]
    lab = np.zeros((h, w, 3), np.uint8)
    c = np.concatenate([d.corners_px() for d in boxes])
    x0, y0 = np.clip(np.floor(c.min(0)).astype(int) - 1, 0, [w, h])
    x1, y1 = np.clip(np.ceil(c.max(0)).astype(int) + 2, 0, [w, h])
    if x1 > x0 and y1 > y0:
        lab[y0:y1, x0:x1] = cv2.cvtColor(np.ascontiguousarray(rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2LAB)
    return lab


def _demote(d: Detection) -> Detection:
    return replace(d, score=min(d.score, 0.35))
