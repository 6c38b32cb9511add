"""Issue #28: bad inputs are refused up front, with a message saying what, the value, and what to do.

Each case builds its own bad input in tmp_path; CLI cases also check exit code 2 and that nothing was written.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge.cli import cli
from coastforge.config import Config, load_config, validate_config
from coastforge.errors import ConfigError
from coastforge.fsio import write_png


def _image(tmp_path, name="a.png", h=64, w=64):
    p = tmp_path / name
    write_png(p, np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8))
    return p


def _no_output(out):
    """Nothing written: the output folder was not even created."""
    return not out.exists()


# ------------------------------------------------------------------------------------------- 1. config

@pytest.mark.parametrize("sets,seed,phrase", [
    (["terrain.max_depth_m=-5"], None, "terrain.max_depth_m = -5.0 must be > 0 (metres; depth far from shore)"),
    (["terrain.max_depth_m=nan"], None, "terrain.max_depth_m = nan must be a finite number"),
    (["terrain.max_depth_m=inf"], None, "must be a finite number"),
    (["match.scale_max=-1"], None, "match.scale_max = -1.0 must be > 0"),
    (["match.scale_min=3"], None, "match.scale_min = 3.0 is larger than match.scale_max = 2.0"),
    (["vegetation.tree_density_per_100m2=-1"], None, "must be >= 0 (instances per 100 m²)"),
    (["vegetation.seaweed_density_per_100m2=-0.1"], None, "vegetation.seaweed_density_per_100m2 = -0.1"),
    (["vegetation.min_spacing_m=-2"], None, "vegetation.min_spacing_m = -2.0 must be >= 0 (metres)"),
    (["detect.min_score=1.5"], None, "detect.min_score = 1.5 must be between 0 and 1"),
    (["detect.nms_iou=-0.1"], None, "detect.nms_iou = -0.1 must be between 0 and 1"),
    (["detect.min_boat_length_m=80"], None, "detect.min_boat_length_m = 80.0 is larger than detect.max_boat_length_m"),
    (["detect.slice_overlap_px=2048"], None, "must be smaller than detect.slice_px"),
    (["detect.work_gsd_m=0"], None, "detect.work_gsd_m = 0.0 must be > 0"),
    (["segment.learned_water=maybe"], None, "segment.learned_water = 'maybe' is not one of fused, classical, net"),
    (["match.mode=random"], None, "match.mode = 'random' is not one of best, sample"),
    (["match.scale_mode=free"], None, "is not one of uniform, per_axis"),
    (["detect.boat_mask=blob"], None, "is not one of core, struct, region"),
    (["detect.backend=magic"], None, "detect.backend = 'magic' is not a known detect backend; valid: classical"),
    (["export.formats=['gltf','fbx']"], None, "export.formats = 'fbx' is not a known export format"),
    (["library.embed_scales=[1.0,-2.0]"], None, "library.embed_scales = (1.0, -2.0) must be a list whose every item"),
    (["render.sun_elevation_deg=120"], None, "render.sun_elevation_deg = 120.0 must be between 0.0 and 90.0"),
    (["io.max_memory_gb=0"], None, "io.max_memory_gb = 0.0 must be > 0"),
    (["seed=-3"], None, "seed = -3 must be between 0 and 9223372036854775807"),
    ([], -1, "seed = -1 must be between 0 and 9223372036854775807; fix it with --seed N"),
    ([], 2**64, "seed = 18446744073709551616 must be between 0"),
])
def test_config_values_checked_when_built(sets, seed, phrase):
    with pytest.raises(ConfigError) as e:
        load_config(sets=sets, seed=seed)
    assert phrase in str(e.value)
    assert "fix it with" in str(e.value) or "fix one of them" in str(e.value)


@pytest.mark.parametrize("section,key,value,phrase", [
    ("terrain", "depth_scale_m", 0.0, "terrain.depth_scale_m = 0.0 must be > 0"),
    ("vegetation", "bush_density_per_100m2", float("nan"), "must be a finite number"),
    ("match", "k", 0, "match.k = 0 must be > 0"),
])
def test_validate_config_on_a_config_built_in_code(section, key, value, phrase):
    cfg = dataclasses.replace(Config(), **{section: dataclasses.replace(getattr(Config(), section), **{key: value})})
    with pytest.raises(ConfigError, match=phrase):
        validate_config(cfg)


def test_every_preset_and_the_defaults_are_valid():
    from coastforge.config import preset_names

    assert validate_config(Config()) == Config()
    for name in preset_names():
        load_config(name)
    # negative where documented: <= 0 turns the heading prior's scaling off; azimuths wrap
    load_config(sets=["match.heading_prior_ref_px=-1", "render.sun_azimuth_deg=-45"])


@pytest.mark.parametrize("args,phrase", [
    (["--seed", "-1"], "seed = -1 must be between 0"),
    (["--set", "terrain.max_depth_m=-5"], "terrain.max_depth_m = -5.0 must be > 0"),
    (["--set", "terrain.max_depth_m=nan"], "terrain.max_depth_m = nan must be a finite number"),
    (["--set", "match.scale_max=-1"], "match.scale_max = -1.0 must be > 0"),
    (["--set", "vegetation.grass_density_per_100m2=-2"], "vegetation.grass_density_per_100m2 = -2.0 must be >= 0"),
    (["--set", "vegetation.min_spacing_m=-1"], "vegetation.min_spacing_m = -1.0 must be >= 0"),
])
def test_generate_refuses_bad_config_before_writing(tmp_path, args, phrase):
    img, out = _image(tmp_path), tmp_path / "out"
    r = CliRunner().invoke(cli, ["generate", str(img), "--gsd", "0.2", "--out", str(out), *args])
    assert r.exit_code == 2, r.output
    assert phrase in r.output and "Traceback" not in r.output
    assert _no_output(out)
