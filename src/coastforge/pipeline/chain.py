"""``generate``: one image in, one complete scene out.

read → segment → detect (reconciled with the class map) → self-check → clean (transient objects and pier
decks filled from their surroundings) → terrain → piers → vegetation → match + place → scene files →
exports → report → scene.json, in one order (``run_chain``) whether the image is held whole
(``WholeImage``) or read by windows (``tiling.TiledImage``). Each stage's wall time goes into the scene's
provenance; side work runs beside the chain (``coastforge.runtime``).
"""

from __future__ import annotations

import json
import platform
import sys
import time
from dataclasses import dataclass, field, replace
from functools import cached_property, partial
from pathlib import Path
from typing import Callable, Protocol

import numpy as np

from .. import __version__
from ..classes import PAVED, WATER
from ..config import Config, LibraryConfig
from ..fsio import atomic_write_text
from .runtime import Background, Job, SideProcess, Timer
from ..scene import Scene, SceneObject, load_scene, save_scene, save_scene_rasters
from ..types import ClassMap, Detection, GeoImage, Grid, HeightMap

Progress = Callable[[str, float], None]  # (stage name, fraction done)


@dataclass(frozen=True)
class GenerateRequest:
    image: str
    out: str
    gsd_m: float | None = None
    size_m: tuple[float, float] | None = None
    library: str | None = None
    exports: tuple[str, ...] = ()
    dems: tuple[str, ...] = ()
    overwrite: bool = False
    report: bool = True
    command: str = ""
    # a spawned side process for GIL-heavy side work on big images; off by default because a spawned
    # child re-imports the caller's __main__ (a script without a main guard would run twice): the CLI,
    # whose entry point is guarded, turns it on
    side_process: bool = False


@dataclass(frozen=True)
class GenerateResult:
    """What ``generate`` made: the paths of the scene, its exports and report, with the run's figures."""

    scene_path: Path
    out_dir: Path
    timings_s: dict[str, float]  # wall seconds per stage, and "total"
    n_objects: dict[str, int]  # per category, vegetation included
    exports: dict[str, list[Path]] = field(default_factory=dict)  # the written files per format
    report_path: Path | None = None
    warnings: list = field(default_factory=list)  # selfcheck.SceneWarning: the scene looks implausible
    notes: tuple[str, ...] = ()  # what the output folder's recovery did (an earlier run's leftovers removed)

    @cached_property
    def scene(self) -> Scene:
        """The generated scene, read from ``scene_path`` on first use (the command only prints paths)."""
        return load_scene(self.scene_path)


def fill_under_objects(class_map: ClassMap, dets: list[Detection], margin_px: float = 2.0) -> ClassMap:
    """Classes under transient objects (boats, vehicles) and pier decks are what surrounds them: a boat sits on
    water, a car on asphalt, and a pier deck over water must not become land in the height map.

    "Around" leaves out the other detected boxes: in a row of dark parked cars the neighbours (often
    segmented as trees) are no evidence of the ground. A vehicle takes the paved class when its free
    surroundings show pavement at all, since cars stand on roads and car parks, not in tree crowns."""
    import cv2

    ids = class_map.ids.copy()
    h, w = ids.shape
    boxes = []
    taken = np.zeros((h, w), np.uint8)  # every detected box, grown by the margin
    for d in dets:
        grow = margin_px
        corners = Detection(d.category, d.score, d.cx_px, d.cy_px, d.length_px + 2 * grow, d.width_px + 2 * grow,
                            d.yaw_deg).corners_px()
        poly = np.round(corners).astype(np.int32)
        boxes.append(poly)
        cv2.fillPoly(taken, [poly], 1)
    for d, poly in zip(dets, boxes):
        x0, y0 = np.maximum(poly.min(0) - 4, 0)
        x1, y1 = np.minimum(poly.max(0) + 5, [w, h])
        if x1 <= x0 or y1 <= y0:
            continue
        inner = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillPoly(inner, [poly - [x0, y0]], 1)
        ring = cv2.dilate(inner, np.ones((7, 7), np.uint8)) & (1 - inner)
        sub = ids[y0:y1, x0:x1]
        free = ring & (1 - taken[y0:y1, x0:x1])
        around = sub[(free if free.sum() >= 0.2 * ring.sum() else ring).astype(bool)]
        if around.size == 0:
            continue
        counts = np.bincount(around, minlength=8)
        if d.category in ("pier_walkway", "pier_finger"):
            # a pier is over water where water dominates its sides; its landward root stays land
            if counts[WATER] < 0.35 * around.size:
                continue
            fill = WATER
        elif d.category == "vehicle" and counts[list(PAVED)].sum() >= 0.15 * around.size:
            fill = int(PAVED[int(np.argmax(counts[list(PAVED)]))])
        else:
            fill = int(counts.argmax())
        sub[inner.astype(bool)] = fill
    return ClassMap(ids, class_map.grid, class_map.proba, class_map.confidence, class_map.source)


def _load_library(path: str | None, config: LibraryConfig = LibraryConfig()):
    """The library at ``path``, else the starter kit built with ``config`` (a built library keeps its own)."""
    from ..assets import library as lib_mod

    return lib_mod.Library.load(path) if path else lib_mod.default_library(config)


def fallback_kit(library, path: str | None, config: LibraryConfig = LibraryConfig()):
    """``(starter kit, categories it stands in for)`` when the user's library (``path``) lacks asset
    categories a scene may need, else ``(None, ())``: a missing category never aborts a run. The kit is
    built with ``config``."""
    from ..classes import ASSET_CATEGORIES

    if path is None:
        return None, ()
    have = {a.category for a in library.assets}
    missing = tuple(c for c in ASSET_CATEGORIES if c not in have)
    if not missing:
        return None, ()
    from ..assets.library import default_library

    return default_library(config), missing


def fallback_warning(path: str | None, missing: tuple[str, ...]):
    from ..selfcheck import SceneWarning

    return SceneWarning("library_fallback", f"The library {path} has no {', '.join(missing)} asset; the starter "
                        "kit's were used for these categories.",
                        "Add such assets to the library (coastforge library build) to use your own.")


def _pier_assets(library):
    piers = [a for a in library.assets if a.category == "pier"]
    if not piers:
        return None, None

    def pick(word):
        for a in piers:
            if word in a.id or word in tuple(getattr(a, "tags", ()) or ()):
                return a
        return None

    walk = pick("walkway") or max(piers, key=lambda a: a.dims_m[1])
    finger = pick("finger") or min(piers, key=lambda a: a.dims_m[1])
    return walk, finger


def place_decisions(decisions, dets: list[Detection], library, grid, config: Config, height, kit=None) -> list:
    """Scene objects for the matched detections, ids numbered per category (``boat_000``, ...); ``kit``:
    the fallback library of the categories ``library`` lacks."""
    from ..placement import place

    assets = {a.id: a for a in (kit.assets if kit is not None else ())}
    assets.update({a.id: a for a in library.assets})
    objects = []
    counters: dict[str, int] = {}
    for dec in decisions:
        d = dets[dec.index]
        k = counters.get(d.category, 0)
        counters[d.category] = k + 1
        objects.append(place(d, assets[dec.asset_id], grid, f"{d.category}_{k:03d}", config.match, height=height,
                             water_level_m=0.0, yaw_deg=dec.yaw_deg, score=dec.confidence,  # in [0, 1]
                             attrs={"heading": dec.heading_source, "detector_score": round(d.score, 4),
                                    "match": dec.index},
                             shape_scale=dec.fit_scale, shape_offset_m=dec.fit_offset_m if dec.fit_scale else None))
    return objects


@dataclass(frozen=True)
class BoxFootprint:
    """A detected object's box in scene metres, for what must keep clear of the object before it is placed
    (a placed object's footprint is its detected box: position, yaw and scale come from it)."""

    x_m: float
    y_m: float
    yaw_deg: float
    length_m: float
    width_m: float

    footprint_m = SceneObject.footprint_m


def detection_footprints(dets: list[Detection], grid) -> list[BoxFootprint]:
    """The boxes of the detections that become placed objects (boats, vehicles, buoys)."""
    from ..placement import box_in_metres

    out = []
    for d in dets:
        if d.category in ("boat", "vehicle", "buoy"):
            x, y, length, width = box_in_metres(d, grid)
            out.append(BoxFootprint(x, y, d.yaw_deg, length, width))
    return out


def assets_by_category(library, kit=None) -> dict[str, list[str]]:
    """Asset ids per category; the categories ``library`` lacks come from ``kit`` (if given)."""
    out: dict[str, list[str]] = {}
    for a in library.assets:
        out.setdefault(a.category, []).append(a.id)
    own = set(out)
    for a in (kit.assets if kit is not None else ()):
        if a.category not in own:
            out.setdefault(a.category, []).append(a.id)
    return out


def scene_provenance(req: GenerateRequest, config: Config, library, gsd_m: float, size_px: tuple[int, int], dets,
                     objects, vegetation, pier_report: dict, decisions, **extra) -> dict:
    """What made a scene: tool, command, seed, input, library, backends, config, counts, decisions."""
    return {
        "tool": "coastforge", "version": __version__, "command": req.command, "seed": config.seed,
        "input": {"image": str(req.image), "gsd_m": gsd_m, "size_px": list(size_px)},
        **extra,
        "library": str(req.library) if req.library else "starter-kit",
        "backends": {"segment": config.segment.backend, "terrain": config.terrain.backend,
                     "detect": config.detect.backend, "embedder": getattr(library.embedder, "name", "?")},
        "config": config.to_dict(),
        "counts": {"detections": len(dets), "objects": len(objects), "vegetation": len(vegetation)},
        "piers": pier_report,
        "matches": [m.to_dict() for m in decisions],
        "python": sys.version.split()[0], "platform": platform.platform(),
    }


def run_generate(req: GenerateRequest, config: Config, progress: Progress | None = None) -> GenerateResult:
    """Run the whole pipeline into ``req.out``, all-or-nothing: everything is written into a staging folder
    beside it and swapped into place only once the scene, its exports and its report are complete (a
    failed or killed run leaves ``req.out`` as it was). Inputs are checked before the first write."""
    from . import tiling
    from ..config import validate_config
    from ..fsio import output_folder
    from ..terrain.dem import DemSource

    validate_config(config)  # a Config built in code gets the checks load_config makes
    check_library_path(req.library)
    timer = Timer(progress)
    with timer.stage("read"):  # the image is read (a large one opened for windows) and checked before any write
        front = (tiling.TiledImage.open(req, config) if tiling.needs_tiling(req.image)
                 else WholeImage.read(req, config))
    check_dems(req, front)
    notes: list[str] = []
    inputs = (req.image, req.library, *(DemSource.parse(d).path for d in req.dems))
    with output_folder(req.out, overwrite=req.overwrite, command=req.command, notes=notes,
                       inputs=inputs) as stage:
        res = run_chain(front, replace(req, out=str(stage), overwrite=False), config, stage, timer)
    return _relocated(res, stage, Path(req.out), notes)


def check_dems(req: GenerateRequest, image) -> None:
    """Refuse, before any work, a --dem that does not exist or cannot be placed: generate fuses DEMs by the
    image's georeference, which a plain PNG/JPEG does not have. ``image``: the read image or the chain's
    front end (anything with the image's ``grid``), or None to read the georeference from the file."""
    if not req.dems:
        return
    from ..errors import InputError
    from ..terrain.dem import check_dem_files

    check_dem_files(req.dems)
    if image is not None:
        georef = image.grid.crs is not None and image.grid.transform is not None
    else:  # a tiled run reads the image later: its header says
        import rasterio

        with rasterio.open(req.image) as src:
            georef = src.crs is not None
    if not georef:
        raise InputError(f"--dem needs to know where the scene is on the map, but {req.image} has no georeference; "
                         "give generate a GeoTIFF, or generate without --dem and fuse the DEM afterwards with "
                         "`coastforge terrain OUT --overwrite --dem FILE --dem-crs CRS --dem-origin X Y`")


def check_library_path(path: str | None) -> None:
    """Refuse, before any work, a ``--library`` that does not exist or is not a library."""
    if path is None:
        return
    from ..errors import LibraryError

    p = Path(path)
    if not p.exists():
        raise LibraryError(f"--library {p} does not exist; build one with `coastforge library build SRC --out "
                           f"{p}`, or leave --library out to use the starter kit")
    if not (p / "library.json").is_file() and not (p.is_file() and p.name == "library.json"):
        raise LibraryError(f"--library {p} is not an asset library (no library.json in it); build one with "
                           "`coastforge library build`, or leave --library out to use the starter kit")


def _relocated(res: GenerateResult, stage: Path, out: Path, notes: list[str]) -> GenerateResult:
    """``res`` with its paths moved from the staging folder to the final one."""
    def mv(p):
        if isinstance(p, (str, Path)):
            try:
                return out / Path(p).relative_to(stage)
            except ValueError:
                return p
        if isinstance(p, list):
            return [mv(x) for x in p]
        return p

    return replace(res, scene_path=mv(res.scene_path), out_dir=out, notes=tuple(notes),
                   exports={k: mv(v) for k, v in res.exports.items()},
                   report_path=mv(res.report_path) if res.report_path else None)


class FrontEnd(Protocol):
    """The stage operations that read the image, for ``run_chain``: ``WholeImage`` holds the image in memory;
    ``tiling.TiledImage`` reads it by windows and merges the results across the seams."""

    @property
    def grid(self) -> Grid:
        """The input image's grid: detections are in its pixels."""

    @property
    def scene_grid(self) -> Grid:
        """The grid of the scene rasters (the input's, or coarser for a large image)."""

    @property
    def preview(self) -> GeoImage:
        """The image on the scene grid (the terrain's optical cue, the cleaned image, the previews)."""

    @property
    def report_image(self) -> np.ndarray | None:
        """The input as the report shows it (None: the report reads it from the file)."""

    @property
    def detections_provenance(self) -> dict | None:
        """What detections.json says about how the detections were made, if anything."""

    @property
    def provenance(self) -> dict:
        """Provenance entries of the scene about how the image was read."""

    def segment(self, config: Config, progress: Progress | None) -> ClassMap:
        """The class map on the input grid."""

    def detect(self, class_map: ClassMap, config: Config, progress: Progress | None, side: SideProcess | None,
               side_queued: Callable[[], None]) -> tuple[list[Detection], ClassMap, dict]:
        """Detections on the input grid, reconciled with the class map: (detections, the corrected class map,
        what the reconciliation changed). ``side_queued()`` is called once this stage's own side-process
        work is queued (the side process runs its jobs in order)."""

    def to_scene_grid(self, class_map: ClassMap, dets: list[Detection],
                      config: Config) -> tuple[ClassMap, list[Detection], dict]:
        """The class map and detections on the scene grid, reconciled across seams: (class map, detections,
        what that changed)."""

    def matcher(self) -> Callable:
        """``match(dets, library, config, kit) -> decisions`` for the input-grid detections; picklable, for
        the side process."""

    def piers(self, dets: list[Detection], class_map: ClassMap, walkway, finger, config) -> tuple[list, dict]:
        """Pier segments for the scene-grid detections and class map: (objects, report)."""


@dataclass(frozen=True)
class WholeImage:
    """The input read whole (``io.read_image``): every stage sees all of it, and the scene grid is its grid."""

    image: GeoImage

    @classmethod
    def read(cls, req: GenerateRequest, config: Config) -> "WholeImage":
        from ..io import read_image

        return cls(read_image(req.image, req.gsd_m, req.size_m, config.io, stages=config))

    @property
    def grid(self) -> Grid:
        return self.image.grid

    @property
    def scene_grid(self) -> Grid:
        return self.image.grid

    @property
    def preview(self) -> GeoImage:
        return self.image

    @property
    def report_image(self) -> np.ndarray:
        return self.image.rgb

    @property
    def detections_provenance(self) -> None:
        return None

    @property
    def provenance(self) -> dict:
        return {}

    def segment(self, config: Config, progress: Progress | None) -> ClassMap:
        from ..segmentation import segment

        return segment(self.image, config.segment, seed=config.seed)

    def detect(self, class_map: ClassMap, config: Config, progress: Progress | None, side: SideProcess | None,
               side_queued: Callable[[], None]) -> tuple[list[Detection], ClassMap, dict]:
        from ..detection import detect

        opts = {}
        if side is not None and config.detect.backend == "hybrid":  # its classical half runs in the side process
            from ..detection.hybrid import classical_part

            opts["classical_dets"] = side.submit(classical_part, self.image, class_map, config.detect, config.seed)
        side_queued()
        return detect(self.image, config.detect, class_map=class_map, seed=config.seed, return_class_map=True,
                      **opts)

    def to_scene_grid(self, class_map: ClassMap, dets: list[Detection],
                      config: Config) -> tuple[ClassMap, list[Detection], dict]:
        return class_map, dets, {}

    def matcher(self) -> Callable:
        return partial(match_in_image, self.image)

    def piers(self, dets: list[Detection], class_map: ClassMap, walkway, finger, config) -> tuple[list, dict]:
        from ..piers import build_piers

        pr = build_piers(dets, class_map, walkway, finger, config)
        return list(pr.objects), pr.report


def match_in_image(image: GeoImage, dets: list[Detection], library, config: Config, kit=None) -> list:
    """``matching.match_detections`` on an image in memory (``kit``: the fallback library)."""
    from ..matching import match_detections

    return match_detections(image, dets, library, config.match, config.seed, fallback=kit)


# the margin of the boxes whose classes are filled from their surroundings, in input pixels
FILL_MARGIN_PX = 2.0


def run_chain(front: FrontEnd, req: GenerateRequest, config: Config, out: Path, timer: Timer) -> GenerateResult:
    """The stages of ``generate`` after reading the image, in one order whether the image is whole in memory
    or read by windows (``front``), into the folder ``out``; with a side process when ``req.side_process``
    asks for one (and the image is big enough)."""
    n_px = front.grid.width_px * front.grid.height_px
    side = SideProcess.start(n_px, _side_warm_up) if req.side_process else None
    try:
        return _stages(front, req, config, out, timer, side)
    finally:
        if side is not None:
            side.close()


def _stages(front: FrontEnd, req: GenerateRequest, config: Config, out: Path, timer: Timer,
            side: SideProcess | None) -> GenerateResult:
    """segment → detect (reconciled with the class map; on the scene grid) → self-check → clean → terrain →
    piers → vegetation → match and placement → scene files → exports → report → scene.json."""
    from ..piers import set_deck_heights
    from ..selfcheck import check_scene
    from ..terrain import estimate_terrain
    from ..vegetation import scatter

    # shapely is imported by the background threads (matching, the report) and by this one (piers): a
    # package whose modules import each other, imported by two threads at once, can hand one of them a
    # half-initialised module (Python breaks the import-lock cycle that way); imported here first, it is
    # whole before any thread starts (13 ms). (A thread that warmed imports beside the chain did hit
    # this, on small images where the chain overtook it; on 2048² it saved nothing measurable.)
    import shapely.geometry  # noqa: F401

    seed = config.seed
    grid, sgrid = front.grid, front.scene_grid
    # Independent work runs beside the main chain: the library loads while segmentation and detection run;
    # matching (it needs the library and the detections, not the terrain) runs beside terrain, piers and
    # vegetation; the cleaned image is needed only by the report, which waits for it last; every side
    # raster is written as soon as its stage is done.
    # threads that wait on the side process hold a worker: room for those and the CPU-bound jobs
    with Background(workers=8) as bg:
        bg.submit(Job.LIBRARY, _load_library, req.library, config.library)
        with timer.stage("segment"):
            class_map = front.segment(config, timer.progress)
        with timer.stage("detect"):
            def side_library():  # the side process loads the library its matching will need
                bg.result(Job.LIBRARY)  # built first (a first run builds the starter kit)
                side.submit(_preload_library, req.library, config.library)

            def side_queued():
                if side is not None:
                    bg.submit(Job.SIDE_LIBRARY, side_library)

            dets, class_map, consistency = front.detect(class_map, config, timer.progress, side, side_queued)
            # the stages from here on run on the scene grid (a large image's is coarser)
            class_map, s_dets, seams = front.to_scene_grid(class_map, dets, config)
            consistency = {**consistency, **seams}
        warnings = check_scene(class_map.ids, sgrid.gsd_m, s_dets)
        with timer.stage("clean"):
            class_map = fill_under_objects(class_map, s_dets, FILL_MARGIN_PX * sgrid.width_px / grid.width_px)
        match = front.matcher()
        if side is not None:  # matching is mostly Python: in the side process it leaves the GIL to the chain
            bg.result(Job.LIBRARY)  # the side process loads the library only once this one has it (built)
            bg.submit(Job.MATCH, side.run, _match_job, match, req.library, dets, config)
        else:
            def match_here():
                library = bg.result(Job.LIBRARY)
                return match(dets, library, config, fallback_kit(library, req.library, config.library)[0])

            bg.submit(Job.MATCH, match_here)
        _write_segment_outputs(bg, out, front, class_map, dets, s_dets, config, seed, side)
        with timer.stage("terrain"):
            terrain = estimate_terrain(class_map, config.terrain, image=front.preview, dems=req.dems, seed=seed)
            height: HeightMap = terrain.height
        _write_terrain_outputs(bg, out, terrain)
        if req.report:  # the report's render from above: its terrain now, while the chain waits for matching
            bg.submit(Job.REPORT_TERRAIN, _report_terrain, class_map.ids, height.z_m, grid, seed)
        with timer.stage("library"):  # the time the chain waited for the library, not its load time
            library = bg.result(Job.LIBRARY)
            kit, missing = fallback_kit(library, req.library, config.library)
            if missing:
                warnings.append(fallback_warning(req.library, missing))
        with timer.stage("piers"):
            walk, finger = _pier_assets(library)
            if walk is None and kit is not None:
                walk, finger = _pier_assets(kit)
            pier_report: dict = {"n_structures": 0}
            pier_objects: list = []
            if walk is not None:
                pier_objects, pier_report = front.piers(s_dets, class_map, walk, finger, config.piers)
                # decks level with the quay they leave, not at the water surface
                pier_objects = set_deck_heights(pier_objects, class_map.ids, height, config.piers,
                                                config.terrain.quay_height_m)
        with timer.stage("vegetation"):  # while the matcher works: clear of the piers and the detected boxes
            veg = scatter(class_map.ids, height.z_m, sgrid, assets_by_category(library, kit),
                          pier_objects + detection_footprints(dets, grid), config.vegetation, seed)
        with timer.stage("match"):  # waiting for the matcher, then placement on the terrain
            decisions = bg.result(Job.MATCH)
            objects = place_decisions(decisions, dets, library, grid, config, height, kit) + pier_objects
        if req.report:  # ... and the meshes it shows (loading them holds the GIL: not beside the stages above)
            plants = veg.vegetation.asset_id if veg.vegetation is not None else ()
            bg.submit(Job.REPORT_MESHES, _load_meshes, library, [o.asset_id for o in objects] + [str(a) for a in plants])
        with timer.stage("write"):
            # the scene rasters; the inpainted image, the segmentation rasters and the report's meshes are
            # still being made beside: the report starts on its other sections meanwhile
            scene = write_scene_files(
                bg, out, req, seed, grid, sgrid.transform, height, class_map, objects, veg,
                scene_provenance(req, config, library, grid.gsd_m, (grid.width_px, grid.height_px), dets, objects,
                                 veg.vegetation, pier_report, decisions, **front.provenance,
                                 consistency=consistency, warnings=[w.to_dict() for w in warnings]),
                pending=(Job.CLEANED, Job.SEGMENTATION, Job.REPORT_MESHES, Job.SCENE_RASTERS, Job.PCG,
                         Job.TERRAIN_OUTPUTS))
        timings = dict(timer.t)
        timings["total"] = round(sum(timer.t.values()), 3)
        exports: dict = {}
        if req.exports:  # exporters read the scene folder: complete it first
            from ..export import export_scene

            bg.wait()
            scene_path = save_scene(_with_timings(scene, timings, timer, bg), out, rasters=False)
            with timer.stage("export"):
                exports = export_scene(out, list(req.exports), out, overwrite=True, config=config.export,
                                       library=library)
            timings["export"] = timer.t["export"]
            timings["total"] = round(timings["total"] + timings["export"], 3)

        report_path = make_report(req, out, timings, scene=_with_timings(scene, timings, timer, bg),
                                  image=front.report_image, library=library,
                                  top_terrain=bg.result(Job.REPORT_TERRAIN) if req.report else None,
                                  wait=report_waiter(bg))
        bg.wait()  # re-raises a failed job (without a report nothing else waited for them all)
        # the JSON last, once every file it describes is written: a folder with a scene.json is complete
        scene_path = save_scene(_with_timings(scene, timings, timer, bg), out, rasters=False)
    return GenerateResult(scene_path, out, timings, object_counts(objects, len(veg.vegetation)), exports,
                          report_path, warnings)


def _with_timings(scene: Scene, timings: dict, timer: Timer, bg: "Background") -> Scene:
    """The scene with its stage timings and what ran beside the main chain (CPU contention makes the stages
    slower by about that much) in its provenance."""
    return replace(scene, provenance={**scene.provenance, "timings_s": dict(timings),
                                      "stage_cpu_s": dict(timer.cpu), "background_s": bg.timings()})


def _report_terrain(ids: np.ndarray, z_m: np.ndarray, grid, seed: int):
    """The terrain layer of the report's render from above, or None (the report then renders it itself)."""
    try:
        from ..render import scene_terrain_layer
        from ..report import top_gsd

        return scene_terrain_layer(ids.astype(np.uint8), z_m.astype(np.float32), grid.extent_m, 0.0,
                                   top_gsd(grid.gsd_m, grid.extent_m), seed=seed)
    except Exception:  # noqa: BLE001 - a head start only: never a reason for generate to fail
        return None


def _load_meshes(library, asset_ids) -> None:
    """Load these assets' meshes into the library's cache (the report's render and 3D preview use them)."""
    for aid in dict.fromkeys(asset_ids):
        try:
            library.mesh(aid)
        except Exception:  # noqa: BLE001 - the report falls back on its own for a mesh that will not load
            pass


def write_scene_files(bg: "Background", out: Path, req: GenerateRequest, seed: int, grid, transform, height: HeightMap,
                      class_map: ClassMap, objects, veg, provenance: dict, pending: tuple[Job, ...] = ()) -> Scene:
    """The scene of a finished chain; its vegetation masks and rasters written (the JSON comes last, from the
    caller, once timings are known). ``transform`` is the scene rasters' (coarser than the input when a tiled
    run downsampled them). Background jobs named in ``pending`` are not waited for (the caller does)."""
    scene = Scene(
        name=Path(req.image).stem, seed=seed, gsd_m=grid.gsd_m, extent_m=grid.extent_m, water_level_m=0.0,
        crs=grid.crs, transform=transform, height=height.z_m.astype(np.float32),
        classes=class_map.ids.astype(np.uint8), objects=tuple(objects), vegetation=veg.vegetation,
        provenance=provenance)
    _write_vegetation_outputs(bg, out, veg)
    bg.submit(Job.SCENE_RASTERS, save_scene_rasters, scene, out, low=True)
    write_instances(scene, out)
    bg.wait(skip=pending)  # re-raises the first failed job
    return scene


def write_instances(scene: Scene, out: Path) -> Path:
    """``instances.json`` beside scene.json: the scene's one label table (DESIGN.md §3), the same one every
    export carries (its objects never change after this point: timings only touch the provenance)."""
    from ..export import INSTANCES_FILE
    from ..export.labels import instances_json
    from ..fsio import atomic_write_bytes

    return atomic_write_bytes(out / INSTANCES_FILE, instances_json(scene))


# what the report waits for (``report.build_report``'s ``wait(part)``): the background job making it
REPORT_PARTS = {"meshes": Job.REPORT_MESHES, "cleaned": Job.CLEANED, "terrain": Job.TERRAIN_OUTPUTS,
                "segmentation": Job.SEGMENTATION}


def report_waiter(bg: Background):
    """``wait(part)`` for the report: the result of the part's job, or every job for "all"; another part
    is an error (it would otherwise wait for the wrong thing, or for everything)."""
    def wait(part: str):
        if part == "all":
            return bg.wait()
        if part not in REPORT_PARTS:
            raise ValueError(f"the report waited for {part!r}; generate makes "
                             f"{', '.join(REPORT_PARTS)} and 'all'")
        return bg.result(REPORT_PARTS[part])

    return wait


def make_report(req: GenerateRequest, out: Path, timings: dict, scene: Scene | None = None,
                image: np.ndarray | None = None, library=None, top_terrain=None, wait=None) -> Path | None:
    """The report, when asked for and its extra is installed (``timings`` gets its time). ``scene``, the
    input ``image``, ``library`` and ``top_terrain`` are what generate holds in memory; ``wait``: see
    ``build_report``."""
    if not req.report:
        return None
    try:
        from ..report import build_report
    except ImportError:
        return None
    t0 = time.perf_counter()
    path = build_report(out, scene=scene, image=image, library=library, top_terrain=top_terrain, wait=wait)
    timings["report"] = round(time.perf_counter() - t0, 3)
    return path


def object_counts(objects, n_vegetation: int) -> dict[str, int]:
    counts: dict[str, int] = {}
    for o in objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    counts["vegetation"] = n_vegetation
    return counts


def _side_warm_up() -> None:
    """Imports the side process needs first, done while the main process segments."""
    import cv2  # noqa: F401

    from .. import matching  # noqa: F401
    from ..assets import library  # noqa: F401
    from ..detection import classical, hybrid  # noqa: F401
    from ..segmentation import clean  # noqa: F401


_HERE: dict = {}  # the side process's own library, kept between its jobs


def _preload_library(path: str | None, lib_config: LibraryConfig = LibraryConfig()) -> None:
    """Load the library into the side process ahead of its matching job."""
    _library_here(path, lib_config)


def _library_here(path: str | None, lib_config: LibraryConfig = LibraryConfig()):
    """The library in this process: loaded once in the side process (which lives for one run only); loaded
    afresh in the main process (where it runs only when the side process died)."""
    import multiprocessing

    if multiprocessing.parent_process() is None:
        return _load_library(path, lib_config)
    key = (str(path or ""), lib_config)
    if key not in _HERE:
        _HERE[key] = _load_library(path, lib_config)
    return _HERE[key]


def _match_job(match: Callable, library_path: str | None, dets: list[Detection], config: Config) -> list:
    """``match`` (a front end's ``matcher()``) with this process's library (a module-level function for the
    side process)."""
    lib = _library_here(library_path, config.library)
    return match(dets, lib, config, fallback_kit(lib, library_path, config.library)[0])


def _write_cleaned(path: Path, image: GeoImage, dets: list[Detection], class_map: ClassMap, seed: int) -> np.ndarray:
    """The inpainted image (boats, vehicles and buoys removed; piers stay), written as a PNG and returned (the
    report shows it); a module-level function so a side process can run it."""
    from ..fsio import write_png
    from ..segmentation.clean import clean_image

    rgb = clean_image(image, dets, class_map, seed)
    write_png(path, rgb)
    return rgb


def _write_segment_outputs(bg: Background, out: Path, front: FrontEnd, class_map: ClassMap, dets, s_dets,
                           config: Config, seed: int, side: SideProcess | None = None) -> None:
    """detections.json now (``dets``, in input pixels); the cleaned image (transient objects removed: no later
    stage reads it, only the report) and the segmentation rasters (previews, paint-layer weights, biome map)
    on the scene grid (``class_map``, ``s_dets``) in the background."""
    from ..detection import detections_to_json
    from ..segmentation.outputs import write_segmentation

    g = front.grid
    atomic_write_text(out / "detections.json", detections_to_json(dets, g.gsd_m, (g.width_px, g.height_px),
                                                                  front.detections_provenance))
    image = front.preview
    if side is not None:
        bg.submit(Job.CLEANED, side.run, _write_cleaned, out / "cleaned.png", image, s_dets, class_map, seed)
    else:
        bg.submit(Job.CLEANED, _write_cleaned, out / "cleaned.png", image, s_dets, class_map, seed)
    bg.submit(Job.SEGMENTATION, write_segmentation, out / "segmentation", class_map, image, config.segment, low=True)


def _write_terrain_outputs(bg: Background, out: Path, terrain) -> None:
    """Hillshade, shore types and cross-sections, in the background."""
    from ..terrain.outputs import write_terrain_outputs

    bg.submit(Job.TERRAIN_OUTPUTS, write_terrain_outputs, out / "terrain_outputs", terrain, low=True)


def _write_vegetation_outputs(bg: Background, out: Path, veg) -> None:
    """The 8-bit PCG masks, one file per rule."""
    from ..fsio import write_png

    def masks():
        for name, mask in veg.masks.items():
            write_png(out / "pcg" / f"{name}.png", mask)

    bg.submit(Job.PCG, masks, low=True)
