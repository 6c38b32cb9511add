"""The chain's front end for images too large to hold (``TiledImage``): segmented and detected by windows
(``tiling``), the later stages on a coarser scene grid. ``run_generate`` picks it for images over
``TILING_THRESHOLD_PX`` (``needs_tiling``); ``generate_tiled`` runs it with other tile sizes."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from ..config import Config
from ..errors import ConfigError
from ..types import ClassMap, Detection, GeoImage, Grid
from .tiling import (Source, check_tiling, detect_tiled, downsample_classes, match_tiled, open_source,
                     piers_tiled, read_overview, scale_detection, segment_tiled)

TILING_THRESHOLD_PX = 4096 * 4096  # larger images are read by windows (TiledImage)


def needs_tiling(image: str | Path, threshold_px: int = TILING_THRESHOLD_PX) -> bool:
    """True when the image has more pixels than ``threshold_px`` (default 4096²): use ``generate_tiled``."""
    import rasterio

    p = Path(image)
    if not p.is_file():
        return False  # read_image reports the missing file with its own message
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with rasterio.open(p) as src:
                return src.width * src.height > threshold_px
    except Exception:  # noqa: BLE001 - unreadable files are reported by the normal reader
        return False


def _tile_progress(progress, stage: str):
    """Per-tile progress of a stage as ``progress(stage, k / n)`` (strictly between 0 and 1 until the end)."""
    if progress is None:
        return None
    return lambda k, n: progress(stage, min(k / max(n, 1), 0.999))


@dataclass(frozen=True)
class TiledImage:
    """A large image as ``pipeline.run_chain`` sees it: segmented and detected by windows at full resolution
    (merged across the seams), the later stages on a scene grid of at most ``scene_max_px`` per side (the
    classes block-majority downsampled, the detections scaled, the moored boats' water decided on the
    whole scene grid)."""

    source: Source
    scene_grid: Grid
    preview: GeoImage  # the image averaged down to the scene grid
    tile_px: int
    overlap_px: int  # the segmentation windows' context
    detect_overlap_px: int  # the detection windows': half the longest boat (``DetectConfig.max_boat_length_m``)

    @classmethod
    def open(cls, req, config: Config, tile_px: int = 2048, overlap_px: int = 256,
             scene_max_px: int = 4096) -> TiledImage:
        """Open and check ``req.image`` (``open_source``), check the run's memory and read the preview."""
        from ..io import check_memory

        check_tiling(tile_px, overlap_px)
        if not (isinstance(scene_max_px, int) and scene_max_px >= 127):
            raise ConfigError(f"scene_max_px = {scene_max_px!r} must be an integer ≥ 127 (e.g. 4096)")
        src = open_source(req.image, req.gsd_m, req.size_m, config.io)
        W, H = src.grid.width_px, src.grid.height_px
        f = max(1.0, max(W, H) / scene_max_px)
        sw, sh = max(8, int(round(W / f))), max(8, int(round(H / f)))
        # the stages after segmentation and detection run on the scene grid (tiles are bounded), beside the
        # full-resolution class ids (1 byte per input pixel)
        check_memory(req.image, sw, sh, src.grid.gsd_m * W / sw, config.io, stages=config,
                     read_bytes_per_px=W * H / (sw * sh), tiled=True)
        preview = read_overview(src, sw, sh)
        # detection's own overlap: an object is whole in the tile that owns its centre when the overlap is at
        # least half its length (more context changes the boxes no more than moving the windows by a pixel)
        half_boat_px = int(math.ceil(config.detect.max_boat_length_m / 2 / src.grid.gsd_m))
        det_ov = min(tile_px, half_boat_px + 8)
        return cls(src, preview.grid, preview, tile_px, overlap_px, det_ov)

    @property
    def grid(self) -> Grid:
        return self.source.grid

    @property
    def report_image(self) -> None:
        return None  # the report reads the input itself

    @property
    def detections_provenance(self) -> dict:
        return {"tiled": True, "tile_px": self.tile_px}

    @property
    def provenance(self) -> dict:
        sg = self.scene_grid
        return {"tiled": {"tile_px": self.tile_px, "overlap_px": self.overlap_px,
                          "detect_overlap_px": self.detect_overlap_px, "scene_grid_px": [sg.width_px, sg.height_px],
                          "scene_gsd_m": sg.gsd_m}}

    def segment(self, config: Config, progress) -> ClassMap:
        ids = segment_tiled(self.source, config=config.segment, tile_px=self.tile_px, overlap_px=self.overlap_px,
                            seed=config.seed, progress=_tile_progress(progress, "segment"))
        return ClassMap(ids, self.grid)

    def detect(self, class_map: ClassMap, config: Config, progress, side,
               side_queued) -> tuple[list[Detection], ClassMap, dict]:
        """Each tile's detections are reconciled with its own class map; the corrected maps are dropped (the
        moored boats' water is decided on the whole scene grid, ``to_scene_grid``)."""
        side_queued()
        dets = detect_tiled(self.source, config=config.detect, class_ids=class_map.ids, tile_px=self.tile_px,
                            overlap_px=self.detect_overlap_px, seed=config.seed,
                            progress=_tile_progress(progress, "detect"), side=side)
        return dets, class_map, {}

    def to_scene_grid(self, class_map: ClassMap, dets: list[Detection],
                      config: Config) -> tuple[ClassMap, list[Detection], dict]:
        from ..consistency import water_from_boats

        sg = self.scene_grid
        f = self.grid.width_px / sg.width_px
        cm = ClassMap(downsample_classes(class_map.ids, sg.width_px, sg.height_px), sg)
        s_dets = [scale_detection(d, f) for d in dets]
        notes: dict = {}
        if config.detect.boats_make_water:
            # a marina cut by tile borders becomes water as in a whole-image run
            cm, notes = water_from_boats(s_dets, cm, sg.gsd_m)
        return cm, s_dets, notes

    def matcher(self):
        return partial(match_tiled, self.source, self.tile_px)

    def piers(self, dets: list[Detection], class_map: ClassMap, walkway, finger, config) -> tuple[list, dict]:
        return piers_tiled(dets, class_map, walkway, finger, config)


def generate_tiled(req, config: Config, progress=None, tile_px: int = 2048, overlap_px: int = 256,
                   scene_max_px: int = 4096):
    """``run_generate``'s chain on a ``TiledImage``, written straight into ``req.out`` (no staging folder):
    for images too large to hold. Returns a ``pipeline.GenerateResult``."""
    from ..config import validate_config
    from .chain import run_chain
    from .runtime import Timer

    validate_config(config)
    timer = Timer(progress)
    with timer.stage("read"):
        front = TiledImage.open(req, config, tile_px, overlap_px, scene_max_px)
    out = Path(req.out)  # every input check done: the first write here
    out.mkdir(parents=True, exist_ok=True)
    return run_chain(front, req, config, out, timer)
