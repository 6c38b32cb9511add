"""``python -m coastforge.bench.big``: big vessels rendered, detected and scored by length."""

from __future__ import annotations

import json

import numpy as np
import pytest

from coastforge.bench.big import BigScore, main, score_level
from coastforge.types import Detection


def test_big_vessels_are_scored_apart_with_their_length():
    """Labels (cx, cy, length, width, yaw px) at 0.2 m/px: a 40 m vessel found whole, a 30 m one found as a
    part (a short box: a match, but no box of 20 m or more), a 6 m boat missed, and a false 25 m box."""
    labels = np.array([[100.0, 100.0, 200.0, 40.0, 0.0], [100.0, 300.0, 150.0, 30.0, 0.0],
                       [400.0, 400.0, 30.0, 10.0, 0.0]])
    dets = [Detection("boat", 0.8, 104.0, 100.0, 220.0, 40.0, 0.0),
            Detection("boat", 0.6, 120.0, 300.0, 40.0, 12.0, 90.0),
            Detection("boat", 0.7, 400.0, 600.0, 125.0, 30.0, 0.0),
            Detection("vehicle", 0.9, 400.0, 400.0, 25.0, 10.0, 0.0)]  # not a boat: not counted
    s = BigScore()
    score_level(dets, labels, 0.2, s)
    out = s.summary()
    assert (out["boats"], out["big_vessels"], out["predicted"]) == (3, 2, 3)
    assert out["recall_20m_and_more"] == 1.0 and out["recall_under_20m"] == 0.0
    assert out["precision"] == pytest.approx(0.667, abs=1e-3)
    assert (out["boxes_20m_and_more"], out["boxes_20m_and_more_true"]) == (2, 1)
    assert out["big_length_ratio_median"] == pytest.approx((1.1 + 40 / 150) / 2, abs=1e-3)


def test_one_level_end_to_end_and_bad_arguments(tmp_path, capsys):
    main(["--levels", "1", "--json", str(tmp_path / "big.json")])
    out = json.loads((tmp_path / "big.json").read_text())
    assert out["levels"] == 1 and out["boats"] > 0 and 0.0 <= out["recall"] <= 1.0
    assert "boats" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="--levels must be at least 1"):
        main(["--levels", "0"])
    with pytest.raises(SystemExit, match="no asset library"):
        main(["--library", str(tmp_path)])
