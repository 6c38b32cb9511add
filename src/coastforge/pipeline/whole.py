"""The chain's front end for an image held whole in memory."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from collections.abc import Callable

import numpy as np

from ..config import Config
from ..types import ClassMap, Detection, GeoImage, Grid
from .request import GenerateRequest, Progress
from .runtime import SideProcess


@dataclass(frozen=True)
class WholeImage:
    """The input read whole (``io.read_image``): every stage sees all of it, and the scene grid is its grid."""

    image: GeoImage

    @classmethod
    def read(cls, req: GenerateRequest, config: Config) -> WholeImage:
        from ..io import read_image

        return cls(read_image(req.image, req.gsd_m, req.size_m, config.io, stages=config))

    @property
    def grid(self) -> Grid:
        return self.image.grid

    @property
    def scene_grid(self) -> Grid:
        return self.image.grid

    @property
    def preview(self) -> GeoImage:
        return self.image

    @property
    def report_image(self) -> np.ndarray:
        return self.image.rgb

    @property
    def detections_provenance(self) -> None:
        return None

    @property
    def provenance(self) -> dict:
        return {}

    def segment(self, config: Config, progress: Progress | None) -> ClassMap:
        from ..segmentation import segment

        return segment(self.image, config.segment, seed=config.seed)

    def detect(self, class_map: ClassMap, config: Config, progress: Progress | None, side: SideProcess | None,
               side_queued: Callable[[], None]) -> tuple[list[Detection], ClassMap, dict]:
        from ..detection import detect

        opts = {}
        if side is not None and config.detect.backend == "hybrid":  # its classical half runs in the side process
            from ..detection.hybrid import classical_part

            opts["classical_dets"] = side.submit(classical_part, self.image, class_map, config.detect, config.seed)
        side_queued()
        dets, cm, notes = detect(self.image, config.detect, class_map=class_map, seed=config.seed,
                                 return_class_map=True, **opts)
        assert cm is not None  # a class map in, a (reconciled) class map out
        return dets, cm, notes

    def to_scene_grid(self, class_map: ClassMap, dets: list[Detection],
                      config: Config) -> tuple[ClassMap, list[Detection], dict]:
        return class_map, dets, {}

    def matcher(self) -> Callable:
        return partial(match_in_image, self.image)

    def piers(self, dets: list[Detection], class_map: ClassMap, walkway, finger, config) -> tuple[list, dict]:
        from ..pier_chains import build_piers

        pr = build_piers(dets, class_map, walkway, finger, config)
        return list(pr.objects), pr.report


def match_in_image(image: GeoImage, dets: list[Detection], library, config: Config, kit=None) -> list:
    """``matching.match_detections`` on an image in memory (``kit``: the fallback library)."""
    from ..matching import match_detections

    return match_detections(image, dets, library, config.match, config.seed, fallback=kit)
