"""Readers for the real third-party sets in ``../shared/data`` and the fixed validation split.

The sets are never copied into the repository (see ``../shared/data/README.md``); everything here reads
them in place and returns ``None`` / empty lists when the folder is absent, so callers skip cleanly.

The **validation split is by image group** and fixed here, once, for training and benchmarks alike
(``python -m coastforge.bench.real`` reports it apart; no threshold or model choice is tuned on it):

- ``landcover_dubai``: tiles 7 and 8 (each tile is one scene cut into 9 parts);
- ``cars_munich``: MOS89-93 and MOS175-179 (the crops are consecutive cuts of two mosaics: the last five
  of each run form one contiguous block of town nobody trained on);
- ``ships_aerial``: images are grouped by near-duplicate thumbnails (the set holds copies such as
  boat37/boat236) and a group is validation when a hash of its first name falls in 1/5 of the range,
  so duplicates never straddle the split.

DOTA crops (``aerial/``) are evaluation-only by their licence and are never used for training.
"""

from __future__ import annotations

import hashlib
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"

DUBAI_VAL_TILES = ("tile_7", "tile_8")
MUNICH_VAL = tuple(f"MOS{i}" for i in (*range(89, 94), *range(175, 180)))
SHIPS_VAL_SHARE = 5  # one group in five

# Dubai mask colours (RGB) -> coarse label; see ../shared/data/README.md (the upstream classes.json is wrong)
DUBAI_COLOURS = {
    (0x3C, 0x10, 0x98): "building",
    (0x84, 0x29, 0xF6): "land",
    (0x6E, 0xC1, 0xE4): "road",
    (0xFE, 0xDD, 0x3A): "vegetation",
    (0xE2, 0xA9, 0x29): "water",
    (0x9B, 0x9B, 0x9B): "unlabeled",
}
# coarse codes used by the benchmark and by training on partial labels
COARSE = ("water", "paved", "vegetation", "bare")
COARSE_IGNORE = 255
BUILDING = 254  # roofs: counted as paved in training, ignored when scoring


def shared_dir() -> Path:
    return SHARED


@dataclass(frozen=True)
class BoxImage:
    """One real image with axis-aligned boxes (pixels: x0, y0, x1, y1) of one category."""

    name: str
    path: Path
    boxes: np.ndarray  # (N, 4) float
    category: str  # "boat" or "vehicle"
    group: str
    val: bool


def read_rgb(path: Path) -> np.ndarray:
    """RGB uint8 of a PNG/JPEG (alpha dropped)."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise OSError(f"cannot read image {path}")
    return np.ascontiguousarray(img[:, :, ::-1])


# ------------------------------------------------------------------------------------------ Dubai

def dubai_coarse(mask_rgb: np.ndarray) -> np.ndarray:
    """Dubai RGB mask -> coarse codes (0 water, 1 paved, 2 vegetation, 3 bare, BUILDING, 255 ignore).

    JPEG-free PNG masks, but colours are matched to the nearest palette entry within 40 levels to be safe."""
    pal = np.array(list(DUBAI_COLOURS), np.int32)
    names = list(DUBAI_COLOURS.values())
    d = ((mask_rgb[:, :, None, :].astype(np.int32) - pal[None, None]) ** 2).sum(3)
    k = d.argmin(2)
    near = d.min(2) <= 40 * 40
    code = {"water": 0, "road": 1, "vegetation": 2, "land": 3, "building": BUILDING, "unlabeled": COARSE_IGNORE}
    lut = np.array([code[n] for n in names], np.uint8)
    out = lut[k]
    out[~near] = COARSE_IGNORE
    return out


def dubai_items() -> list[tuple[str, Path, Path, bool]]:
    """(name, image, mask, is_validation) for every Dubai image, sorted; empty when absent."""
    root = SHARED / "real" / "landcover_dubai"
    out = []
    if not root.is_dir():
        return out
    for tile in sorted(p for p in root.iterdir() if p.is_dir()):
        for img in sorted((tile / "images").glob("*.jpg")):
            mask = tile / "masks" / (img.stem + ".png")
            if mask.is_file():
                out.append((f"{tile.name}/{img.stem}", img, mask, tile.name in DUBAI_VAL_TILES))
    return out


# ------------------------------------------------------------------------------------------ boxes

def _voc_boxes(xml_path: Path) -> np.ndarray:
    root = ET.parse(xml_path).getroot()
    boxes = []
    for obj in root.iter("object"):
        bb = obj.find("bndbox")
        if bb is None:
            continue
        boxes.append([float(bb.findtext(k)) for k in ("xmin", "ymin", "xmax", "ymax")])
    return np.asarray(boxes, np.float64).reshape(-1, 4)


def _thumb(path: Path) -> np.ndarray:
    import cv2

    g = cv2.cvtColor(read_rgb(path), cv2.COLOR_RGB2GRAY)
    t = cv2.resize(g, (16, 16), interpolation=cv2.INTER_AREA).astype(np.float32).ravel()
    t -= t.mean()
    return t / (np.linalg.norm(t) + 1e-6)


def _groups(names: list[str], thumbs: np.ndarray, same: float = 0.95) -> dict[str, str]:
    """Near-duplicate images (thumbnail correlation >= ``same``, transitively) form a group, named after its
    first member; name -> group name."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    _n, comp = connected_components(csr_matrix(thumbs @ thumbs.T >= same), directed=False)
    first = {}
    for i, c in enumerate(comp):
        first.setdefault(c, names[i])
    return {n: first[c] for n, c in zip(names, comp)}


def _is_val_group(group: str) -> bool:
    return int(hashlib.sha1(group.encode()).hexdigest()[:8], 16) % SHIPS_VAL_SHARE == 0


def ships_items() -> list[BoxImage]:
    """Every ``ships_aerial`` image with its boat boxes; empty when absent."""
    root = SHARED / "real" / "ships_aerial"
    if not (root / "images").is_dir():
        return []
    paths = sorted((root / "images").glob("*.png"), key=lambda p: (len(p.stem), p.stem))
    names = [p.stem for p in paths]
    groups = _groups(names, np.stack([_thumb(p) for p in paths]))
    out = []
    for p in paths:
        xml = root / "annotations" / f"{p.stem}.xml"
        if not xml.is_file():
            continue
        g = groups[p.stem]
        out.append(BoxImage(p.stem, p, _voc_boxes(xml), "boat", g, _is_val_group(g)))
    return out


def ships_gsd(boxes: np.ndarray) -> float:
    """The benchmark's GSD rule for ``ships_aerial`` (DESIGN.md §5): 10 m / median labelled long side in
    pixels, clipped to [0.15, 1.2] m/px."""
    long_side = np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])
    return float(np.clip(10.0 / max(float(np.median(long_side)), 1e-6), 0.15, 1.2))


MUNICH_GSD_M = 0.13


def munich_items(classes: tuple[int, ...] = (0, 1, 2, 3)) -> list[BoxImage]:
    """Every ``cars_munich`` crop with its vehicle boxes (car, truck, bus, minibus; cyclists left out)."""
    root = SHARED / "real" / "cars_munich"
    if not root.is_dir():
        return []
    out = []
    paths = sorted(root.glob("MOS*.png"), key=lambda p: int(re.sub(r"\D", "", p.stem)))
    for p in paths:
        txt = p.with_suffix(".txt")
        if not txt.is_file():
            continue
        import cv2

        h, w = cv2.imread(str(p), cv2.IMREAD_UNCHANGED).shape[:2]
        rows = [ln.split() for ln in txt.read_text().splitlines() if ln.strip()]
        b = []
        for r in rows:
            c, cx, cy, bw, bh = int(r[0]), *map(float, r[1:5])
            if c in classes:
                b.append([(cx - bw / 2) * w, (cy - bh / 2) * h, (cx + bw / 2) * w, (cy + bh / 2) * h])
        num = int(re.sub(r"\D", "", p.stem))
        out.append(BoxImage(p.stem, p, np.asarray(b, np.float64).reshape(-1, 4), "vehicle",
                            "MOS74-93" if num < 100 else "MOS155-179", p.stem in MUNICH_VAL))
    return out
