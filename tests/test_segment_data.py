"""Training-data commands of the learned segmenter and detector: the shared part (train/common.py)."""

from __future__ import annotations

import json

import pytest

from coastforge.errors import InputError
from coastforge.train import common


def test_parse_seeds_ranges_lists_and_reserved():
    assert common.parse_seeds("100:103") == [100, 101, 102]
    assert common.parse_seeds("150, 120") == [150, 120]
    with pytest.raises(InputError, match="reserved for validation"):
        common.parse_seeds("0:200")
    with pytest.raises(InputError, match="must be 'A:B'"):
        common.parse_seeds("1-2")
    with pytest.raises(InputError, match="reserved"):
        common.parse_seeds("")
    # both commands use the one implementation
    from coastforge.train import detector_data, seg_data

    assert detector_data.parse_seeds is common.parse_seeds
    assert seg_data.data_main is common.data_main and detector_data.data_main is common.data_main


def test_render_levels_resumes_skips_and_draws_the_same_levels(tmp_path):
    calls = []

    def make_item(preset, seed, gsd, size, out):
        if seed == 102:
            raise ValueError("cannot lay out this size")
        calls.append((preset, seed, gsd, size))
        (out / f"{preset}_{seed}.png").write_bytes(b"x")
        return {"image": f"{preset}_{seed}.png", "seed": seed, "gsd": gsd}, "ok"

    kw = dict(stage="unit", index_head={"gsd_m": 0.2}, presets=["a", "b"], gsd_range=(0.1, 0.4),
              size_range_m=(60.0, 80.0))
    idx = common.render_levels(tmp_path, [100, 101, 102, 103], make_item, **kw)
    index = json.loads(idx.read_text())
    assert index["gsd_m"] == 0.2
    assert [it["image"] for it in index["items"]] == ["a_100.png", "b_101.png", "b_103.png"]  # 102 skipped
    for _preset, _seed, gsd, size in calls:
        assert 0.1 <= gsd <= 0.4 and 60.0 <= size <= 80.0 and size % 2 == 0
    first = list(calls)
    # a second run resumes: nothing already written is rendered again
    calls.clear()
    common.render_levels(tmp_path, [100, 101, 102, 103, 104], make_item, **kw)
    assert [c[1] for c in calls] == [104]
    assert len(json.loads(idx.read_text())["items"]) == 4
    # the draws depend only on (seed, stage, preset): a fresh folder gets the same levels
    calls.clear()
    common.render_levels(tmp_path / "again", [100, 101, 102, 103], make_item, **kw)
    assert calls == first


def test_data_commands_parse_the_shared_options(capsys):
    from coastforge.train import detector_data, seg_data

    for mod in (seg_data, detector_data):
        with pytest.raises(SystemExit):
            mod.main(["--help"])
        out = capsys.readouterr().out
        assert "--seeds" in out and "--minutes" in out and "--out" in out
        with pytest.raises(InputError, match="reserved"):
            mod.main(["--out", "unused", "--seeds", "5:7"])


def test_covers_go_on_boats_only_and_are_drawn_from_the_seed():
    from coastforge.synth import synthesize_level
    from coastforge.train.detector_data import COVER_COLOURS, vary_covers

    level = synthesize_level("marina", 3406, size_m=80)
    n_boats = sum(o.category == "boat" for o in level.scene.objects)
    all_covered = vary_covers(level, common_rng(1), p_boat=1.0)
    for o in all_covered.scene.objects:
        assert ("cover" in o.attrs) == (o.category == "boat")
        if o.category == "boat":
            assert tuple(o.attrs["cover"]) in COVER_COLOURS
    half = [vary_covers(level, common_rng(s)) for s in (2, 2, 3)]
    covered = [[o.attrs.get("cover") for o in h.scene.objects] for h in half]
    assert covered[0] == covered[1]  # same seed, same covers
    k = sum(c is not None for c in covered[0]) + sum(c is not None for c in covered[2])
    assert n_boats >= 4 and 0 < k < 2 * n_boats


def test_wakes_trail_boats_in_open_water_only():
    """``detector_data --looks wakes``: foam astern of a boat with open water behind it, none ahead of it; a
    boat whose wake would cross land (moored by the quay) and a vehicle get none."""
    import numpy as np

    from coastforge.train.detector_data import add_wakes

    rgb = np.full((200, 300, 3), (30, 70, 90), np.uint8)
    water = np.ones((200, 300), bool)
    water[:, 250:] = False  # a quay on the east
    under_way = [0, 100.0, 60.0, 20.0, 8.0, 0.0]  # heading east: its wake runs west, over water
    moored = [0, 230.0, 150.0, 20.0, 8.0, 180.0]  # heading west: its wake would run onto the quay
    car = [1, 280.0, 100.0, 20.0, 8.0, 0.0]
    out = add_wakes(rgb, [under_way, moored, car], water, common_rng(4), p_boat=1.0)
    light = out.astype(int).sum(2)
    base = int(rgb[0, 0].astype(int).sum())
    assert light[58:63, 60:88].mean() > base + 100  # astern of the stern (x 90): foam
    assert (light[40:80, 112:250] == base).all()  # ahead of the bow (x 110): untouched
    assert (light[120:180, 150:300] == base).all()  # the moored boat and the quay: untouched
    assert (light[:, 250:] == base).all()
    assert (add_wakes(rgb, [under_way], water, common_rng(4), p_boat=0.0) == rgb).all()


def common_rng(seed: int):
    from coastforge.rng import stage_rng

    return stage_rng(seed, "test", "covers")
