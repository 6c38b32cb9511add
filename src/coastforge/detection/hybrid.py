"""The ``hybrid`` detector: the learned network for boats, vehicles and buoys, the classical detector for piers.

The learned network (trained on coastforge's renders) is far better on rendered scenes (boats: recall 0.98 vs
0.72, orientation 2° vs 25°, heading 98 % vs 86 %) but finds fewer boats on the real marina photo (0.68 vs 0.89);
it does not detect piers. Learned boats far from the classical detector's water are on land (the net takes
some buses, vans and roofs for boats): vehicle-sized ones become vehicles, others are dropped (real marina
precision 0.81 -> 0.91). ``union=True`` also keeps the classical boats that no learned box overlaps or
mostly contains, which recovers real-photo recall at some cost in precision on renders.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import DetectConfig
from ..types import ClassMap, Detection, GeoImage

PIERS = ("pier_walkway", "pier_finger")
UNION_IOA = 0.3
# learned boats this far (m) from the classical water mask are on land: true boats were at most 5.5 m
# from it (synthetic levels, real marina), the net's boats on land (cars, buses, roofs) 10-60 m
LAND_REACH_M = 8.0


class HybridDetector:
    def __init__(self, config: DetectConfig | None = None, weights: str | None = None, union: bool | None = None,
                 **_opts):
        from .classical import ClassicalDetector
        from .learned import LearnedDetector

        self.config = config or DetectConfig()
        self.learned = LearnedDetector(self.config, weights=weights)
        self.classical = ClassicalDetector(self.config)
        self.union = self.config.hybrid_union if union is None else bool(union)

    def detect(self, image: GeoImage, class_map: ClassMap | None = None, seed: int = 0) -> list[Detection]:
        from .learned import MAX_GSD_M, MIN_GSD_M
        from .nms import rotated_nms

        classical = self.classical.detect(image, class_map, seed)
        if not (MIN_GSD_M <= image.grid.gsd_m <= MAX_GSD_M):
            return classical  # e.g. satellite ports at 10 m/px: outside what the network was trained on
        objects = self._on_land_as_vehicles(self.learned.detect(image, class_map, seed), image.grid.gsd_m)
        piers = [d for d in classical if d.category in PIERS]
        if not self.union:
            return objects + piers
        extra = [d for d in classical if d.category == "boat"]
        # learned boxes first, so on overlap the learned box (better orientation and heading) survives;
        # a classical box lying mostly inside a learned one is a piece of the same boat (a cabin, a
        # deck split by shadow) and goes too (real marina: precision 0.69 -> 0.73 at the same recall)
        merged = rotated_nms([*objects, *[_demote(d) for d in extra]], self.config.nms_iou,
                             ioa_threshold=UNION_IOA)
        return merged + piers


    def _on_land_as_vehicles(self, dets: list[Detection], gsd_m: float) -> list[Detection]:
        """A learned boat with no water within ``LAND_REACH_M`` of its box (in the classical
        detector's water mask) is on land: a vehicle when it has a vehicle's size (a bus, a van), else
        dropped. Boats on trailers are rare enough next to this net's buses-as-boats."""
        import cv2

        water = getattr(self.classical, "water_work", None)
        if water is None or not water.any():
            return dets  # no water model (e.g. an inland image): nothing to check against
        s = float(self.classical.work_scale)
        # water within reach of a pixel: dilate once, look up each box's pixels
        reach = max(1, int(round(LAND_REACH_M / gsd_m * s)))
        near = cv2.dilate(water.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                                            (2 * reach + 1, 2 * reach + 1))) > 0
        out = []
        h, w = near.shape
        for d in dets:
            if d.category != "boat":
                out.append(d)
                continue
            pts = np.round(d.corners_px() * s - 0.5).astype(np.int32)
            box = np.zeros((h, w), np.uint8)
            c0, r0 = np.clip(pts.min(0) - 1, 0, [w, h])
            c1, r1 = np.clip(pts.max(0) + 2, 0, [w, h])
            if c1 <= c0 or r1 <= r0:
                out.append(d)
                continue
            sub = box[r0:r1, c0:c1]
            cv2.fillPoly(sub, [pts - [c0, r0]], 1)
            if near[r0:r1, c0:c1][sub > 0].any():
                out.append(d)
            elif d.length_px * gsd_m <= self.config.max_vehicle_length_m:
                out.append(replace(d, category="vehicle"))
        return out


def _demote(d: Detection) -> Detection:
    return replace(d, score=min(d.score, 0.35))
