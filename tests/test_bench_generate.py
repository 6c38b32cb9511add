"""The generate-speed benchmark command runs end to end (its figures are measured, never asserted)."""

from __future__ import annotations

import json

import pytest


def test_generate_benchmark_reports_wall_memory_and_stages(tmp_path, capsys):
    pytest.importorskip("psutil")
    from coastforge.bench.generate import main

    out = tmp_path / "figures.json"
    main(["--size", "256", "--runs", "1", "--no-report", "--work", str(tmp_path / "w"), "--json", str(out)])
    text = capsys.readouterr().out
    assert "peak memory (process tree)" in text and "stages of the best run" in text
    res = json.loads(out.read_text())
    assert res["image_px"] == 256 and res["report"] is False
    assert res["wall_s"][0] > 0 and res["peak_gb"] > 0.05  # a Python process with numpy is > 50 MB
    assert {"segment", "detect", "terrain", "total"} <= set(res["best_run_stages_s"])
    assert res["calibration_s"] > 0 and res["calibration_end_s"] > 0 and res["calibration_one_thread_s"]["two_processes_at_once"] > 0


def test_generate_benchmark_refuses_nonsense(capsys):
    from coastforge.bench.generate import main

    with pytest.raises(SystemExit):
        main(["--runs", "0"])
    assert "--runs must be at least 1" in capsys.readouterr().err
