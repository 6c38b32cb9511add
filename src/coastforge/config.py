"""One typed config: dataclass defaults ← a named TOML preset ← a user TOML file ← ``--set key=value``.

Each stage owns one section. ``--set terrain.max_depth_m=12`` parses the value as TOML (so numbers,
booleans, lists and quoted strings work) and checks it against the field's type.
"""

from __future__ import annotations

import dataclasses
import math
import operator
import os
import sys
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from .errors import ConfigError


@dataclass(frozen=True)
class IOConfig:
    max_pixels: int = 1_100_000_000  # larger images are refused as decompression bombs (~33k x 33k)
    gsd_tolerance: float = 0.01  # relative disagreement allowed between --gsd, --size-m and a georeference
    # plausible ground sample distances: finer or coarser values are almost always a wrong --gsd or a
    # georeference in the wrong units (sen2ships' Sentinel-2 ports are 7-9 m/px; drones reach ~1 cm/px)
    min_gsd_m: float = 0.005
    max_gsd_m: float = 50.0
    max_memory_gb: float = 8.0  # refuse an image whose run would need more working memory than this (estimate)


@dataclass(frozen=True)
class SegmentConfig:
    # learned: the small U-Net trained on our renders for land classes + the classical water model; it checks
    # itself against the classical colour rules and falls back to "classical" on photos unlike our renders
    # (and outside 0.04-0.6 m/px); "classical": colour rules only, no network
    backend: str = "learned"
    smooth_px: int = 3  # majority filter radius in pixels
    min_region_m2: float = 20.0  # smaller land patches merge into their surroundings (a small tree crown is ~20 m2)
    weight_blur_m: float = 1.0  # softened borders of the paint-layer weight maps
    self_training: bool = True
    work_gsd_m: float = 0.4  # classical works at this resolution (or the image's, if coarser), then upsamples
    max_work_px: int = 600_000  # cap on the working raster size (speed)
    water_min_m2: float = 1500.0  # smooth water-coloured regions smaller than this are not water
    water_close_m: float = 2.5  # gaps between boats / pier fingers narrower than ~2x this are closed over
    water_hole_max_m2: float = 6000.0  # enclosed non-water blobs up to this size (boats, pier clusters) become water
    pier_open_m: float = 5.0  # structures narrower than ~2x this, tied to the shore and fragmented (piers with boats), are water
    rocks_shore_m: float = 15.0  # rocks farther than this from water are unlikely (0 = no prior)
    vehicle_area_max_m2: float = 400.0  # blobs up to this size enclosed by asphalt become asphalt (parked cars)
    edge_refine_m: float = 1.0  # classical: land pixels this close to a class border are re-decided by their fine features (0 = off)
    biome_shore_m: float = 15.0  # biome map: land this close to the waterline is "shore"
    biome_shallow_m: float = 20.0  # biome map: water this close to land is "shallow" (seaweed)
    # learned backend: water from the network and the classical water model's vote ("fused"), the classical
    # model alone ("classical") or the network alone ("net")
    learned_water: str = "fused"
    learned_flips: int = 2  # learned backend: test-time flips averaged (1 = none, 2 = + mirror, up to 4)
    learned_min_region_m2: float = 12.0  # learned backend: smaller land specks join their surroundings


@dataclass(frozen=True)
class TerrainConfig:
    backend: str = "default"
    max_depth_m: float = 8.0  # depth far from shore
    depth_scale_m: float = 40.0  # distance over which the seabed approaches max depth
    berth_depth_m: float = 4.0  # depth in front of quay walls
    quay_height_m: float = 1.2  # top of a quay above the water level
    d50_mm: float = 0.3  # sand grain size for Dean's profile A = 0.21 D50^0.48
    beach_height_m: float = 1.5  # height of the berm behind a beach
    intertidal_m: float = 0.0  # beach band allowed below the water level (tidal flats)
    revetment_slope: float = 0.6  # rise/run of rock revetments
    bank_slope: float = 0.15  # natural banks (grass, dirt, trees)
    land_rise_m: float = 3.0  # gentle rise of land far from the shore
    land_rise_scale_m: float = 150.0
    noise_m: float = 0.15  # small-scale natural variation (not on paved areas)
    seam_m: float = 20.0  # DEM blending band
    optical_depth: bool = False  # Stumpf log-ratio modulation in clear shallow water
    beach_slope: float = 0.08  # rise/run of the beach face up to the berm
    revetment_height_m: float = 2.0  # crest of a rock revetment above the water level
    revetment_toe_m: float = 2.5  # depth at the foot of a rock revetment
    bank_height_m: float = 1.0  # top of a natural bank above the water level
    shore_blend_m: float = 3.0  # along-coast length over which neighbouring shore types blend
    optical_max_depth_m: float = 6.0  # the optical estimate is trusted only in water shallower than this


@dataclass(frozen=True)
class DetectConfig:
    # hybrid: learned boats/vehicles/buoys + classical piers (+ checked classical boats, hybrid_union);
    # "learned": the net alone; "classical": no network
    backend: str = "hybrid"
    hybrid_union: bool = True  # hybrid backend: also keep classical boats no learned box overlaps
    hybrid_support: float = 0.1  # ... only where the net's boat score reaches this (0: keep them all)
    # learned and hybrid backends: each confident boat's axis averaged with the network's on its crop turned
    # by 90, 180 and 270° (see ``LearnedDetector.tta_axes``); False: the one pass's axis
    axis_tta: bool = True
    # learned backend: the network also runs on each tile mirrored, and the two heatmaps and box maps are
    # averaged (an object one pass is unsure of is found when the other is sure; axes steadier)
    flip_tta: bool = True
    # learned backend: a boat or vehicle the network is unsure of gains this much score for each confident one
    # of its class moored or parked beside it, parallel (at most two: ``detection.learned.row_context``)
    row_context: float = 0.05
    # learned backend: the network also runs on the image shrunk this many times, for big vessels (20 m and
    # more: longer than anything its working scale was trained on), which replace the parts of them the normal
    # pass saw (``LearnedDetector.big_vessels``; 0 = off)
    big_pass: float = 3.0
    # a boat or vehicle whose box lies less than this share inside the image is left out: the picture's
    # edge cuts it, so its size and kind are guesses, and the neighbouring image of a mosaic holds it
    # (``detection.drop_cut_by_frame``; 0 keeps them all)
    min_inside: float = 0.7
    min_boat_length_m: float = 2.0
    max_boat_length_m: float = 60.0
    min_vehicle_length_m: float = 3.0
    max_vehicle_length_m: float = 14.0
    min_score: float = 0.3
    slice_px: int = 1024
    slice_overlap_px: int = 128
    nms_iou: float = 0.3
    refine: bool = True  # fit boat/vehicle/buoy boxes to the object's symmetry axis and silhouette
    # classical backend (lengths in metres; colour differences in Lab units)
    work_gsd_m: float = 0.15  # finer images are downsampled to this for speed
    min_water_area_m2: float = 400.0
    water_min_chroma: float = 9.0  # water is tinted (blue/green); grey asphalt is not
    water_model_m: float = 8.0  # scale of the local water colour model
    near_water_m: float = 15.0  # objects further from water are land
    boats_need_water: bool = True  # any backend: a boat further than near_water_m from water is not one
    boats_make_water: bool = True  # any backend, with a class map: clusters of moored boats are water (consistency.py)
    # any backend, with a class map: a vehicle whose box is at least this fraction water or rock (riprap) is
    # not one (0 = off): the learned net took riprap blocks along breakwaters for cars (synthetic levels,
    # seeds 1, 2 and 4: 26 boxes, 0.84-1.0 water or rock under them); every true car of seeds 0-4 had under
    # 0.2, every car found on the DOTA marina under 0.02
    vehicle_max_wet: float = 0.5
    struct_dl: float = 15.0  # structure over water: brighter than the water by this
    struct_dc: float = 10.0  # ... or of another colour by this
    boat_mask: str = "core"  # core: bright/coloured cores grown by watershed | struct: all structure
    boat_core_dl: float = 70.0
    boat_core_headroom: float = 0.55  # ... at most this fraction of (255 - water L) on light water
    boat_core_dc: float = 14.0
    boat_region_dl: float = 30.0
    boat_region_dc: float = 12.0
    boat_open_m: float = 0.4
    min_boat_width_m: float = 1.2
    min_boat_aspect: float = 1.4
    merge_gap_m: float = 1.0  # boat pieces on one axis closer than this are joined
    max_boat_aspect: float = 5.5
    split_area_m2: float = 25.0  # cores bigger than this may be re-seeded to split rafted boats...
    split_max_aspect: float = 1.5  # ... when squatter than this (one boat is ~2.5-4 times longer than wide)
    boat_water_touch_m: float = 4.0  # a boat comes at least this close to open water
    mainland_cut_m: float = 2.0  # walkways narrower than twice this do not join a pier block to land
    mainland_far_m: float = 20.0  # land reaches this far from any water
    snap_deg: float = 10.0  # snap boat axes to their pier's direction (or perpendicular) within this
    snap_radius_m: float = 15.0  # ... when the pier is this close (or one boat length)
    pier_gsd_m: float = 0.3  # piers are searched on a grid this coarse (speed)
    # classical (and hybrid) piers: the pier-deck network's decks join the structure mask (``detection.pier_net``)
    pier_net: bool = True
    # ... and pier walkways along the spine of the deck parts the straight line openings left (curved walkways:
    # ``piers.deck_spines``)
    deck_spines: bool = True
    walkway_min_m: float = 18.0
    walkway_max_width_m: float = 3.0
    finger_min_m: float = 5.0
    finger_max_width_m: float = 1.6
    buoy_min_area_m2: float = 0.04
    buoy_max_area_m2: float = 2.0
    buoy_clear_m: float = 3.0  # nothing else this close to a buoy
    buoy_contrast: float = 40.0
    vehicles: bool = True
    vehicle_water_gap_m: float = 3.0
    vehicle_hat_m: float = 3.2  # top-hat disc: wider than a car, narrower than two
    vehicle_dl: float = 40.0
    vehicle_dc: float = 25.0  # ... or this much more colourful than the ground (chroma top-hat)
    vehicle_ground_chroma: float = 20.0  # paved ground around a car is this grey ...
    vehicle_ground_frac: float = 0.25  # ... on at least this fraction of a ring 1 m round it
    vehicle_shadow_m: float = 2.0  # dark blobs this close to vegetation are taken for tree shadows
    vehicle_pitch_m: float = 2.6  # centre spacing of cars parked side by side


@dataclass(frozen=True)
class LibraryConfig:
    # how `library build` and the starter kit generate uses (built once per setting, cached) render and embed
    # assets; a library given with --library keeps the settings it was built with
    embedder: str = "default"
    view_gsd_m: float = 0.05  # base metres per pixel of the views; each asset uses base x 2^k so it fits
    view_size_px: int = 128
    lightings: int = 3
    backgrounds: tuple[str, ...] = ("water", "ground")
    embed_scales: tuple[float, ...] = (1.0, 2.0, 4.0)  # views are also embedded downsampled (coarse queries)
    workers: int = 0  # build processes; 0 = one per core (at most 4)
    paint_variants: bool = True  # also embed vehicles and small boats repainted in common body colours
    # query-like views: each asset also rendered at these coarse GSDs (random yaw, every lighting and
    # background, cropped like the matcher's crops) wherever it is shorter than query_view_max_px pixels:
    # small objects in aerial images are a few pixels, which the downsampled standard views do not mimic
    query_view_gsds_m: tuple[float, ...] = (0.05, 0.07, 0.1, 0.14, 0.2, 0.28, 0.4)
    query_view_max_px: float = 40.0
    # per GSD and background, this many more query-like views under random lightings (water colour, sun,
    # haze): a few-pixel object shows little more than its contrast with the background
    query_view_random_lightings: int = 2
    # vehicles and boats also rendered between copies of themselves, as they are parked or berthed, at these
    # GSDs (this many views each, random lighting and yaw): a crop around a car in a row or a boat in a berth
    # holds its neighbours too (figures: docs/benchmarks.md, "library: crowded views")
    crowded_views: int = 2
    crowded_gsds_m: tuple[float, ...] = (0.1, 0.2)


@dataclass(frozen=True)
class MatchConfig:
    mode: str = "best"  # best | sample
    size_weight: float = 0.5  # how much the metric size counts against appearance
    sample_margin: float = 0.03  # sample among candidates within this similarity of the best
    scale_mode: str = "uniform"  # uniform | per_axis
    scale_min: float = 0.5
    scale_max: float = 2.0
    # shape re-ranking: the crop against each candidate's top views at metric scale (paint-invariant
    # orientation fields, searched over scale, shift and both headings); weights tuned on synthetic levels
    shape: bool = True
    shape_appearance_weight: float = 0.2  # the embedding's cosine added to the shape correlation
    shape_scale_weight: float = 0.02  # log-normal prior on an instance's size against the asset's
    shape_scale_sigma_boat: float = 0.15  # boats of one type vary in size ...
    shape_scale_sigma_vehicle: float = 0.03  # ... cars of one model hardly do (docs/benchmarks.md)
    shape_scale_sigma_buoy: float = 0.1
    shape_length_weight: float = 0.02  # the detected length against the fitted asset's
    shape_length_sigma: float = 0.15
    shape_width_weight: float = 0.02
    shape_width_sigma: float = 0.35
    # heading (bow/stern) decision: the shape fit's evidence (NCC at the same minus at the flipped heading)
    # + the detector's prior (weight x logit(confidence)) + a grey-level cue; prior and grey cue are scaled by
    # ref_px / the object's length in compared pixels: on few pixels the fit's heading evidence is noisier.
    # Tuned on synthetic seeds 0 and 1, seed 2 held out (docs/benchmarks.md).
    heading_prior_weight: float = 0.02
    heading_prior_ref_px: float = 45.0  # length (pixels) at which the weights apply as they are; <= 0: no scaling
    # the crop's grey levels against the chosen asset's mean view at both headings (polarity-aware: dark
    # glass, light roof), which the paint-invariant fit cannot see. A tie-breaker, kept small so it does not
    # move flips onto small levels (docs/benchmarks.md); 0 = off
    heading_appearance_weight: float = 0.02
    # placement from the shape fit: its scale instead of the box's (uniform scale mode), and a weighted mean of
    # its centre and the box centre (weights at 0.1 and 0.2 m/px, linear in the GSD, never below 0: the fit's
    # centre gets noisier as pixels grow; tuned on the synthetic benchmark, seed 0)
    use_shape_fit: bool = True
    shape_offset_weight_fine: float = 0.75  # at 0.1 m/px (and finer)
    shape_offset_weight_coarse: float = 0.5  # at 0.2 m/px


@dataclass(frozen=True)
class PierConfig:
    max_gap_m: float = 6.0  # a pier end this close to land or a walkway is extended to reach it
    deck_height_m: float = 0.6  # a pier asset's deck top above its origin (the kit's decks; synth.PIER_DECK_M)


@dataclass(frozen=True)
class VegetationConfig:
    enabled: bool = True
    tree_density_per_100m2: float = 1.2
    bush_density_per_100m2: float = 0.8
    grass_density_per_100m2: float = 2.0
    rock_density_per_100m2: float = 1.0
    seaweed_density_per_100m2: float = 0.3
    max_slope_deg_trees: float = 25.0
    min_spacing_m: float = 2.0
    max_instances: int = 50_000


@dataclass(frozen=True)
class ExportConfig:
    formats: tuple[str, ...] = ("ue5", "holoocean", "gltf")
    template_level: str = "/Game/HoloOcean/Maps/CoastforgeTemplate"
    package_name: str = "Ocean"
    gltf_max_vertices: int = 250_000
    ue_max_size: int = 8129
    content_path: str = "/Game/Coastforge"  # where build_level.py saves the level and imported meshes
    pcg_graph: str = ""  # optional PCG graph asset path set on the scene's PCG volume
    ticks_per_sec: int = 30  # HoloOcean simulation rate (every sensor Hz must be <= this)
    big_float_length_m: float = 8.0  # floating boats this long or longer go to float/big_float
    max_vegetation_actors: int = 5000  # more instances are left to the PCG masks in Unreal
    sdf_heightmap_max: int = 1025  # Gazebo heightmap side (2^n + 1 samples)
    texture_max_px: int = 4096  # terrain texture side limit for glTF / SDF


@dataclass(frozen=True)
class Config:
    seed: int = 0
    io: IOConfig = field(default_factory=IOConfig)
    segment: SegmentConfig = field(default_factory=SegmentConfig)
    terrain: TerrainConfig = field(default_factory=TerrainConfig)
    detect: DetectConfig = field(default_factory=DetectConfig)
    library: LibraryConfig = field(default_factory=LibraryConfig)
    match: MatchConfig = field(default_factory=MatchConfig)
    piers: PierConfig = field(default_factory=PierConfig)
    vegetation: VegetationConfig = field(default_factory=VegetationConfig)
    export: ExportConfig = field(default_factory=ExportConfig)

    def to_dict(self) -> dict[str, Any]:
        return _to_plain(dataclasses.asdict(self))


def _to_plain(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _to_plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_to_plain(x) for x in v]
    return v


def _coerce(value: Any, tp: Any, key: str) -> Any:
    origin = typing.get_origin(tp)
    if tp is bool:
        if isinstance(value, bool):
            return value
    elif tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif tp is str:
        if isinstance(value, str):
            return value
    elif origin is tuple:
        if isinstance(value, (list, tuple)):
            (item_tp, *_rest) = typing.get_args(tp)
            return tuple(_coerce(v, item_tp, key) for v in value)
    else:  # pragma: no cover - every field type is one of the above
        return value
    tname = getattr(tp, "__name__", str(tp))
    raise ConfigError(f"config key {key} = {value!r} must be of type {tname}")


def _apply(cls: type, base: Any, data: dict, prefix: str) -> Any:
    if not isinstance(data, dict):
        raise ConfigError(f"config section {prefix or '(top)'} must be a table, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in fields(cls)}
    changes = {}
    for k, v in data.items():
        key = f"{prefix}{k}"
        if k not in names:
            raise _unknown_key(key, names)
        tp = hints[k]
        if isinstance(tp, type) and dataclasses.is_dataclass(tp):
            changes[k] = _apply(tp, getattr(base, k), v, key + ".")
        else:
            changes[k] = _coerce(v, tp, key)
    return dataclasses.replace(base, **changes)


# keys that were accepted once and read by nothing: removed, with a word on why instead of a bare "unknown"
REMOVED_KEYS = {
    "render": "nothing read it (`coastforge render` takes its lighting from --sun-azimuth and --sun-elevation)",
    "segment.superpixel_m": "the classical segmenter uses no superpixels",
    "match.k": "the matcher scores every asset of the detected category",
}


def _unknown_key(key: str, names: set[str]) -> ConfigError:
    why = REMOVED_KEYS.get(key)
    if why:
        return ConfigError(f"config key {key!r} was removed: {why}; delete it from --set or the config file")
    return ConfigError(f"unknown config key {key!r}; valid keys here: {', '.join(sorted(names))}; fix the name "
                       "in --set or the config file")


def preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files("coastforge.presets").iterdir() if p.name.endswith(".toml"))


def _read_toml(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where} is not valid TOML: {exc}") from exc


def parse_set(item: str) -> dict:
    """``a.b=value`` → ``{"a": {"b": value}}`` with the value parsed as TOML (bare words are strings)."""
    if "=" not in item:
        raise ConfigError(f"--set {item!r} must look like section.key=value (e.g. terrain.max_depth_m=12)")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ConfigError(f"--set {item!r} has an empty key")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    out: dict = {}
    cur = out
    parts = key.split(".")
    for p in parts[:-1]:
        cur = cur.setdefault(p, {})
    cur[parts[-1]] = value
    return out


def load_config(preset: str = "default", path: str | os.PathLike[str] | None = None, sets: list[str] | tuple[str, ...] = (),
                seed: int | None = None) -> Config:
    """Build the config from a named preset, an optional TOML file, ``--set`` items and ``--seed``."""
    cfg = Config()
    names = preset_names()
    if preset not in names:
        raise ConfigError(f"unknown preset {preset!r}; presets: {', '.join(names)}")
    text = resources.files("coastforge.presets").joinpath(f"{preset}.toml").read_text(encoding="utf-8")
    cfg = _apply(Config, cfg, _read_toml(text, f"preset {preset}"), "")
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"config file {p} does not exist; pass an existing TOML file with --config")
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ConfigError(f"config file {p} is not a text file (an image?); pass a TOML file with sections "
                              "as in the presets, e.g. [terrain] max_depth_m = 12") from None
        cfg = _apply(Config, cfg, _read_toml(text, str(p)), "")
    cfg = apply_settings(cfg, sets)
    if seed is not None:
        cfg = with_seed(cfg, seed)
    return validate_config(cfg)


def apply_settings(cfg: Config, settings: Mapping[str, Any] | Iterable[str] | None) -> Config:
    """``cfg`` with single overrides applied, in order: ``--set`` items (``"terrain.max_depth_m=12"``, the
    value parsed as TOML) or a mapping of dotted keys to Python values (``{"terrain.max_depth_m": 12}``; a
    section may also map to a dict of its keys). Unknown keys and wrong types raise ``ConfigError``; ranges
    are left to ``validate_config``."""
    if settings is None:
        return cfg
    if isinstance(settings, str):  # one item, not its characters
        settings = (settings,)
    if isinstance(settings, Mapping):
        for key, value in settings.items():
            if not isinstance(key, str) or not all(key.split(".")):
                raise ConfigError(f"config override key {key!r} must look like section.key (e.g. "
                                  "terrain.max_depth_m)")
            nested: Any = value
            for part in reversed(key.split(".")):
                nested = {part: nested}
            cfg = _apply(Config, cfg, nested, "")
        return cfg
    items = settings if isinstance(settings, Iterable) else (settings,)
    for item in items:
        if not isinstance(item, str):
            raise ConfigError(f"config override {item!r} must be a KEY=VALUE string (e.g. terrain.max_depth_m=12) "
                              "or given in a mapping {key: value}")
        cfg = _apply(Config, cfg, parse_set(item), "")
    return cfg


def with_seed(cfg: Config, seed: Any) -> Config:
    """``cfg`` with the root seed ``seed``: a whole number (ints and numpy ints; not 1.5, True or "3")."""
    try:
        if isinstance(seed, bool):
            raise TypeError
        seed = operator.index(seed)
    except TypeError:
        raise ConfigError(f"--seed {seed!r} must be a whole number between 0 and {2**63 - 1}") from None
    return dataclasses.replace(cfg, seed=seed)


# ------------------------------------------------------------------------------------------ validation
# Every numeric key must be finite and >= 0; the tables below tighten (or, for the few keys that may be
# negative, replace) that rule. Checked when the config is built, so a bad value stops a run before any
# file is written instead of failing deep inside a stage (or silently producing garbage).

_POSITIVE = frozenset({  # divisors, sizes and scales: 0 would divide by zero or make an empty raster
    "io.max_pixels", "io.min_gsd_m", "io.max_gsd_m", "io.max_memory_gb",
    "segment.work_gsd_m", "segment.max_work_px",
    "terrain.max_depth_m", "terrain.depth_scale_m", "terrain.berth_depth_m", "terrain.quay_height_m",
    "terrain.d50_mm", "terrain.beach_height_m", "terrain.revetment_slope", "terrain.bank_slope",
    "terrain.beach_slope", "terrain.revetment_height_m", "terrain.revetment_toe_m", "terrain.bank_height_m",
    "terrain.land_rise_scale_m", "terrain.shore_blend_m", "terrain.seam_m", "terrain.optical_max_depth_m",
    "detect.max_boat_length_m", "detect.max_vehicle_length_m", "detect.slice_px", "detect.work_gsd_m",
    "detect.water_model_m", "detect.pier_gsd_m", "detect.min_boat_aspect", "detect.max_boat_aspect",
    "detect.split_max_aspect", "detect.buoy_max_area_m2", "detect.walkway_max_width_m",
    "detect.finger_max_width_m", "detect.vehicle_hat_m", "detect.vehicle_dc", "detect.vehicle_pitch_m",
    "library.view_gsd_m", "library.view_size_px", "library.lightings", "library.embed_scales",
    "library.query_view_gsds_m", "library.query_view_max_px", "library.crowded_gsds_m",
    "match.scale_min", "match.scale_max", "match.shape_scale_sigma_boat",
    "match.shape_scale_sigma_vehicle", "match.shape_scale_sigma_buoy", "match.shape_length_sigma",
    "match.shape_width_sigma",
    "export.gltf_max_vertices", "export.ue_max_size", "export.ticks_per_sec", "export.sdf_heightmap_max",
    "export.texture_max_px",
})

_FRACTIONS = frozenset({  # scores, thresholds, IoUs, fractions and blend weights: [0, 1]
    "io.gsd_tolerance", "detect.hybrid_support", "detect.row_context", "detect.min_score", "detect.min_inside",
    "detect.nms_iou", "detect.vehicle_max_wet",
    "detect.boat_core_headroom", "detect.vehicle_ground_frac", "match.sample_margin",
    "match.shape_offset_weight_fine", "match.shape_offset_weight_coarse",
})

_RANGES: dict[str, tuple[float, float]] = {  # inclusive; these replace the ">= 0" rule
    "seed": (0, 2**63 - 1),  # numpy seeds are unsigned
    "segment.learned_flips": (1, 4),  # as is, mirrored, flipped, both
    "detect.snap_deg": (0.0, 90.0),
    "detect.big_pass": (0.0, 8.0),  # 0 = off; else how many times the image is shrunk (> 1)
    "vegetation.max_slope_deg_trees": (0.0, 90.0),
    "match.heading_prior_ref_px": (-math.inf, math.inf),  # documented: <= 0 means no scaling
    "segment.smooth_px": (0, 255),  # a majority filter radius; OpenCV's box filters take no more
    "library.view_size_px": (8, 8192),  # what the view renderer draws
}

# heights, depths and lengths of the terrain model: beyond 12 km (deeper than any sea, higher than any coast)
# a value is a unit mistake, and the height rasters' float32 overflow; each must also pass its rule above
TERRAIN_MAX_ABS_M = 12_000.0

_ORDERED = (  # (smaller, larger): the first must not exceed the second
    ("io.min_gsd_m", "io.max_gsd_m"),
    ("match.scale_min", "match.scale_max"),
    ("detect.min_boat_length_m", "detect.max_boat_length_m"),
    ("detect.min_vehicle_length_m", "detect.max_vehicle_length_m"),
    ("detect.buoy_min_area_m2", "detect.buoy_max_area_m2"),
    ("detect.min_boat_aspect", "detect.max_boat_aspect"),
)

_CHOICES: dict[str, tuple[str, ...]] = {  # the values the consuming code knows
    "segment.learned_water": ("fused", "classical", "net"),  # segmentation.learned.WATER_MODES
    "match.mode": ("best", "sample"),  # matching.match_detections
    "match.scale_mode": ("uniform", "per_axis"),  # placement.fit_scale
    "detect.boat_mask": ("core", "struct", "region"),  # detection.classical
    "library.backgrounds": ("water", "ground"),  # assets.library
}

_BACKEND_STAGES = {"segment.backend": "segment", "terrain.backend": "terrain", "detect.backend": "detect",
                   "library.embedder": "embed", "export.formats": "export"}

_UNITS = (("_per_100m2", "instances per 100 m²"), ("_m2", "square metres"), ("_mm", "millimetres"),
          ("gsd", "metres per pixel"), ("gsds_m", "metres per pixel"), ("_m", "metres"), ("_px", "pixels"),
          ("_deg", "degrees"), ("_gb", "GiB"))


def _meaning(key: str) -> str:
    """The key's unit and its comment in this file, for messages (e.g. "metres; depth far from shore")."""
    section, _, name = key.rpartition(".")
    unit = next((u for suffix, u in _UNITS if name.endswith(suffix) or (suffix == "gsd" and "gsd" in name)), "")
    comment = ""
    try:  # the field's own comment says what it is; read only when a message needs it
        import inspect

        cls = typing.get_type_hints(Config)[section] if section else Config
        for line in inspect.getsource(cls).splitlines():
            if line.strip().startswith(f"{name}:") and "#" in line:
                comment = line.split("#", 1)[1].strip()
                break
    except (OSError, TypeError, KeyError):  # pragma: no cover - no source (frozen app)
        pass
    return "; ".join(p for p in (unit, comment) if p)


def _bad(key: str, value: Any, rule: str) -> ConfigError:
    what = _meaning(key)
    how = "--seed N" if key == "seed" else f"--set {key}=..."
    return ConfigError(f"config key {key} = {value!r} must be {rule}{f' ({what})' if what else ''}; "
                       f"fix it with {how} or in the config file")


def _flat(cfg: Any, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in fields(cfg):
        v = getattr(cfg, f.name)
        if dataclasses.is_dataclass(v):
            out.update(_flat(v, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = v
    return out


def validate_config(cfg: Config) -> Config:
    """Check every value's range, choices and min/max pairs; raise ``ConfigError`` naming the key. Returns ``cfg``."""
    from . import registry

    flat = _flat(cfg)
    for key, value in flat.items():
        if isinstance(value, (str, bool)):
            continue
        items = value if isinstance(value, tuple) else (value,)
        for v in items:
            if isinstance(v, (str, bool)):
                continue
            each = "" if items is not value else "a list whose every item is "
            if not math.isfinite(v):
                raise _bad(key, value, each + "a finite number")
            if key in _RANGES:
                lo, hi = _RANGES[key]
                if not lo <= v <= hi:
                    raise _bad(key, value, f"{each}between {lo} and {hi}")
            elif key in _POSITIVE and not v > 0:
                raise _bad(key, value, each + "> 0")
            elif key in _FRACTIONS and not 0 <= v <= 1:
                raise _bad(key, value, each + "between 0 and 1")
            elif not v >= 0:
                raise _bad(key, value, each + ">= 0")
            if key.startswith("terrain.") and key.endswith("_m") and abs(v) > TERRAIN_MAX_ABS_M:
                raise _bad(key, value, f"{each}at most {TERRAIN_MAX_ABS_M:g}, as no coast is higher or sea deeper "
                                       "than 12 km")
    for lo_key, hi_key in _ORDERED:
        if flat[lo_key] > flat[hi_key]:
            raise ConfigError(f"config key {lo_key} = {flat[lo_key]!r} is larger than {hi_key} = {flat[hi_key]!r}; "
                              f"the minimum must not exceed the maximum: fix one of them with --set or in the "
                              "config file")
    if 0 < flat["detect.big_pass"] <= 1:
        raise _bad("detect.big_pass", flat["detect.big_pass"], "0 (off) or how many times to shrink the image, "
                                                               "more than 1 (the default: 3)")
    if flat["detect.slice_overlap_px"] >= flat["detect.slice_px"]:
        raise ConfigError(f"config key detect.slice_overlap_px = {flat['detect.slice_overlap_px']!r} must be smaller "
                          f"than detect.slice_px = {flat['detect.slice_px']!r} (windows would not advance); fix "
                          "it with --set or in the config file")
    for key, valid in _CHOICES.items():
        for v in flat[key] if isinstance(flat[key], tuple) else (flat[key],):
            if v not in valid:
                raise ConfigError(f"config key {key} = {v!r} is not one of {', '.join(valid)}; fix it with "
                                  f"--set {key}=... or in the config file")
    for key, stage in _BACKEND_STAGES.items():
        kind = "export format" if stage == "export" else f"{stage} backend"
        valid = tuple(s.name for s in registry.specs(stage))
        for v in flat[key] if isinstance(flat[key], tuple) else (flat[key],):
            if v not in valid:
                raise ConfigError(f"config key {key} = {v!r} is not a known {kind}; valid: "
                                  f"{', '.join(valid)}; fix it with --set {key}=... or in the config file")
    return cfg
