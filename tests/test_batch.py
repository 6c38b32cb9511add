"""Batches: list parsing, resumable items (a finished request is skipped, a changed one re-runs), failures
isolated into the report, and one small batch on a local Dask cluster."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.batch import BatchItem, read_batch_list, run_item
from coastforge.config import Config
from coastforge.errors import InputError
from coastforge.fsio import write_png


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A small rendered level (one good image) and a PNG with a valid signature and garbage after it."""
    from coastforge.synth import synth_to_dir

    d = tmp_path_factory.mktemp("batch_in")
    synth_to_dir("simple_pier_b", 1, d / "lvl", gsds=(0.25,), size_m=50, overwrite=True)
    good = d / "harbor.png"
    good.write_bytes((d / "lvl" / "image_0.25m.png").read_bytes())
    bad = d / "broken.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(np.random.default_rng(0).integers(0, 256, 3000, dtype=np.uint8)))
    return d, good, bad


def test_read_batch_list_json_and_text(tmp_path):
    write_png(tmp_path / "a.png", np.zeros((8, 8, 3), np.uint8))
    (tmp_path / "list.json").write_text(json.dumps({"items": [{"image": "a.png", "gsd_m": 0.2},
                                                              {"image": "a.png", "size_m": [2, 2]}]}))
    items = read_batch_list(tmp_path / "list.json")
    assert [i.name for i in items] == ["a", "a_1"]  # duplicate names made unique
    assert items[0].image == str(tmp_path / "a.png") and items[1].size_m == (2, 2)
    (tmp_path / "list.txt").write_text("# images\na.png 0.3\n\na.png  # no gsd\n")
    txt = read_batch_list(tmp_path / "list.txt")
    assert [i.gsd_m for i in txt] == [0.3, None]
    (tmp_path / "bad.txt").write_text("a.png fast\n")
    with pytest.raises(InputError, match="fast"):
        read_batch_list(tmp_path / "bad.txt")
    with pytest.raises(InputError, match="does not exist"):
        read_batch_list(tmp_path / "missing.json")


def test_run_item_done_skipped_rerun_and_failed(inputs, tmp_path):
    _d, good, bad = inputs
    cfg = Config()
    item = BatchItem(str(good), "harbor", gsd_m=0.25)
    first = run_item(item, str(tmp_path), cfg, None, ())
    assert first.status == "done", first.error
    assert (tmp_path / "harbor" / "scene.json").is_file() and (tmp_path / "harbor" / ".done").is_file()
    assert run_item(item, str(tmp_path), cfg, None, ()).status == "skipped"
    # another seed is another request: it runs again
    again = run_item(BatchItem(str(good), "harbor", gsd_m=0.25, seed=5), str(tmp_path), cfg, None, ())
    assert again.status == "done"
    failed = run_item(BatchItem(str(bad), "broken", gsd_m=0.25), str(tmp_path), cfg, None, ())
    assert failed.status == "failed" and "broken.png" in failed.error
    assert not (tmp_path / "broken" / ".done").exists()


def test_run_batch_on_a_local_cluster(inputs, tmp_path):
    pytest.importorskip("distributed")
    from coastforge.batch import run_batch

    _d, good, bad = inputs
    items = [BatchItem(str(bad), "broken", gsd_m=0.25), BatchItem(str(good), "harbor", gsd_m=0.25)]
    seen = []
    rep = run_batch(items, tmp_path, Config(), workers=1, progress=lambda r, k, n: seen.append((r.name, k, n)))
    assert (rep["done"], rep["failed"], rep["skipped"]) == (1, 1, 0), rep["items"]
    assert [it["name"] for it in rep["items"]] == ["broken", "harbor"]  # in list order
    assert {s[0] for s in seen} == {"broken", "harbor"} and [s[1:] for s in seen] == [(1, 2), (2, 2)]
    assert json.loads((tmp_path / "batch_report.json").read_text())["failed"] == 1
