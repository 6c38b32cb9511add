"""Optical (Stumpf log-ratio) depth: a synthetic shallow-water image with Beer-Lambert attenuation."""

from __future__ import annotations

import numpy as np

from coastforge.bench.terrain import synthetic_class_map
from coastforge.classes import WATER
from coastforge.config import TerrainConfig
from coastforge.terrain import estimate_terrain
from coastforge.terrain.optical import stumpf_ratio
from coastforge.types import ClassMap, GeoImage, Grid

N, GSD = 200, 0.5


def _water_image(depth: np.ndarray, land: np.ndarray) -> np.ndarray:
    """Reflectance over a bright sandy bottom: R = R_deep + (R_bottom - R_deep) exp(-2 K depth),
    K_blue < K_green."""
    out = np.zeros(depth.shape + (3,), np.float32)
    for ch, (r_deep, r_bot, k) in enumerate(((0.02, 0.35, 0.30), (0.04, 0.40, 0.15), (0.08, 0.45, 0.06))):
        out[..., ch] = r_deep + (r_bot - r_deep) * np.exp(-2 * k * depth)
    out[land] = (0.5, 0.45, 0.3)
    return np.clip(out * 255, 0, 255).astype(np.uint8)


def test_stumpf_ratio_grows_with_depth():
    d = np.linspace(0, 6, 50)[None]
    rgb = _water_image(d, np.zeros_like(d, bool))
    r = stumpf_ratio(rgb)[0]
    assert np.corrcoef(d[0], r)[0, 1] > 0.95 and r[-1] > r[0] + 0.1  # monotone up to 8-bit quantisation


def test_optical_depth_moves_the_model_towards_the_true_bathymetry():
    ids = synthetic_class_map("beach", N, GSD)
    cm = ClassMap(ids, Grid(N, N, GSD))
    cfg = TerrainConfig(noise_m=0.0)
    model = estimate_terrain(cm, cfg).height.z_m
    water = ids == WATER
    # the truth: the model's profile plus a trough the class map cannot know about (the optical fit
    # takes its scale from the model, so it can only add shape)
    cols = np.arange(N)[None].repeat(N, 0)
    rows = np.arange(N)[:, None].repeat(N, 1)
    true_depth = np.where(water, -model + 1.0 * np.exp(-((cols - 120) ** 2) / 200.0) * (rows > 0), 0)
    true_depth = np.clip(true_depth, 0, None)
    img = GeoImage(_water_image(true_depth, ~water), cm.grid)
    on = TerrainConfig(noise_m=0.0, optical_depth=True)
    res = estimate_terrain(cm, on, image=img)
    z = res.height.z_m
    fit = res.diagnostics.optical
    assert fit["used"] and fit["gain"] > 0 and fit["r2"] > 0.3
    assert (z[water] < 0).all() and np.array_equal(z[~water], model[~water])
    shallow = water & (true_depth < on.optical_max_depth_m * 0.5)
    rmse_model = np.sqrt(np.mean((-model[shallow] - true_depth[shallow]) ** 2))
    rmse_opt = np.sqrt(np.mean((-z[shallow] - true_depth[shallow]) ** 2))
    assert rmse_opt < 0.8 * rmse_model, (rmse_opt, rmse_model)


def test_turbid_water_keeps_the_model():
    ids = synthetic_class_map("beach", N, GSD)
    cm = ClassMap(ids, Grid(N, N, GSD))
    rng = np.random.default_rng(0)
    rgb = rng.integers(30, 120, (N, N, 3), dtype=np.uint8)  # no depth signal at all
    base = estimate_terrain(cm, TerrainConfig()).height.z_m
    res = estimate_terrain(cm, TerrainConfig(optical_depth=True), image=GeoImage(rgb, cm.grid))
    assert not res.diagnostics.optical["used"] and res.diagnostics.optical["note"]
    assert np.array_equal(res.height.z_m, base)
