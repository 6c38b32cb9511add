"""What ``coastforge library query`` and ``library info`` call."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...classes import ASSET_CATEGORIES
from ...errors import InputError
from ...fsio import read_png
from .cache import default_library, open_library
from .store import Library


def query_image(lib_path: str | Path | None, image_path: str | Path, gsd_m: float, k: int = 5,
                category: str | None = None, embedder: str | None = None, weights: str | Path | None = None
                ) -> list[dict]:
    """``coastforge library query``: the ``k`` nearest assets of one image file, best first."""
    from ...config import IOConfig
    from ...io import image_damage

    if not (isinstance(gsd_m, (int, float)) and gsd_m > 0 and math.isfinite(gsd_m)):
        raise InputError(f"--gsd {gsd_m!r} must be a positive number of metres per pixel")
    io_cfg = IOConfig()
    if not io_cfg.min_gsd_m <= gsd_m <= io_cfg.max_gsd_m:
        raise InputError(f"--gsd {gsd_m:g} m/px is outside the {io_cfg.min_gsd_m:g}-{io_cfg.max_gsd_m:g} m/px "
                         "coastforge works with; --gsd is metres per pixel of the crop (e.g. 0.1)")
    if k < 1:
        raise InputError(f"--k {k} must be at least 1")
    image_path = Path(image_path)
    if not image_path.is_file():
        raise InputError(f"image {image_path} is not a file; pass a PNG or JPEG crop of one object")
    why = image_damage(image_path)
    if why:
        raise InputError(f"{image_path} is truncated or corrupt: {why}; re-export or re-download it")
    lib = Library.load(lib_path, embedder=embedder, weights=weights) if lib_path is not None else default_library()
    if category is not None and category in ASSET_CATEGORIES and not any(a.category == category for a in lib.assets):
        have = sorted({a.category for a in lib.assets})
        raise InputError(f"library {lib.root} has no {category!r} asset (it has {', '.join(have)}); query "
                         "another --category, or add such assets with coastforge library build")
    img = read_png(image_path)
    if img.dtype != np.uint8:
        img = (img / 257).astype(np.uint8)
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[:, :, :3]
    hits = lib.query(img, float(gsd_m), k=k, category=category)
    return [{"asset_id": aid, "category": lib.asset(aid).category, "score": round(float(s), 6)} for aid, s in hits]


def library_info(path: str | Path | None = None) -> dict:
    lib = open_library(path)
    return {
        "root": str(lib.root), "embedder": lib.embedder_name, "rows": lib.index.rows,
        "assets": [{"id": a.id, "category": a.category, "dims_m": list(a.dims_m), "view_gsd_m": a.view_gsd_m,
                    "ue_path": a.ue_path, "floating": a.floating, "draft_m": a.draft_m} for a in lib.assets],
    }
