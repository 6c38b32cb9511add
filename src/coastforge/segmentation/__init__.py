"""Terrain segmentation into the eight classes of DESIGN.md §2, and cleaning of transient objects.

Backends (``coastforge.registry``, stage ``segment``): ``classical`` (no weights, any GSD), ``learned``
(a small U-Net trained by coastforge on its own renders, shipped as ONNX; classical outside 0.04-0.6 m/px),
``labels`` (the user's own class raster), ``onnx`` (any ONNX segmentation model), ``gemini`` (the
paper's method).
Each is a class built as ``Backend(config: SegmentConfig, **backend_options)`` with
``segment(image: GeoImage, seed: int) -> ClassMap`` (uint8 ids on the image grid).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..classes import N_CLASSES
from ..config import Config, SegmentConfig
from ..errors import InputError
from ..types import ClassMap, GeoImage

__all__ = ["Segmenter", "check_class_map", "segment", "segment_file"]


@runtime_checkable
class Segmenter(Protocol):
    """What every segmentation backend provides."""

    def segment(self, image: GeoImage, seed: int) -> ClassMap: ...


def check_class_map(cm: ClassMap, image: GeoImage, backend: str) -> ClassMap:
    """Make sure a backend returned uint8 ids in range on the image grid."""
    ids = np.asarray(cm.ids)
    if ids.shape != image.rgb.shape[:2]:
        raise InputError(f"segment backend {backend!r} returned a {ids.shape} class map for a "
                         f"{image.rgb.shape[:2]} image; it must return ids on the image grid")
    if ids.size and int(ids.max()) >= N_CLASSES:
        raise InputError(f"segment backend {backend!r} returned class id {int(ids.max())}; ids must be 0..{N_CLASSES - 1}")
    if ids.dtype != np.uint8:
        cm = ClassMap(ids=ids.astype(np.uint8), grid=cm.grid, proba=cm.proba, confidence=cm.confidence,
                      source=cm.source)
    return cm


def segment(image: GeoImage, config: SegmentConfig | Config | None = None, backend: str | None = None,
            seed: int | None = None, **options: Any) -> ClassMap:
    """Segment ``image`` with ``backend`` (default: ``config.backend``, normally ``learned``).

    ``config`` may be the stage's ``SegmentConfig`` or the whole ``Config`` (then its root seed is used
    unless ``seed`` is given). ``options`` go to the backend (e.g. ``labels=``, ``mapping=`` for
    ``labels``; ``weights=``, ``mapping=`` for ``onnx``; ``client=`` for ``gemini``)."""
    from .. import registry

    root_seed = 0
    if isinstance(config, Config):
        root_seed = config.seed
        config = config.segment
    cfg = config or SegmentConfig()
    name = backend or cfg.backend
    cls = registry.load("segment", name)
    seg = cls(cfg, **options)
    cm = seg.segment(image, root_seed if seed is None else int(seed))
    return check_class_map(cm, image, name)


def segment_file(image_path: str | Path, out_dir: str | Path, *, gsd_m: float | None = None,
                 size_m: tuple[float, float] | None = None, config: Config | None = None,
                 backend: str | None = None, overwrite: bool = False, **options: Any) -> dict:
    """Read an image, segment it and write the outputs of ``outputs.write_segmentation`` to ``out_dir``.

    Returns the written paths (name → path) and the class fractions."""
    from ..fsio import prepare_output_dir
    from ..io import read_image
    from .outputs import write_segmentation

    cfg = config or Config()
    image = read_image(image_path, gsd_m=gsd_m, size_m=size_m, config=cfg.io)
    out = prepare_output_dir(out_dir, overwrite)
    cm = segment(image, cfg, backend=backend, **options)
    return write_segmentation(out, cm, image, cfg.segment, backend=backend or cfg.segment.backend)
