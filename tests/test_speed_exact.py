"""The speed-ups of the segment and detect stages (issue #7) give the same values as the plain code they
replace (reference implementations below are the code as it was)."""

from __future__ import annotations

import numpy as np
import pytest

from coastforge.config import DetectConfig
from coastforge.types import GeoImage, Grid


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def test_lab_cache_windows_equal_converting_each_window():
    from coastforge.detection.crops import LabCache, lab_window

    rgb = (_rng().random((150, 170, 3)) * 255).astype(np.uint8)
    cache = LabCache(rgb)
    lab_window(cache, 20.0, 20.0, 5.0)
    assert cache.done.any() and not cache.done.all()  # only the blocks asked for are converted
    r = _rng(1)
    for _ in range(60):  # overlapping windows, some clipped at the image's borders
        cx, cy, reach = r.uniform(-10, 180), r.uniform(-10, 160), r.uniform(1, 60)
        a, oa = lab_window(rgb, cx, cy, reach)
        b, ob = lab_window(cache, cx, cy, reach)
        assert oa == ob and np.array_equal(a, b)
    with pytest.raises(ValueError):  # read-only views: the cache cannot be corrupted by a caller
        b[...] = 0


def test_lab_cache_without_a_full_buffer_for_huge_images(monkeypatch):
    from coastforge.detection.crops import LabCache, lab_window

    monkeypatch.setattr(LabCache, "MAX_PIXELS", 100)
    rgb = (_rng().random((40, 50, 3)) * 255).astype(np.uint8)
    cache = LabCache(rgb)
    assert cache.lab is None
    assert np.array_equal(lab_window(cache, 20, 20, 9)[0], lab_window(rgb, 20, 20, 9)[0])


def _mirror_cost_reference(crop, ci, half_v, shifts):
    k = np.arange(1, half_v + 1)
    c = np.round(ci + shifts).astype(int)[:, None]
    up, dn = c - k[None], c + k[None]
    ok = (up[:, -1] >= 0) & (dn[:, -1] < crop.shape[0])
    out = np.full(len(shifts), np.inf)
    if ok.any():
        d = np.abs(crop[up[ok]] - crop[dn[ok]])
        out[ok] = d.reshape(d.shape[0], -1).mean(1)
    return out


@pytest.mark.parametrize("rows,ci", [(68, 33.5), (41, 20.0), (30, 14.5), (12, 5.5)])
def test_mirror_cost_equals_the_reference(rows, ci):
    from coastforge.detection.refine import _mirror_cost

    crop = _rng(rows).random((rows, 23, 3), dtype=np.float32) * 100
    shifts = np.arange(-10, 11)
    got, ref = _mirror_cost(crop, ci, 8, shifts), _mirror_cost_reference(crop, ci, 8, shifts)
    assert np.array_equal(got, ref)
    assert np.isinf(got).any() == np.isinf(ref).any()


def _background_modes_reference(ring, core, k=3, iters=6, min_share=0.12, max_in_core=0.3, tol=8.0):
    x = ring.reshape(-1, 3)
    if len(x) > 1200:
        x = x[:: len(x) // 1200 + 1]
    if len(x) < 10:
        return []
    centres = np.quantile(x, np.linspace(0.15, 0.85, k), axis=0)
    for _ in range(iters):
        lab = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(-1), 1)
        for j in range(k):
            sel = x[lab == j]
            if len(sel):
                centres[j] = np.median(sel, 0)
    lab = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(-1), 1)
    c = core.reshape(-1, 3)
    out = []
    for j in range(k):
        share = float((lab == j).mean())
        if share < min_share:
            continue
        if len(c) and (np.sqrt(((c - centres[j]) ** 2).sum(-1)) < tol).mean() > max_in_core:
            continue
        out.append((centres[j].copy(), share))
    return sorted(out, key=lambda m: -m[1])


@pytest.mark.parametrize("seed", range(8))
def test_background_modes_equal_the_reference(seed):
    from coastforge.detection.crops import background_modes

    r = _rng(seed)
    n = int(r.integers(20, 3000))
    # two or three colour clusters with noise (water and a pier deck...), some values tied
    centres = r.uniform(0, 100, (3, 3))
    ring = (centres[r.integers(0, 3, n)] + r.normal(0, r.uniform(0.5, 8), (n, 3))).astype(np.float32)
    if seed % 2:
        ring = np.round(ring)
    core = (centres[0] + r.normal(0, 3, (50, 3))).astype(np.float32)
    got, ref = background_modes(ring, core), _background_modes_reference(ring, core)
    assert len(got) == len(ref)
    for (a, sa), (b, sb) in zip(got, ref):
        assert np.array_equal(a, b) and sa == sb


def test_median_and_squared_distance_helpers_equal_numpy():
    from coastforge.detection.crops import _median0, sq_dist

    r = _rng(3)
    for n in (1, 2, 3, 10, 11, 400, 401):
        a = (r.normal(50, 20, (n, 3))).astype(np.float32)
        assert np.array_equal(_median0(a), np.median(a, 0))
    crop = r.random((30, 40, 3), dtype=np.float32) * 100
    for m in (np.array([50.0, 3.0, -7.0]), np.array([50.0, 3.0, -7.0], np.float32)):
        ref = ((crop - m) ** 2).sum(-1)
        got = sq_dist(crop, m)
        assert got.dtype == ref.dtype and np.array_equal(got, ref)


def test_labels_in_equals_isin():
    from coastforge.detection.piers import labels_in

    lab = _rng(4).integers(0, 500, (60, 70)).astype(np.int32)
    for ids in (np.array([], int), np.array([0, 3, 499]), np.arange(1, 500, 7)):
        assert np.array_equal(labels_in(lab, ids, 500), np.isin(lab, ids))


def test_softmax_equals_the_reference():
    from coastforge.segmentation.learned import _softmax

    for dtype in (np.float32, np.float64):
        lg = (_rng(5).normal(0, 6, (37, 41, 8))).astype(dtype)
        e = np.exp(lg - lg.max(axis=2, keepdims=True))
        ref = (e / e.sum(axis=2, keepdims=True)).astype(np.float32)
        got = _softmax(lg)
        assert got.dtype == np.float32 and np.array_equal(got, ref)


def test_classical_detector_can_skip_vehicles_without_changing_the_rest(tmp_path):
    from coastforge.detection.classical import ClassicalDetector
    from coastforge.io import read_image
    from coastforge.synth import synth_to_dir

    r = synth_to_dir("pier_parking", 3, tmp_path / "lvl", gsds=(0.2,), size_m=80.0)
    img = read_image(r.image_paths[0], gsd_m=0.2)
    det = ClassicalDetector(DetectConfig())
    full = det.detect(img, None, 0)
    some = det.detect(img, None, 0, vehicles=False)
    assert not any(d.category == "vehicle" for d in some)
    key = lambda d: (d.category, d.cx_px, d.cy_px, d.length_px, d.width_px, d.yaw_deg, d.score)  # noqa: E731
    assert [key(d) for d in full if d.category != "vehicle"] == [key(d) for d in some]


def test_hybrid_keeps_classical_vehicles_outside_the_networks_range():
    from coastforge.detection.hybrid import HybridDetector

    calls = []

    class Spy:
        def detect(self, image, class_map, seed, vehicles=True):
            calls.append(vehicles)
            return []

    hyb = HybridDetector(DetectConfig())
    hyb.classical = Spy()
    hyb.detect(GeoImage(np.zeros((64, 64, 3), np.uint8), Grid(64, 64, 8.0)))  # satellite scale: classical only
    assert calls == [True]
