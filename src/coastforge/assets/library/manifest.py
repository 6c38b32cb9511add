"""What a library is built from: a JSON/TOML manifest of assets, or a folder of models whose categories
are guessed from their names."""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Sequence

from ...classes import ASSET_CATEGORIES
from ...errors import LibraryError
from ..meshes import MESH_SUFFIXES


_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}$")


_MANIFEST_KEYS = {"id", "category", "mesh", "length_m", "height_m", "up_axis", "forward_axis", "unit", "ue_path",
                  "tags", "draft_m", "floating", "dims_m", "name", "notes", "origin"}


# Category words for folders of models without a manifest (matched against name tokens).
CATEGORY_WORDS: dict[str, tuple[str, ...]] = {
    "boat": ("boat", "ship", "yacht", "sail", "sailboat", "kayak", "canoe", "ferry", "tug", "tugboat", "vessel",
             "dinghy", "lifeboat", "catamaran", "trawler", "jetski", "skiff", "cruiser", "speedboat", "barge"),
    "vehicle": ("car", "truck", "van", "bus", "taxi", "suv", "pickup", "vehicle", "trailer", "jeep", "sedan",
                "coupe", "hatchback", "lorry", "police", "ambulance", "racecar", "copcar"),
    "pier": ("pier", "dock", "jetty", "pontoon", "wharf", "walkway", "boardwalk", "quay", "marina"),
    "buoy": ("buoy", "marker", "mooring"),
    "tree": ("tree", "palm", "pine", "oak", "birch", "fir", "conifer", "spruce", "willow", "maple"),
    "bush": ("bush", "shrub", "hedge"),
    "rock": ("rock", "stone", "boulder", "pebble", "cliff"),
    "grass": ("grass", "reed", "fern", "weed", "flower", "plant"),
    "seaweed": ("seaweed", "kelp", "algae", "seagrass"),
}


@dataclass(frozen=True)
class AssetSpec:
    """One asset to ingest, as the manifest (or the folder scan) describes it."""

    id: str
    category: str
    mesh: Path
    length_m: float | None = None
    height_m: float | None = None
    up_axis: str | None = None
    forward_axis: str | None = None
    unit: str | float | None = None
    ue_path: str | None = None
    tags: tuple[str, ...] = ()
    draft_m: float | None = None
    floating: bool | None = None
    guessed: str = ""  # how the category was guessed (folder scans)
    origin: str = "base"  # "base": lowest point at z = 0 (then the draft below the waterline); "keep": as authored
    thumb: dict | None = None  # an Unreal thumbnails.json entry (no mesh): dims from bounds, views captured


@dataclass(frozen=True)
class SkippedAsset:
    id: str
    error: str


def check_id(value: Any, where: str) -> str:
    if not isinstance(value, str) or not _ID_RE.match(value):
        raise LibraryError(
            f"{where}: asset id {value!r} is invalid; use 1-100 letters, digits, '_', '-' or '.', starting with "
            "a letter or digit"
        )
    return value


def _opt_float(a: dict, key: str, aid: str, positive: bool = True) -> float | None:
    v = a.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (positive and v <= 0) \
            or v < 0:
        raise LibraryError(f"asset {aid!r}: {key} = {v!r} must be a {'positive ' if positive else ''}number")
    return float(v)


def parse_asset_entry(a: Any, base: Path, index: int, where: str, lenient: bool = False) -> AssetSpec:
    """Validate one manifest entry; errors name the asset and the bad value. ``lenient`` ignores unknown
    fields (manifests written by other tools, like the starter kit's) instead of refusing them."""
    if not isinstance(a, dict):
        raise LibraryError(f"{where}: assets[{index}] must be a table/object, got {a!r}")
    aid = check_id(a.get("id"), f"{where}: assets[{index}]")
    unknown = sorted(set(a) - _MANIFEST_KEYS)
    if unknown and not lenient:
        raise LibraryError(f"asset {aid!r}: unknown field(s) {unknown}; valid fields: {sorted(_MANIFEST_KEYS)}")
    cat = a.get("category")
    if cat not in ASSET_CATEGORIES:
        raise LibraryError(f"asset {aid!r}: unknown category {cat!r}; use one of {', '.join(ASSET_CATEGORIES)}")
    mesh = a.get("mesh")
    if not isinstance(mesh, str) or not mesh.strip():
        raise LibraryError(f"asset {aid!r}: 'mesh' must be a path relative to the manifest, got {mesh!r}")
    if os.path.isabs(mesh) or re.match(r"^[A-Za-z]:[\\/]", mesh):
        raise LibraryError(f"asset {aid!r}: mesh path {mesh!r} is absolute; give it relative to the manifest folder")
    base_n = os.path.normpath(os.path.abspath(base))
    full = os.path.normpath(os.path.join(base_n, mesh))
    if os.path.commonpath([base_n, full]) != base_n:
        raise LibraryError(f"asset {aid!r}: mesh path {mesh!r} escapes the manifest folder {base}; "
                           "copy the model inside it")
    # and once links are resolved: a symlink in the folder to a file elsewhere escapes it just as ../ does
    # (a manifest from someone else could point the build at any file on this machine)
    real_base, real = os.path.realpath(base_n), os.path.realpath(full)
    if os.path.commonpath([real_base, real]) != real_base:
        raise LibraryError(f"asset {aid!r}: mesh path {mesh!r} is a link to {real}, outside the manifest folder "
                           f"{base}; copy the model inside it")
    tags = a.get("tags", ())
    if isinstance(tags, str) or not all(isinstance(t, str) for t in tags):
        raise LibraryError(f"asset {aid!r}: tags = {tags!r} must be a list of strings")
    ue = a.get("ue_path")
    if ue is not None and not isinstance(ue, str):
        raise LibraryError(f"asset {aid!r}: ue_path = {ue!r} must be a string like /Game/Boats/SM_Boat")
    fl = a.get("floating")
    if fl is not None and not isinstance(fl, bool):
        raise LibraryError(f"asset {aid!r}: floating = {fl!r} must be true or false")
    for k in ("up_axis", "forward_axis"):
        if a.get(k) is not None and not isinstance(a.get(k), str):
            raise LibraryError(f"asset {aid!r}: {k} = {a.get(k)!r} must be a string like '+y'")
    origin = a.get("origin", "base")
    if origin not in ("base", "keep"):
        raise LibraryError(f"asset {aid!r}: origin = {origin!r} must be 'base' (lowest point at z = 0) or 'keep'")
    return AssetSpec(
        id=aid, category=cat, mesh=Path(full), length_m=_opt_float(a, "length_m", aid),
        height_m=_opt_float(a, "height_m", aid), up_axis=a.get("up_axis"), forward_axis=a.get("forward_axis"),
        unit=a.get("unit"), ue_path=ue, tags=tuple(tags), draft_m=_opt_float(a, "draft_m", aid, positive=False),
        floating=fl, origin=origin,
    )


def read_manifest(path: str | Path, lenient: bool = False) -> tuple[list[AssetSpec], list[SkippedAsset]]:
    """Parse a JSON or TOML manifest with a top-level ``assets`` list. Bad entries are returned as skipped."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise LibraryError(f"manifest {path} is not a text file (a model or an image?); give a JSON or TOML "
                           "manifest with an 'assets' list, or the folder of models") from None
    except OSError as exc:
        raise LibraryError(f"cannot read manifest {path}: {exc}") from exc
    try:
        if path.suffix.lower() == ".toml":
            from ...config import tomllib

            doc = tomllib.loads(text)
        else:
            doc = json.loads(text)
    except ValueError as exc:
        raise LibraryError(f"manifest {path} is not valid {path.suffix[1:].upper() or 'JSON'}: {exc}") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("assets"), list):
        raise LibraryError(f"manifest {path} needs a top-level 'assets' list (each with id, category, mesh)")
    if not doc["assets"]:
        raise LibraryError(f"manifest {path} lists no assets")
    specs, skipped, seen = [], [], {}
    for i, a in enumerate(doc["assets"]):
        try:
            s = parse_asset_entry(a, path.parent, i, str(path), lenient)
            if s.id in seen:
                raise LibraryError(f"asset {s.id!r}: duplicate id (assets[{seen[s.id]}] and assets[{i}]); "
                                   "ids must be unique")
            seen[s.id] = i
            specs.append(s)
        except LibraryError as exc:
            aid = a.get("id") if isinstance(a, dict) and isinstance(a.get("id"), str) else f"assets[{i}]"
            skipped.append(SkippedAsset(str(aid), str(exc)))
    return specs, skipped


def _tokens(text: str) -> list[str]:
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", text)
    return [t for t in re.split(r"[^A-Za-z]+", text.lower()) if t]


def guess_category(name: str, folders: Sequence[str] = (), tags: Sequence[str] = ()) -> tuple[str | None, str]:
    """Category from a model's name (last matching word wins: 'Ship_pack__Boat' is a boat), then its tags,
    then its folders. Returns (category or None, the reason)."""
    for source, texts in (("name", [name]), ("tags", list(tags)), ("folder", list(reversed(folders)))):
        for text in texts:
            hits = []
            toks = _tokens(text)
            for pos, t in enumerate(toks):
                for cat, words in CATEGORY_WORDS.items():
                    singular = {t, t[:-1] if t.endswith("s") else t, t[:-2] if t.endswith("es") else t}
                    if singular & set(words) or any(t.endswith(w) and len(w) >= 4 for w in words):
                        hits.append((pos, cat, t))
            if hits:
                pos, cat, word = max(hits, key=lambda h: h[0])
                return cat, f"{source} word {word!r} in {text!r}"
    return None, "no category word in its name, tags or folders"


def scan_folder(src: Path) -> tuple[list[AssetSpec], list[SkippedAsset]]:
    """Every model file under ``src``, category guessed from names; unguessable ones are skipped."""
    files = sorted(p for p in src.rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
    if not files:
        raise LibraryError(f"folder {src} holds no models ({', '.join(MESH_SUFFIXES)}); give a folder of models "
                           "or a manifest")
    specs, skipped, seen = [], [], {}
    for f in files:
        aid = re.sub(r"[^A-Za-z0-9_.\-]", "_", f.stem).strip("._-")[:100] or "asset"
        if not aid[0].isalnum():
            aid = "a" + aid
        folders = list(f.relative_to(src).parent.parts)
        cat, why = guess_category(f.stem, folders)
        if aid in seen:
            skipped.append(SkippedAsset(aid, f"asset {aid!r}: duplicate id from {f} and {seen[aid]}; rename one "
                                             "file or write a manifest"))
            continue
        seen[aid] = f
        if cat is None:
            skipped.append(SkippedAsset(aid, f"asset {aid!r} ({f.name}): cannot guess its category ({why}); write a "
                                             f"manifest with category one of {', '.join(ASSET_CATEGORIES)}"))
            continue
        specs.append(AssetSpec(id=aid, category=cat, mesh=f, guessed=why))
    return specs, skipped
