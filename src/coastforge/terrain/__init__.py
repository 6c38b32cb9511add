"""Terrain: a height map (land and bathymetry, metres, z = 0 at the water level) from the class map.

``estimate_terrain`` runs a backend (``default``: shore-aware profiles, no weights; ``onnx``: a
learned model), optionally modulates shallow-water depth with the Stumpf blue/green log-ratio,
fuses user DEMs (which override the estimate where they have data, blended across a seam), and
returns the heights with the shore-type map, shore cross-sections and diagnostics.

Backend protocol: a class built with ``(config: TerrainConfig, **opts)`` with a method
``estimate(class_map: ClassMap, image: GeoImage | None, seed: int) -> HeightMap``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol
from collections.abc import Mapping, Sequence

import numpy as np

from ..config import Config, TerrainConfig
from ..errors import InputError
from ..types import ClassMap, GeoImage, HeightMap
from .default import SHORE_TYPES  # names of the shore_type map's values (0..3; -1 = no shoreline)


class TerrainBackend(Protocol):
    def estimate(self, class_map: ClassMap, image: GeoImage | None, seed: int) -> HeightMap: ...


@dataclass(frozen=True, eq=False)
class CrossSection:
    """Heights along a transect perpendicular to the shore, for a side-view plot.

    ``distance_m`` is signed: negative inland, positive offshore, 0 at the shoreline."""

    shore_type: str
    distance_m: np.ndarray
    height_m: np.ndarray
    start_px: tuple[float, float]  # (col, row) of the inland end
    end_px: tuple[float, float]  # (col, row) of the offshore end

    def to_dict(self) -> dict:
        return {"shore_type": self.shore_type, "start_px": list(self.start_px), "end_px": list(self.end_px),
                "distance_m": [round(float(v), 4) for v in self.distance_m],
                "height_m": [round(float(v), 4) for v in self.height_m]}


@dataclass(frozen=True)
class TerrainDiagnostics:
    backend: str
    seconds: float
    shore_types: tuple[str, ...]  # shore types present along the coastline
    water_fraction: float
    water_at_or_above: int  # water pixels at or above the water level (0 for the default model)
    land_at_or_below: int  # land pixels at or below it, outside the allowed intertidal band
    dem_files: tuple[str, ...] = ()
    dem_coverage: float = 0.0  # fraction of the scene with DEM data
    optical: dict = field(default_factory=dict)  # Stumpf fit summary (used, gain, offset, r2, n_pixels, note)

    def to_dict(self) -> dict:
        return {"backend": self.backend, "seconds": round(self.seconds, 4),
                "shore_types": list(self.shore_types),
                "water_fraction": round(self.water_fraction, 6), "water_at_or_above": self.water_at_or_above,
                "land_at_or_below": self.land_at_or_below, "dem_files": list(self.dem_files),
                "dem_coverage": round(self.dem_coverage, 6), "optical": dict(self.optical)}


@dataclass(frozen=True, eq=False)
class TerrainResult:
    height: HeightMap
    shore_type: np.ndarray  # (H, W) int8 index into SHORE_TYPES, -1 where the image has no shoreline
    cross_sections: tuple[CrossSection, ...]
    diagnostics: TerrainDiagnostics


def make_backend(config: TerrainConfig, backend: str | TerrainBackend | None = None,
                 opts: Mapping[str, Any] | None = None) -> TerrainBackend:
    """A backend instance from a name (``config.backend`` when None) or an object already built."""
    if backend is not None and not isinstance(backend, str):
        if not hasattr(backend, "estimate"):
            raise InputError(f"terrain backend {backend!r} has no estimate(class_map, image, seed) method")
        return backend
    from .. import registry

    cls = registry.load("terrain", backend or config.backend)
    return cls(config, **dict(opts or {}))


def _check_class_map(class_map: ClassMap) -> None:
    ids = np.asarray(class_map.ids)
    if ids.ndim != 2 or ids.shape != class_map.grid.shape:
        raise InputError(f"class map of shape {ids.shape} does not match its grid "
                         f"{class_map.grid.shape} (H, W)")


def _image_on_grid(image: GeoImage, class_map: ClassMap) -> GeoImage:
    """The image resampled onto the class map's grid when their pixel sizes differ."""
    if image.rgb.shape[:2] == class_map.grid.shape:
        return image
    import cv2

    h, w = class_map.grid.shape
    rgb = cv2.resize(image.rgb, (w, h), interpolation=cv2.INTER_AREA)
    return GeoImage(rgb=rgb, grid=class_map.grid, path=image.path)


def estimate_terrain(class_map: ClassMap, config: TerrainConfig | Config, image: GeoImage | None = None,
                     dems: Sequence = (), seed: int = 0, backend: str | TerrainBackend | None = None, *,
                     backend_opts: Mapping[str, Any] | None = None, placement=None) -> TerrainResult:
    """Heights for ``class_map`` (DESIGN.md §4), with DEM fusion and optional optical depth.

    ``dems``: ``DemSource`` items or strings ``FILE[:offset=M][,scale=S]`` (later files win where they
    overlap). ``placement``: a ``dem.Placement`` for scenes without a georeference."""
    from .default import DefaultTerrain, analyse_shore
    from .outputs import cross_sections

    t0 = time.perf_counter()
    cfg = config.terrain if isinstance(config, Config) else config
    _check_class_map(class_map)
    ids = np.asarray(class_map.ids)
    grid = class_map.grid
    model = make_backend(cfg, backend, backend_opts)
    if image is not None:
        image = _image_on_grid(image, class_map)
    shore = analyse_shore(ids, grid.gsd_m, cfg)
    if isinstance(model, DefaultTerrain):
        hm = model.estimate_from_shore(class_map, shore, seed)
    else:
        hm = model.estimate(class_map, image, seed)
        if np.asarray(hm.z_m).shape != ids.shape:
            raise InputError(f"terrain backend {type(model).__name__} returned heights of shape "
                             f"{np.asarray(hm.z_m).shape}, expected {ids.shape}")
    z = np.asarray(hm.z_m, dtype=np.float32)

    optical: dict = {}
    if cfg.optical_depth:
        if image is None:
            raise InputError("terrain.optical_depth = true needs the RGB image; pass it (e.g. --image FILE) "
                             "or --set terrain.optical_depth=false")
        from .optical import apply_optical_depth

        z, fit = apply_optical_depth(z, shore, image.rgb, cfg)
        optical = fit.to_dict()

    dem_files: tuple[str, ...] = ()
    coverage = 0.0
    if dems:
        from .dem import fuse_dems

        z, info = fuse_dems(z, grid, dems, cfg, placement=placement)
        dem_files, coverage = info.files, info.coverage

    water = shore.water
    it = max(cfg.intertidal_m, 0.0)
    from ..classes import SAND

    allowed = (ids == SAND) & (z > -it - 1e-6) if it > 0 else np.zeros_like(water)
    height = HeightMap(z_m=z.astype(np.float32, copy=False), grid=grid)
    sections = cross_sections(z, shore, ids)
    diag = TerrainDiagnostics(
        backend=getattr(model, "name", type(model).__name__),
        seconds=time.perf_counter() - t0,
        shore_types=tuple(SHORE_TYPES[t] for t in shore.present()),
        water_fraction=float(water.mean()),
        water_at_or_above=int(np.count_nonzero(water & (z >= 0))),
        land_at_or_below=int(np.count_nonzero(~water & (z <= 0) & ~allowed)),
        dem_files=dem_files, dem_coverage=coverage, optical=optical,
    )
    return TerrainResult(height=height, shore_type=shore.dominant, cross_sections=sections, diagnostics=diag)


def load_terrain_scene(scene_dir: str | Path, overwrite: bool = False):
    """The scene ``coastforge terrain`` works on, checked: it has a class raster, and its height and terrain
    outputs are replaced only with ``overwrite`` (then the old height is not even read: a damaged one is
    what a new run repairs). Returns (folder, scene)."""
    from ..fsio import check_writable_file
    from ..scene import load_scene
    from .outputs import output_paths

    folder = Path(scene_dir)
    if folder.is_file() and folder.name.endswith(".json"):
        folder = folder.parent
    scene = load_scene(folder, rasters=False)
    height_path = folder / scene.terrain_paths["height"]
    for p in [height_path, *output_paths(folder / "terrain").values()]:
        check_writable_file(p, overwrite)
    scene = load_scene(folder, height=False)
    if scene.classes is None:
        raise InputError(f"scene {folder} has no class raster ({scene.terrain_paths['classes']}); "
                         "run `coastforge segment` first or add the class map")
    return folder, scene


def terrain_scene(scene_dir: str | Path, config: Config, dems: Sequence = (), placement=None,
                  image_path: str | Path | None = None, backend_opts: Mapping[str, Any] | None = None,
                  overwrite: bool = False, *, scene=None, image=None) -> TerrainResult:
    """The ``coastforge terrain`` command: heights for a scene folder, written into it with the outputs.
    ``scene`` and ``image``: already loaded and checked (``load_terrain_scene``, ``io.read_image``), e.g. from
    the real folder before the run writes into a staging copy of it."""
    from ..io import read_image
    from ..scene import save_scene
    from .outputs import write_terrain_outputs

    folder = Path(scene_dir)
    if folder.is_file() and folder.name.endswith(".json"):
        folder = folder.parent
    if scene is None:
        folder, scene = load_terrain_scene(folder, overwrite)
    grid = scene.grid
    class_map = ClassMap(ids=scene.classes, grid=grid)
    if image is None and image_path is not None:
        image = read_image(image_path, size_m=tuple(scene.extent_m), config=config.io)
    res = estimate_terrain(class_map, config, image=image, dems=dems, seed=scene.seed,
                           backend_opts=backend_opts, placement=placement)
    prov = dict(scene.provenance)
    prov["terrain"] = {"params": config.to_dict()["terrain"], **res.diagnostics.to_dict()}
    save_scene(replace(scene, height=res.height.z_m, provenance=prov), folder)
    write_terrain_outputs(folder / "terrain", res, plot_engine="auto")
    return res


__all__ = ["SHORE_TYPES", "CrossSection", "TerrainBackend", "TerrainDiagnostics", "TerrainResult", "estimate_terrain",
           "load_terrain_scene", "make_backend", "terrain_scene"]
