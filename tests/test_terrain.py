"""Default terrain model: DESIGN.md §4 invariants and shore profiles on synthetic class maps and the real
marina."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from coastforge.bench.terrain import KINDS, max_interior_step, synthetic_class_map
from coastforge.classes import ASPHALT, GRASS, PAVED, SAND, SIDEWALK, WATER
from coastforge.config import Config, TerrainConfig
from coastforge.errors import ConfigError, InputError
from coastforge.terrain import estimate_terrain
from coastforge.terrain.default import DefaultTerrain, analyse_shore, dean_a, dean_depth
from coastforge.types import ClassMap, Grid

GSD = 0.25
N = 256
X0 = int(0.4 * N)  # first water column of the straight synthetic coasts


def _run(kind: str, cfg: TerrainConfig | None = None, seed: int = 0, n: int = N, gsd: float = GSD):
    ids = synthetic_class_map(kind, n, gsd)
    res = estimate_terrain(ClassMap(ids, Grid(n, n, gsd)), cfg or TerrainConfig(), seed=seed)
    return ids, res.height.z_m, res


@pytest.mark.parametrize("kind", KINDS)
def test_water_below_and_land_above_the_water_level(kind):
    ids, z, res = _run(kind)
    water = ids == WATER
    assert z.dtype == np.float32 and z.shape == ids.shape
    assert np.isfinite(z).all()
    assert (z[water] < 0).all(), f"{kind}: water pixel at {z[water].max()} m"
    assert (z[~water] > 0).all(), f"{kind}: land pixel at {z[~water].min()} m"
    assert res.diagnostics.water_at_or_above == 0 and res.diagnostics.land_at_or_below == 0


def test_beach_follows_deans_profile_within_20_percent():
    cfg = TerrainConfig()
    _ids, z, _ = _run("beach", cfg)
    d = (np.arange(X0, N) - X0 + 0.5) * GSD  # distance offshore of each water column
    dean = dean_depth(d, cfg.d50_mm)
    for row in (30, 128, 200):
        depth = -z[row, X0:]
        ok = dean < 0.5 * cfg.max_depth_m  # the nearshore part, before the cap at max depth
        rel = np.abs(depth[ok] - dean[ok]) / dean[ok]
        assert rel.max() <= 0.2, f"row {row}: {rel.max():.3f} off Dean's curve"
    # A from D50 in millimetres (0.3 mm sand -> about 0.12 m^1/3)
    assert dean_a(0.3) == pytest.approx(0.21 * 0.3 ** 0.48)
    # on land the beach face rises to a berm near beach_height_m
    assert 0.7 * cfg.beach_height_m < z[128, X0 - int(20 / GSD)] < 1.5 * cfg.beach_height_m


def test_quay_wall_is_vertical_with_berth_depth_in_front():
    cfg = TerrainConfig(berth_depth_m=5.0, quay_height_m=1.4)
    _ids, z, _ = _run("quay", cfg)
    for row in range(0, N, 17):
        assert z[row, X0] == pytest.approx(-cfg.berth_depth_m, abs=0.05)  # the first water pixel
        assert z[row, X0 - 1] == pytest.approx(cfg.quay_height_m, abs=0.05)  # the wall's top
    # the berth stays at berth depth for a while in front of the wall
    assert np.allclose(z[:, X0:X0 + int(10 / GSD)], -cfg.berth_depth_m, atol=0.1)


def test_shore_types_order_of_steepness():
    """Revetments are steeper than natural banks, which are steeper than beaches (first 3 m offshore)."""
    k = int(3 / GSD)
    slopes = {}
    for kind in ("beach", "revetment", "bank"):
        _ids, z, _ = _run(kind)
        slopes[kind] = float(np.median((z[:, X0] - z[:, X0 + k]) / (k * GSD)))
    assert slopes["revetment"] > slopes["bank"] > slopes["beach"] > 0


def test_no_spurious_steps_inside_class_regions():
    ids, z, res = _run("mixed", n=400)
    assert set(res.diagnostics.shore_types) == {"beach", "revetment", "quay", "bank"}
    step, cls = max_interior_step(ids, z)
    # a step is spurious if it is steeper than 45° inside one class (walls are at class boundaries)
    assert step <= 1.0 * GSD, f"step of {step:.3f} m between neighbours inside class {cls}"


def test_shore_types_blend_smoothly_along_the_coast():
    ids = synthetic_class_map("mixed", 400, GSD)
    sf = analyse_shore(ids, GSD, TerrainConfig())
    w = sf.weights
    assert np.allclose(w.sum(axis=0), 1.0, atol=1e-4)
    # neighbouring weights never jump (no Voronoi edges): the largest change per pixel is small
    jump = max(np.abs(np.diff(w, axis=1)).max(), np.abs(np.diff(w, axis=2)).max())
    assert jump < 0.25


def test_paved_areas_are_flat_and_noise_free():
    ids, z0, _ = _run("mixed", seed=0)
    _, z1, _ = _run("mixed", seed=1)
    paved = np.isin(ids, PAVED)
    assert np.array_equal(z0[paved], z1[paved])  # the seeded variation never touches paved areas
    grass = ids == GRASS
    assert not np.allclose(z0[grass], z1[grass])
    _, z0b, _ = _run("mixed", seed=0)
    assert np.array_equal(z0, z0b)  # same seed, same terrain
    # paved interior: slope below 5 %
    asph = ids == ASPHALT
    gy, gx = np.gradient(z0, GSD)
    inner = asph & np.roll(asph, 2, 0) & np.roll(asph, -2, 0) & np.roll(asph, 2, 1) & np.roll(asph, -2, 1)
    assert np.hypot(gx, gy)[inner].max() < 0.05


def test_intertidal_band_on_beaches_only():
    cfg = TerrainConfig(intertidal_m=0.5)
    ids, z, res = _run("mixed", cfg)
    water = ids == WATER
    assert (z[water] < 0).all()
    sand = ids == SAND
    assert z[sand].min() < 0  # tidal flat at the waterline
    assert z[sand].min() >= -0.5 - 1e-5
    assert (z[~water & ~sand] > 0).all()
    assert res.diagnostics.land_at_or_below == 0


def test_no_coastline_in_view():
    cfg = TerrainConfig()
    ids = np.zeros((64, 64), np.uint8)
    z = estimate_terrain(ClassMap(ids, Grid(64, 64, 1.0)), cfg).height.z_m
    assert (z < 0).all() and np.allclose(z, -cfg.max_depth_m, atol=cfg.noise_m + 1e-3)
    ids[:] = GRASS
    res = estimate_terrain(ClassMap(ids, Grid(64, 64, 1.0)), cfg)
    assert (res.height.z_m > 0).all() and res.cross_sections == ()


def test_cross_sections_cross_the_shore_once_per_type():
    _ids, _z, res = _run("mixed", n=400)
    types = {s.shore_type: s for s in res.cross_sections}
    assert set(types) == {"beach", "revetment", "quay", "bank"}
    for s in res.cross_sections:
        land, sea = s.distance_m < -0.2, s.distance_m > 0.2
        assert land.sum() >= 4 and sea.sum() >= 4, s.shore_type
        assert (s.height_m[sea] < 0).all() and (s.height_m[land] > 0).all(), s.shore_type
        json.dumps(s.to_dict())
    q = types["quay"]
    first_sea = np.argmax(q.distance_m > 0)
    assert q.height_m[first_sea] < -0.9 * TerrainConfig().berth_depth_m


def test_bad_inputs_name_the_value():
    with pytest.raises(ConfigError, match="max_depth_m"):
        DefaultTerrain(TerrainConfig(max_depth_m=-1.0))
    with pytest.raises(InputError, match=r"class id|id 9"):
        estimate_terrain(ClassMap(np.full((8, 8), 9, np.uint8), Grid(8, 8, 1.0)), TerrainConfig())
    with pytest.raises(InputError, match="shape"):
        estimate_terrain(ClassMap(np.zeros((8, 9), np.uint8), Grid(8, 8, 1.0)), TerrainConfig())
    with pytest.raises(ConfigError, match="unknown terrain backend"):
        estimate_terrain(ClassMap(np.zeros((8, 8), np.uint8), Grid(8, 8, 1.0)), TerrainConfig(backend="nope"))


def test_accepts_the_full_config_and_optical_needs_an_image():
    ids = synthetic_class_map("beach", 64, 1.0)
    cm = ClassMap(ids, Grid(64, 64, 1.0))
    estimate_terrain(cm, Config())
    cfg = dataclasses.replace(TerrainConfig(), optical_depth=True)
    with pytest.raises(InputError, match="optical_depth"):
        estimate_terrain(cm, cfg)


def _marina_class_map(shared_data):
    """Class map of the real marina: the segmentation stage if it is there, else a colour threshold."""
    import cv2

    from coastforge.io import read_image

    img = read_image(shared_data / "aerial" / "marina_p0861" / "image.jpg", gsd_m=0.2)
    try:
        from coastforge.segmentation import segment

        return img, segment(img, Config().segment, seed=0)
    except ImportError:
        pass
    hsv = cv2.cvtColor(img.rgb, cv2.COLOR_RGB2HSV)
    lab = cv2.cvtColor(img.rgb, cv2.COLOR_RGB2LAB).astype(np.int16)
    # the marina's water is dark olive-green and smooth; land is brighter, greyer or greener
    water = (lab[..., 0] < 95) & (hsv[..., 1] > 40)
    water = cv2.morphologyEx(water.astype(np.uint8), cv2.MORPH_OPEN, np.ones((5, 5), np.uint8)).astype(bool)
    ids = np.full(water.shape, ASPHALT, np.uint8)
    ids[(hsv[..., 1] < 30) & (lab[..., 0] > 150)] = SIDEWALK
    ids[(hsv[..., 0] > 30) & (hsv[..., 0] < 85) & (hsv[..., 1] > 60) & ~water] = GRASS
    ids[water] = WATER
    return img, ClassMap(ids, img.grid)


@pytest.mark.shared_data
def test_real_marina_invariants(shared_data):
    img, cm = _marina_class_map(shared_data)
    ids = np.asarray(cm.ids)
    assert (ids == WATER).mean() > 0.2  # the class map found the marina basin
    res = estimate_terrain(cm, TerrainConfig(), image=img, seed=0)
    z = res.height.z_m
    water = ids == WATER
    assert (z[water] < 0).all() and (z[~water] > 0).all()
    step, cls = max_interior_step(ids, z)
    assert step <= 1.0 * img.grid.gsd_m, f"step {step:.3f} m inside class {cls}"
    # where paved land meets the water, the berth depth is reached within one pixel of the wall
    quay_edge = water & np.isin(np.roll(ids, 1, 1), PAVED) & (res.shore_type == 2)
    wq = analyse_shore(ids, img.grid.gsd_m, TerrainConfig()).weights[2]
    strong = quay_edge & (wq > 0.99)
    if strong.any():
        assert np.median(z[strong]) <= -0.95 * TerrainConfig().berth_depth_m
