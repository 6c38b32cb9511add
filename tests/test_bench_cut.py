"""``python -m coastforge.bench.cut``: crops labelled as DOTA's split labels them, scored as bench.real scores."""

from __future__ import annotations

import numpy as np
import pytest

from coastforge.bench.cut import CutScore, crop_labels, main, score_crop
from coastforge.bench.detection import Truth
from coastforge.types import Detection


def test_an_object_under_70_percent_inside_the_crop_is_no_label():
    truth = [Truth("boat", 100.0, 50.0, 40.0, 10.0, 0.0),  # x 80 .. 120 in the level: inside
             Truth("boat", 90.0, 150.0, 40.0, 10.0, 0.0),  # x 70 .. 110: 35 % outside a crop from x 84
             Truth("boat", 96.0, 250.0, 40.0, 10.0, 0.0),  # x 76 .. 116: 20 % outside
             Truth("vehicle", 150.0, 50.0, 5.0, 2.0, 0.0)]
    boats = crop_labels(truth, 84, 0, 300, "boat", 0.7)
    assert [round(float(q[:, 1].mean())) for q in boats] == [50, 250]
    assert np.allclose(boats[0].mean(0), (16.0, 50.0))  # in the crop's pixels
    assert len(crop_labels(truth, 84, 0, 300, "vehicle", 0.7)) == 1


def test_a_cut_boat_found_at_the_edge_is_a_false_box_counted_apart():
    labels = {"boat": np.array([[[10, 45], [50, 45], [50, 55], [10, 55]]], float),
              "vehicle": np.zeros((0, 4, 2))}
    found = Detection("boat", 0.9, 30.0, 50.0, 40.0, 10.0, 0.0, True, 0.9)
    cut = Detection("boat", 0.8, 12.0, 150.0, 24.0, 10.0, 0.0, True, 0.9)  # x 0 .. 24: at the edge
    stray = Detection("boat", 0.7, 150.0, 150.0, 20.0, 6.0, 0.0, True, 0.9)  # inside, no label
    scores = {"boat": CutScore(), "vehicle": CutScore()}
    score_crop([found, cut, stray], labels, 300, scores)
    s = scores["boat"]
    assert (s.labels, s.preds, s.matched, s.unmatched_at_edge) == (1, 3, 1, 1)
    assert s.recall == 1.0 and s.precision == pytest.approx(1 / 3) and s.precision_without_edge == 0.5
    assert scores["vehicle"].preds == 0


def test_a_folder_that_is_no_level_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit, match="not a coastforge synth level"):
        main([str(tmp_path)])
