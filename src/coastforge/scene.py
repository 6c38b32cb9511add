"""The scene file (DESIGN.md §3): the contract between stages, exporters and evaluation.

``scene.json`` beside its rasters (``terrain/height.tif`` float32 metres, ``terrain/classes.png``
uint8 class ids) and an optional ``vegetation.csv``. ``load_scene`` → ``save_scene`` round-trips
exactly. Validation names the bad field and its value.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from .classes import N_CLASSES, OBJECT_CATEGORIES
from .errors import SceneFormatError
from .fsio import atomic_write_text, read_png, write_geotiff, write_png
from .types import Affine, Grid, affine6

FORMAT = "coastforge.scene/1"
SOURCES = ("detection", "pier", "synthetic", "manual")
VEG_COLUMNS = ("asset_id", "category", "x_m", "y_m", "z_m", "yaw_deg", "scale")


@dataclass(frozen=True)
class SceneObject:
    id: str
    category: str  # boat | vehicle | pier | buoy | vegetation | rock
    asset_id: str
    x_m: float
    y_m: float
    z_m: float
    yaw_deg: float
    scale: tuple[float, float, float]
    length_m: float
    width_m: float
    source: str = "detection"
    score: float = 1.0
    attrs: dict = field(default_factory=dict, compare=False)  # stage-specific extras (kept on round trip)

    def footprint_m(self, grow_m: float = 0.0) -> np.ndarray:
        """The 4 (x, y) corners of the object's rectangle in scene metres: front-left, rear-left, rear-right,
        front-right (``grow_m`` enlarges it on every side)."""
        r = np.deg2rad(self.yaw_deg)
        f = np.array([np.cos(r), np.sin(r)]) * (self.length_m / 2 + grow_m)
        left = np.array([-np.sin(r), np.cos(r)]) * (self.width_m / 2 + grow_m)
        c = np.array([self.x_m, self.y_m])
        return np.array([c + f + left, c - f + left, c - f - left, c + f - left])


@dataclass(frozen=True, eq=False)
class Vegetation:
    """Many instances as a compact column table."""

    asset_id: np.ndarray  # str
    category: np.ndarray  # str
    x_m: np.ndarray
    y_m: np.ndarray
    z_m: np.ndarray
    yaw_deg: np.ndarray
    scale: np.ndarray

    def __len__(self) -> int:
        return len(self.x_m)

    @staticmethod
    def empty() -> Vegetation:
        e = np.zeros(0)
        return Vegetation(np.array([], dtype=object), np.array([], dtype=object), e, e, e, e, e)

    @staticmethod
    def from_rows(rows: list[dict]) -> Vegetation:
        if not rows:
            return Vegetation.empty()
        return Vegetation(
            np.array([str(r["asset_id"]) for r in rows], dtype=object),
            np.array([str(r["category"]) for r in rows], dtype=object),
            *(np.array([float(r[k]) for r in rows]) for k in VEG_COLUMNS[2:]),
        )

    def rows(self) -> list[dict]:
        return [
            {"asset_id": str(self.asset_id[i]), "category": str(self.category[i]),
             **{k: float(getattr(self, k)[i]) for k in VEG_COLUMNS[2:]}}
            for i in range(len(self))
        ]


@dataclass(frozen=True, eq=False)
class Scene:
    name: str
    seed: int
    gsd_m: float
    extent_m: tuple[float, float]
    water_level_m: float = 0.0
    crs: str | None = None
    transform: Affine | None = None
    height: np.ndarray | None = None  # (H, W) float32 metres on the scene grid
    classes: np.ndarray | None = None  # (H, W) uint8 class ids
    objects: tuple[SceneObject, ...] = ()
    vegetation: Vegetation | None = None
    provenance: dict = field(default_factory=dict)
    terrain_paths: dict = field(default_factory=lambda: {"height": "terrain/height.tif",
                                                         "classes": "terrain/classes.png"})
    vegetation_ref: str | None = "vegetation.csv"  # None: vegetation inline in scene.json
    extra: dict = field(default_factory=dict)  # unknown top-level keys, kept on round trip

    @property
    def grid(self) -> Grid:
        """The scene grid (the rasters' grid)."""
        if self.height is not None:
            h, w = self.height.shape
        elif self.classes is not None:
            h, w = self.classes.shape
        else:
            w, h = round(self.extent_m[0] / self.gsd_m), round(self.extent_m[1] / self.gsd_m)
        gsd = self.extent_m[0] / w
        return Grid(w, h, gsd, self.crs, self.transform if self.transform else None)

    def with_objects(self, objects) -> Scene:
        return replace(self, objects=tuple(objects))

    @classmethod
    def load(cls, path: str | Path, rasters: bool = True) -> Scene:
        """The scene in ``path``: a scene folder, its ``scene.json``, or a synthetic level's ``truth.json``
        (``load_scene``). Raises ``SceneFormatError`` naming what is missing or malformed."""
        return load_scene(path, rasters=rasters)

    def save(self, folder: str | Path, filename: str = "scene.json") -> Path:
        """Write the scene file and its rasters into ``folder`` (``save_scene``); returns the scene file."""
        return save_scene(self, folder, filename)


# ---------------------------------------------------------------- validation


def _fail(where: str, msg: str) -> NoReturn:
    raise SceneFormatError(f"{where}: {msg}")


def _num(d: dict, key: str, where: str, positive: bool = False) -> float:
    if key not in d:
        _fail(where, f"missing required field {key!r}")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _fail(where, f"{key} = {v!r} is not a finite number")
    if positive and v <= 0:
        _fail(where, f"{key} = {v!r} must be > 0")
    return float(v)


def _str(d: dict, key: str, where: str) -> str:
    if key not in d:
        _fail(where, f"missing required field {key!r}")
    if not isinstance(d[key], str):
        _fail(where, f"{key} = {d[key]!r} is not a string")
    return d[key]


def object_from_dict(d: Any, where: str) -> SceneObject:
    if not isinstance(d, dict):
        _fail(where, f"expected an object (JSON dict), got {type(d).__name__}")
    cat = _str(d, "category", where)
    if cat not in OBJECT_CATEGORIES:
        _fail(where, f"category = {cat!r} is not one of {', '.join(OBJECT_CATEGORIES)}")
    src = _str(d, "source", where)
    if src not in SOURCES:
        _fail(where, f"source = {src!r} is not one of {', '.join(SOURCES)}")
    yaw = _num(d, "yaw_deg", where)
    if not (-180.0 < yaw <= 180.0):
        _fail(where, f"yaw_deg = {yaw!r} is outside (-180, 180]; wrap it (coastforge.frames.wrap_deg)")
    sc = d.get("scale")
    if (not isinstance(sc, list) or len(sc) != 3
            or not all(isinstance(s, (int, float)) and not isinstance(s, bool) and math.isfinite(s) and s > 0
                       for s in sc)):
        _fail(where, f"scale = {sc!r} must be a list of 3 positive numbers [sx, sy, sz]")
    known = {"id", "category", "asset_id", "x_m", "y_m", "z_m", "yaw_deg", "scale", "length_m", "width_m",
             "source", "score", "attrs"}
    unknown = set(d) - known
    if unknown:
        _fail(where, f"unknown field(s) {sorted(unknown)}; put stage-specific data under 'attrs'")
    attrs = d.get("attrs", {})
    if not isinstance(attrs, dict):
        _fail(where, f"attrs = {attrs!r} must be an object")
    return SceneObject(
        id=_str(d, "id", where), category=cat, asset_id=_str(d, "asset_id", where),
        x_m=_num(d, "x_m", where), y_m=_num(d, "y_m", where), z_m=_num(d, "z_m", where), yaw_deg=yaw,
        scale=(float(sc[0]), float(sc[1]), float(sc[2])), length_m=_num(d, "length_m", where, positive=True),
        width_m=_num(d, "width_m", where, positive=True), source=src, score=_num(d, "score", where), attrs=attrs,
    )


def position_margin_m(extent_m) -> float:
    """How far outside the extent a position may lie: half the scene's larger side, at least 100 m (piers
    and boats at the border reach a little out; anything farther is a unit or frame error)."""
    return max(100.0, 0.5 * max(float(extent_m[0]), float(extent_m[1])))


def _check_inside(where: str, what: str, x: float, y: float, extent_m) -> None:
    w, h = float(extent_m[0]), float(extent_m[1])
    m = position_margin_m(extent_m)
    if not (math.isfinite(x) and math.isfinite(y) and abs(x) <= w / 2 + m and abs(y) <= h / 2 + m):
        _fail(where, f"{what} is at x_m = {x!r}, y_m = {y!r}, more than {m:g} m outside the scene (x in "
                     f"[{-w / 2:g}, {w / 2:g}], y in [{-h / 2:g}, {h / 2:g}] m); positions are metres from the "
                     "image centre: fix or remove it")


def object_to_dict(o: SceneObject) -> dict:
    d = {"id": o.id, "category": o.category, "asset_id": o.asset_id, "x_m": o.x_m, "y_m": o.y_m, "z_m": o.z_m,
         "yaw_deg": o.yaw_deg, "scale": list(o.scale), "length_m": o.length_m, "width_m": o.width_m,
         "source": o.source, "score": o.score}
    if o.attrs:
        d["attrs"] = o.attrs
    return d


_TOP = ("format", "name", "seed", "gsd_m", "extent_m", "water_level_m", "crs", "transform", "terrain", "objects",
        "vegetation", "provenance")


def scene_from_dict(d: Any, where: str = "scene.json") -> Scene:
    """Validate a scene dict (without rasters) and build a Scene."""
    if not isinstance(d, dict):
        _fail(where, "the top level must be a JSON object")
    fmt = d.get("format")
    if fmt != FORMAT:
        _fail(where, f"format = {fmt!r}; expected {FORMAT!r}")
    name = _str(d, "name", where)
    seed = d.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int):
        _fail(where, f"seed = {seed!r} must be an integer")
    gsd = _num(d, "gsd_m", where, positive=True)
    ext = d.get("extent_m")
    if (not isinstance(ext, list) or len(ext) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
                       for v in ext)):
        _fail(where, f"extent_m = {ext!r} must be [width, height] in metres, both finite and > 0")
    wl = _num(d, "water_level_m", where)
    crs = d.get("crs")
    if crs is not None and not isinstance(crs, str):
        _fail(where, f"crs = {crs!r} must be a string or null")
    tr = d.get("transform")
    if tr is not None and (not isinstance(tr, list) or len(tr) != 6
                           or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                      for v in tr)):
        _fail(where, f"transform = {tr!r} must be 6 finite numbers [a, b, c, d, e, f] or null")
    terrain = d.get("terrain")
    if not isinstance(terrain, dict) or not isinstance(terrain.get("height"), str) \
            or not isinstance(terrain.get("classes"), str):
        _fail(where, f"terrain = {terrain!r} must be {{'height': path, 'classes': path}}")
    for k, v in terrain.items():
        if not isinstance(v, str) or Path(v).is_absolute() or ".." in Path(v).parts:
            _fail(where, f"terrain.{k} = {v!r} must be a relative path inside the scene folder")
    objs = d.get("objects")
    if not isinstance(objs, list):
        _fail(where, f"objects = {objs!r} must be a list")
    loaded: list[SceneObject] = []
    for i, o in enumerate(objs):
        named = f" (id {o['id']!r})" if isinstance(o, dict) and isinstance(o.get("id"), str) else ""
        loaded.append(object_from_dict(o, f"{where}: objects[{i}]{named}"))
        _check_inside(where, f"object {loaded[-1].id!r}", loaded[-1].x_m, loaded[-1].y_m, ext)
    objects = tuple(loaded)
    ids = [o.id for o in objects]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        _fail(where, f"duplicate object id(s) {dup[:5]}")
    veg = d.get("vegetation")
    veg_ref: str | None
    vegetation: Vegetation | None = None
    if veg is None:
        veg_ref = None
    elif isinstance(veg, str):
        veg_ref = veg
    elif isinstance(veg, list):
        veg_ref = None
        for i, r in enumerate(veg):
            if not isinstance(r, dict) or any(k not in r for k in VEG_COLUMNS):
                _fail(where, f"vegetation[{i}] = {r!r} needs the fields {', '.join(VEG_COLUMNS)}")
        vegetation = vegetation_from_rows(veg, where, lambda i: f"vegetation[{i}]")
    else:
        _fail(where, f"vegetation = {veg!r} must be a CSV path or a list of instances")
    prov = d.get("provenance", {})
    if not isinstance(prov, dict):
        _fail(where, f"provenance = {prov!r} must be an object")
    return Scene(
        name=name, seed=seed, gsd_m=gsd, extent_m=(float(ext[0]), float(ext[1])), water_level_m=wl, crs=crs,
        transform=affine6(tr) if tr else None, objects=objects, vegetation=vegetation,
        provenance=prov, terrain_paths=dict(terrain), vegetation_ref=veg_ref,
        extra={k: v for k, v in d.items() if k not in _TOP},
    )


def scene_to_dict(s: Scene) -> dict:
    d: dict[str, Any] = {
        "format": FORMAT, "name": s.name, "seed": int(s.seed), "gsd_m": float(s.gsd_m),
        "extent_m": [float(s.extent_m[0]), float(s.extent_m[1])], "water_level_m": float(s.water_level_m),
        "crs": s.crs, "transform": list(s.transform) if s.transform else None,
        "terrain": dict(s.terrain_paths),
        "objects": [object_to_dict(o) for o in s.objects],
    }
    if s.vegetation_ref is not None:
        d["vegetation"] = s.vegetation_ref
    elif s.vegetation is not None:
        d["vegetation"] = s.vegetation.rows()
    d["provenance"] = s.provenance
    d.update(s.extra)
    return d


def dumps(s: Scene) -> str:
    # allow_nan=False: a NaN slipping in must fail loudly here, not produce invalid JSON
    return json.dumps(scene_to_dict(s), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


# ---------------------------------------------------------------- files


def _resolve(folder: Path, rel: str, what: str) -> Path:
    p = (folder / rel).resolve()
    if folder.resolve() not in p.parents and p != folder.resolve():
        raise SceneFormatError(f"{what} = {rel!r} points outside the scene folder {folder}")
    return p


def load_scene(path: str | Path, rasters: bool = True, height: bool = True) -> Scene:
    """Load ``scene.json`` (or a folder holding one, or the ``truth.json`` that ``coastforge synth``
    writes) with its rasters and vegetation table. ``height=False`` leaves the height raster unread (a run
    that replaces it, e.g. ``coastforge terrain --overwrite``, must not stop on a damaged one)."""
    path = Path(path)
    if path.is_dir():
        folder = path
        path = folder / "scene.json"
        if not path.is_file() and (folder / "truth.json").is_file():
            path = folder / "truth.json"
    if not path.is_file():
        raise SceneFormatError(f"no scene file at {path}; expected a scene.json written by coastforge "
                               "(or the truth.json of a synthetic level)")
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SceneFormatError(f"{path} is not valid JSON: {exc}") from exc
    scene = scene_from_dict(d, where=str(path))
    folder = path.parent
    z = classes = None
    if rasters:
        hp = _resolve(folder, scene.terrain_paths["height"], "terrain.height")
        cp = _resolve(folder, scene.terrain_paths["classes"], "terrain.classes")
        if height and hp.exists():
            z = read_height(hp)
            _check_raster_grid(scene, hp, z.shape)
        if cp.exists():
            from .io import image_damage

            why = image_damage(cp)
            if why:
                raise SceneFormatError(f"{cp.name} is truncated or corrupt ({cp}: {why}); re-run coastforge "
                                       "generate to write it again")
            classes = read_png(cp)
            if classes.ndim != 2 or classes.dtype != np.uint8:
                raise SceneFormatError(f"{cp}: class map must be a single-band 8-bit PNG of class ids")
            if classes.max(initial=0) >= N_CLASSES:
                raise SceneFormatError(f"{cp}: class id {int(classes.max())} is not one of 0..{N_CLASSES - 1}")
            _check_raster_grid(scene, cp, classes.shape)
        if z is not None and classes is not None and z.shape != classes.shape:
            raise SceneFormatError(f"{hp} is {z.shape} but {cp} is {classes.shape}; they must share a grid")
    veg = scene.vegetation
    if scene.vegetation_ref is not None:
        vp = _resolve(folder, scene.vegetation_ref, "vegetation")
        veg = read_vegetation_csv(vp) if vp.exists() else Vegetation.empty()
    if veg is not None and len(veg):  # exporters place every instance: none at 1e7 m
        x, y = np.asarray(veg.x_m, float), np.asarray(veg.y_m, float)
        m = position_margin_m(scene.extent_m)
        bad = ~((np.abs(x) <= scene.extent_m[0] / 2 + m) & (np.abs(y) <= scene.extent_m[1] / 2 + m))  # NaN: bad
        if bad.any():
            i = int(np.argmax(bad))
            _check_inside(str(path), f"vegetation instance {i} ({veg.asset_id[i]})", float(x[i]), float(y[i]),
                          scene.extent_m)
    return replace(scene, height=z, classes=classes, vegetation=veg)


def _check_raster_grid(scene: Scene, path: Path, shape: tuple[int, ...]) -> None:
    """A raster must cover the scene's grid: extent_m / gsd_m pixels, or the scene grid of a tiled run."""
    w_m, h_m = scene.extent_m
    tiled = scene.provenance.get("tiled") if isinstance(scene.provenance, dict) else None
    grid = tiled.get("scene_grid_px") if isinstance(tiled, dict) else None
    if isinstance(grid, list) and len(grid) == 2 and all(isinstance(v, int) for v in grid):
        ew, eh = grid
        how = "the scene grid of the tiled run, provenance.tiled.scene_grid_px"
    else:
        ew, eh = round(w_m / scene.gsd_m), round(h_m / scene.gsd_m)
        how = f"extent_m {w_m:g} x {h_m:g} m at gsd_m {scene.gsd_m:g}"
    h, w = shape[:2]
    if abs(w - ew) > 1 or abs(h - eh) > 1:  # 1 px: the extent rounds to whole pixels
        raise SceneFormatError(f"{path} is {w}x{h} px but the scene's grid is {ew}x{eh} px ({how}); the raster "
                               "belongs to another scene or was resized: restore it, or re-run coastforge generate")


_REWRITE_HEIGHT = "re-run coastforge terrain SCENE --overwrite (or coastforge generate) to write it again"


def read_height(path: Path) -> np.ndarray:
    """The height raster: a single-band GeoTIFF of finite metres (what coastforge writes)."""
    import warnings

    import rasterio

    from .io import gdal_reason

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(path) as src:
                if src.driver != "GTiff" or src.count != 1:
                    raise SceneFormatError(
                        f"{path} is a {src.count}-band {src.driver} {src.dtypes[0]} raster, not a height map: "
                        f"terrain heights are a single-band GeoTIFF of metres; {_REWRITE_HEIGHT}")
                z = src.read(1).astype(np.float32)
    except rasterio.errors.RasterioIOError as exc:
        raise SceneFormatError(f"{path.name} is truncated or corrupt ({path}: {gdal_reason(exc)}); "
                               f"{_REWRITE_HEIGHT}") from exc
    bad = ~np.isfinite(z)
    if bad.any():
        raise SceneFormatError(f"{path} holds {int(bad.sum())} of {bad.size} cells that are NaN or infinite; "
                               f"heights must be finite metres: {_REWRITE_HEIGHT}")
    return z


def vegetation_from_rows(rows: list[dict], where: str, row_name) -> Vegetation:
    """Vegetation from table rows, each number checked: finite, and a positive scale (exporters place every
    instance; a NaN height or a negative scale would be written as is)."""
    for i, r in enumerate(rows):
        for k in VEG_COLUMNS[2:]:
            v: Any = r.get(k)
            try:
                f = float(v)
            except (TypeError, ValueError):
                f = None
            if f is None or isinstance(v, bool) or not math.isfinite(f) or (k == "scale" and f <= 0):
                need = "a positive number" if k == "scale" else "a finite number"
                _fail(where, f"{row_name(i)}: {k} = {v!r} must be {need}; fix or remove that row")
    return Vegetation.from_rows(rows)


def read_vegetation_csv(path: Path) -> Vegetation:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames is None or list(reader.fieldnames) != list(VEG_COLUMNS):
                raise SceneFormatError(f"{path}: header must be {','.join(VEG_COLUMNS)}, got {reader.fieldnames}")
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise SceneFormatError(f"{path} is not a CSV text table ({exc}); it must hold the columns "
                               f"{','.join(VEG_COLUMNS)}: restore it, or re-run coastforge generate") from None
    return vegetation_from_rows(rows, str(path), lambda i: f"line {i + 2}")


def vegetation_csv(v: Vegetation) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(VEG_COLUMNS)
    for i in range(len(v)):
        w.writerow([v.asset_id[i], v.category[i], *(repr(float(getattr(v, k)[i])) for k in VEG_COLUMNS[2:])])
    return buf.getvalue()


def save_scene(scene: Scene, folder: str | Path, filename: str = "scene.json", rasters: bool = True) -> Path:
    """Write scene.json (or ``filename``, e.g. truth.json) and its rasters into ``folder``.

    Each file is written atomically; the JSON last, so a scene file always points at complete rasters.
    ``rasters=False`` rewrites only the JSON (e.g. to add timings to a scene already saved, or after
    ``save_scene_rasters``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    text = dumps(scene)  # validate serialisability before touching any file
    scene_from_dict(json.loads(text))
    if rasters:
        save_scene_rasters(scene, folder)
    return atomic_write_text(folder / filename, text)


def save_scene_rasters(scene: Scene, folder: str | Path) -> None:
    """Write the files scene.json points at (height GeoTIFF, class PNG, vegetation CSV), without the JSON.
    ``generate`` writes them in the background while it finishes the scene, then ``save_scene(...,
    rasters=False)``."""
    folder = Path(folder)
    if scene.height is not None:
        tr = scene.transform if scene.transform else scene.grid.scene_transform()
        write_geotiff(_resolve(folder, scene.terrain_paths["height"], "terrain.height"),
                      scene.height.astype(np.float32), tr, crs=scene.crs)
    if scene.classes is not None:
        write_png(_resolve(folder, scene.terrain_paths["classes"], "terrain.classes"), scene.classes.astype(np.uint8))
    if scene.vegetation_ref is not None:
        atomic_write_text(_resolve(folder, scene.vegetation_ref, "vegetation"),
                          vegetation_csv(scene.vegetation or Vegetation.empty()))
