"""The user's own class raster, mapped to our eight classes and resampled to the scene grid.

Mapping file (JSON or TOML): a table from raster values or colours to class names::

    {"classes": {"1": "water", "2": "asphalt", "#5aaa3c": "grass", "[230, 210, 150]": "sand"},
     "default": "dirt"}            # optional: every value not listed

Keys are integers (single-band rasters, or palette indices of a paletted PNG) or colours
(``"#rrggbb"``, ``"r,g,b"`` or ``"[r, g, b]"``) for RGB rasters. Values are class names (DESIGN.md §2)
or class ids 0..7. Values of the raster that the mapping does not list are an error that lists them.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import cv2
import numpy as np

from ..classes import CLASS_IDS, CLASS_NAMES, N_CLASSES
from ..config import SegmentConfig
from ..errors import InputError
from ..types import ClassMap, GeoImage

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")


def class_id(v, where: str) -> int:
    if isinstance(v, bool):
        raise InputError(f"{where}: {v!r} is not a class; use one of {', '.join(CLASS_NAMES)}")
    if isinstance(v, int) and 0 <= v < N_CLASSES:
        return v
    if isinstance(v, str) and v.strip().lower() in CLASS_IDS:
        return CLASS_IDS[v.strip().lower()]
    raise InputError(f"{where}: {v!r} is not a class; use one of {', '.join(CLASS_NAMES)} (or ids 0..7)")


def _parse_key(k: str, where: str) -> tuple[str, int]:
    """A mapping key → ("value", v) or ("colour", 0xRRGGBB)."""
    s = str(k).strip()
    m = _HEX.match(s) if s.startswith("#") else None
    if m:
        return "colour", int(m.group(1), 16)
    inner = s.strip("[]() ")
    parts = [p for p in re.split(r"[,\s]+", inner) if p]
    if len(parts) == 3 and all(p.isdigit() for p in parts):
        r, g, b = (int(p) for p in parts)
        if max(r, g, b) > 255:
            raise InputError(f"{where}: colour {s!r} has a channel above 255")
        return "colour", (r << 16) | (g << 8) | b
    if re.fullmatch(r"-?\d+", s):
        return "value", int(s)
    raise InputError(f"{where}: key {s!r} is neither an integer value nor a colour ('#rrggbb' or 'r,g,b')")


def load_mapping(path: str | Path | dict) -> tuple[str, dict[int, int], int | None]:
    """Read a mapping file → (kind "value"|"colour", {key: class id}, default class id or None)."""
    if isinstance(path, dict):
        data, where = path, "mapping"
    else:
        p = Path(path)
        where = str(p)
        if not p.is_file():
            raise InputError(f"mapping file {p} does not exist; pass a JSON or TOML file with --mapping")
        text = p.read_text(encoding="utf-8")
        try:
            data = tomllib.loads(text) if p.suffix.lower() == ".toml" else json.loads(text)
        except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
            raise InputError(f"mapping file {p} is not valid {'TOML' if p.suffix.lower() == '.toml' else 'JSON'}: {exc}") from exc
    if not isinstance(data, dict):
        raise InputError(f"{where}: expected a table of value/colour → class name")
    table = data.get("classes", {k: v for k, v in data.items() if k != "default"})
    if not isinstance(table, dict) or not table:
        raise InputError(f"{where}: the mapping is empty; list values or colours → class names under \"classes\"")
    kinds = set()
    out: dict[int, int] = {}
    for k, v in table.items():
        kind, key = _parse_key(k, where)
        kinds.add(kind)
        out[key] = class_id(v, f"{where} [{k}]")
    if len(kinds) > 1:
        raise InputError(f"{where}: mixes integer values and colours; use one kind of key")
    default = data.get("default")
    return kinds.pop(), out, (None if default is None else class_id(default, f"{where} default"))


def read_label_raster(path: str | Path, kind: str) -> np.ndarray:
    """(H, W) integer values, or (H, W) packed 0xRRGGBB colours when ``kind == "colour"``."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"label raster {p} does not exist; pass a PNG or GeoTIFF with --labels")
    if p.suffix.lower() in (".tif", ".tiff"):
        import rasterio

        try:
            with rasterio.open(p) as src:
                a = src.read()
        except Exception as exc:  # rasterio raises several types for unreadable files
            raise InputError(f"label raster {p} cannot be read ({exc})") from exc
        a = a[0] if a.shape[0] == 1 else np.moveaxis(a[:3], 0, -1)
    else:
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(p) as im:
                if im.mode == "P" and kind == "value":
                    a = np.asarray(im)  # palette indices
                elif im.mode in ("L", "I", "I;16", "I;16B", "P") and kind == "value":
                    a = np.asarray(im)
                else:
                    a = np.asarray(im.convert("RGB"))
        except (UnidentifiedImageError, OSError) as exc:
            raise InputError(f"label raster {p} is not a readable image ({exc})") from exc
    if kind == "colour":
        if a.ndim != 3:
            raise InputError(f"label raster {p} is single-band but the mapping lists colours; map its values instead")
        a = a.astype(np.int64)
        return (a[..., 0] << 16) | (a[..., 1] << 8) | a[..., 2]
    if a.ndim == 3:
        raise InputError(f"label raster {p} is RGB but the mapping lists integer values; map colours ('#rrggbb') instead")
    return a.astype(np.int64)


def _fmt_key(v: int, kind: str) -> str:
    return f"#{v:06x}" if kind == "colour" else str(v)


def apply_mapping(raw: np.ndarray, kind: str, table: dict[int, int], default: int | None, where: str) -> np.ndarray:
    values, inverse = np.unique(raw.ravel(), return_inverse=True)
    lut = np.empty(values.size, np.uint8)
    missing = []
    for i, v in enumerate(values.tolist()):
        if v in table:
            lut[i] = table[v]
        elif default is not None:
            lut[i] = default
        else:
            missing.append(v)
    if missing:
        shown = ", ".join(_fmt_key(v, kind) for v in missing[:20]) + (" ..." if len(missing) > 20 else "")
        raise InputError(
            f"{where} holds {len(missing)} {'colour' if kind == 'colour' else 'value'}(s) the mapping does not list: "
            f"{shown}; add them to the mapping (or set \"default\": \"<class>\")"
        )
    return lut[inverse].reshape(raw.shape)


class LabelsSegmenter:
    """Segmentation from the user's own class raster (``labels=`` path) and ``mapping=`` file."""

    def __init__(self, config: SegmentConfig | None = None, labels: str | Path | None = None,
                 mapping: str | Path | dict | None = None, **options):
        if options:
            raise InputError(f"the labels segmenter takes labels= and mapping=, not {', '.join(sorted(options))}")
        if labels is None or mapping is None:
            raise InputError("the labels backend needs --labels FILE (your class raster) and --mapping FILE "
                             "(JSON/TOML: values or colours → class names)")
        self.config = config or SegmentConfig()
        self.labels = Path(labels)
        self.mapping = mapping

    def segment(self, image: GeoImage, seed: int = 0) -> ClassMap:
        kind, table, default = load_mapping(self.mapping)
        raw = read_label_raster(self.labels, kind)
        ids = apply_mapping(raw, kind, table, default, str(self.labels))
        H, W = image.grid.shape
        h, w = ids.shape
        if (h, w) != (H, W):
            if abs(w / h - W / H) > 0.02 * (W / H):
                raise InputError(
                    f"label raster {self.labels} is {w}x{h} px but the image is {W}x{H} px (different aspect ratio); "
                    "the labels must cover the same area as the image"
                )
            ids = cv2.resize(ids, (W, H), interpolation=cv2.INTER_NEAREST)
        return ClassMap(ids=np.ascontiguousarray(ids, dtype=np.uint8), grid=image.grid)
