"""`make demo` end to end: generate on the bundled example, every export, the report; re-runs are safe."""

from __future__ import annotations

import json

import pytest

from coastforge import demo
from coastforge.scene import load_scene


@pytest.mark.slow
def test_demo_generates_exports_and_reports(tmp_path, capsys):
    out = tmp_path / "demo"
    assert demo.main(["--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "report.html" in printed and "against the truth" in printed
    scene = load_scene(out)
    cats = {o.category for o in scene.objects}
    assert {"boat", "vehicle", "pier"} <= cats
    assert scene.height is not None and (scene.height[scene.classes == 0] < 0).all()
    for fmt in ("ue5", "holoocean", "gltf", "sdf"):
        assert any((out / fmt).iterdir()), fmt
    assert (out / "report.html").stat().st_size > 100_000
    timings = json.loads((out / "scene.json").read_text())["provenance"]["timings_s"]
    assert {"segment", "detect", "terrain", "match", "export"} <= set(timings)
    # a second run replaces its own output ...
    assert demo.main(["--out", str(out)]) == 0
    # ... but never a folder somebody else made
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert demo.main(["--out", str(other)]) == 2
    assert (other / "notes.txt").read_text() == "mine"
    assert "pass --overwrite" in capsys.readouterr().err
