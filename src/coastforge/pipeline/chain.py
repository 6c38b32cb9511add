"""The chain of ``generate``, after the image is read: one stage order for every image.

segment → detect (reconciled with the class map) → self-check → clean (transient objects and pier
decks filled from their surroundings) → terrain → piers → vegetation → match + place → scene files →
exports → report → scene.json, in one order (``run_chain``) whether the image is held whole
(``whole.WholeImage``) or read by windows (``tiled.TiledImage``). Each stage's wall time goes into the
scene's provenance; side work runs beside the chain (``runtime``).
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import replace
from pathlib import Path
from typing import Protocol
from collections.abc import Callable

import numpy as np

from ..config import Config
from ..scene import Scene, save_scene
from ..types import ClassMap, Detection, GeoImage, Grid, HeightMap
from .assemble import (detection_footprints, fill_under_objects, object_counts, place_decisions,
                       scene_provenance)
from .libraries import assets_by_category, fallback_kit, fallback_warning, load_library, pier_assets
from .outputs import submit_segment_outputs, submit_terrain_outputs, write_scene_files
from .request import GenerateRequest, GenerateResult, Progress
from .runtime import Background, Job, SideProcess, Timer
from .side import match_job, preload_library, warm_up


class FrontEnd(Protocol):
    """The stage operations that read the image, for ``run_chain``: ``WholeImage`` holds the image in memory;
    ``TiledImage`` reads it by windows and merges the results across the seams."""

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


# the margin of the boxes whose classes are filled from their surroundings, in input pixels
FILL_MARGIN_PX = 2.0


def run_chain(front: FrontEnd, req: GenerateRequest, config: Config, out: Path, timer: Timer) -> GenerateResult:
    """The stages of ``generate`` after reading the image, in one order whether the image is whole in memory
    or read by windows (``front``), into the folder ``out``; with a side process when ``req.side_process``
    asks for one (and the image is big enough)."""
    n_px = front.grid.width_px * front.grid.height_px
    side = SideProcess.start(n_px, warm_up) if req.side_process else None
    try:
        return _stages(front, req, config, out, timer, side)
    finally:
        if side is not None:
            side.close()


def _stages(front: FrontEnd, req: GenerateRequest, config: Config, out: Path, timer: Timer,
            side: SideProcess | None) -> GenerateResult:
    """segment → detect (reconciled with the class map; on the scene grid) → self-check → clean → terrain →
    piers → vegetation → match and placement → scene files → exports → report → scene.json."""
    from ..pier_chains import set_deck_heights
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
        bg.submit(Job.LIBRARY, load_library, req.library, config.library)
        with timer.stage("segment"):
            class_map = front.segment(config, timer.progress)
        with timer.stage("detect"):
            def side_library():  # the side process loads the library its matching will need
                bg.result(Job.LIBRARY)  # built first (a first run builds the starter kit)
                side.submit(preload_library, req.library, config.library)

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
            bg.submit(Job.MATCH, side.run, match_job, match, req.library, dets, config)
        else:
            def match_here():
                library = bg.result(Job.LIBRARY)
                return match(dets, library, config, fallback_kit(library, req.library, config.library)[0])

            bg.submit(Job.MATCH, match_here)
        submit_segment_outputs(bg, out, front, class_map, dets, s_dets, config, seed, side)
        with timer.stage("terrain"):
            terrain = estimate_terrain(class_map, config.terrain, image=front.preview, dems=req.dems, seed=seed)
            height: HeightMap = terrain.height
        submit_terrain_outputs(bg, out, terrain)
        if req.report:  # the report's render from above: its terrain now, while the chain waits for matching
            bg.submit(Job.REPORT_TERRAIN, _report_terrain, class_map.ids, height.z_m, grid, seed)
        with timer.stage("library"):  # the time the chain waited for the library, not its load time
            library = bg.result(Job.LIBRARY)
            kit, missing = fallback_kit(library, req.library, config.library)
            if missing:
                warnings.append(fallback_warning(req.library, missing))
        with timer.stage("piers"):
            walk, finger = pier_assets(library)
            if walk is None and kit is not None:
                walk, finger = pier_assets(kit)
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


def _with_timings(scene: Scene, timings: dict, timer: Timer, bg: Background) -> Scene:
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
        # any error: the report falls back on its own for a mesh that will not load
        with contextlib.suppress(Exception):
            library.mesh(aid)


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
