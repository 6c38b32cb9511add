"""The ``hybrid`` detector: the learned network for boats, vehicles and buoys, the classical detector for piers.

The learned network (trained on coastforge's renders) is far better on rendered scenes (boats: recall 0.98 vs
0.72, orientation 2° vs 25°, heading 98 % vs 86 %) but finds fewer boats on the real marina photo (0.68 vs 0.89);
it does not detect piers. ``union=True`` also keeps the classical boats that no learned box overlaps, which
recovers real-photo recall at some cost in precision on renders.
"""

from __future__ import annotations

from ..config import DetectConfig
from ..types import ClassMap, Detection, GeoImage

PIERS = ("pier_walkway", "pier_finger")


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
        objects = self.learned.detect(image, class_map, seed)
        piers = [d for d in classical if d.category in PIERS]
        if not self.union:
            return objects + piers
        extra = [d for d in classical if d.category == "boat"]
        # learned boxes first, so on overlap the learned box (better orientation and heading) survives
        merged = rotated_nms([*objects, *[_demote(d) for d in extra]], self.config.nms_iou)
        return merged + piers


def _demote(d: Detection) -> Detection:
    from dataclasses import replace

    return replace(d, score=min(d.score, 0.35))
