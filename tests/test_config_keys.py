"""Every config key has an effect (issue #29): a table maps each key to a probe that runs the code reading it
on a small fixed input, and changing the key from its default to another valid value changes what the probe
returns. A key without a probe fails ``test_every_key_has_a_probe``: give it one, or remove the key.

Most probes return a stage's output (class ids, detections, heights, matches, scattered instances, exported
files). A few keys bound or steer a run rather than shape its output; their probes return what they decide,
said in the table's ``how``: whether an input is accepted (io limits), which backend runs (a backend that
needs weights refuses without them), how many build processes are asked for (library.workers).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any
from collections.abc import Callable

import numpy as np
import pytest

from coastforge.classes import ASPHALT, GRASS, WATER
from coastforge.config import Config, _flat
from coastforge.errors import CoastforgeError
from coastforge.types import ClassMap, Detection, GeoImage, Grid
from onnx_models import constant_detector

GSD = 0.25  # the rendered level's metres per pixel


# ------------------------------------------------------------------------------------------ small inputs

class World:
    """The probes' inputs, each made on first use and shared by every probe of the module."""

    def __init__(self, tmp: Path):
        self.tmp = tmp

    def scratch(self) -> Path:
        return Path(tempfile.mkdtemp(dir=self.tmp))

    @cached_property
    def level(self):
        """A rendered 100 m marina: berthed boats, a buoy, pier fingers, parked cars (400 px at 0.25 m/px)."""
        import cv2

        from coastforge.io import read_image
        from coastforge.scene import load_scene
        from coastforge.synth import synth_to_dir

        d = self.tmp / "level"
        synth_to_dir("marina", 1, d, gsds=(GSD,), size_m=100, overwrite=True)
        img = read_image(d / "image_0.25m.png", gsd_m=GSD)
        truth = load_scene(d / "truth.json")  # its rasters are finer than the image: resampled to it
        size = (img.grid.width_px, img.grid.height_px)
        classes = cv2.resize(truth.classes, size, interpolation=cv2.INTER_NEAREST)
        height = cv2.resize(truth.height, size, interpolation=cv2.INTER_AREA)
        return img.rgb, classes, height

    @cached_property
    def image(self) -> GeoImage:
        rgb = self.level[0]
        return GeoImage(rgb, Grid(rgb.shape[1], rgb.shape[0], GSD))

    @cached_property
    def image_path(self) -> Path:
        from coastforge.fsio import write_png

        return write_png(self.tmp / "crop.png", self.image.rgb)

    @cached_property
    def class_map(self) -> ClassMap:
        return ClassMap(self.level[1], self.image.grid)

    @cached_property
    def height(self):
        from coastforge.types import HeightMap

        return HeightMap(self.level[2].astype(np.float32), self.image.grid)

    @cached_property
    def detections(self) -> list[Detection]:
        """What the default detector finds on the level, with its class map."""
        from coastforge.detection import detect

        return detect(self.image, Config().detect, class_map=self.class_map, seed=0)

    @cached_property
    def library(self):
        from coastforge.assets.library import default_library

        return default_library()

    @cached_property
    def to_match(self) -> list[Detection]:
        """Two boats, two cars and the buoy (matching costs per detection)."""
        by = {c: [d for d in self.detections if d.category == c] for c in ("boat", "vehicle", "buoy")}
        return by["boat"][:2] + by["vehicle"][:2] + by["buoy"][:1]

    @cached_property
    def decisions(self):
        from coastforge.matching import match_detections

        return match_detections(self.image, self.to_match, self.library, Config().match, 0)

    @cached_property
    def shores(self) -> ClassMap:
        """A wavy coast with a beach, a revetment, a quay and a natural bank (160 px at 0.5 m/px)."""
        from coastforge.bench.terrain import synthetic_class_map

        return ClassMap(synthetic_class_map("mixed", 160, 0.5), Grid(160, 160, 0.5))

    @cached_property
    def shores_image(self) -> GeoImage:
        """Water whose green darkens with the default model's depth (the optical fit then holds)."""
        from coastforge.config import TerrainConfig
        from coastforge.terrain import estimate_terrain

        z = estimate_terrain(self.shores, TerrainConfig()).height.z_m
        rgb = np.full((*z.shape, 3), (90, 140, 60), np.uint8)
        depth = np.clip(-z, 0.0, 10.0)
        water = self.shores.ids == WATER
        rgb[water, 0] = 30
        rgb[water, 1] = np.clip(190.0 - 14.0 * depth[water], 20, 255).astype(np.uint8)
        rgb[water, 2] = 170
        return GeoImage(rgb, self.shores.grid)

    @cached_property
    def dem(self) -> Path:
        """A DEM of 3 m over the west half of a georeferenced 64 px scene."""
        from coastforge.fsio import write_geotiff

        z = np.full((32, 16), 3.0, np.float32)
        return write_geotiff(self.tmp / "dem.tif", z, (1.0, 0.0, 550_000.0, 0.0, -1.0, 4_180_000.0),
                             crs="EPSG:32610")

    @cached_property
    def wet_and_dry(self):
        """A strip of water, asphalt and a lawn; a row of moored boats on the asphalt (water the segmenter
        missed), a car in the water, a boat on the lawn and a car-sized 'boat' 25 m from the water."""
        ids = np.full((400, 600), ASPHALT, np.uint8)
        ids[:, :100] = WATER
        ids[:150, 300:] = GRASS
        cm = ClassMap(ids, Grid(600, 400, GSD))

        def det(cat, cx, cy, length_m, width_m, yaw=90.0):
            return Detection(cat, 0.8, float(cx), float(cy), length_m / GSD, width_m / GSD, yaw, True, 0.9)

        dets = [det("boat", 350 + i * 3.5 / GSD, 300, 8.0, 3.0) for i in range(6)]
        dets += [det("vehicle", 50, 200, 4.5, 1.8, 0.0), det("boat", 450, 60, 6.0, 2.5),
                 det("boat", 200, 200, 4.5, 1.8, 0.0)]
        return dets, cm

    @cached_property
    def pier_comb(self):
        """Water mask (0.25 m/px) with a pier tied to the shore: a walkway and eight fingers, no vegetation."""
        water = np.ones((200, 200), bool)
        water[:, :60] = False
        water[98:103, 60:160] = False
        for x in range(70, 160, 12):
            water[60:140, x:x + 4] = False
        return water, np.zeros_like(water)

    @cached_property
    def lone_boat(self) -> list[Detection]:
        """A classical "boat" on the breakwater's boulders (textured: no deck), where the network sees none."""
        return [Detection("boat", 0.6, 95.0, 80.0, 6.0 / GSD, 2.4 / GSD, 30.0)]

    @cached_property
    def pier_world(self):
        """A quay (land at 1 m) west of water (-2 m); a walkway 5 m off the quay with a finger on it."""
        from coastforge.types import HeightMap

        ids = np.full((200, 200), WATER, np.uint8)
        ids[:, :60] = ASPHALT
        grid = Grid(200, 200, GSD)
        z = np.where(ids == WATER, -2.0, 1.0).astype(np.float32)
        dets = [Detection("pier_walkway", 0.9, 140.0, 100.0, 120.0, 10.0, 0.0),
                Detection("pier_finger", 0.9, 150.0, 120.0, 32.0, 5.0, 90.0)]
        return dets, ClassMap(ids, grid), HeightMap(z, grid)

    @cached_property
    def garden(self):
        """60 x 60 m at 0.5 m/px: water 0.5-4 m deep, riprap, lawn, trees and bare ground on a gentle rise."""
        from coastforge.classes import DIRT, ROCKS, TREES

        ids = np.full((120, 120), GRASS, np.uint8)
        cols = np.arange(120)[None, :].repeat(120, 0)
        ids[:, :40] = WATER
        ids[:, 40:46] = ROCKS
        ids[:60, 70:] = TREES
        ids[90:, 70:] = DIRT
        z = np.where(ids == WATER, -0.5 - (40 - cols) * 0.1, 0.5 + (cols - 40) * 0.05).astype(np.float32)
        return ids, z, Grid(120, 120, 0.5)

    @cached_property
    def onnx_detector(self) -> Path:
        """An ONNX detector that ignores its input and finds one boat in every window it is given."""
        return constant_detector(self.tmp / "det.onnx", [[20, 20, 16, 4, 0.0, 0.9, 0]], names="{0: 'ship'}")

    @cached_property
    def scene(self):
        """A 100 x 75 m scene (0.5 m/px): deep water west, a beach, grass; two boats (6 and 12 m), a car, a
        pier segment and two trees, with starter-kit assets."""
        from coastforge.scene import Scene, SceneObject, Vegetation

        h, w = 150, 200
        cols = np.arange(w)[None, :].repeat(h, 0)
        classes = np.where(cols < 100, WATER, GRASS).astype(np.uint8)
        classes[:, 100:106] = 7  # sand
        classes[:20, 150:] = ASPHALT
        height = np.where(cols < 100, -0.3 - (100 - cols) * 0.15, 0.3 + (cols - 100) * 0.04).astype(np.float32)
        objs = (
            SceneObject("boat_000", "boat", "runabout", -20.0, 5.0, 0.0, 30.0, (1.0, 1.0, 1.0), 6.0, 2.4,
                        "detection", 0.9),
            SceneObject("boat_001", "boat", "fishing_boat", -35.0, -12.0, 0.0, 179.0, (1.0, 1.0, 1.0), 12.0, 4.2,
                        "detection", 0.7),
            SceneObject("vehicle_000", "vehicle", "sedan", 40.0, 30.0, 0.5, -120.0, (1.0, 1.0, 1.0), 4.6, 1.8,
                        "detection", 0.8),
            SceneObject("pier_000", "pier", "pier_walkway", -5.0, 0.0, 0.6, 0.0, (1.0, 1.0, 1.0), 10.0, 2.5,
                        "pier", 1.0),
        )
        veg = Vegetation(np.array(["tree_broadleaf"] * 2, dtype=object), np.array(["tree"] * 2, dtype=object),
                         np.array([25.0, 30.0]), np.array([15.0, 18.0]), np.array([1.5, 1.6]),
                         np.array([10.0, 50.0]), np.array([1.0, 1.2]))
        return Scene(name="probe", seed=0, gsd_m=0.5, extent_m=(100.0, 75.0), height=height, classes=classes,
                     objects=objs, vegetation=veg)

    @cached_property
    def scene_dir(self) -> Path:
        from coastforge.scene import save_scene

        d = self.tmp / "scene"
        save_scene(self.scene, d)
        return d

    @cached_property
    def kit_asset(self):
        """The starter kit's hatchback as a library source (paintable, small: every kind of view)."""
        from coastforge.assets.kit import MANIFEST_NAME, kit_dir
        from coastforge.assets.library import read_manifest

        specs, _ = read_manifest(kit_dir() / MANIFEST_NAME, lenient=True)
        return next(replace(s, origin="keep") for s in specs if s.id == "hatchback")


# ------------------------------------------------------------------------------------------------ probes

def seg_classical(cfg: Config, w: World):
    from coastforge.segmentation.classical import ClassicalSegmenter

    return ClassicalSegmenter(cfg.segment).segment(w.image, 0).ids


def seg_structures(cfg: Config, w: World):
    """The classical segmenter's pier absorption (land tied to the shore that is a fragmented structure)."""
    from types import SimpleNamespace

    from coastforge.segmentation.classical import _absorb_structures

    water, veg = w.pier_comb
    return _absorb_structures(water, SimpleNamespace(gsd_m=GSD), cfg.segment, veg)


def seg_default(cfg: Config, w: World):
    """``segment`` as generate calls it (the configured backend, the root seed)."""
    from coastforge.segmentation import segment

    return segment(w.image, cfg).ids


def seg_learned(cfg: Config, w: World):
    from coastforge.segmentation.learned import LearnedSegmenter

    cm = LearnedSegmenter(cfg.segment).segment(w.image, 0)
    return cm.ids, cm.confidence


def seg_outputs(cfg: Config, w: World):
    """The paint-layer weight maps and the biome map written beside the class map."""
    from coastforge.fsio import read_png
    from coastforge.segmentation.outputs import write_segmentation

    out = w.scratch()
    write_segmentation(out, w.class_map, None, cfg.segment)
    return read_png(out / "biome.png"), read_png(out / "weights" / "grass.png")


def terrain_shores(cfg: Config, w: World):
    from coastforge.terrain import estimate_terrain

    try:
        return estimate_terrain(w.shores, cfg.terrain, seed=cfg.seed).height.z_m
    except CoastforgeError as exc:
        return f"{type(exc).__name__}: {exc}"


def terrain_optical(cfg: Config, w: World):
    from coastforge.terrain import estimate_terrain

    res = estimate_terrain(w.shores, cfg.terrain, image=w.shores_image, seed=cfg.seed)
    return res.height.z_m, res.diagnostics.optical


def terrain_dem(cfg: Config, w: World):
    from coastforge.terrain.dem import fuse_dems

    grid = Grid(64, 64, 0.5, "EPSG:32610", (0.5, 0.0, 550_000.0, 0.0, -0.5, 4_180_000.0))
    return fuse_dems(np.zeros((64, 64), np.float32), grid, [w.dem], cfg.terrain)[0]


def detect_classical(cfg: Config, w: World):
    """The classical backend alone (no refinement, no class map): every key it reads shows here."""
    from coastforge.detection.classical import ClassicalDetector

    return ClassicalDetector(cfg.detect).detect(w.image, None, 0)


def detect_curved_pier(cfg: Config, w: World):
    """The classical backend on a walkway bent through a half circle, the pier-deck network stood in for."""
    from pier_scenes import StandNet, curved_pier_scene

    from coastforge.detection.classical import ClassicalDetector

    image, deck = curved_pier_scene()
    det = ClassicalDetector(cfg.detect)
    det.pier_net = lambda: StandNet(deck)  # type: ignore[method-assign]
    return det.detect(image, None, 0)


def detect_run(cfg: Config, w: World):
    """``detect`` as generate calls it: the configured backend, refinement, the class map's reconciliation."""
    from coastforge.detection import detect

    return detect(w.image, cfg.detect, class_map=w.class_map, seed=0)


def detect_cut(cfg: Config, w: World):
    """``detect`` on the level cut through the middle of its first boat (the right half of it left out)."""
    from coastforge.detection import detect

    boats = [d for d in detect(w.image, replace(cfg.detect, min_inside=0.0), seed=0) if d.category == "boat"]
    b = boats[0]
    rgb = np.ascontiguousarray(w.image.rgb[:, :int(round(b.cx_px))])
    return detect(GeoImage(rgb, Grid(rgb.shape[1], rgb.shape[0], GSD)), cfg.detect, seed=0)


def detect_seen_closer(cfg: Config, w: World):
    """``detect`` told the level is three times coarser than it is: its boats are then 15-30 m vessels."""
    from coastforge.detection import detect

    rgb = w.image.rgb
    return detect(GeoImage(rgb, Grid(rgb.shape[1], rgb.shape[0], 3 * GSD)), cfg.detect, seed=0)


def detect_hybrid(cfg: Config, w: World):
    """The hybrid backend, its classical half's boats given (as the side process gives them)."""
    from concurrent.futures import Future

    from coastforge.detection.hybrid import HybridDetector

    classical = Future()
    classical.set_result(w.lone_boat)
    return HybridDetector(cfg.detect, classical_dets=classical).detect(w.image, None, 0)


def detect_onnx(cfg: Config, w: World):
    from coastforge.detection.onnx_backend import OnnxDetector

    return OnnxDetector(cfg.detect, weights=w.onnx_detector).detect(w.image, None, 0)


def reconcile_probe(cfg: Config, w: World):
    from coastforge.consistency import reconcile

    dets, cm = w.wet_and_dry
    rec = reconcile(dets, cm, GSD, cfg.detect)
    return rec.dets, rec.class_map.ids


def match_probe(cfg: Config, w: World):
    from coastforge.matching import match_detections

    return [m.to_dict() for m in match_detections(w.image, w.to_match, w.library, cfg.match, cfg.seed)]


def place_probe(cfg: Config, w: World):
    """The matched objects placed (scale and position from the shape fit)."""
    from coastforge.placement import place

    assets = {a.id: a for a in w.library.assets}
    return [place(w.to_match[m.index], assets[m.asset_id], w.image.grid, f"o{m.index}", cfg.match,
                  w.height, yaw_deg=m.yaw_deg, shape_scale=m.fit_scale, shape_offset_m=m.fit_offset_m)
            for m in w.decisions]


def piers_probe(cfg: Config, w: World):
    from coastforge.pier_chains import build_piers, set_deck_heights

    walk, finger = (next(a for a in w.library.assets if a.id == i) for i in ("pier_walkway", "pier_finger"))
    dets, cm, height = w.pier_world
    res = build_piers(dets, cm, walk, finger, cfg.piers)
    return set_deck_heights(list(res.objects), cm.ids, height, cfg.piers, cfg.terrain.quay_height_m)


def vegetation_probe(cfg: Config, w: World):
    from coastforge.vegetation import scatter

    kinds = {"tree": ["tree_broadleaf", "tree_palm"], "bush": ["bush_round"], "grass": ["grass_clump"],
             "rock": ["rock_small"], "seaweed": ["seaweed_kelp"]}
    ids, z, grid = w.garden
    res = scatter(ids, z, grid, kinds, (), cfg.vegetation, cfg.seed)
    return res.vegetation


def read_probe(cfg: Config, w: World):
    """Whether the image is read: ``read_image`` with --gsd and a --size-m 0.5 % off it."""
    from coastforge.io import read_image

    h, wd = w.image.rgb.shape[:2]
    try:
        read_image(w.image_path, GSD, (wd * GSD * 1.005, h * GSD * 1.005), cfg.io, stages=cfg)
        return "read"
    except CoastforgeError as exc:
        return f"{type(exc).__name__}: {exc}"


def export_probe(fmt: str) -> Callable:
    def probe(cfg: Config, w: World):
        from coastforge.export import DefaultResolver, run_exporter

        return run_exporter(fmt, w.scene, DefaultResolver(), cfg.export)

    probe.__name__ = f"export_{fmt}"
    return probe


def export_command(cfg: Config, w: World):
    """``coastforge export SCENE`` without --format: the folders it writes."""
    from click.testing import CliRunner

    from coastforge.cli import cli

    out = w.scratch()
    formats = json.dumps(list(cfg.export.formats))
    r = CliRunner().invoke(cli, ["export", str(w.scene_dir), "--out", str(out), "--set", f"export.formats={formats}"])
    assert r.exit_code == 0, r.output
    return sorted(p.name for p in out.iterdir() if p.is_dir())


def library_views(cfg: Config, w: World):
    """One asset of the starter kit rendered and embedded as a library build does it (in this process)."""
    from coastforge.assets.library.build import config_dict
    from coastforge.assets.library.ingest import ingest_mesh

    res = ingest_mesh(w.kit_asset, str(w.scratch()), config_dict(cfg.library), {"name": cfg.library.embedder})
    assert "record" in res, res
    rec = {k: v for k, v in res["record"].items() if k not in ("source_mesh",)}
    return rec, res["vectors"]


def library_kit(cfg: Config, w: World):
    """The starter kit as generate gets it: its embedder (dinov3 needs weights, so it refuses)."""
    from coastforge.assets.library import default_library

    try:
        return default_library(cfg.library).embedder_name
    except CoastforgeError as exc:
        return f"{type(exc).__name__}: {exc}"


def library_workers(cfg: Config, w: World):
    """How many render processes a library build asks for (the jobs themselves are not run)."""
    from unittest import mock

    from coastforge.assets.library import build as lib

    asked = []

    def record(jobs, workers, say):
        asked.append(workers)
        raise _Stop

    src = w.scratch()
    shutil.copy(w.kit_asset.mesh, src / "car.glb")
    manifest = src / "manifest.json"
    manifest.write_text(json.dumps({"assets": [{"id": "car", "category": "vehicle", "mesh": "car.glb"}]}))
    with mock.patch.object(lib, "_run_jobs", record), pytest.raises(_Stop):
        lib.build_library(manifest, w.scratch(), config=cfg.library)
    return asked


class _Stop(Exception):
    pass


def generate_probe(cfg: Config, w: World):
    """A whole generate run on the level (vegetation and objects; what the root seed reaches)."""
    from coastforge.pipeline import GenerateRequest, run_generate
    from coastforge.scene import load_scene

    res = run_generate(GenerateRequest(str(w.image_path), str(w.scratch() / "out"), gsd_m=GSD, report=False), cfg)
    scene = load_scene(res.scene_path)
    return [dataclasses.astuple(o) for o in scene.objects], scene.vegetation


# -------------------------------------------------------------------------------------------------- table

@dataclass(frozen=True)
class Probe:
    fn: Callable[[Config, World], Any]
    value: Any  # a valid value other than the default
    base: dict = field(default_factory=dict)  # other keys set for this probe (both runs)
    how: str = ""  # what the probe observes, when it is not the stage's output


def _p(fn, value, how="", **base):
    return Probe(fn, value, {k.replace("__", "."): v for k, v in base.items()}, how)


ACCEPTED = "whether the input is accepted (a limit)"
BACKEND = "which backend runs; one that needs weights refuses without them"
LEARNED = {"detect__backend": "learned"}

PROBES: dict[str, Probe] = {
    "seed": _p(generate_probe, 7),
    # io: limits on what is read
    "io.max_pixels": _p(read_probe, 1000, ACCEPTED),
    "io.gsd_tolerance": _p(read_probe, 0.001, ACCEPTED),
    "io.min_gsd_m": _p(read_probe, 0.3, ACCEPTED),
    "io.max_gsd_m": _p(read_probe, 0.2, ACCEPTED),
    "io.max_memory_gb": _p(read_probe, 0.001, ACCEPTED),
    # segment
    "segment.backend": _p(seg_default, "classical"),
    "segment.smooth_px": _p(seg_classical, 0),
    "segment.min_region_m2": _p(seg_classical, 200.0),
    "segment.weight_blur_m": _p(seg_outputs, 4.0),
    "segment.self_training": _p(seg_classical, False),
    "segment.work_gsd_m": _p(seg_classical, 0.25),
    "segment.max_work_px": _p(seg_classical, 20_000),
    "segment.water_min_m2": _p(seg_classical, 100_000.0),
    "segment.water_close_m": _p(seg_classical, 8.0),
    "segment.water_hole_max_m2": _p(seg_classical, 0.0),
    "segment.pier_open_m": _p(seg_structures, 0.0),
    "segment.rocks_shore_m": _p(seg_classical, 0.0),
    "segment.vehicle_area_max_m2": _p(seg_classical, 0.0),
    "segment.edge_refine_m": _p(seg_classical, 0.0),
    "segment.biome_shore_m": _p(seg_outputs, 40.0),
    "segment.biome_shallow_m": _p(seg_outputs, 5.0),
    "segment.learned_water": _p(seg_learned, "net"),
    "segment.learned_flips": _p(seg_learned, 1),
    "segment.learned_min_region_m2": _p(seg_learned, 200.0),
    # terrain
    "terrain.backend": _p(terrain_shores, "onnx", BACKEND),
    "terrain.max_depth_m": _p(terrain_shores, 12.0),
    "terrain.depth_scale_m": _p(terrain_shores, 20.0),
    "terrain.berth_depth_m": _p(terrain_shores, 6.0),
    "terrain.quay_height_m": _p(terrain_shores, 2.0),
    "terrain.d50_mm": _p(terrain_shores, 1.0),
    "terrain.beach_height_m": _p(terrain_shores, 3.0),
    "terrain.intertidal_m": _p(terrain_shores, 1.0),
    "terrain.revetment_slope": _p(terrain_shores, 1.2),
    "terrain.bank_slope": _p(terrain_shores, 0.4),
    "terrain.land_rise_m": _p(terrain_shores, 6.0),
    "terrain.land_rise_scale_m": _p(terrain_shores, 40.0),
    "terrain.noise_m": _p(terrain_shores, 0.0),
    "terrain.seam_m": _p(terrain_dem, 5.0),
    "terrain.optical_depth": _p(terrain_optical, True),
    "terrain.beach_slope": _p(terrain_shores, 0.2),
    "terrain.revetment_height_m": _p(terrain_shores, 3.0),
    "terrain.revetment_toe_m": _p(terrain_shores, 5.0),
    "terrain.bank_height_m": _p(terrain_shores, 2.0),
    "terrain.shore_blend_m": _p(terrain_shores, 10.0),
    "terrain.optical_max_depth_m": _p(terrain_optical, 3.0, terrain__optical_depth=True),
    # detect: the backend and what every backend shares
    "detect.backend": _p(detect_run, "classical"),
    "detect.hybrid_union": _p(detect_hybrid, False, detect__hybrid_support=0.0),
    "detect.hybrid_support": _p(detect_hybrid, 0.0),
    "detect.axis_tta": _p(detect_run, False, **LEARNED),
    "detect.flip_tta": _p(detect_run, False, **LEARNED),
    "detect.row_context": _p(detect_run, 0.3, **LEARNED),
    "detect.big_pass": _p(detect_seen_closer, 0.0, **LEARNED),
    "detect.min_score": _p(detect_run, 0.8),
    "detect.min_inside": _p(detect_cut, 0.0),
    "detect.slice_px": _p(detect_onnx, 256),
    "detect.slice_overlap_px": _p(detect_onnx, 32, detect__slice_px=160),
    "detect.nms_iou": _p(detect_onnx, 0.0, detect__slice_px=160),
    "detect.refine": _p(detect_run, False),
    "detect.boats_need_water": _p(reconcile_probe, False),
    "detect.boats_make_water": _p(reconcile_probe, False),
    "detect.vehicle_max_wet": _p(reconcile_probe, 0.0),
    "detect.near_water_m": _p(reconcile_probe, 30.0),
    "detect.min_water_area_m2": _p(reconcile_probe, 5000.0),
    # detect: the classical backend
    "detect.min_boat_length_m": _p(detect_classical, 6.0),
    "detect.max_boat_length_m": _p(detect_classical, 3.0),
    "detect.min_vehicle_length_m": _p(detect_classical, 4.6),
    "detect.max_vehicle_length_m": _p(detect_classical, 4.5),
    "detect.work_gsd_m": _p(detect_classical, 0.5),
    "detect.water_min_chroma": _p(detect_classical, 40.0),
    "detect.water_model_m": _p(detect_classical, 30.0),
    "detect.struct_dl": _p(detect_classical, 40.0),
    "detect.struct_dc": _p(detect_classical, 30.0),
    "detect.boat_mask": _p(detect_classical, "struct"),
    "detect.boat_core_dl": _p(detect_classical, 20.0),
    "detect.boat_core_headroom": _p(detect_classical, 0.1),
    "detect.boat_core_dc": _p(detect_classical, 4.0),
    "detect.boat_region_dl": _p(detect_classical, 60.0),
    "detect.boat_region_dc": _p(detect_classical, 40.0),
    "detect.boat_open_m": _p(detect_classical, 1.5),
    "detect.min_boat_width_m": _p(detect_classical, 4.0),
    "detect.min_boat_aspect": _p(detect_classical, 2.5),
    "detect.merge_gap_m": _p(detect_classical, 6.0),
    "detect.max_boat_aspect": _p(detect_classical, 2.5),
    "detect.split_area_m2": _p(detect_classical, 5.0),
    "detect.split_max_aspect": _p(detect_classical, 4.0),
    "detect.boat_water_touch_m": _p(detect_classical, 0.0),
    "detect.mainland_cut_m": _p(detect_classical, 6.0),
    "detect.mainland_far_m": _p(detect_classical, 60.0),
    "detect.snap_deg": _p(detect_classical, 45.0),
    "detect.snap_radius_m": _p(detect_classical, 0.0),
    "detect.pier_gsd_m": _p(detect_classical, 1.0),
    "detect.pier_net": _p(detect_classical, False),
    "detect.deck_spines": _p(detect_curved_pier, False),
    "detect.walkway_min_m": _p(detect_classical, 40.0),
    "detect.walkway_max_width_m": _p(detect_classical, 1.0),
    "detect.finger_min_m": _p(detect_classical, 15.0),
    "detect.finger_max_width_m": _p(detect_classical, 0.5),
    "detect.buoy_min_area_m2": _p(detect_classical, 1.5),
    "detect.buoy_max_area_m2": _p(detect_classical, 0.5),
    "detect.buoy_clear_m": _p(detect_classical, 10.0),
    "detect.buoy_contrast": _p(detect_classical, 100.0),
    "detect.vehicles": _p(detect_classical, False),
    "detect.vehicle_water_gap_m": _p(detect_classical, 30.0),
    "detect.vehicle_hat_m": _p(detect_classical, 6.0),
    "detect.vehicle_dl": _p(detect_classical, 80.0),
    "detect.vehicle_dc": _p(detect_classical, 5.0),
    "detect.vehicle_ground_chroma": _p(detect_classical, 2.0),
    "detect.vehicle_ground_frac": _p(detect_classical, 0.9),
    "detect.vehicle_shadow_m": _p(detect_classical, 8.0),
    "detect.vehicle_pitch_m": _p(detect_classical, 1.5),
    # library: the views and embeddings of one asset, the starter kit, the build
    "library.embedder": _p(library_kit, "dinov3", BACKEND),
    "library.view_gsd_m": _p(library_views, 0.06),
    "library.view_size_px": _p(library_views, 96),
    "library.lightings": _p(library_views, 1),
    "library.backgrounds": _p(library_views, ("ground",)),
    # the downsampled copies stand in for coarser scales only where no query-like view does
    "library.embed_scales": _p(library_views, (1.0,), library__query_view_gsds_m=(), library__crowded_views=0),
    "library.workers": _p(library_workers, 1, "the number of render processes a build asks for"),
    "library.paint_variants": _p(library_views, False),
    "library.query_view_gsds_m": _p(library_views, (0.2,)),
    "library.query_view_max_px": _p(library_views, 10.0),
    "library.query_view_random_lightings": _p(library_views, 0),
    "library.crowded_views": _p(library_views, 0),
    "library.crowded_gsds_m": _p(library_views, (0.1,)),
    # match: choices and scores
    "match.mode": _p(match_probe, "sample", match__sample_margin=0.5),
    "match.size_weight": _p(match_probe, 0.9, match__shape=False),
    "match.sample_margin": _p(match_probe, 0.5, match__mode="sample"),
    "match.shape": _p(match_probe, False),
    "match.shape_appearance_weight": _p(match_probe, 0.5),
    "match.shape_scale_weight": _p(match_probe, 0.5),
    "match.shape_scale_sigma_boat": _p(match_probe, 0.05),
    "match.shape_scale_sigma_vehicle": _p(match_probe, 0.1),
    "match.shape_scale_sigma_buoy": _p(match_probe, 0.3),
    "match.shape_length_weight": _p(match_probe, 0.5),
    "match.shape_length_sigma": _p(match_probe, 0.05),
    "match.shape_width_weight": _p(match_probe, 0.5),
    "match.shape_width_sigma": _p(match_probe, 0.1),
    "match.heading_prior_weight": _p(match_probe, 0.5),
    "match.heading_prior_ref_px": _p(match_probe, 0.0),
    "match.heading_appearance_weight": _p(match_probe, 0.0),
    # match: placement from the fit
    "match.scale_mode": _p(place_probe, "per_axis"),
    "match.scale_min": _p(place_probe, 1.5),
    "match.scale_max": _p(place_probe, 1.0),
    "match.use_shape_fit": _p(place_probe, False),
    "match.shape_offset_weight_fine": _p(place_probe, 0.0),
    "match.shape_offset_weight_coarse": _p(place_probe, 0.0),
    # piers
    "piers.max_gap_m": _p(piers_probe, 0.5),
    "piers.deck_height_m": _p(piers_probe, 0.2),
    # vegetation
    "vegetation.enabled": _p(vegetation_probe, False),
    "vegetation.tree_density_per_100m2": _p(vegetation_probe, 0.0),
    "vegetation.bush_density_per_100m2": _p(vegetation_probe, 0.0),
    "vegetation.grass_density_per_100m2": _p(vegetation_probe, 0.0),
    "vegetation.rock_density_per_100m2": _p(vegetation_probe, 0.0),
    "vegetation.seaweed_density_per_100m2": _p(vegetation_probe, 0.0),
    "vegetation.max_slope_deg_trees": _p(vegetation_probe, 0.0),
    "vegetation.min_spacing_m": _p(vegetation_probe, 8.0),
    "vegetation.max_instances": _p(vegetation_probe, 10),
    # export
    "export.formats": _p(export_command, ("gltf",), "the formats `coastforge export` writes without --format"),
    "export.template_level": _p(export_probe("ue5"), "/Game/Maps/Other"),
    "export.package_name": _p(export_probe("holoocean"), "Other"),
    "export.gltf_max_vertices": _p(export_probe("gltf"), 5_000),
    "export.ue_max_size": _p(export_probe("ue5"), 127),
    "export.content_path": _p(export_probe("ue5"), "/Game/Other"),
    "export.pcg_graph": _p(export_probe("ue5"), "/Game/PCG/Graph"),
    "export.ticks_per_sec": _p(export_probe("holoocean"), 60),
    "export.big_float_length_m": _p(export_probe("ue5"), 15.0),
    "export.max_vegetation_actors": _p(export_probe("ue5"), 1),
    "export.sdf_heightmap_max": _p(export_probe("sdf"), 129),
    "export.texture_max_px": _p(export_probe("gltf"), 64),
}


# ------------------------------------------------------------------------------------------------ checks

def _with(cfg: Config, values: dict) -> Config:
    for key, v in values.items():
        if "." not in key:
            cfg = replace(cfg, **{key: v})
            continue
        section, name = key.split(".")
        cfg = replace(cfg, **{section: replace(getattr(cfg, section), **{name: v})})
    return cfg


def _fingerprint(x: Any) -> Any:
    """A comparable, hashable digest of a probe's output (arrays by their bytes)."""
    if isinstance(x, np.ndarray):
        if x.dtype == object:
            return ("obj", x.shape, tuple(map(str, x.ravel())))
        return ("nd", x.shape, str(x.dtype), hashlib.sha1(np.ascontiguousarray(x).tobytes()).hexdigest())
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return (type(x).__name__, tuple((f.name, _fingerprint(getattr(x, f.name))) for f in dataclasses.fields(x)))
    if isinstance(x, dict):
        return tuple(sorted((str(k), _fingerprint(v)) for k, v in x.items()))
    if isinstance(x, (list, tuple)):
        return tuple(_fingerprint(v) for v in x)
    if isinstance(x, bytes):
        return hashlib.sha1(x).hexdigest()
    if isinstance(x, float):
        return repr(x)
    return x


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    return World(tmp_path_factory.mktemp("config_keys"))


_RUNS: dict = {}


def _run(probe: Probe, cfg: Config, world: World):
    """A probe's fingerprint, computed once per config (the baselines are shared)."""
    key = (probe.fn, cfg)
    if key not in _RUNS:
        _RUNS[key] = _fingerprint(probe.fn(cfg, world))
    return _RUNS[key]


def test_every_key_has_a_probe():
    keys = set(_flat(Config()))
    assert sorted(keys - set(PROBES)) == [], "a config key without a probe: add one here, or remove the key"
    assert sorted(set(PROBES) - keys) == [], "a probe of a key the config no longer has"


@pytest.mark.parametrize("key", sorted(PROBES))
def test_changing_a_key_changes_what_reads_it(key, world):
    from coastforge.config import validate_config

    probe = PROBES[key]
    default = _flat(Config())[key]
    assert probe.value != default
    base = _with(Config(), {k: v for k, v in probe.base.items() if k != key})
    changed = validate_config(_with(base, {key: probe.value}))
    same = _run(probe, base, world) == _run(probe, changed, world)
    assert not same, f"{key}: {default!r} -> {probe.value!r} changed nothing {probe.fn.__name__} returns"


# ------------------------------------------------------------------------------------ config.library

# a starter kit quick to build: one lighting, no paints, query-like views at one scale, built in this process
SMALL_KIT = dict(lightings=1, paint_variants=False, query_view_gsds_m=(0.2,), crowded_views=0,
                 query_view_random_lightings=0, workers=1)


def test_generate_builds_the_starter_kit_from_config_library(world, tmp_path, monkeypatch):
    """Without --library, generate matches against the starter kit built with ``config.library``: in its
    threads and in its side process (which would build a kit of its own from other settings)."""
    from coastforge.pipeline import runtime
    from coastforge.assets.library.build import config_dict
    from coastforge.config import LibraryConfig
    from coastforge.pipeline import GenerateRequest, run_generate

    monkeypatch.setenv("COASTFORGE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(runtime, "SIDE_PROCESS_MIN_PX", 0)
    cfg = replace(Config(), library=LibraryConfig(**SMALL_KIT))
    for side in (False, True):
        req = GenerateRequest(str(world.image_path), str(tmp_path / f"out{side}"), gsd_m=GSD, report=False,
                              side_process=side)
        res = run_generate(req, cfg)
        assert res.n_objects.get("boat")
    kits = [json.loads(p.read_text()) for p in (tmp_path / "cache").glob("kit-*/library.json")]
    assert [k["config"] for k in kits] == [config_dict(cfg.library)]


def test_the_fallback_kit_and_the_report_use_config_library(monkeypatch):
    """A user library lacking a category borrows it from the kit built with ``config.library``; the report of
    a scene rebuilt later opens the kit its run used (from the scene's provenance)."""
    from coastforge.assets import library as lib_mod
    from coastforge.config import LibraryConfig
    from coastforge.pipeline import libraries
    from coastforge.report.inputs import library_config

    asked = []
    monkeypatch.setattr(lib_mod, "default_library", lambda config=LibraryConfig(): asked.append(config) or "kit")
    small = LibraryConfig(**SMALL_KIT)
    only_boats = type("Lib", (), {"assets": [type("A", (), {"category": "boat"})()]})()
    assert libraries.fallback_kit(only_boats, "my_lib", small)[0] == "kit" and asked == [small]
    assert libraries.load_library(None, small) == "kit" and asked == [small, small]
    prov = {"config": Config(library=small).to_dict()}
    assert library_config(prov) == small
    assert library_config({}) == library_config({"config": {"library": {"view_size_px": "big"}}}) == LibraryConfig()
