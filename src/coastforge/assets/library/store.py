"""Asset libraries: ingest 3D models (or Unreal thumbnails), render top-down views, embed, index.

A library is a folder::

    library.json        format coastforge.library/1: assets, embedder, settings, content hashes
    index.faiss         one row per (asset, view, scale): L2-normalised embeddings, inner product
    meshes/<id>.glb     each model normalised to the scene frame (metres, z up, forward +x;
                        z = 0 at the waterline for floating assets, at the base for the rest)
    views/<id>/l<k>_<background>.png   top-down renders, lighting k of 3, background water|ground
    views/<id>/paint<k>_<background>.png   vehicles and small boats repainted in common body colours
    views/<id>/query_views.npz  small assets also rendered as a query sees them: at coarse GSDs (a few
                        pixels long), random yaw, cropped like the matcher's crops
                        (LibraryConfig.query_view_*); vehicles and boats also between copies of
                        themselves (LibraryConfig.crowded_views)
    views/<id>/silhouette.png   the footprint (255 = object), aligned with the views

``build_library`` re-renders only assets whose mesh or settings changed and re-embeds only what the
embedder has not seen. ``Library.load`` checks the format, the index hash and shape, and the
embedder; a query with another embedder is refused.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ... import __version__
from ...classes import ASSET_CATEGORIES
from ...config import LibraryConfig
from ...errors import CoastforgeError, InputError, LibraryError, OutputExistsError
from ...fsio import atomic_write_bytes, atomic_write_text, read_png, write_png
from ..index import VectorIndex
from ..meshes import MESH_SUFFIXES, file_hash, footprint_mask, load_mesh, normalise_mesh

FORMAT = "coastforge.library/1"
# scene frame (z up) -> glTF (y up): (x, y, z) -> (x, z, -y); a rotation about +x, so faces keep their winding
Z_UP_TO_GLTF = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])
THUMBNAILS_FORMAT = "coastforge.thumbnails/1"
LIBRARY_JSON = "library.json"
INDEX_FILE = "index.faiss"
FLOATING = ("boat", "buoy")
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


# --------------------------------------------------------------------------------------------------
# records


@dataclass(frozen=True)
class AssetRecord:
    """One asset of a library. ``mesh_path`` is the normalised GLB (None for thumbnail-only assets)."""

    id: str
    category: str
    dims_m: tuple[float, float, float]  # length (x, forward), width (y), height (z)
    draft_m: float  # depth of the hull below the waterline (floating assets)
    floating: bool
    ue_path: str | None
    mesh_path: Path | None
    views: tuple[Path, ...]  # PNGs, in the order of ``view_conditions``
    view_gsd_m: float  # metres per pixel of every view of this asset
    tags: tuple[str, ...] = ()
    view_conditions: tuple[str, ...] = ()  # "l<k>_<background>" per view
    mesh_up: str = "z"  # "y": the GLB follows glTF's y-up convention (libraries built since this field exists)
    silhouette_path: Path | None = None  # footprint mask aligned with the views (libraries built since it exists)

    @property
    def length_m(self) -> float:
        return self.dims_m[0]


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


@dataclass(frozen=True)
class BuildReport:
    rendered: tuple[str, ...]  # assets (re-)rendered in this build
    reused: tuple[str, ...]  # assets whose views were unchanged
    embedded: tuple[str, ...]  # assets (re-)embedded
    skipped: tuple[SkippedAsset, ...]
    notes: dict  # asset id -> normalisation notes (guesses)
    seconds: float
    rows: int


# --------------------------------------------------------------------------------------------------
# manifests and folders


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def _sha(*parts: Any) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else _canonical(p).encode())
    return h.hexdigest()


def _check_id(value: Any, where: str) -> str:
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
    aid = _check_id(a.get("id"), f"{where}: assets[{index}]")
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
        folders = [p for p in f.relative_to(src).parent.parts]
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


# --------------------------------------------------------------------------------------------------
# views


def view_lightings():
    from ...render import standard_view_lightings

    return standard_view_lightings()


def _render_source_hash() -> str:
    """Renderer code changes make old views stale: hash its source into the view settings."""
    h = hashlib.sha256()
    from ... import render

    for p in sorted(Path(render.__file__).parent.glob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def view_settings(config: LibraryConfig) -> dict:
    return {
        "size_px": int(config.view_size_px), "base_gsd_m": float(config.view_gsd_m),
        "backgrounds": list(config.backgrounds), "lightings": int(config.lightings),
        "lighting_params": [dataclasses.asdict(l) for l in view_lightings()[: config.lightings]],
        "renderer": _render_source_hash(),
        "paint_variants": bool(config.paint_variants), "paints": [list(p) for p in PAINTS],
        "silhouette": 1,  # footprint masks stored beside the views
        "query_views": {"version": 2, "gsds_m": [float(g) for g in config.query_view_gsds_m],
                        "random_lightings": int(config.query_view_random_lightings),
                        "max_px": float(config.query_view_max_px), "pad": QUERY_PAD, "min_px": QUERY_MIN_PX},
        "crowded_views": {"version": 1, "n": int(config.crowded_views),
                          "gsds_m": [float(g) for g in config.crowded_gsds_m]},
    }


def choose_view_gsd(dims_m: Sequence[float], config: LibraryConfig) -> float:
    """The finest standard scale (base x 2^k) at which the footprint and its shadow fit the view."""
    L, W, H = (float(v) for v in dims_m)
    # diagonal of the footprint plus room for a low sun's shadow
    reach = math.hypot(L, W) + 0.6 * min(H, 2.0 * max(L, W))
    for k in range(-4, 12):
        g = config.view_gsd_m * 2.0 ** k
        if reach / g <= 0.9 * config.view_size_px:
            return float(g)
    raise LibraryError(f"an asset of {L:.1f} x {W:.1f} m does not fit the views; raise library.view_size_px")


def view_conditions(config: LibraryConfig) -> list[tuple[int, str]]:
    n = int(config.lightings)
    if not 1 <= n <= 3:
        raise LibraryError(f"library.lightings = {n} must be 1, 2 or 3")
    for b in config.backgrounds:
        if b not in ("water", "ground"):
            raise LibraryError(f"library.backgrounds has {b!r}; use water and/or ground")
    return [(k, b) for b in config.backgrounds for k in range(n)]


def scale_variants(img: np.ndarray, gsd: float, length_m: float, factors: Sequence[float]):
    """The view plus coarser copies (area-averaged), as a coarser sensor would see it: queries come at any
    metres-per-pixel and small objects lose detail; matching against a copy at a similar scale helps."""
    import cv2

    out = []
    for f in factors:
        if f <= 1.0:
            out.append((img, gsd))
            continue
        if length_m / (gsd * f) < 8:  # too few pixels along the object to say anything more
            break
        h, w = img.shape[:2]
        small = cv2.resize(img, (max(4, round(w / f)), max(4, round(h / f))), interpolation=cv2.INTER_AREA)
        out.append((small, gsd * w / small.shape[1]))
    return out


QUERY_PAD = 1.5  # query-like views are cropped as the matcher crops a detection: 1.5 x its size + 4 px ...
QUERY_MIN_PX = 12  # ... and at least this many pixels, so even a one-pixel object has background around it


def query_view_plan(dims_m: Sequence[float], view_gsd: float, config: LibraryConfig) -> list[tuple[float, int]]:
    """(gsd, crop side in px) of the query-like views of an asset: every configured GSD coarser than its
    standard views at which it is shorter than ``query_view_max_px`` pixels."""
    size = round(max(float(dims_m[0]), float(dims_m[1])), 4)  # as recorded (dims_m are stored rounded)
    out = []
    for g in sorted(float(x) for x in config.query_view_gsds_m):
        if not (g > 0 and math.isfinite(g)):
            raise LibraryError(f"library.query_view_gsds_m has {g!r}; give positive metres per pixel")
        if g <= view_gsd * 1.0001 or size / g >= float(config.query_view_max_px):
            continue
        out.append((g, int(max(QUERY_MIN_PX, math.ceil(size * QUERY_PAD / g - 1e-6) + 4))))
    return out


CROWD_MAX_LENGTH_M = 25.0  # larger boats lie alone (ships at a quay, not in berths)
CROWD_MAX_PX = 160  # crowded views at most this many pixels across


def crowd_mesh(mesh, category: str, dims_m: Sequence[float], rng) -> tuple[Any, tuple[float, float]]:
    """The asset between copies of itself as cars are parked or boats berthed (side by side, a small gap,
    some bays empty; cars facing either way, sometimes a row behind), repainted where it can be. Returns the
    mesh and the centre of the middle asset's footprint."""
    import trimesh

    L, W = float(dims_m[0]), float(dims_m[1])
    b = mesh.bounds
    c = np.array([0.5 * (b[0, 0] + b[1, 0]), 0.5 * (b[0, 1] + b[1, 1]), 0.0])
    paintable = is_paintable(category, dims_m)
    vehicle = category == "vehicle"

    def copy(dx: float, dy: float, flip: bool, paint: bool):
        m = repaint(mesh, PAINTS[int(rng.integers(len(PAINTS)))]) if paint else mesh.copy()
        if flip:
            m.apply_transform(trimesh.transformations.rotation_matrix(math.pi, [0, 0, 1], c))
        m.apply_translation([dx, dy, 0.0])
        return m

    parts = [copy(0.0, 0.0, False, paintable and rng.random() < 0.5)]
    gap = (0.4, 1.2) if vehicle else (0.6, 2.0)
    for side in (-1.0, 1.0):
        if rng.random() < 0.85:
            parts.append(copy(float(rng.uniform(-0.1, 0.1)) * L, side * (W + float(rng.uniform(*gap))),
                              vehicle and rng.random() < 0.5, paintable))
    if vehicle and rng.random() < 0.5:  # the row behind (or in front), nose to nose
        sx = float(rng.choice([-1.0, 1.0])) * (L + float(rng.uniform(0.3, 1.0)))
        parts.append(copy(sx, float(rng.uniform(-0.3, 0.3)), rng.random() < 0.5, paintable))
    return trimesh.util.concatenate(parts), (float(c[0]), float(c[1]))


def render_query_views(mesh, asset_id: str, dims_m: Sequence[float], view_gsd: float, config: LibraryConfig,
                       category: str | None = None):
    """Query-like views (see ``LibraryConfig.query_view_gsds_m``): list of (image, meta dict)."""
    from ...render import render_mesh_view
    from ...rng import stage_rng

    n_random = int(config.query_view_random_lightings)
    if n_random < 0:
        raise LibraryError(f"library.query_view_random_lightings = {n_random} must be 0 or more")
    lightings = view_lightings()
    rng = stage_rng(0, "library-query-views", asset_id)
    out = []
    for g, side in query_view_plan(dims_m, view_gsd, config):
        for k, bg in view_conditions(config):
            yaw = round(float(rng.uniform(-180.0, 180.0)), 3)
            img = render_mesh_view(mesh, g, side, lightings[k], bg, yaw_deg=yaw, seed=int(rng.integers(1 << 30)))
            out.append((img, {"lighting": k, "background": bg, "gsd_m": g, "yaw_deg": yaw}))
        # a few-pixel object shows little more than its contrast with the background, which the water's
        # colour, the sun and haze change: these views sample that variety (random lightings of the library's
        # own stream)
        for bg in config.backgrounds:
            out.extend(_random_lit_view(mesh, g, side, bg, rng) for _ in range(n_random))
    n_crowd = int(config.crowded_views)
    if n_crowd < 0:
        raise LibraryError(f"library.crowded_views = {n_crowd} must be 0 or more")
    for g in config.crowded_gsds_m:
        if not (float(g) > 0 and math.isfinite(float(g))):
            raise LibraryError(f"library.crowded_gsds_m has {g!r}; give positive metres per pixel")
    if n_crowd > 0 and category in ("vehicle", "boat") and float(dims_m[0]) <= CROWD_MAX_LENGTH_M:
        size = max(float(dims_m[0]), float(dims_m[1]))
        crng = stage_rng(0, "library-crowded-views", asset_id)
        bg = "ground" if category == "vehicle" else "water"
        for g in sorted(float(x) for x in config.crowded_gsds_m):
            side = int(max(QUERY_MIN_PX, math.ceil(size * QUERY_PAD / g - 1e-6) + 4))
            if side > CROWD_MAX_PX:
                continue
            out.extend(crowded_view(mesh, category, dims_m, g, side, bg, crng) for _ in range(n_crowd))
    return out


def crowded_view(mesh, category: str, dims_m: Sequence[float], gsd: float, side: int, background: str, rng):
    """One view of the asset between copies of itself (``crowd_mesh``), centred on it, under a random
    lighting and yaw drawn from ``rng``: (image, meta dict)."""
    crowd, centre = crowd_mesh(mesh, category, dims_m, rng)
    img, meta = _random_lit_view(crowd, gsd, side, background, rng, centre)
    return img, {**meta, "crowded": True}


def _random_lit_view(mesh, gsd: float, side: int, background: str, rng, centre_xy=None):
    """One query-like view under a random lighting and yaw drawn from ``rng``: (image, meta dict)."""
    from ...render import random_lighting, render_mesh_view

    light = random_lighting(rng)
    yaw = round(float(rng.uniform(-180.0, 180.0)), 3)
    img = render_mesh_view(mesh, gsd, side, light, background, yaw_deg=yaw, seed=int(rng.integers(1 << 30)),
                           centre_xy=centre_xy)
    return img, {"lighting": "random", "background": background, "gsd_m": gsd, "yaw_deg": yaw}


def write_query_views(path: Path, images: Sequence[np.ndarray]) -> None:
    """All query-like views of one asset in one file (one write instead of dozens of tiny PNGs)."""
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, *[np.asarray(i, np.uint8) for i in images])
    atomic_write_bytes(path, buf.getvalue())


def read_query_views(path: Path, n: int) -> list[np.ndarray]:
    try:
        with np.load(path) as z:
            imgs = [z[f"arr_{i}"] for i in range(n)]
    except (OSError, KeyError, ValueError) as exc:
        raise LibraryError(f"query views {path} are missing or unreadable ({exc}); rebuild the library") from exc
    return imgs


# Common body colours (sRGB): cars and small boats come in any of them, so the library also embeds
# each paintable asset repainted, and a red car in a query still finds its shape.
PAINTS = ((236, 236, 232), (22, 24, 28), (172, 174, 178), (30, 50, 110), (160, 25, 30), (30, 70, 45),
          (235, 190, 30))


def is_paintable(category: str, dims_m: Sequence[float]) -> bool:
    return category == "vehicle" or (category == "boat" and float(dims_m[0]) <= 8.0)


def repaint(mesh, rgb):
    """A copy of ``mesh`` with its body colour (the colour of most of its top-facing area) set to ``rgb``."""
    m = mesh.copy()
    fc = np.asarray(m.visual.face_colors).copy()
    if not len(fc):
        return m
    cols, inv = np.unique(fc[:, :3], axis=0, return_inverse=True)
    inv = inv.ravel()
    top = np.asarray(m.area_faces) * (np.asarray(m.face_normals)[:, 2] > 0.3)
    body = inv == int(np.argmax(np.bincount(inv, weights=top, minlength=len(cols))))
    fc[body, :3] = np.asarray(rgb, np.uint8)
    m.visual.face_colors = fc
    return m


def estimate_draft(category: str, dims_m: Sequence[float]) -> float:
    """Typical draft when the manifest does not give one: small craft ~0.3 m, ships grow with length."""
    L, _W, H = dims_m
    if category == "boat":
        return round(float(min(0.35 * H, 0.04 * L + 0.12)), 3)
    if category == "buoy":
        return round(float(0.4 * H), 3)
    return 0.0


# --------------------------------------------------------------------------------------------------
# per-asset work (runs in worker processes)


def _ingest_one(spec: AssetSpec, out: str, cfg: dict, want_vectors: dict | None) -> dict:
    """Load, normalise, save the mesh, render and save the views; embed when ``want_vectors`` is given.
    Returns a plain dict (picklable); errors come back as {'error': message}."""
    if spec.thumb is not None:
        return _ingest_thumb(spec, out, cfg, want_vectors)
    try:
        from ...render import render_mesh_view

        config = LibraryConfig(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in cfg.items()})
        raw = load_mesh(spec.mesh, spec.id)
        mesh, norm = normalise_mesh(raw, spec.category, asset_id=spec.id, length_m=spec.length_m,
                                    height_m=spec.height_m, up_axis=spec.up_axis, forward_axis=spec.forward_axis,
                                    unit=spec.unit, suffix=spec.mesh.suffix, keep_z=spec.origin == "keep",
                                    source=spec.mesh)
        floating = spec.floating if spec.floating is not None else spec.category in FLOATING
        draft = spec.draft_m if spec.draft_m is not None else (estimate_draft(spec.category, norm.dims_m)
                                                               if floating else 0.0)
        if floating and draft > 0 and spec.origin != "keep":
            mesh.apply_translation([0.0, 0.0, -draft])  # z = 0 at the waterline
        root = Path(out)
        mesh_rel = f"meshes/{spec.id}.glb"
        # glTF is y-up: store (x, y, z) as (x, z, -y), so Unreal's and other glTF importers see it upright
        gltf_mesh = mesh.copy()
        gltf_mesh.apply_transform(Z_UP_TO_GLTF)
        atomic_write_bytes(root / mesh_rel, gltf_mesh.export(file_type="glb"))
        gsd = choose_view_gsd(norm.dims_m, config)
        lightings = view_lightings()
        views, images = [], []
        for k, bg in view_conditions(config):
            img = render_mesh_view(mesh, gsd, int(config.view_size_px), lightings[k], bg, yaw_deg=0.0, seed=k)
            rel = f"views/{spec.id}/l{k}_{bg}.png"
            write_png(root / rel, img)
            views.append({"file": rel, "lighting": k, "background": bg})
            images.append(img)
        # the footprint, aligned with the views: the matcher's templates need it, and rasterising it from the
        # mesh at match time would load trimesh and every mesh into a generate run
        sil_rel = f"views/{spec.id}/silhouette.png"
        write_png(root / sil_rel, footprint_mask(mesh, int(config.view_size_px), gsd) * np.uint8(255))
        paint_views = []
        if config.paint_variants and is_paintable(spec.category, norm.dims_m):
            bg = "ground" if spec.category == "vehicle" else "water"
            for k, rgb in enumerate(PAINTS):
                img = render_mesh_view(repaint(mesh, rgb), gsd, int(config.view_size_px), lightings[1], bg,
                                       yaw_deg=0.0, seed=10 + k)
                rel = f"views/{spec.id}/paint{k}_{bg}.png"
                write_png(root / rel, img)
                paint_views.append({"file": rel, "lighting": 1, "background": bg, "paint": list(rgb)})
                images.append(img)
        qv = render_query_views(mesh, spec.id, norm.dims_m, gsd, config, spec.category)
        query_images, query_views = [q[0] for q in qv], [q[1] for q in qv]
        qfile = f"views/{spec.id}/query_views.npz" if qv else None
        if qfile:
            write_query_views(root / qfile, query_images)
        rec = {
            "id": spec.id, "category": spec.category, "dims_m": [round(v, 5) for v in norm.dims_m],
            "draft_m": float(draft), "floating": bool(floating), "ue_path": spec.ue_path, "mesh": mesh_rel, "mesh_up": "y",
            "source_mesh": str(spec.mesh), "views": views, "paint_views": paint_views,
            "query_views": query_views, "query_views_file": qfile, "silhouette": sil_rel,
            "view_gsd_m": gsd,
            "tags": list(spec.tags),
            "normalisation": {"up_axis": norm.up_axis, "forward_axis": norm.forward_axis, "unit": norm.unit,
                              "scale": norm.scale},
            "notes": ([f"category guessed from the {spec.guessed}"] if spec.guessed else []) + list(norm.notes),
        }
        result = {"record": rec}
        if want_vectors is not None:
            emb = _make_embedder(want_vectors["name"], want_vectors.get("weights"))
            result["vectors"] = _embed_views(emb, images, gsd, norm.dims_m[0], config, query_images,
                                             [q["gsd_m"] for q in query_views])
        else:
            result["images"] = images
            result["query_images"] = query_images
        return result
    except CoastforgeError as exc:
        return {"error": str(exc)}
    except OSError as exc:
        return _os_failure(spec, exc)
    except Exception as exc:  # a broken model must not take the other assets down
        return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}


_OUTPUT_ERRNOS = (28, 122, 30)  # ENOSPC, EDQUOT, EROFS: the library folder, not the asset, is the problem


def _os_failure(spec, exc: OSError) -> dict:
    """An asset job's OS error: a full or read-only disk stops the build (every asset would fail the same
    way, and "no asset could be built" would hide why); others only skip the asset."""
    if exc.errno in _OUTPUT_ERRNOS:
        return {"oserror": (exc.errno, exc.strerror, None if exc.filename is None else str(exc.filename))}
    return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}


def _embed_views(emb, images: list, gsd: float, length_m: float, config: LibraryConfig,
                 query_images: Sequence = (), query_gsds: Sequence[float] = ()) -> np.ndarray:
    """Rows of one asset: each standard view at its scale variants, then the query-like views as they are.
    Downsampled copies as coarse as the query-like views are left out: those views stand for that scale."""
    crops, gsds = [], []
    coarse = min(query_gsds) * 0.99 if len(query_gsds) else math.inf
    for img in images:
        for im, g in scale_variants(img, gsd, length_m, config.embed_scales):
            if g > gsd * 1.0001 and g >= coarse:
                continue
            crops.append(im)
            gsds.append(g)
    crops.extend(query_images)
    gsds.extend(float(g) for g in query_gsds)
    return np.asarray(emb.embed(crops, gsds), np.float32)


def _stored_images(out: Path, rec: dict) -> tuple[list, list, list[float]]:
    """(standard + paint views, query-like views, their GSDs) of a built asset, read back from disk."""
    def rgb(v):
        img = read_png(out / v["file"])
        return img[:, :, :3] if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2)

    qv = rec.get("query_views", [])
    qimgs = read_query_views(out / rec["query_views_file"], len(qv)) if qv else []
    return [rgb(v) for v in rec["views"] + rec.get("paint_views", [])], qimgs, [float(v["gsd_m"]) for v in qv]


def _make_embedder(name: str, weights: str | None = None):
    from ... import registry

    cls = registry.load("embed", name)
    return cls(weights=weights)


# --------------------------------------------------------------------------------------------------
# the library


class Library:
    """A built library on disk. Load with ``Library.load(path)``."""

    def __init__(self, root: Path, doc: dict, assets: tuple[AssetRecord, ...], index: VectorIndex,
                 weights: str | None = None, report: BuildReport | None = None):
        self.root = Path(root)
        self.doc = doc
        self.assets = assets
        self._by_id = {a.id: i for i, a in enumerate(assets)}
        self.index = index
        self._weights = weights
        self._embedder = None
        self._meshes: dict[str, Any] = {}
        self.build_report = report

    # -- loading
    @classmethod
    def load(cls, path: str | Path, embedder: str | None = None, weights: str | Path | None = None,
             check_files: bool = True) -> "Library":
        """Open a library folder (or its library.json). ``embedder`` (a name) must match the one it was built
        with; ``weights`` overrides the recorded weights folder of a weights-based embedder. ``check_files``:
        refuse a library missing a file it lists (a view, a silhouette, a model copy)."""
        root = Path(path)
        if root.is_file() and root.name == LIBRARY_JSON:
            root = root.parent
        jpath = root / LIBRARY_JSON
        if not jpath.is_file():
            raise LibraryError(f"{root} is not an asset library (no {LIBRARY_JSON}); build one with "
                               "`coastforge library build SRC --out DIR`")
        try:
            doc = json.loads(jpath.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise LibraryError(f"{jpath} is not readable JSON ({exc}); rebuild the library") from exc
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
            raise LibraryError(f"{jpath}: format {got!r} is not {FORMAT!r}; rebuild the library with this version")
        try:
            emb = doc["embedder"]
            assets, row_asset = [], []
            for i, a in enumerate(doc["assets"]):
                start, count = a["index_rows"]
                row_asset.extend([i] * int(count))
                assets.append(_record_from_json(root, a))
            idx_info = doc["index"]
            if len(row_asset) != int(idx_info["rows"]):
                raise ValueError(f"assets claim {len(row_asset)} index rows but the index has {idx_info['rows']}")
            starts = [a["index_rows"][0] for a in doc["assets"]]
            if starts != sorted(starts) or (starts and starts[0] != 0):
                raise ValueError("index rows are not contiguous per asset")
        except (KeyError, TypeError, ValueError) as exc:
            raise LibraryError(f"{jpath} is malformed ({type(exc).__name__}: {exc}); rebuild the library") from exc
        if embedder is not None and embedder != emb["name"]:
            raise LibraryError(
                f"library {root} was built with the {emb['name']!r} embedder, not {embedder!r}; query it with "
                f"--embedder {emb['name']} or rebuild it with --embedder {embedder}"
            )
        index = VectorIndex.load(root / idx_info["file"], row_asset, int(emb["dim"]), idx_info.get("sha256"))
        if check_files:
            missing = [(a["id"], f) for a in doc["assets"] for f in _record_files(a) if not (root / f).is_file()]
            if missing:
                shown = ", ".join(f"{f} (asset {aid!r})" for aid, f in missing[:3])
                raise LibraryError(f"library {root} is incomplete: {len(missing)} file(s) it lists are missing, "
                                   f"e.g. {shown}; rebuild it (coastforge library build SRC --out {root}: only "
                                   "the damaged assets are rendered again)")
        return cls(root, doc, tuple(assets), index, str(weights) if weights is not None else emb.get("weights"))

    # -- assets
    def asset(self, asset_id: str) -> AssetRecord:
        try:
            return self.assets[self._by_id[asset_id]]
        except KeyError:
            raise LibraryError(f"asset {asset_id!r} is not in library {self.root}; it has "
                               f"{len(self.assets)} assets, e.g. {', '.join(list(self._by_id)[:8])}") from None

    def __contains__(self, asset_id: str) -> bool:
        return asset_id in self._by_id

    def __len__(self) -> int:
        return len(self.assets)

    def mesh(self, asset_id: str):
        """The asset's mesh in the scene frame (a copy). Thumbnail-only assets get a box of their bounds."""
        import trimesh

        a = self.asset(asset_id)
        if asset_id not in self._meshes:
            if a.mesh_path is None:
                L, W, H = a.dims_m
                box = trimesh.creation.box(extents=(L, W, H))
                box.apply_translation([0, 0, H / 2 - a.draft_m])
                box.visual.face_colors = np.array([150, 150, 150, 255], np.uint8)
                self._meshes[asset_id] = box
            else:
                try:
                    m = load_mesh(a.mesh_path, asset_id)
                except LibraryError as exc:  # the library's own copy: the user did not write that file
                    raise LibraryError(f"asset {asset_id!r}: the library's copy of its model, {a.mesh_path}, is "
                                       f"missing or unreadable ({exc}); rebuild the library (coastforge library "
                                       f"build SRC --out {self.root})") from None
                if a.mesh_up == "y":  # stored in glTF's y-up convention: back to the scene frame
                    m.apply_transform(np.linalg.inv(Z_UP_TO_GLTF))
                self._meshes[asset_id] = m
        return self._meshes[asset_id].copy()

    def view(self, asset_id: str, lighting: int = 1, background: str = "water") -> tuple[np.ndarray, float]:
        """One top-down view (RGB uint8, forward = image right) and its metres per pixel."""
        a = self.asset(asset_id)
        key = f"l{lighting}_{background}"
        if key not in a.view_conditions:
            key = next((c for c in a.view_conditions if c.endswith(background)), a.view_conditions[0])
        p = a.views[a.view_conditions.index(key)]
        try:
            return read_png(p), a.view_gsd_m
        except InputError as exc:
            raise LibraryError(f"asset {asset_id!r}: view {p} is missing or unreadable; rebuild the library") from exc

    def views_on(self, asset_id: str, background: str) -> list[np.ndarray]:
        """Every stored view of the asset on ``background`` (lightings and repainted copies), all at
        ``view_gsd_m``; falls back to the views on the other background when none match."""
        self.asset(asset_id)  # a clear error for an unknown id
        rec = self.doc["assets"][self._by_id[asset_id]]
        files = [v["file"] for v in rec.get("views", []) + rec.get("paint_views", []) if v["background"] == background]
        if not files:
            files = [v["file"] for v in rec.get("views", [])]
        out = []
        for f in files:
            try:
                img = read_png(self.root / f)
            except InputError as exc:
                raise LibraryError(f"asset {asset_id!r}: view {self.root / f} is missing or unreadable; rebuild the "
                                   "library") from exc
            out.append(img[:, :, :3] if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2))
        if not out:
            raise LibraryError(f"asset {asset_id!r} has no views in {self.root}; rebuild the library")
        return out

    def silhouette(self, asset_id: str) -> np.ndarray | None:
        """The asset's footprint seen from above, aligned with its views (float32 0/1), or None when the
        library has none stored (thumbnail assets, libraries built before silhouettes were stored)."""
        p = self.asset(asset_id).silhouette_path
        if p is None:
            return None
        try:
            return (read_png(p) > 127).astype(np.float32)
        except InputError as exc:
            raise LibraryError(f"the silhouette of asset {asset_id!r} ({p}) is unreadable; rebuild the library") from exc

    def top_view(self, asset_id: str, background: str = "water") -> tuple[np.ndarray, float]:
        """The noon-light view on ``background`` (what the matcher compares a crop's heading against)."""
        return self.view(asset_id, 1, background)

    # -- embedding and search
    @property
    def embedder_name(self) -> str:
        return self.doc["embedder"]["name"]

    @property
    def embedder(self):
        """The embedder that built this library (created on first use; its settings are checked)."""
        if self._embedder is None:
            emb = _make_embedder(self.embedder_name, self._weights)
            self.check_embedder(emb)
            self._embedder = emb
        return self._embedder

    def check_embedder(self, emb) -> None:
        rec = self.doc["embedder"]
        old_v = rec.get("settings", {}).get("version") if isinstance(rec.get("settings"), dict) else None
        new_v = emb.settings.get("version") if isinstance(emb.settings, dict) else None
        if emb.name == rec["name"] and old_v != new_v:
            raise LibraryError(
                f"library {self.root} was embedded with version {old_v} of the {emb.name!r} embedder, this is "
                f"version {new_v}: its vectors are not comparable; rebuild it from its models (coastforge library "
                f"build SRC --out {self.root})"
            )
        if emb.name != rec["name"] or _canonical(emb.settings) != _canonical(rec["settings"]) or emb.dim != rec["dim"]:
            raise LibraryError(
                f"library {self.root} was embedded with {rec['name']!r} (settings {_canonical(rec['settings'])[:120]}"
                f"...), not with {emb.name!r} (settings {_canonical(emb.settings)[:120]}...); query it with the same "
                "embedder and weights or rebuild it"
            )

    def embed(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray:
        return self.embedder.embed(list(images), list(gsd_m))

    def _allowed(self, category) -> np.ndarray | None:
        if category is None:
            return None
        cats = {category} if isinstance(category, str) else set(category)
        bad = cats - set(ASSET_CATEGORIES)
        if bad:
            raise LibraryError(f"unknown category {sorted(bad)}; use one of {', '.join(ASSET_CATEGORIES)}")
        return np.array([a.category in cats for a in self.assets], bool)

    # Category vote for searches over all categories: the category of the first hit is the one with the
    # most evidence, sum over its assets of exp((cosine - best) / T) (the category's posterior when every
    # asset is a priori as likely and exp(cosine / T) is its likelihood), not the category of the single
    # best asset, which a lone look-alike of another category can take. 0 turns it off. T tuned on the
    # retrieval benchmark (python -m coastforge.bench.library, seeds 0-2; 3-4 held out), with embedder v5:
    # category misses of rendered queries 67 -> 62 of 1980 (seeds 0-4; 0 and 1 lose 2 each, 2-4 gain), of
    # crops of the synthetic scenes 259 -> 208 of 742 (every seed gains). T is in units of the default
    # embedder's cosine; libraries of other embedders keep the plain ranking until T is calibrated for them.
    CATEGORY_VOTE_T = 0.03
    CATEGORY_VOTE_EMBEDDERS = ("default",)
    # The vote is weighed by the category head's posteriors to this power (``category_prior``; 0: off).
    # Tuned on the retrieval benchmark: 0.5 improves all three sets (rendered queries, synthetic-scene crops,
    # real photos); at 1 and above the head alone decides more, which costs the real crops.
    CATEGORY_PRIOR_BETA = 0.5

    def category_prior(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray | None:
        """The category head's posteriors of crops over this library's categories (sorted names), to weigh
        the category vote of ``search``; None when it does not apply (another embedder, one category, the
        head switched off or not installed)."""
        from ..category_net import CATEGORIES, shipped_head

        names = sorted({a.category for a in self.assets})
        if self.CATEGORY_PRIOR_BETA <= 0 or len(names) < 2 or \
                self.doc.get("embedder", {}).get("name") not in self.CATEGORY_VOTE_EMBEDDERS:
            return None
        head = shipped_head()
        if head is None:
            return None
        post = head.posteriors(images, gsd_m)
        cols = [CATEGORIES.index(c) for c in names]
        prior = post[:, cols] + 1e-6
        return prior / prior.sum(1, keepdims=True)

    def search(self, vectors: np.ndarray, k: int = 5, category: str | Sequence[str] | None = None,
               prior: np.ndarray | None = None) -> list[list[tuple[str, float]]]:
        """Per query vector, the ``k`` best assets as (asset_id, cosine), best first. Without ``category``
        the first hit is the best asset of the category voted for (see ``CATEGORY_VOTE_T``), weighed by
        ``prior`` (per query, over the sorted category names: ``category_prior``) when given; the rest
        follow by cosine."""
        cats = [a.category for a in self.assets]
        if category is None and self.CATEGORY_VOTE_T > 0 and len(set(cats)) > 1 and self.index.rows \
                and self.doc.get("embedder", {}).get("name") in self.CATEGORY_VOTE_EMBEDDERS:
            if int(k) < 1:
                raise LibraryError(f"k = {k} must be at least 1")
            vectors = np.asarray(vectors, np.float32)
            if prior is not None and np.shape(prior) != (len(vectors), len(set(cats))):
                raise LibraryError(f"prior of shape {np.shape(prior)} for {len(vectors)} queries and "
                                   f"{len(set(cats))} categories")
            return self._voted_search(vectors, int(k), cats, prior)
        hits = self.index.search(np.asarray(vectors, np.float32), int(k), self._allowed(category))
        return [[(self.assets[i].id, s) for i, s in row] for row in hits]

    def _voted_search(self, vectors: np.ndarray, k: int, cats: list[str], prior: np.ndarray | None = None
                      ) -> list[list[tuple[str, float]]]:
        scores = self.index.asset_scores(vectors, len(self.assets))
        names = sorted(set(cats))
        cat_of = np.array([names.index(c) for c in cats])
        out = []
        for q, row in enumerate(scores):
            have = np.isfinite(row)
            order = [int(i) for i in np.argsort(-row, kind="stable") if have[i]]
            w = np.where(have, np.exp((row - row[order[0]]) / self.CATEGORY_VOTE_T), 0.0)
            evidence = np.bincount(cat_of, weights=w, minlength=len(names))
            if prior is not None:
                evidence = evidence * np.power(prior[q], self.CATEGORY_PRIOR_BETA)
            voted = int(np.argmax(evidence))
            first = next(i for i in order if cat_of[i] == voted)
            ranked = [first] + [i for i in order if i != first]
            out.append([(self.assets[i].id, float(row[i])) for i in ranked[:k]])
        return out

    def query(self, image: np.ndarray, gsd_m: float, k: int = 5, category: str | Sequence[str] | None = None
              ) -> list[tuple[str, float]]:
        """The ``k`` assets most like one crop (object centred, any rotation)."""
        prior = self.category_prior([image], [gsd_m]) if category is None else None
        return self.search(self.embed([image], [gsd_m]), k, category, prior)[0]


def _record_files(a: dict) -> list[str]:
    """The files (relative to the library) one asset record of library.json lists."""
    files = [v["file"] for v in a.get("views", []) + a.get("paint_views", [])]
    files += [a[k] for k in ("silhouette", "mesh", "query_views_file") if a.get(k)]
    return files


def _intact(path: Path) -> bool:
    """A stored view or model copy that is complete: a PNG whose chunks pass their CRCs, a GLB as long as its
    header says. (An interrupted copy or a damaged disk leaves files that exist but cannot be read.)"""
    from ...io import image_damage

    if path.suffix.lower() == ".png":
        return image_damage(path) is None
    if path.suffix.lower() == ".glb":
        try:
            with open(path, "rb") as fh:
                head = fh.read(12)
            return len(head) == 12 and head[:4] == b"glTF" and int.from_bytes(head[8:12], "little") == \
                path.stat().st_size
        except OSError:
            return False
    return path.is_file()


def _record_from_json(root: Path, a: dict) -> AssetRecord:
    views = tuple(root / v["file"] for v in a["views"])
    conds = tuple(f"l{int(v['lighting'])}_{v['background']}" for v in a["views"])
    dims = tuple(float(v) for v in a["dims_m"])
    if len(dims) != 3 or min(dims) <= 0:
        raise ValueError(f"asset {a.get('id')!r}: dims_m {a['dims_m']!r} must be three positive numbers")
    return AssetRecord(
        id=str(a["id"]), category=str(a["category"]), dims_m=dims, draft_m=float(a.get("draft_m", 0.0)),
        floating=bool(a.get("floating", False)), ue_path=a.get("ue_path"),
        mesh_path=(root / a["mesh"]) if a.get("mesh") else None, views=views, view_gsd_m=float(a["view_gsd_m"]),
        tags=tuple(a.get("tags", ())), view_conditions=conds, mesh_up=str(a.get("mesh_up", "z")),
        silhouette_path=(root / a["silhouette"]) if a.get("silhouette") else None,
    )


# --------------------------------------------------------------------------------------------------
# building


def _previous(out: Path) -> tuple[dict | None, VectorIndex | None, str]:
    """The library already in ``out`` (for incremental rebuilds), or (None, None, why) if absent/unusable."""
    try:
        lib = Library.load(out, check_files=False)  # a missing view is rendered again, not a reason to stop
    except LibraryError as exc:
        return None, None, str(exc)
    return lib.doc, lib.index, ""


def _config_dict(config: LibraryConfig) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(config).items()}


def build_library(src: str | Path | None, out: str | Path, embedder: str = "default", weights: str | Path | None = None,
                  strict: bool = False, config: LibraryConfig = LibraryConfig(), *, from_thumbnails: str | Path | None
                  = None, overwrite: bool = False, workers: int | None = None,
                  progress: Callable[[str], None] | None = None, keep_origin: bool = False,
                  shown_as: str | Path | None = None) -> Library:
    """Build (or incrementally rebuild) a library in ``out`` from a models folder, a manifest, or (with
    ``from_thumbnails``) a folder captured by the Unreal script. Returns the loaded library with
    ``build_report`` set. One bad asset is reported and skipped unless ``strict``. ``shown_as``: the folder
    messages name (``out`` is a staging copy of it)."""
    t0 = time.perf_counter()
    say = progress or (lambda _m: None)
    out = Path(out)
    shown = Path(shown_as) if shown_as is not None else out
    if from_thumbnails is not None:
        specs, skipped = read_thumbnails(Path(from_thumbnails))
    else:
        if src is None:
            raise InputError("give a models folder or a manifest (SRC), or --from-thumbnails DIR")
        src = Path(src)
        if src.is_dir():
            if (src / "thumbnails.json").is_file():
                raise InputError(f"{src} holds a thumbnails.json from Unreal: use --from-thumbnails {src}")
            specs, skipped = scan_folder(src)
        elif src.is_file():
            if src.suffix.lower() not in (".json", ".toml"):
                raise InputError(f"SRC {src} is neither a folder of models nor a .json/.toml manifest")
            specs, skipped = read_manifest(src, lenient=keep_origin)
        else:
            raise InputError(f"SRC {src} does not exist; give a folder of models or a manifest file")
    if keep_origin:  # models authored in the scene frame (the starter kit): keep their waterline / ground
        specs = [dataclasses.replace(s, origin="keep") for s in specs]
    if strict and skipped:
        raise LibraryError(f"{len(skipped)} asset(s) are invalid (--strict): " + "; ".join(s.error for s in skipped))
    if not specs:
        raise LibraryError("no usable assets: " + "; ".join(s.error for s in skipped))
    emb = _make_embedder(embedder, str(weights) if weights is not None else None)
    view_conditions(config)
    # output folder
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {shown} exists and is not a folder")
    prev_doc, prev_index = (None, None)
    if out.is_dir() and any(out.iterdir()):
        prev_doc, prev_index, why = _previous(out)
        if prev_doc is None and not overwrite:
            if (out / LIBRARY_JSON).is_file():
                raise OutputExistsError(f"{shown} holds a library that cannot be read ("
                                        f"{why.replace(str(out), str(shown))}); pass --overwrite to build it "
                                        "again from scratch, or choose another --out")
            raise OutputExistsError(f"{shown} is not empty and holds no valid library; pass --overwrite or "
                                    "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    vset = view_settings(config)
    emb_info = {"name": emb.name, "settings": emb.settings, "dim": int(emb.dim),
                "weights": str(Path(weights).resolve()) if weights is not None else None}
    emb_hash = _sha(emb.name, emb.settings, list(config.embed_scales))
    prev_assets = {a["id"]: a for a in (prev_doc or {}).get("assets", [])}
    dropped = sorted(set(prev_assets) - {s.id for s in specs})
    if dropped and not overwrite:  # an update may add and refresh assets; removing some needs --overwrite
        raise OutputExistsError(f"{shown} holds {len(dropped)} asset(s) that SRC no longer has "
                                f"({', '.join(dropped[:5])}{', ...' if len(dropped) > 5 else ''}); pass "
                                "--overwrite to remove them from the library, or choose another --out")
    prev_vectors = prev_index.vectors() if prev_index is not None else None
    # which assets need work
    records: dict[str, dict] = {}
    vectors: dict[str, np.ndarray] = {}
    todo: list[tuple[AssetSpec, str]] = []
    rendered, reused, embedded = [], [], []
    for s in specs:
        try:
            content = _content_hash(s, vset)
        except OSError as exc:
            skipped.append(SkippedAsset(s.id, f"asset {s.id!r}: cannot read {s.mesh}: {exc}"))
            continue
        old = prev_assets.get(s.id)
        if old is not None and old.get("hashes", {}).get("content") == content and all(
                _intact(out / f) for f in _record_files(old)):  # a missing or damaged file: render it again
            rec = {k: v for k, v in old.items() if k not in ("index_rows", "hashes")}
            records[s.id] = rec
            reused.append(s.id)
            if old["hashes"].get("embedding") == emb_hash and prev_vectors is not None:
                a0, n = old["index_rows"]
                vectors[s.id] = prev_vectors[a0:a0 + n]
            records[s.id]["_content"] = content
        else:
            todo.append((s, content))
    # render (and, for the weight-free default, embed) in worker processes
    in_worker = emb.name == "default"
    if config.workers and workers is None:
        workers = int(config.workers)
    cfg = _config_dict(config)
    results = _run_jobs([(s, str(out), cfg, {"name": emb.name} if in_worker else None) for s, _c in todo],
                        workers, say)
    for res in results:
        if "oserror" in res:
            raise OSError(*res["oserror"])
    for (s, content), res in zip(todo, results):
        if "error" in res:
            skipped.append(SkippedAsset(s.id, res["error"]))
            continue
        rec = res["record"]
        rec["_content"] = content
        records[s.id] = rec
        rendered.append(s.id)
        if "vectors" in res:
            vectors[s.id] = res["vectors"]
        else:
            vectors[s.id] = _embed_views(emb, res["images"], rec["view_gsd_m"], rec["dims_m"][0], config,
                                         res.get("query_images", ()), [q["gsd_m"] for q in rec.get("query_views", [])])
        embedded.append(s.id)
    if strict and skipped:
        raise LibraryError(f"{len(skipped)} asset(s) failed (--strict): " + "; ".join(x.error for x in skipped))
    # reused assets whose embedding is stale: embed their stored views
    for aid, rec in records.items():
        if aid not in vectors:
            imgs, qimgs, qgsds = _stored_images(out, rec)
            vectors[aid] = _embed_views(emb, imgs, rec["view_gsd_m"], rec["dims_m"][0], config, qimgs, qgsds)
            embedded.append(aid)
    if not records:
        raise LibraryError("no asset could be built: " + "; ".join(x.error for x in skipped))
    lib = _write_library(out, [s.id for s in specs if s.id in records], records, vectors, emb_info, emb_hash, vset,
                         config, skipped, weights)
    _prune(out, set(records))
    notes = {aid: tuple(records[aid].get("notes", ())) for aid in records}
    lib.build_report = BuildReport(tuple(rendered), tuple(reused), tuple(embedded), tuple(skipped), notes,
                                   time.perf_counter() - t0, lib.index.rows)
    lib._embedder = emb
    say(f"library {shown}: {len(records)} assets ({len(rendered)} rendered, {len(reused)} reused), "
        f"{len(skipped)} skipped, {lib.index.rows} index rows")
    return lib


def _write_library(out: Path, order: list[str], records: dict, vectors: dict, emb_info: dict, emb_hash: str,
                   vset: dict, config: LibraryConfig, skipped: list, weights) -> Library:
    rows, row_asset, assets_json = [], [], []
    start = 0
    for i, aid in enumerate(order):
        rec = dict(records[aid])
        content = rec.pop("_content")
        v = np.asarray(vectors[aid], np.float32)
        if v.ndim != 2 or v.shape[1] != emb_info["dim"] or not len(v):
            raise LibraryError(f"asset {aid!r}: embedder returned {v.shape} vectors, expected (n, {emb_info['dim']})")
        rec["index_rows"] = [start, int(len(v))]
        rec["hashes"] = {"content": content, "embedding": emb_hash}
        start += len(v)
        rows.append(v)
        row_asset.extend([i] * len(v))
        assets_json.append(rec)
    index = VectorIndex(np.vstack(rows), row_asset)
    digest = index.save(out / INDEX_FILE)
    doc = {
        "format": FORMAT, "generator": f"coastforge {__version__}",
        "embedder": emb_info, "views": vset, "config": _config_dict(config),
        "index": {"file": INDEX_FILE, "kind": "faiss.IndexFlatIP", "rows": index.rows, "dim": index.dim,
                  "sha256": digest},
        "assets": assets_json,
        "skipped": [{"id": s.id, "error": s.error} for s in skipped],
    }
    atomic_write_text(out / LIBRARY_JSON, json.dumps(doc, indent=1))
    return Library.load(out, weights=weights)


def _prune(out: Path, keep: set[str]) -> None:
    """Remove views and meshes of assets no longer in the library (only inside our own sub-folders)."""
    views = out / "views"
    if views.is_dir():
        for d in views.iterdir():
            if d.is_dir() and d.name not in keep:
                shutil.rmtree(d, ignore_errors=True)
    meshes = out / "meshes"
    if meshes.is_dir():
        for f in meshes.glob("*.glb"):
            if f.stem not in keep:
                f.unlink(missing_ok=True)


def _start_method() -> str:
    """``fork`` when it is safe, else ``spawn`` (which needs the caller's script to guard its entry point).

    Forking while another thread holds a lock leaves the child waiting forever on that lock; spawned workers
    start clean. Two such cases: generate builds the starter kit in a background thread while the main thread
    imports scipy, and after our first embree ray cast its TBB pool has native threads of its own (a test that
    rendered views in-process, then built the kit with a forked pool, hung in the child's first ray cast).
    BLAS and OpenCV pools, which every numpy / cv2 process has, fork safely.
    """
    import threading

    ro = sys.modules.get("coastforge.render.objects")
    return "fork" if threading.active_count() == 1 and not getattr(ro, "EMBREE_USED", False) else "spawn"


def _run_jobs(jobs: list[tuple], workers: int | None, say) -> list[dict]:
    """Run ``_ingest_one`` over jobs in worker processes when there is more than one core."""
    if not jobs:
        return []
    n = workers if workers is not None else min(os.cpu_count() or 1, 4)
    if n <= 1 or len(jobs) == 1 or sys.platform == "win32":
        return [_ingest_one(*j) for j in jobs]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ctx = multiprocessing.get_context(_start_method())
    with ProcessPoolExecutor(max_workers=min(n, len(jobs)), mp_context=ctx) as pool:
        futs = [pool.submit(_ingest_one, *j) for j in jobs]
        out = []
        for i, f in enumerate(futs):
            out.append(f.result())
            if (i + 1) % 20 == 0:
                say(f"  {i + 1}/{len(jobs)} assets rendered")
        return out


# --------------------------------------------------------------------------------------------------
# Unreal thumbnails


def read_thumbnails(folder: Path) -> tuple[list[AssetSpec], list[SkippedAsset]]:
    """Parse ``thumbnails.json`` written by ``coastforge/assets/unreal/capture_thumbnails.py``."""
    jpath = folder / "thumbnails.json"
    if not jpath.is_file():
        from ..unreal import CAPTURE_SCRIPT

        raise LibraryError(f"{folder} has no thumbnails.json; capture it in Unreal with the script "
                           f"{CAPTURE_SCRIPT}")
    try:
        doc = json.loads(jpath.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise LibraryError(f"{jpath} is not readable JSON: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != THUMBNAILS_FORMAT or not isinstance(doc.get("assets"), list):
        raise LibraryError(f"{jpath}: expected format {THUMBNAILS_FORMAT!r} with an 'assets' list")
    specs, skipped, seen = [], [], set()
    base = os.path.normpath(os.path.abspath(folder))
    for i, a in enumerate(doc["assets"]):
        name = a.get("name") if isinstance(a, dict) else None
        try:
            if not isinstance(a, dict) or not isinstance(a.get("asset_path"), str):
                raise LibraryError(f"{jpath}: assets[{i}] needs an 'asset_path' string")
            raw = name or a["asset_path"].rsplit("/", 1)[-1].split(".")[0]
            aid = a.get("id") or re.sub(r"[^A-Za-z0-9_.\-]", "_", raw).strip("._-")
            _check_id(aid, f"{jpath}: assets[{i}]")
            if aid in seen:
                raise LibraryError(f"asset {aid!r}: duplicate id in {jpath}; ids must be unique")
            seen.add(aid)
            cat = a.get("category")
            why = ""
            if cat is None:
                cat, why = guess_category(raw, a["asset_path"].split("/")[:-1], a.get("tags", ()))
                if cat is None:
                    raise LibraryError(f"asset {aid!r} ({a['asset_path']}): cannot guess its category ({why}); add "
                                       f"\"category\" to its entry in {jpath}")
            if cat not in ASSET_CATEGORIES:
                raise LibraryError(f"asset {aid!r}: unknown category {cat!r}; use one of {', '.join(ASSET_CATEGORIES)}")
            ext = [float(v) for v in a["bounds_cm"]["box_extent"]]
            if len(ext) != 3 or min(ext) <= 0:
                raise LibraryError(f"asset {aid!r}: bounds_cm.box_extent {ext} must be three positive numbers")
            gsd = float(a["gsd_m"])
            if not gsd > 0:
                raise LibraryError(f"asset {aid!r}: gsd_m {gsd} must be positive")
            views = []
            for v in a["views"]:
                full = os.path.normpath(os.path.join(base, v["file"]))
                if os.path.commonpath([base, full]) != base:
                    raise LibraryError(f"asset {aid!r}: view {v['file']!r} escapes {folder}")
                if not os.path.isfile(full):
                    raise LibraryError(f"asset {aid!r}: view {full} is missing; re-run the capture")
                if v["background"] not in ("water", "ground"):
                    raise LibraryError(f"asset {aid!r}: view background {v['background']!r} must be water or ground")
                views.append({"file": full, "lighting": int(v["lighting"]), "background": v["background"]})
            if not views:
                raise LibraryError(f"asset {aid!r} has no views in {jpath}")
            thumb = {"asset_path": a["asset_path"], "box_extent_cm": ext, "gsd_m": gsd, "views": views}
            specs.append(AssetSpec(id=aid, category=cat, mesh=Path(views[0]["file"]), ue_path=a["asset_path"],
                                   tags=tuple(a.get("tags", ())), guessed=why, thumb=thumb))
        except (KeyError, TypeError, ValueError) as exc:
            skipped.append(SkippedAsset(str(name or f"assets[{i}]"),
                                        f"{jpath}: assets[{i}] is malformed ({type(exc).__name__}: {exc})"))
        except LibraryError as exc:
            skipped.append(SkippedAsset(str(name or f"assets[{i}]"), str(exc)))
    return specs, skipped


def _ingest_thumb(spec: AssetSpec, out: str, cfg: dict, want_vectors: dict | None) -> dict:
    """Thumbnail assets: copy the captured views, dimensions from the Unreal bounds (cm, X forward)."""
    try:
        config = LibraryConfig(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in cfg.items()})
        t = spec.thumb
        ex, ey, ez = t["box_extent_cm"]
        dims = (2 * ex / 100.0, 2 * ey / 100.0, 2 * ez / 100.0)
        notes = ([f"category guessed from the {spec.guessed}"] if spec.guessed else [])
        if dims[1] > dims[0] * 1.05:
            notes.append("the Unreal bounds are longer across Y than along X: forward (+X) may be the short axis")
        floating = spec.category in FLOATING
        draft = estimate_draft(spec.category, dims) if floating else 0.0
        root = Path(out)
        views, images = [], []
        for v in t["views"]:
            img = read_png(v["file"])
            if img.ndim == 3 and img.shape[2] == 4:
                img = img[:, :, :3]
            if img.ndim != 3:
                raise LibraryError(f"asset {spec.id!r}: view {v['file']} is not an RGB image")
            rel = f"views/{spec.id}/l{v['lighting']}_{v['background']}.png"
            write_png(root / rel, img)
            views.append({"file": rel, "lighting": v["lighting"], "background": v["background"]})
            images.append(img)
        rec = {
            "id": spec.id, "category": spec.category, "dims_m": [round(d, 5) for d in dims], "draft_m": draft,
            "floating": floating, "ue_path": spec.ue_path, "mesh": None, "source_mesh": None, "views": views,
            "view_gsd_m": float(t["gsd_m"]), "tags": list(spec.tags),
            "normalisation": {"up_axis": "+z", "forward_axis": "+x", "unit": "cm", "scale": 0.01}, "notes": notes,
        }
        result = {"record": rec}
        if want_vectors is not None:
            emb = _make_embedder(want_vectors["name"], want_vectors.get("weights"))
            result["vectors"] = _embed_views(emb, images, rec["view_gsd_m"], dims[0], config)
        else:
            result["images"] = images
        return result
    except CoastforgeError as exc:
        return {"error": str(exc)}
    except OSError as exc:
        return _os_failure(spec, exc)
    except Exception as exc:
        return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}


def _content_hash(s: AssetSpec, vset: dict) -> str:
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(s).items()
              if k not in ("mesh", "guessed", "thumb")}
    if s.thumb is not None:
        pngs = [hashlib.sha256(Path(v["file"]).read_bytes()).hexdigest() for v in s.thumb["views"]]
        return _sha("thumb", fields, {k: v for k, v in s.thumb.items() if k != "views"},
                    [(v["lighting"], v["background"]) for v in s.thumb["views"]], pngs)
    return _sha(s.mesh.name, file_hash(s.mesh) if s.mesh.is_file() else "missing", fields, vset)


# --------------------------------------------------------------------------------------------------
# the default (starter kit) library


def cache_root() -> Path:
    """``$COASTFORGE_CACHE``, else ``$XDG_CACHE_HOME/coastforge``, else ``~/.cache/coastforge``."""
    if os.environ.get("COASTFORGE_CACHE"):
        return Path(os.environ["COASTFORGE_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "coastforge"


_DEFAULT: dict[str, Library] = {}


def default_library(config: LibraryConfig = LibraryConfig()) -> Library:
    """The starter kit as a library, built once into the user cache (atomically) and reused."""
    from ..kit import MANIFEST_NAME, kit_dir

    manifest = kit_dir() / MANIFEST_NAME
    if not manifest.is_file():
        raise LibraryError(f"the starter kit manifest {manifest} is missing; reinstall coastforge")
    kit_hash = hashlib.sha256(manifest.read_bytes())
    for p in sorted(kit_dir().glob("*.glb")):
        kit_hash.update(p.name.encode())
        kit_hash.update(p.read_bytes())
    emb = _make_embedder(config.embedder)
    key = _sha(kit_hash.hexdigest(), _config_dict(config), emb.settings, view_settings(config), __version__)[:16]
    if key in _DEFAULT:
        return _DEFAULT[key]
    root = cache_root() / f"kit-{key}"
    lib = None
    if (root / LIBRARY_JSON).is_file():
        try:
            lib = Library.load(root)
        except LibraryError:
            lib = None  # corrupted cache: rebuild beside it and swap
    if lib is None:
        root.parent.mkdir(parents=True, exist_ok=True)
        tmp = root.parent / f".kit-{key}.tmp-{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        build_library(manifest, tmp, embedder=config.embedder, config=config, strict=True, keep_origin=True)
        if root.exists():
            try:  # another process finished first: keep its copy (it may be in use)
                Library.load(root)
            except LibraryError:  # the corrupted cache we could not load: replace it
                shutil.rmtree(root, ignore_errors=True)
        try:
            os.rename(tmp, root)
        except OSError:
            pass
        shutil.rmtree(tmp, ignore_errors=True)
        lib = Library.load(root)
    _DEFAULT[key] = lib
    return lib


def open_library(path: str | Path | None = None, config: LibraryConfig = LibraryConfig()) -> Library:
    """The library at ``path``, or the starter-kit library when ``path`` is None (what ``--library`` means)."""
    return default_library(config) if path is None else Library.load(path)


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
