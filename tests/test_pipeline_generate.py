"""generate end to end on a tiny synthetic level: every output of the scene contract is written (some of
them by background jobs), failures in background jobs surface, and the fast side-raster maths agrees with
the exact version."""

from __future__ import annotations

import json
import sys
from dataclasses import replace

import numpy as np
import pytest

from coastforge.classes import CLASS_NAMES, GRASS, ROCKS, SAND, TREES, WATER
from coastforge.config import Config
from coastforge.errors import OutputExistsError
from coastforge.fsio import read_png
from coastforge.report import SECTION_FAILED


@pytest.fixture(scope="module")
def level(tmp_path_factory):
    from coastforge.synth import synth_to_dir

    d = tmp_path_factory.mktemp("level")
    synth_to_dir("simple_pier_a", 3, d, gsds=(0.25,), size_m=60, overwrite=True)
    return d / "image_0.25m.png"


def _request(image, out, **kw):
    from coastforge.pipeline import GenerateRequest

    return GenerateRequest(image=str(image), out=str(out), gsd_m=0.25, **{"report": False, **kw})


def test_generate_writes_every_output(level, tmp_path):
    from coastforge.pipeline import run_generate
    from coastforge.scene import load_scene

    out = tmp_path / "gen"
    res = run_generate(_request(level, out), Config())
    scene = load_scene(res.scene_path)
    h, w = scene.height.shape
    assert (h, w) == read_png(level).shape[:2] == scene.classes.shape
    expected = ["scene.json", "terrain/height.tif", "terrain/classes.png", "vegetation.csv", "cleaned.png",
                "detections.json", "segmentation/classes.png", "segmentation/classes_preview.png",
                "segmentation/biome.png", "segmentation/biome.json", "segmentation/segmentation.json",
                "terrain_outputs/hillshade.png", "terrain_outputs/shore_types.png",
                "terrain_outputs/cross_section.json", "terrain_outputs/cross_section.png"]
    expected += [f"segmentation/weights/{n}.png" for n in CLASS_NAMES]
    missing = [p for p in expected if not (out / p).is_file()]
    assert not missing
    assert list((out / "pcg").glob("*.png"))
    assert np.array_equal(read_png(out / "segmentation" / "classes.png"), scene.classes)
    total = sum(read_png(out / "segmentation" / "weights" / f"{n}.png").astype(int) for n in CLASS_NAMES)
    assert (total == 255).all()
    assert read_png(out / "cleaned.png").shape == (h, w, 3)
    prov = json.loads((out / "scene.json").read_text())["provenance"]
    stages = ("read", "segment", "detect", "clean", "terrain", "library", "piers", "match", "vegetation", "write")
    assert all(s in prov["timings_s"] for s in stages) and set(prov["stage_cpu_s"]) == set(stages)
    assert {"library", "match", "cleaned", "segmentation", "terrain_outputs", "pcg", "scene_rasters"} <= set(
        prov["background_s"])
    # objects were matched against the library loaded beside segmentation and detection
    assert sum(v for k, v in res.n_objects.items() if k != "vegetation") > 0
    assert all(o.asset_id for o in scene.objects)
    # a second run refuses the non-empty folder without overwrite
    with pytest.raises(OutputExistsError):
        run_generate(_request(level, out), Config())


def test_a_failing_background_job_fails_generate(level, tmp_path, monkeypatch):
    from coastforge.pipeline import run_generate
    from coastforge.segmentation import outputs

    def broken(*a, **k):
        raise OSError("disk full (test)")

    monkeypatch.setattr(outputs, "write_segmentation", broken)
    out = tmp_path / "gen"
    with pytest.raises(OSError, match="disk full"):
        run_generate(_request(level, out, report=True), Config())
    assert not (out / "scene.json").exists()  # the JSON is written last, never over incomplete outputs
    assert not (out / "report.html").exists()  # the report waits for every output before it is written


def test_side_process_gives_the_same_cleaned_image_and_report(level, tmp_path, monkeypatch):
    """The spawned side process (the CLI's default on big images) writes what the threads write."""
    from coastforge.pipeline import runtime
    from coastforge.pipeline import run_generate

    monkeypatch.setattr(runtime, "SIDE_PROCESS_MIN_PX", 0)
    started = []
    real_start = runtime.SideProcess.start.__func__

    def start(cls, n_px, warm_up=None):
        sp = real_start(cls, n_px, warm_up)
        started.append(sp)
        return sp

    monkeypatch.setattr(runtime.SideProcess, "start", classmethod(start))
    a = run_generate(replace(_request(level, tmp_path / "threads"), report=True), Config())
    b = run_generate(replace(_request(level, tmp_path / "side"), report=True, side_process=True), Config())
    assert len(started) == 1 and started[0] is not None  # only the second run asked for it, and got it
    assert np.array_equal(read_png(a.out_dir / "cleaned.png"), read_png(b.out_dir / "cleaned.png"))
    # the classical detections and the matching ran in the child: the same scene
    sa, sb = (json.loads((r.out_dir / "scene.json").read_text()) for r in (a, b))
    assert sa["objects"] and sa["objects"] == sb["objects"]
    assert (json.loads((a.out_dir / "detections.json").read_text())["detections"]
            == json.loads((b.out_dir / "detections.json").read_text())["detections"])
    html_a, html_b = (r.report_path.read_text(encoding="utf-8") for r in (a, b))
    for html in (html_a, html_b):  # the terrain plots came back from the child
        assert "Height map with land and bathymetry" in html
        assert SECTION_FAILED not in html
        assert "Generated scene rendered from above" in html  # from the terrain layer rendered ahead


def test_work_for_a_dead_side_process_is_redone_here():
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    from coastforge.pipeline.runtime import SideProcess

    class DeadPool:
        def submit(self, fn, *args):
            f = Future()
            f.set_exception(BrokenProcessPool("killed (test)"))
            return f

    assert SideProcess(DeadPool()).run(divmod, 7, 2) == (3, 1)


def test_coarse_weight_blur_matches_the_exact_blur():
    import cv2

    from coastforge.segmentation.outputs import _blur_factor, weight_maps

    rng = np.random.default_rng(0)
    ids = cv2.resize(rng.integers(0, 8, (12, 12)).astype(np.uint8), (300, 260), interpolation=cv2.INTER_NEAREST)
    gsd, blur = 0.1, 1.5  # sigma 15 px: computed 5x coarser
    assert _blur_factor(blur / gsd) == 5
    wm = weight_maps(ids, gsd, blur)
    assert wm.shape == (260, 300, 8) and wm.dtype == np.uint8
    assert (wm.astype(int).sum(-1) == 255).all()
    exact = np.stack([cv2.GaussianBlur((ids == c).astype(np.float32), (0, 0), blur / gsd,
                                       borderType=cv2.BORDER_REFLECT) for c in range(8)], -1) * 255
    assert np.abs(wm - exact).max() <= 8.0 and np.abs(wm - exact).mean() < 1.0  # flooring alone: ~0.5
    # no blur: exact one-hot maps
    hard = weight_maps(ids, gsd, 0.0)
    assert np.array_equal(hard.argmax(-1), ids) and set(np.unique(hard)) == {0, 255}


def test_biome_distances_match_scipy():
    from scipy import ndimage as ndi

    from coastforge.segmentation.outputs import BIOME_IDS, biome_map

    rng = np.random.default_rng(1)
    ids = np.full((200, 240), GRASS, np.uint8)
    yy, xx = np.mgrid[0:200, 0:240]
    ids[(xx - 60) ** 2 + (yy - 100) ** 2 < 50 ** 2] = WATER
    ids[rng.random(ids.shape) < 0.05] = ROCKS
    ids[150:, 150:] = TREES
    ids[:20, 200:] = SAND
    gsd, shore, shallow = 0.5, 6.0, 8.0
    b = biome_map(ids, gsd, shore, shallow)
    water = ids == WATER
    near_water = ndi.distance_transform_edt(~water) * gsd <= shore
    near_land = ndi.distance_transform_edt(water) * gsd <= shallow
    assert np.array_equal(b == BIOME_IDS["shallow_water"], water & near_land)
    assert np.array_equal(b == BIOME_IDS["deep_water"], water & ~near_land)
    assert np.array_equal(b == BIOME_IDS["shore_grass"], (ids == GRASS) & near_water)
    assert np.array_equal(b == BIOME_IDS["rocky_ground"], (ids == ROCKS) & ~near_water)
    assert (b[ids == TREES] == BIOME_IDS["woodland"]).all() and (b[ids == SAND] == BIOME_IDS["beach"]).all()
    # no waterline at all: every grass pixel is inland
    assert (biome_map(np.full((30, 30), GRASS, np.uint8), gsd) == BIOME_IDS["inland_grass"]).all()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice values are a Linux feature")
def test_low_priority_background_jobs_run_at_a_higher_nice_value():
    """Output files nothing waits for yield the CPU to the chain: their threads are niced (Linux)."""
    import os
    import threading

    from coastforge.pipeline.runtime import Background, Job

    def nice():
        return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())

    with Background() as bg:
        bg.submit(Job.PCG, nice, low=True)
        bg.submit(Job.MATCH, nice)
        assert bg.result(Job.PCG) > bg.result(Job.MATCH) == os.getpriority(os.PRIO_PROCESS, 0)


def test_background_job_names_are_typed():
    """A misspelt job name is an error, at submit and at result; it never waits for every job instead."""
    from coastforge.pipeline import report_waiter
    from coastforge.pipeline.runtime import Background, Job

    with Background() as bg:
        bg.submit("cleaned", divmod, 7, 2)  # a job's own name is accepted
        assert bg.result(Job.CLEANED) == (3, 1)
        with pytest.raises(ValueError, match="unknown background job 'nonexistent'"):
            bg.result("nonexistent")
        with pytest.raises(ValueError, match="unknown background job"):
            bg.submit("clean", divmod, 7, 2)
        with pytest.raises(KeyError, match="was not submitted"):
            bg.result(Job.MATCH)
        wait = report_waiter(bg)
        assert wait("cleaned") == (3, 1)
        with pytest.raises(ValueError, match="the report waited for 'mesh'"):
            wait("mesh")


def test_fill_under_a_row_of_dark_cars_is_the_pavement_not_the_neighbours():
    """A row of dark parked cars segmented as trees: each car's surroundings, leaving out its neighbours'
    boxes, are asphalt aisle and a strip of grass; the fill is asphalt, and a boat still gets water."""
    from coastforge.classes import ASPHALT, GRASS, TREES, WATER
    from coastforge.pipeline import fill_under_objects
    from coastforge.types import ClassMap, Detection, Grid

    ids = np.full((60, 80), ASPHALT, np.uint8)
    ids[14:18, :] = GRASS  # planting strip behind the row
    ids[12:32, :6] = TREES  # a tree at each end of the row
    ids[12:32, 58:66] = TREES
    ids[40:, :] = WATER
    cars = [Detection("vehicle", 0.9, 10.0 + 9.0 * k, 23.0, 10.0, 7.0, 90.0) for k in range(6)]
    for d in cars:  # dark roofs taken for tree crowns, touching from car to car
        ids[18:28, int(d.cx_px) - 4:int(d.cx_px) + 5] = TREES
    boat = Detection("boat", 0.9, 40.0, 50.0, 12.0, 4.0, 0.0)
    ids[48:53, 34:47] = TREES  # a dark deck
    out = fill_under_objects(ClassMap(ids, Grid(80, 60, 0.2)), cars + [boat]).ids
    assert (out[19:27, 8:56] == ASPHALT).all()
    assert (out[48:53, 35:46] == WATER).all()
    assert (out[14:18, 66:] == GRASS).all()  # outside the boxes nothing changes
    assert (out[12:32, :4] == TREES).all()
