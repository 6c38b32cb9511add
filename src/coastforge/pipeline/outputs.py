"""The files the chain writes beside the scene as their stages finish, most of them from background jobs."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..config import Config
from ..fsio import atomic_write_text
from ..scene import Scene, save_scene_rasters
from ..types import ClassMap, Detection, GeoImage, HeightMap
from .request import GenerateRequest
from .runtime import Background, Job, SideProcess

if TYPE_CHECKING:  # pragma: no cover
    from .chain import FrontEnd


def write_scene_files(bg: Background, out: Path, req: GenerateRequest, seed: int, grid, transform, height: HeightMap,
                      class_map: ClassMap, objects, veg, provenance: dict, pending: tuple[Job, ...] = ()) -> Scene:
    """The scene of a finished chain; its vegetation masks and rasters written (the JSON comes last, from the
    caller, once timings are known). ``transform`` is the scene rasters' (coarser than the input when a tiled
    run downsampled them). Background jobs named in ``pending`` are not waited for (the caller does)."""
    scene = Scene(
        name=Path(req.image).stem, seed=seed, gsd_m=grid.gsd_m, extent_m=grid.extent_m, water_level_m=0.0,
        crs=grid.crs, transform=transform, height=height.z_m.astype(np.float32),
        classes=class_map.ids.astype(np.uint8), objects=tuple(objects), vegetation=veg.vegetation,
        provenance=provenance)
    submit_vegetation_outputs(bg, out, veg)
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


def write_cleaned(path: Path, image: GeoImage, dets: list[Detection], class_map: ClassMap, seed: int) -> np.ndarray:
    """The inpainted image (boats, vehicles and buoys removed; piers stay), written as a PNG and returned (the
    report shows it); a module-level function so a side process can run it."""
    from ..fsio import write_png
    from ..segmentation.clean import clean_image

    rgb = clean_image(image, dets, class_map, seed)
    write_png(path, rgb)
    return rgb


def submit_segment_outputs(bg: Background, out: Path, front: FrontEnd, class_map: ClassMap, dets, s_dets,
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
        bg.submit(Job.CLEANED, side.run, write_cleaned, out / "cleaned.png", image, s_dets, class_map, seed)
    else:
        bg.submit(Job.CLEANED, write_cleaned, out / "cleaned.png", image, s_dets, class_map, seed)
    bg.submit(Job.SEGMENTATION, write_segmentation, out / "segmentation", class_map, image, config.segment, low=True)


def submit_terrain_outputs(bg: Background, out: Path, terrain) -> None:
    """Hillshade, shore types and cross-sections, in the background."""
    from ..terrain.outputs import write_terrain_outputs

    bg.submit(Job.TERRAIN_OUTPUTS, write_terrain_outputs, out / "terrain_outputs", terrain, low=True)


def submit_vegetation_outputs(bg: Background, out: Path, veg) -> None:
    """The 8-bit PCG masks, one file per rule."""
    from ..fsio import write_png

    def masks():
        for name, mask in veg.masks.items():
            write_png(out / "pcg" / f"{name}.png", mask)

    bg.submit(Job.PCG, masks, low=True)
