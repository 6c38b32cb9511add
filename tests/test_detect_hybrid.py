"""The hybrid detector: learned objects + classical piers, union switch, satellite fallback."""

from __future__ import annotations

import numpy as np

from coastforge.config import DetectConfig, load_config
from coastforge.detection import detect
from coastforge.synth import synth_to_dir
from coastforge.io import read_image


def test_default_preset_uses_hybrid():
    assert load_config().detect.backend == "hybrid"


def test_hybrid_finds_boats_and_piers_on_a_rendered_level(tmp_path):
    r = synth_to_dir("simple_pier_a", 7, tmp_path / "lvl", gsds=(0.2,), size_m=80.0)
    img = read_image(r.image_paths[0], gsd_m=0.2)
    dets = detect(img, DetectConfig(), backend="hybrid")
    cats = {d.category for d in dets}
    assert "boat" in cats or "vehicle" in cats
    union = detect(img, DetectConfig(hybrid_union=True), backend="hybrid")
    assert len([d for d in union if d.category == "boat"]) >= len([d for d in dets if d.category == "boat"])


def test_hybrid_falls_back_to_classical_outside_the_learned_gsd_range():
    from coastforge.types import GeoImage, Grid

    rgb = np.full((64, 64, 3), (20, 60, 90), np.uint8)
    img = GeoImage(rgb, Grid(64, 64, 8.0))
    assert detect(img, DetectConfig(), backend="hybrid") == detect(img, DetectConfig(), backend="classical")


def test_learned_boats_on_land_become_vehicles_or_go():
    from types import SimpleNamespace

    from coastforge.detection.hybrid import HybridDetector
    from coastforge.types import Detection

    hyb = HybridDetector(DetectConfig())
    water = np.zeros((100, 100), bool)
    water[:, :40] = True  # water on the left; work grid at half the image resolution
    hyb.classical = SimpleNamespace(water_work=water, work_scale=0.5)
    afloat = Detection("boat", 0.9, 155.0, 100.0, 40.0, 14.0, 90.0)  # 6.8 m from the water at 0.1 m/px
    bus = Detection("boat", 0.9, 185.0, 60.0, 60.0, 25.0, 90.0)  # 6 m long, 9.2 m from the water
    huge = Detection("boat", 0.9, 190.0, 100.0, 160.0, 15.0, 90.0)  # 16 m: no vehicle that long
    car = Detection("vehicle", 0.9, 180.0, 180.0, 45.0, 18.0, 0.0)
    out = hyb._on_land_as_vehicles([afloat, bus, huge, car], 0.1)
    assert [(d.category, d.cx_px) for d in out] == [("boat", 155.0), ("vehicle", 185.0), ("vehicle", 180.0)]
