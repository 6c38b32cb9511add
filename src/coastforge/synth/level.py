"""A synthetic level: its layout (``presets``) rasterised into classes, its truth heights (``terrain``),
its objects and vegetation as a ``Scene``; ``synth_to_dir`` renders it (``render``) and writes its files."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import shapely
from shapely import affinity

from .. import __version__, frames
from ..classes import ASPHALT, DIRT, GRASS, ROCKS, SAND, TREES, WATER
from ..errors import InputError
from ..rng import stage_rng
from ..scene import Scene, SceneObject, Vegetation
from .layout import BENCHMARK_MIX, Mix

PRESETS: tuple[str, ...] = ("simple_pier_a", "simple_pier_b", "pier_parking", "marina", "lake_harbor",
                            "beach", "rocky_shore")
DEFAULT_GSDS: tuple[float, ...] = (0.1, 0.2)
DEFAULT_GRID_M = 0.2  # truth raster resolution


@dataclass(frozen=True)
class SynthResult:
    preset: str
    seed: int
    out_dir: Path
    truth_path: Path
    inputs_path: Path
    image_paths: tuple[Path, ...]
    gsds: tuple[float, ...]
    n_objects: int
    n_vegetation: int
    extent_m: tuple[float, float]
    timings: tuple[tuple[str, float], ...]  # (step, seconds)

    @property
    def timing(self) -> dict[str, float]:
        return dict(self.timings)


# ---------------------------------------------------------------- assets


def check_preset(preset: str) -> str:
    if preset not in PRESETS:
        raise InputError(f"unknown synth preset {preset!r}; choose one of: {', '.join(PRESETS)} (or 'all')")
    return preset


def kit_catalog():
    """Asset id → ``AssetDims`` of the starter kit (the ids the layouts are written with)."""
    from ..assets.kit import kit_assets
    from .layout import AssetDims

    return {a.id: AssetDims(a.id, a.category, *map(float, a.dims_m), float(a.draft_m), bool(a.floating),
                            tuple(a.tags)) for a in kit_assets()}


def asset_catalog(library: str | Path | None = None, rng: np.random.Generator | None = None):
    """Layout role (a kit id: "sedan", "pier_finger", ...) → the ``AssetDims`` of the asset placed in
    that role: the kit's own asset, or with ``library`` the library asset of the same category whose
    length is closest (one of the nearest few, drawn by ``rng``). Roles the library cannot fill (no
    asset of that category) keep the kit asset."""
    kit = kit_catalog()
    if library is None:
        return kit
    from ..assets.library import Library
    from .layout import AssetDims

    lib = Library.load(library)
    try:
        assets = [AssetDims(str(a.id), str(a.category), *map(float, a.dims_m),
                            float(getattr(a, "draft_m", 0.0)),
                            bool(getattr(a, "floating", a.category in ("boat", "buoy"))),
                            tuple(getattr(a, "tags", ()))) for a in lib.assets]
    except (AttributeError, TypeError, ValueError) as exc:
        raise InputError(f"--library {library}: cannot read its assets' ids, categories and dimensions "
                         f"({exc}); omit --library to use the starter kit") from exc
    rng = rng if rng is not None else np.random.default_rng(0)
    out = {}
    for role, k in kit.items():
        cands = [a for a in assets if a.category == k.category and a.length_m > 0]
        if not cands:
            out[role] = k
            continue
        err = np.array([abs(math.log(a.length_m / k.length_m)) for a in cands])
        order = np.argsort(err, kind="stable")
        near = [int(i) for i in order[:3] if err[i] <= err[order[0]] + math.log(1.25)]
        out[role] = cands[near[int(rng.integers(0, len(near)))]]
    return out


# ---------------------------------------------------------------- rasters


def _polygons(geom):
    if geom.is_empty:
        return []
    if geom.geom_type == "Polygon":
        return [geom]
    return [g for part in getattr(geom, "geoms", []) for g in _polygons(part)]


def rasterize(layout, grid_m: float) -> np.ndarray:
    """The layout's land-use polygons painted (by priority) on the scene grid → class ids (H, W) uint8."""
    import cv2

    n = int(round(layout.size_m / grid_m))
    classes = np.full((n, n), WATER, np.uint8)
    for _z, _k, geom, cls in sorted(layout.paints, key=lambda p: (p[0], p[1])):
        for poly in _polygons(geom):
            rings = [np.asarray(poly.exterior.coords)] + [np.asarray(r.coords) for r in poly.interiors]
            px = []
            for r in rings:
                x, y = layout.to_scene(r[:, 0], r[:, 1])
                col, row = frames.scene_to_pixel(x, y, n, n, grid_m)
                # OpenCV: integer coordinates are pixel centres
                px.append(np.stack([col - 0.5, row - 0.5], -1))
            lo = np.floor(px[0].min(0)).astype(int) - 1
            hi = np.ceil(px[0].max(0)).astype(int) + 2
            c0, r0 = max(lo[0], 0), max(lo[1], 0)
            c1, r1 = min(hi[0], n), min(hi[1], n)
            if c1 <= c0 or r1 <= r0:
                continue
            mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
            pts = [np.round((p - (c0, r0)) * 16).astype(np.int32) for p in px]
            cv2.fillPoly(mask, [pts[0]], 1, lineType=cv2.LINE_8, shift=4)
            if len(pts) > 1:
                cv2.fillPoly(mask, pts[1:], 0, lineType=cv2.LINE_8, shift=4)
            classes[r0:r1, c0:c1][mask.astype(bool)] = cls
    return classes


def sample_raster(a: np.ndarray, x, y, grid_m: float) -> np.ndarray:
    """Nearest-pixel values of a scene-grid raster at scene points."""
    h, w = a.shape
    col, row = frames.scene_to_pixel(np.asarray(x, float), np.asarray(y, float), w, h, grid_m)
    return a[np.clip(np.floor(row).astype(int), 0, h - 1), np.clip(np.floor(col).astype(int), 0, w - 1)]


# ---------------------------------------------------------------- vegetation

# terrain class -> (asset category, instances per 100 m², minimum spacing m, scale range)
VEG_RULES: dict[int, tuple[tuple[str, float, float, tuple[float, float]], ...]] = {
    TREES: (("tree", 1.5, 3.5, (0.7, 1.3)), ("bush", 0.6, 1.5, (0.7, 1.2))),
    GRASS: (("tree", 0.03, 6.0, (0.7, 1.2)), ("bush", 0.12, 2.0, (0.6, 1.2)),
            ("grass", 0.7, 1.0, (0.6, 1.4))),
    DIRT: (("grass", 0.2, 1.0, (0.5, 1.0)), ("rock", 0.08, 1.0, (0.4, 0.9))),
    ROCKS: (("rock", 5.0, 0.9, (0.5, 1.6)),),
    SAND: (("grass", 0.1, 1.2, (0.5, 1.1)), ("rock", 0.01, 2.0, (0.4, 0.8))),
}


def scatter_vegetation(classes: np.ndarray, height: np.ndarray, grid_m: float, catalog,
                       rng: np.random.Generator, keep_out) -> Vegetation:
    """Trees on tree patches, bushes and grass clumps on grass, rocks on riprap, by class density."""
    from scipy.spatial import cKDTree

    by_cat: dict[str, list[str]] = {}
    for a in catalog.values():
        by_cat.setdefault(a.category, []).append(a.id)
    h, w = classes.shape
    rows: list[tuple[str, str, float, float, float]] = []
    flat = classes.ravel()
    for cls, rules in VEG_RULES.items():
        idx = np.flatnonzero(flat == cls)
        if not len(idx):
            continue
        area = len(idx) * grid_m * grid_m
        for cat, dens, spacing, (s0, s1) in rules:
            ids = sorted(by_cat.get(cat, []))
            if not ids:
                continue
            n = int(rng.poisson(area / 100.0 * dens))
            if n == 0:
                continue
            pick = idx[rng.integers(0, len(idx), n)]
            r, c = np.divmod(pick, w)
            x, y = frames.pixel_to_scene(c + rng.uniform(0, 1, n), r + rng.uniform(0, 1, n), w, h, grid_m)
            # thin to the minimum spacing (greedy: drop the later point of every close pair)
            drop = set()
            for i, j in sorted(cKDTree(np.stack([x, y], -1)).query_pairs(spacing)):
                if i not in drop:
                    drop.add(j)
            keep = np.array([i for i in range(n) if i not in drop], int)
            if keep_out is not None and len(keep):
                keep = keep[~shapely.contains_xy(keep_out, x[keep], y[keep])]
            for i in keep:
                rows.append((str(rng.choice(ids)), cat, float(x[i]), float(y[i]), float(rng.uniform(s0, s1))))
    if not rows:
        return Vegetation.empty()
    xs = np.array([r[2] for r in rows])
    ys = np.array([r[3] for r in rows])
    zs = sample_raster(height, xs, ys, grid_m).astype(float)
    return Vegetation(
        np.array([r[0] for r in rows], dtype=object),
        np.array(["rock" if r[1] == "rock" else "vegetation" for r in rows], dtype=object),
        np.round(xs, 3), np.round(ys, 3), np.round(zs, 3),
        np.round(rng.uniform(-179.9, 180.0, len(rows)), 2), np.round(np.array([r[4] for r in rows]), 3),
    )


# ---------------------------------------------------------------- assembling the scene


def _tint(rng: np.random.Generator, category: str) -> list[float]:
    """Per-instance colour jitter (a multiplier over the whole mesh)."""
    if category == "vehicle":
        t = np.full(3, rng.uniform(0.9, 1.08)) * rng.uniform(0.96, 1.04, 3)
    elif category == "boat":
        # white/grey gel coat ages and yellows a little; paint colours come from ``_paint``
        t = np.full(3, rng.uniform(0.82, 1.08)) * (1.0 + rng.uniform(-0.04, 0.04, 3))
    else:
        t = rng.uniform(0.88, 1.1, 3) * rng.uniform(0.9, 1.1)
    return [round(float(v), 3) for v in t]


PIER_DECK_M = 0.6  # the kit's pier decks stand this high above their origin (the water level)


# real-world paint colours (sRGB) and how common they are
CAR_PAINTS = (((236, 236, 232), 0.24), ((22, 24, 28), 0.17), ((172, 174, 178), 0.16), ((96, 99, 104), 0.13),
              ((30, 45, 92), 0.08), ((158, 24, 30), 0.08), ((32, 62, 42), 0.04), ((192, 176, 140), 0.04),
              ((118, 150, 186), 0.04), ((212, 112, 30), 0.02))
SMALL_BOAT_PAINTS = ((200, 30, 40), (30, 60, 140), (20, 110, 70), (25, 25, 30), (240, 200, 20),
                     (230, 110, 30), (236, 236, 232))
# body colour varies; the shape tells the type
REPAINTED = ("sedan", "suv", "pickup", "van", "runabout", "kayak")


def _paint(rng: np.random.Generator, asset_id: str) -> list[int] | None:
    """The body colour of a car or small boat (None: the kit's own colours)."""
    if asset_id not in REPAINTED:
        return None
    if asset_id in ("runabout", "kayak"):
        return list(SMALL_BOAT_PAINTS[int(rng.integers(0, len(SMALL_BOAT_PAINTS)))])
    w = np.array([p for _c, p in CAR_PAINTS])
    return list(CAR_PAINTS[int(rng.choice(len(CAR_PAINTS), p=w / w.sum()))][0])


def _objects(layout, classes: np.ndarray, height: np.ndarray, grid_m: float, rng: np.random.Generator,
             dropped: list) -> tuple[SceneObject, ...]:
    out = []
    # a pier stands level with the ground at its land end (deck flush with a quay), never below the water
    deck_z = {}
    pier_tint: dict = {}
    for sid, (u, v) in layout.pier_roots.items():
        x, y = layout.to_scene(u, v)
        deck_z[sid] = float(np.clip(sample_raster(height, [x], [y], grid_m)[0] - PIER_DECK_M, 0.0, 1.5))
    for o in layout.objects:
        x, y = layout.to_scene(o.u, o.v)
        x, y = round(float(x), 4), round(float(y), 4)  # as stored: heights are sampled where the object is
        # last line of defence against a land-use polygon painted over a placed object after the fact
        c = int(sample_raster(classes, [x], [y], grid_m)[0])
        if (o.category == "vehicle" and c != ASPHALT) or (o.category in ("boat", "buoy") and c != WATER):
            dropped.append(o.id)
            continue
        if o.z_kind == "terrain":
            z = float(sample_raster(height, [x], [y], grid_m)[0])
        elif o.z_kind == "deck":
            z = deck_z.get(o.attrs.get("structure"), 0.0)
        else:
            z = 0.0
        attrs = dict(o.attrs)
        if o.category == "pier":  # one structure was built (and weathered) as one
            attrs["tint"] = pier_tint.setdefault(o.attrs.get("structure"), _tint(rng, "pier"))
        else:
            attrs["tint"] = _tint(rng, o.category)
        paint = _paint(rng, o.asset_id)
        if paint is not None:
            attrs["paint"] = paint
        yaw = round(float(frames.wrap_deg(o.yaw_local + layout.theta_deg)), 3)
        out.append(SceneObject(
            id=o.id, category=o.category, asset_id=o.asset_id,
            x_m=x, y_m=y, z_m=round(z, 4),
            yaw_deg=yaw if yaw != -180.0 else 180.0, scale=tuple(round(s, 5) for s in o.scale),
            length_m=round(o.length_m, 4), width_m=round(o.width_m, 4), source="synthetic", score=1.0,
            attrs=attrs,
        ))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class SynthLevel:
    """A synthesized level: the truth scene plus what only the renderer needs (clutter, layout)."""

    scene: Scene
    layout: object  # layout.Layout (local frame geometry, decor)
    seconds: float


def synthesize_level(preset: str, seed: int, *, size_m: float | None = None, grid_m: float = DEFAULT_GRID_M,
                     library: str | Path | None = None, mix: Mix | None = None) -> SynthLevel:
    """Lay out and rasterize one level (see ``synthesize``), keeping the layout for the renderer.

    ``mix`` (default: the benchmark's) sets which asset types are drawn how often (``layout.Mix``)."""
    from .presets import build_layout
    from .terrain import truth_heights

    check_preset(preset)
    if not (isinstance(grid_m, (int, float)) and 0.02 <= grid_m <= 2.0
            and abs(2.0 / grid_m - round(2.0 / grid_m)) < 1e-6):
        raise InputError(f"grid_m = {grid_m!r} must divide 2 m (level sizes are even metres), "
                         "e.g. 0.1, 0.2, 0.25, 0.5 or 1")
    if size_m is not None and not (isinstance(size_m, (int, float)) and 40 <= size_m <= 1000):
        raise InputError(f"size_m = {size_m!r} must be between 40 and 1000 metres")
    t0 = time.perf_counter()
    catalog = asset_catalog(library, stage_rng(seed, "synth", preset, "library_roles"))
    missing = [a for a in ("pier_walkway", "pier_finger", "buoy", "sedan", "runabout") if a not in catalog]
    if missing:
        raise InputError(f"the asset set lacks {missing}; synth needs the starter kit's ids "
                         "(or a library with them)")
    layout, tparams, info = build_layout(preset, stage_rng(seed, "synth", preset, "layout"), catalog, size_m,
                                         mix or BENCHMARK_MIX)
    classes = rasterize(layout, grid_m)
    height = truth_heights(classes, grid_m, tparams, stage_rng(seed, "synth", preset, "terrain"))
    dropped: list[str] = []
    objects = _objects(layout, classes, height, grid_m, stage_rng(seed, "synth", preset, "tint"), dropped)
    keep_out = shapely.union_all([affinity.rotate(o.footprint, layout.theta_deg, origin=(0, 0))
                                  .buffer(1.0) for o in layout.objects]) if layout.objects else None
    veg = scatter_vegetation(classes, height, grid_m, catalog, stage_rng(seed, "synth", preset, "vegetation"),
                             keep_out)
    S = layout.size_m
    dt = time.perf_counter() - t0
    prov = {
        "tool": f"coastforge {__version__}", "stage": "synth", "preset": preset,
        "level": {k: (round(v, 4) if isinstance(v, float) else v) for k, v in info.items()},
        "terrain_model": {k: round(v, 4) for k, v in tparams.__dict__.items()},
        "grid_m": grid_m, "library": str(library) if library is not None else "kit",
        "counts": {c: sum(1 for o in objects if o.category == c)
                   for c in ("boat", "vehicle", "pier", "buoy")},
        "dropped": dropped,
    }
    scene = Scene(name=f"synth_{preset}", seed=int(seed), gsd_m=float(grid_m), extent_m=(S, S), height=height,
                  classes=classes, objects=objects, vegetation=veg, provenance=prov)
    return SynthLevel(scene, layout, dt)


def synthesize(preset: str, seed: int, *, size_m: float | None = None, grid_m: float = DEFAULT_GRID_M,
               library: str | Path | None = None) -> Scene:
    """The truth scene of one synthetic level (rasters in memory; nothing written).

    ``size_m`` overrides the preset's random size (rounded to even metres; e.g. small fast levels in
    tests); ``grid_m`` is the truth raster resolution (stored as ``scene.gsd_m``); ``library`` fills
    the layout's asset roles from an asset library instead of the starter kit."""
    return synthesize_level(preset, seed, size_m=size_m, grid_m=grid_m, library=library).scene


# ---------------------------------------------------------------- writing


def parse_gsds(text: str | tuple | list) -> tuple[float, ...]:
    """``"0.1,0.2"`` → (0.1, 0.2), validated."""
    items = text.split(",") if isinstance(text, str) else list(text)
    out = []
    for it in items:
        try:
            g = float(it)
        except (TypeError, ValueError):
            raise InputError(f"--gsd {text!r}: {it!r} is not a number; "
                             "give metres per pixel like 0.1,0.2") from None
        if not (math.isfinite(g) and 0.02 <= g <= 2.0):
            raise InputError(f"--gsd {text!r}: {g} must be between 0.02 and 2 metres per pixel")
        out.append(g)
    if not out:
        raise InputError("--gsd is empty; give at least one GSD, e.g. --gsd 0.1,0.2")
    if len(set(out)) != len(out):
        raise InputError(f"--gsd {text!r} lists a GSD twice")
    return tuple(out)


def image_name(gsd: float) -> str:
    return f"image_{gsd:.2f}m.png"


def synth_to_dir(preset: str, seed: int, out_dir: str | Path, gsds=DEFAULT_GSDS,
                 library: str | Path | None = None, overwrite: bool = False, *, size_m: float | None = None,
                 grid_m: float = DEFAULT_GRID_M, prepared: bool = False) -> SynthResult:
    """Synthesize a level, render one image per GSD and write truth.json (+ rasters, vegetation.csv),
    the images and inputs.json into ``out_dir`` (refused if not empty unless ``overwrite``)."""
    import json

    from ..fsio import atomic_write_text, prepare_output_dir, write_png
    from ..scene import save_scene
    from .render import mesh_source, render_level

    check_preset(preset)
    gsds = parse_gsds(gsds)
    if not prepared and Path(out_dir).exists():
        prepare_output_dir(out_dir, overwrite)  # refuse a non-empty folder before doing any work
    timings = []
    level = synthesize_level(preset, seed, size_m=size_m, grid_m=grid_m, library=library)
    timings.append(("synthesize", level.seconds))
    meshes = mesh_source(library)
    out = Path(out_dir) if prepared else prepare_output_dir(out_dir, overwrite)
    paths = []
    images = []
    for g in gsds:
        t0 = time.perf_counter()
        rgb = render_level(level, meshes, g, seed)
        p = write_png(out / image_name(g), rgb)
        timings.append((f"render_{g:.2f}m", time.perf_counter() - t0))
        paths.append(p)
        # the image covers the level exactly: at a GSD that does not divide its size, the true GSD
        # differs slightly from the requested one, and inputs.json records the true one
        true_gsd = level.scene.extent_m[0] / rgb.shape[1]
        images.append({"path": p.name, "gsd_m": g if abs(true_gsd - g) < 1e-9 else round(true_gsd, 9)})
    t0 = time.perf_counter()
    scene = replace(level.scene, provenance={**level.scene.provenance,
                                             "timings_s": {k: round(v, 3) for k, v in timings},
                                             "images": images})
    truth = save_scene(scene, out, filename="truth.json")
    inputs = atomic_write_text(out / "inputs.json", json.dumps({"images": images}, indent=2) + "\n")
    timings.append(("write", time.perf_counter() - t0))
    return SynthResult(preset, int(seed), out, truth, inputs, tuple(paths), gsds, len(scene.objects),
                       len(scene.vegetation) if scene.vegetation is not None else 0, scene.extent_m,
                       tuple(timings))


def synth_many(presets: str | list[str], seed: int, out_dir: str | Path, gsds=DEFAULT_GSDS,
               library: str | Path | None = None, overwrite: bool = False) -> list[SynthResult]:
    """``presets`` = a name, a list, or "all": one level per preset (in one subfolder each when several)."""
    from ..fsio import prepare_output_dir

    names = list(PRESETS) if presets == "all" else ([presets] if isinstance(presets, str) else list(presets))
    for n in names:
        check_preset(n)
    gsds = parse_gsds(gsds)
    if len(names) == 1:
        return [synth_to_dir(names[0], seed, out_dir, gsds, library, overwrite)]
    if library is not None:
        from ..assets.library import Library

        Library.load(library)  # a bad --library fails before any folder is made
    root = prepare_output_dir(out_dir, overwrite)
    return [synth_to_dir(n, seed, root / n, gsds, library, overwrite) for n in names]
