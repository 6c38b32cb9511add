"""Config, randomness, backend registry and the CLI shell."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from coastforge import registry
from coastforge.cli import COMMANDS, cli
from coastforge.config import Config, load_config, parse_set, preset_names
from coastforge.errors import BackendUnavailable, ConfigError
from coastforge.rng import stage_rng, stage_seed


def test_config_defaults_are_the_default_preset():
    # one source of defaults: code that builds Config() runs the pipeline the CLI runs
    assert Config() == load_config("default") == load_config()
    assert Config().segment.backend == "learned" and Config().detect.backend == "hybrid"


def test_config_defaults_presets_and_sets(tmp_path):
    assert {"default", "fast", "variety"} <= set(preset_names())
    assert load_config("variety").match.mode == "sample"
    c = load_config(sets=["terrain.max_depth_m=12", "export.formats=['gltf','usd']", "match.mode=sample",
                          "vegetation.enabled=false"], seed=5)
    assert c.terrain.max_depth_m == 12.0 and c.export.formats == ("gltf", "usd") and c.match.mode == "sample"
    assert c.vegetation.enabled is False and c.seed == 5
    f = tmp_path / "c.toml"
    f.write_text("[terrain]\nberth_depth_m = 6\n")
    assert load_config(path=f).terrain.berth_depth_m == 6.0


@pytest.mark.parametrize("item,msg", [
    ("terrain.nope=1", "unknown config key 'terrain.nope'; valid keys here: backend, .*; fix the name in --set"),
    ("terrain.max_depth_m=deep", "must be of type float"),
    ("vegetation.enabled=3", "must be of type bool"),
    ("noequals", "must look like section.key=value"),
    ("nosection=1", "unknown config key 'nosection'"),
])
def test_config_errors(item, msg):
    with pytest.raises(ConfigError, match=msg):
        load_config(sets=[item])


@pytest.mark.parametrize("item,key", [
    ("render.glint=0.5", "render"), ("segment.superpixel_m=3", "segment.superpixel_m"), ("match.k=5", "match.k"),
])
def test_removed_config_keys_say_so(tmp_path, item, key):
    """Keys nothing read were removed: --set or a TOML file naming one stops with what to do."""
    with pytest.raises(ConfigError, match=rf"config key '{key}' was removed: .*; delete it from --set or the config"):
        load_config(sets=[item])
    f = tmp_path / "old.toml"
    section, _, name = item.partition("=")[0].rpartition(".")
    f.write_text(f"[{section}]\n{name} = {item.partition('=')[2]}\n")
    with pytest.raises(ConfigError, match=f"config key '{key}' was removed"):
        load_config(path=f)


def test_config_unknown_preset():
    with pytest.raises(ConfigError, match="unknown preset 'nope'; presets: default"):
        load_config("nope")


def test_parse_set_types():
    assert parse_set("a.b=1.5") == {"a": {"b": 1.5}}
    assert parse_set("a=hello world") == {"a": "hello world"}


def test_stage_rng_is_deterministic_and_independent():
    a = stage_rng(1, "terrain").random(5)
    assert np.array_equal(a, stage_rng(1, "terrain").random(5))
    assert not np.array_equal(a, stage_rng(1, "detect").random(5))
    assert not np.array_equal(a, stage_rng(2, "terrain").random(5))
    assert stage_seed(1, "x", 3) == stage_seed(1, "x", 3)


def test_registry_lists_without_importing_heavy_modules():
    code = ("import sys; from coastforge import registry; [registry.missing_modules(s) for s in registry.specs()]; "
            "print(any(m in sys.modules for m in ('torch','ultralytics','transformers','pxr','google.genai')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_registry_errors():
    with pytest.raises(ConfigError, match="unknown segment backend 'nope'; valid backends: classical"):
        registry.get_spec("segment", "nope")
    fake = registry.BackendSpec("segment", "fake", "x:y", ("no_such_module_xyz",), "fake")
    assert registry.missing_modules(fake) == ["no_such_module_xyz"]
    with pytest.raises(BackendUnavailable, match=r"pip install 'coastforge\[extra\]'"):
        registry.require("no_such_module_xyz", "extra", "a test")
    assert all(registry.default_name(s) for s in ("segment", "terrain", "detect", "embed"))
    cfg = Config()  # `coastforge backends` marks the config's defaults
    assert [registry.default_name(s) for s in ("segment", "terrain", "detect", "embed")] == [
        cfg.segment.backend, cfg.terrain.backend, cfg.detect.backend, cfg.library.embedder]


def test_cli_help_fast_and_without_heavy_imports():
    t0 = time.perf_counter()
    code = ("import sys; from coastforge.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit: pass\n"
            "print('HEAVY', [m for m in ('numpy','torch','rasterio','cv2','trimesh') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert time.perf_counter() - t0 < 5  # generous: a loaded CI machine; the real figure is ~0.15 s
    assert "HEAVY []" in out
    assert "Commands:" in out


def test_every_subcommand_has_help():
    runner = CliRunner()
    for name in cli.list_commands(None):
        r = runner.invoke(cli, [name, "--help"])
        assert r.exit_code == 0, (name, r.output)
        assert "Usage" in r.output
    assert set(cli.list_commands(None)) <= set(COMMANDS)


def test_backends_command():
    r = CliRunner().invoke(cli, ["backends", "--json"])
    assert r.exit_code == 0 and '"stage": "segment"' in r.output


def test_cli_error_is_one_line_without_traceback(tmp_path):
    r = CliRunner().invoke(cli, ["evaluate", "--truth", str(tmp_path / "t.json"), "--pred", str(tmp_path)])
    assert r.exit_code == 2
    assert "Error: no scene file" in r.output and "Traceback" not in r.output
