"""Matching: shape re-ranking identifies same-size, differently shaped assets despite paint, scale and a
wrong heading; orientation fields are paint-invariant; the plain (embedding + size) path still works."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from coastforge.assets.library import build_library, repaint
from coastforge.config import LibraryConfig, MatchConfig
from coastforge.errors import LibraryError
from coastforge.matching import ShapeMatcher, match_detections, orientation_field
from coastforge.render import render_mesh_view, standard_view_lightings
from coastforge.types import Detection, GeoImage, Grid

SMALL = LibraryConfig(lightings=1, backgrounds=("ground",), embed_scales=(1.0,), view_size_px=64,
                      paint_variants=False, crowded_views=0)  # blue cars only (crowded views are repainted)
BODY, GLASS = (40, 60, 200), (25, 28, 32)


def _box(ext, at, colour):
    m = trimesh.creation.box(extents=ext)
    m.apply_translation(at)
    m.visual.face_colors = np.array([*colour, 255], np.uint8)
    return m


def _car(kind: str) -> trimesh.Trimesh:
    """Three 4.6 x 1.9 m cars that differ only in where the cabin is (front at +x)."""
    parts = [_box((4.6, 1.9, 0.8), (0, 0, 0.4), BODY)]
    if kind == "sedan":  # cabin in the middle
        parts += [_box((2.0, 1.7, 0.5), (-0.1, 0, 1.05), BODY), _box((0.5, 1.6, 0.3), (1.05, 0, 0.95), GLASS)]
    elif kind == "hatch":  # cabin to the rear end
        parts += [_box((2.6, 1.7, 0.55), (-0.95, 0, 1.07), BODY), _box((0.5, 1.6, 0.3), (0.6, 0, 0.95), GLASS)]
    else:  # pickup: cab at the front, open bed with side walls behind
        parts += [_box((1.4, 1.7, 0.6), (0.9, 0, 1.1), BODY), _box((0.4, 1.6, 0.3), (1.75, 0, 0.95), GLASS),
                  _box((2.2, 0.15, 0.35), (-1.1, 0.85, 0.97), BODY), _box((2.2, 0.15, 0.35), (-1.1, -0.85, 0.97), BODY),
                  _box((2.0, 1.5, 0.02), (-1.1, 0, 0.81), (70, 70, 70))]
    return trimesh.util.concatenate(parts)


KINDS = ("sedan", "hatch", "pickup")


@pytest.fixture(scope="module")
def car_library(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cars")
    src = tmp / "src"
    src.mkdir()
    entries = []
    for k in KINDS:
        (src / f"{k}.glb").write_bytes(_car(k).export(file_type="glb"))
        entries.append({"id": k, "category": "vehicle", "mesh": f"{k}.glb", "up_axis": "+z", "forward_axis": "+x"})
    (src / "manifest.json").write_text(json.dumps({"assets": entries}))
    return build_library(src / "manifest.json", tmp / "lib", config=SMALL, workers=1)


def _scene(kind: str, paint, yaw: float, scale: float, gsd: float = 0.1, size: int = 96):
    """One repainted, scaled car on ground seen from above, its footprint centre at the image centre."""
    mesh = repaint(_car(kind), paint)
    mesh.apply_scale(scale)
    rgb = render_mesh_view(mesh, gsd, size, standard_view_lightings()[0], "ground", yaw_deg=yaw, seed=3)
    return GeoImage(rgb, Grid(size, size, gsd))


def _det(image: GeoImage, length_m: float, width_m: float, yaw: float, known=True, conf=0.9) -> Detection:
    g = image.grid.gsd_m
    c = image.grid.width_px / 2.0 - 0.5
    return Detection("vehicle", 0.9, c, c, length_m / g, width_m / g, yaw, known, conf)


@pytest.mark.parametrize("paint", [(230, 230, 226), (160, 25, 30)])
def test_shape_identifies_same_size_cars_despite_paint_and_scale(car_library, paint):
    """The library holds only blue cars; white and red ones of the same size must be told apart by shape."""
    for kind in KINDS:
        for yaw, scale in ((35.0, 1.04), (-120.0, 0.96)):
            img = _scene(kind, paint, yaw, scale)
            det = _det(img, 4.6 * scale, 1.9 * scale, yaw)
            dec = match_detections(img, [det], car_library, MatchConfig(), seed=0)[0]
            assert dec.asset_id == kind, (kind, paint, yaw, [(c.asset_id, c.score) for c in dec.candidates])
            assert dec.fit_scale is not None and abs(math.log(dec.fit_scale / scale)) < 0.09  # one 2^(1/12) step
            d = (dec.yaw_deg - yaw + 180) % 360 - 180
            assert abs(d) < 1e-6
            assert dec.to_dict()["candidates"][0]["shape"] is not None


def test_shape_fit_flips_a_wrong_unsure_heading_and_keeps_a_right_one(car_library):
    img = _scene("pickup", (96, 99, 104), 70.0, 1.0)
    wrong = _det(img, 4.6, 1.9, 70.0 + 180.0, known=True, conf=0.55)
    dec = match_detections(img, [wrong], car_library, MatchConfig(), seed=0)[0]
    assert dec.asset_id == "pickup"
    assert abs((dec.yaw_deg - 70.0 + 180) % 360 - 180) < 1e-6 and dec.heading_source == "library"
    assert dec.flip_evidence > 0
    unknown = _det(img, 4.6, 1.9, 70.0, known=False, conf=0.0)
    dec = match_detections(img, [unknown], car_library, MatchConfig(), seed=0)[0]
    assert abs((dec.yaw_deg - 70.0 + 180) % 360 - 180) < 1e-6


def test_shape_fit_reports_the_centre_offset(car_library):
    """A box 0.4 m behind the car's centre: the fit says the car is 0.4 m ahead of the box centre."""
    img = _scene("sedan", (230, 230, 226), 0.0, 1.0)
    det = _det(img, 4.6, 1.9, 0.0)
    det = Detection("vehicle", 0.9, det.cx_px - 4.0, det.cy_px, det.length_px, det.width_px, 0.0, True, 0.9)
    dec = match_detections(img, [det], car_library, MatchConfig(), seed=0)[0]
    assert dec.asset_id == "sedan"
    assert abs(dec.fit_offset_m[0] - 0.4) <= 0.06 and abs(dec.fit_offset_m[1]) <= 0.06, dec.fit_offset_m
    # rotated, and the detector's heading backwards: the offset is given along the final (flipped) yaw
    img = _scene("pickup", (230, 230, 226), 120.0, 1.0)
    det = _det(img, 4.6, 1.9, 300.0, known=True, conf=0.55)
    a = math.radians(120.0)
    det = Detection("vehicle", 0.9, det.cx_px - 4.0 * math.cos(a), det.cy_px + 4.0 * math.sin(a), det.length_px,
                    det.width_px, 300.0, True, 0.55)
    dec = match_detections(img, [det], car_library, MatchConfig(), seed=0)[0]
    assert dec.asset_id == "pickup" and abs((dec.yaw_deg - 120.0 + 180) % 360 - 180) < 1e-6
    assert abs(dec.fit_offset_m[0] - 0.4) <= 0.08 and abs(dec.fit_offset_m[1]) <= 0.08, dec.fit_offset_m


def test_orientation_field_is_paint_and_polarity_invariant():
    yy, xx = np.mgrid[0:48, 0:48]
    shape = (abs(yy - 24) < 8) & (abs(xx - 24) < 16)
    light = np.where(shape[:, :, None], np.uint8(230), np.uint8(120)).repeat(3, 2).astype(np.uint8)
    dark = np.where(shape[:, :, None], np.uint8(20), np.uint8(120)).repeat(3, 2).astype(np.uint8)
    fl, fd = orientation_field(light), orientation_field(dark)
    assert fl.shape == (48, 48, 2)
    assert np.abs(fl).max() > 0.5  # the edges are there ...
    assert np.abs(fl - fd).max() < 0.05  # ... the same for a white and a black object
    assert np.abs(fl[24, 24]).max() < 1e-3  # flat areas carry no structure


def test_templates_are_shared_across_scale_and_resolution(car_library):
    sm = ShapeMatcher(car_library)
    a = sm.template("sedan", "ground", 0.1, 1.0)
    b = sm.template("sedan", "ground", 0.1 * 2 ** 0.25, 2 ** (3 / 12))  # the same gsd / scale
    assert a is b
    c = sm.template("sedan", "ground", 0.2, 1.0)
    assert c.shape[1] < a.shape[1]


def test_plain_path_and_bad_mode(car_library):
    img = _scene("hatch", (172, 174, 178), 10.0, 1.0)
    det = _det(img, 4.6, 1.9, 10.0, known=False, conf=0.0)
    dec = match_detections(img, [det], car_library, MatchConfig(shape=False), seed=0)[0]
    assert dec.asset_id in KINDS and dec.fit_scale is None and dec.candidates[0].shape is None
    with pytest.raises(LibraryError, match=r"match.mode"):
        match_detections(img, [det], car_library, MatchConfig(mode="nearest"), seed=0)
    buoy = Detection("buoy", 0.9, 48, 48, 10, 10, 0.0)
    with pytest.raises(LibraryError, match="no buoy asset"):
        match_detections(img, [buoy], car_library, MatchConfig(), seed=0)


def test_sample_mode_is_seeded(car_library):
    img = _scene("sedan", (30, 50, 110), 0.0, 1.0)
    det = _det(img, 4.6, 1.9, 0.0)
    cfg = MatchConfig(mode="sample", sample_margin=1.0)
    a = [match_detections(img, [det], car_library, cfg, seed=s)[0].asset_id for s in range(6)]
    b = [match_detections(img, [det], car_library, cfg, seed=s)[0].asset_id for s in range(6)]
    assert a == b and len(set(a)) > 1


def test_library_views_on(car_library):
    views = car_library.views_on("sedan", "ground")
    assert len(views) == 1 and views[0].shape == (64, 64, 3) and views[0].dtype == np.uint8
    assert len(car_library.views_on("sedan", "water")) == 1  # none on water: falls back to what there is
    with pytest.raises(LibraryError, match="not in library"):
        car_library.views_on("tractor", "ground")


def test_matcher_leaves_the_edge_extent_out_of_its_crops(car_library):
    """The edge extent measures whatever has edges in a crop: a car parked between two others looks as wide
    as the row. The matcher's vectors drop that block and the ring clutter (zero, then unit again); other
    embedders are untouched."""
    from coastforge.matching import _without_context_blocks, detection_crop

    emb = car_library.embedder
    sl = emb.block_slices["edge_extent"]
    gsd, size = 0.1, 120
    lone = _scene("sedan", BODY, 0.0, 1.0, gsd, size)
    row = lone.rgb.copy()
    for dy in (-25, 25):  # neighbours 2.5 m to either side, as in a parking row
        row = np.minimum(row, np.roll(lone.rgb, dy, axis=0))
    crops = [detection_crop(img, _det(img, 4.6, 1.9, 0.0))[0] for img in (lone, GeoImage(row, lone.grid))]
    v = emb.embed(crops, [gsd, gsd])
    # the row's edges reach farther out than the lone car's: the block differs ...
    assert float(v[0, sl] @ v[1, sl]) / max(float(np.linalg.norm(v[0, sl]) * np.linalg.norm(v[1, sl])), 1e-9) < 0.8
    w = _without_context_blocks(car_library, v)
    assert not w[:, sl].any() and np.allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-5)
    assert v[:, emb.block_slices["clutter"]].any() and not w[:, emb.block_slices["clutter"]].any()
    # ... and without it the two crops are closer than with it
    assert float(w[0] @ w[1]) > float(v[0] @ v[1])

    class Other:  # an embedder without blocks (dinov3): vectors pass unchanged
        embedder = object()

    assert _without_context_blocks(Other(), v) is v
