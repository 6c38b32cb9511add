"""Tiled processing: windows, windowed reads with one global stretch, tiled segmentation / detection /
terrain against untiled processing on small images (600 x 600, tiles of 256 with 64 px overlap)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from coastforge.classes import ASPHALT, GRASS, WATER
from coastforge.config import Config, DetectConfig, SegmentConfig, TerrainConfig
from coastforge.errors import ConfigError, InputError
from coastforge.frames import yaw_from_direction_px
from coastforge.fsio import write_png
from coastforge.io import read_image
from coastforge.pipeline import generate_tiled, tiling
from coastforge.types import ClassMap, Detection, GeoImage, Grid

TILE, OVERLAP = 256, 64
BOATS = [  # (cx, cy, length, width, yaw): several straddle the tile borders at 256 and 512
    (256, 400, 42, 14, 30.0), (420, 256, 50, 16, -60.0), (512, 470, 36, 12, 90.0), (380, 540, 40, 14, 0.0),
    (470, 120, 44, 15, 120.0), (512, 256, 30, 12, 45.0),
]
WALKWAY = ((330, 580), (560, 330), 10)  # a pier walkway longer than the overlap, crossing two tile borders


def _scene_rgb(h=600, w=600, seed=1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    yy, xx = np.mgrid[0:h, 0:w]
    water = (xx + 0.3 * yy) > 0.45 * w
    img[water] = (28, 78, 120)
    img[~water] = (95, 95, 92)
    img[(~water) & (yy < h * 0.4)] = (80, 130, 60)
    img += rng.normal(0, 3, img.shape)
    img = np.clip(img, 0, 255).astype(np.uint8)
    for cx, cy, L, W, yaw in BOATS:
        box = cv2.boxPoints(((cx, cy), (L, W), -yaw))
        cv2.fillPoly(img, [np.round(box).astype(np.int32)], (235, 235, 230))
    (a, b, width) = WALKWAY
    cv2.line(img, a, b, (170, 120, 60), width)
    return img


@pytest.fixture(scope="module")
def scene_png(tmp_path_factory):
    p = tmp_path_factory.mktemp("tiling") / "scene.png"
    write_png(p, _scene_rgb())
    return p


# ------------------------------------------------------------------------ local stand-ins for backends

def local_segmenter(image: GeoImage, seed: int) -> ClassMap:
    """A pixel-local segmenter (colour rule + 9 x 9 majority): tiling must reproduce it exactly."""
    rgb = image.rgb.astype(np.int16)
    water = (rgb[..., 2] > rgb[..., 0] + 30).astype(np.float32)
    grass = (rgb[..., 1] > rgb[..., 0] + 25).astype(np.float32)
    water, grass = cv2.blur(water, (9, 9)), cv2.blur(grass, (9, 9))
    ids = np.full(rgb.shape[:2], ASPHALT, np.uint8)
    ids[grass > 0.5] = GRASS
    ids[water > 0.5] = WATER
    return ClassMap(ids, image.grid)


def _blob_detections(mask: np.ndarray, category: str, min_px: int = 30) -> list[Detection]:
    n, lbl, st, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    out = []
    for k in range(1, n):
        if st[k, cv2.CC_STAT_AREA] < min_px:
            continue
        ys, xs = np.nonzero(lbl == k)
        (cx, cy), (w, h), _a = cv2.minAreaRect(np.stack([xs, ys], 1).astype(np.float32))
        pts = cv2.boxPoints(((cx, cy), (w, h), _a))
        e1, e2 = pts[1] - pts[0], pts[2] - pts[1]
        long_e = e1 if np.hypot(*e1) >= np.hypot(*e2) else e2
        yaw = float(yaw_from_direction_px(long_e[0], long_e[1]))
        out.append(Detection(category, 0.9, float(cx) + 0.5, float(cy) + 0.5, float(max(w, h)) + 1,
                             float(min(w, h)) + 1, yaw))
    return out


def local_detector(image: GeoImage, class_map, seed: int) -> list[Detection]:
    """White blobs are boats, brown ones pier walkways: a detector with no context beyond the object."""
    rgb = image.rgb.astype(np.int16)
    white = (rgb.min(axis=2) > 200)
    brown = (rgb[..., 0] > 140) & (rgb[..., 2] < 90) & (rgb[..., 1] > 90)
    return _blob_detections(white, "boat") + _blob_detections(brown, "pier_walkway")


# ------------------------------------------------------------------------------------------- windows

def test_windows_partition_the_image():
    tiles = list(tiling.iter_windows(600, 530, TILE, OVERLAP))
    assert len(tiles) == 9
    cover = np.zeros((530, 600), np.int32)
    for t in tiles:
        cover[t.core_global()] += 1
        c0, r0, c1, r1 = t.core
        # the window holds the core plus the overlap (clipped at the border), and is never smaller than others
        assert t.col_off <= max(0, c0 - OVERLAP) and t.row_off <= max(0, r0 - OVERLAP)
        assert t.col_off + t.width >= min(600, c1 + OVERLAP) and t.row_off + t.height >= min(530, r1 + OVERLAP)
        assert 0 <= t.col_off and t.col_off + t.width <= 600 and t.row_off + t.height <= 530
        assert t.width == TILE + 2 * OVERLAP and t.height == TILE + 2 * OVERLAP
        rs, cs = t.core_local()
        assert rs.stop - rs.start == r1 - r0 and cs.stop - cs.start == c1 - c0
    assert (cover == 1).all()
    with pytest.raises(ConfigError, match="tile_px"):
        list(tiling.iter_windows(100, 100, 8, 0))
    with pytest.raises(ConfigError, match="overlap_px"):
        list(tiling.iter_windows(100, 100, 64, -1))


def test_read_window_16bit_geotiff_matches_whole_read(tmp_path):
    import rasterio
    from affine import Affine

    rng = np.random.default_rng(0)
    data = (rng.random((3, 300, 340)) * 4000 + 300).astype(np.uint16)
    data[:, :5, :5] = 60000  # outliers the robust stretch must ignore
    p = tmp_path / "ortho.tif"
    t = Affine(0.25, 0.0, 500000.0, 0.0, -0.25, 4100000.0)
    with rasterio.open(p, "w", driver="GTiff", width=340, height=300, count=3, dtype="uint16",
                       crs="EPSG:32633", transform=t) as dst:
        dst.write(data)
    whole = read_image(p)
    src = tiling.open_source(p)
    assert src.grid == whole.grid and src.stretch is not None
    for tile in tiling.iter_windows(340, 300, 128, 16):
        img = tiling.read_window(src, tile)
        sl = (slice(tile.row_off, tile.row_off + tile.height), slice(tile.col_off, tile.col_off + tile.width))
        assert np.array_equal(img.rgb, whole.rgb[sl])  # the same stretch in every tile
        a, _b, c, _d, e, f = img.grid.transform
        assert c == pytest.approx(500000.0 + 0.25 * tile.col_off) and f == pytest.approx(4100000.0 - 0.25 * tile.row_off)
        assert (img.grid.width_px, img.grid.height_px) == (tile.width, tile.height) and a == 0.25 and e == -0.25


def test_open_source_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        tiling.open_source(tmp_path / "missing.tif", gsd_m=0.2)
    gray = tmp_path / "gray.png"
    write_png(gray, np.zeros((40, 40), np.uint8))
    with pytest.raises(InputError, match="band"):
        tiling.open_source(gray, gsd_m=0.2)
    rgb = tmp_path / "rgb.png"
    write_png(rgb, np.zeros((40, 40, 3), np.uint8))
    with pytest.raises(InputError, match="--gsd"):
        tiling.open_source(rgb)


# -------------------------------------------------------------------------------------- segmentation

def test_segment_tiled_equals_untiled_for_a_local_segmenter(scene_png, tmp_path):
    img = read_image(scene_png, gsd_m=0.2)
    full = local_segmenter(img, 0).ids
    src = tiling.open_source(scene_png, gsd_m=0.2)
    ids = tiling.segment_tiled(src, tile_px=TILE, overlap_px=OVERLAP, segmenter=local_segmenter)
    assert ids.dtype == np.uint8 and ids.shape == full.shape
    assert np.array_equal(ids, full)  # the 9 x 9 context is far inside the 64 px overlap
    mm = tiling.segment_tiled(src, tile_px=TILE, overlap_px=OVERLAP, segmenter=local_segmenter,
                              out=tmp_path / "ids.npy")
    assert np.array_equal(np.load(tmp_path / "ids.npy"), full) and np.array_equal(mm, full)
    # with no overlap the seams show: the test above can fail
    ids0 = tiling.segment_tiled(src, tile_px=TILE, overlap_px=0, segmenter=local_segmenter)
    assert not np.array_equal(ids0, full)


def test_segment_tiled_classical_agrees_away_from_seams(scene_png):
    from coastforge.segmentation import segment

    cfg = Config(segment=SegmentConfig(backend="classical"))
    img = read_image(scene_png, gsd_m=0.2)
    full = segment(img, cfg.segment, seed=0).ids
    ids = tiling.segment_tiled(scene_png, Grid(600, 600, 0.2), cfg.segment, TILE, OVERLAP, seed=0)
    away = np.ones(full.shape, bool)
    for s in (TILE, 2 * TILE):
        away[:, s - 24:s + 24] = False
        away[s - 24:s + 24, :] = False
    # the classical segmenter trains a per-image classifier and looks ~100 m around: tiles may differ a little
    water_full, water_tiled = full == WATER, ids == WATER
    assert (water_full[away] == water_tiled[away]).mean() > 0.98
    assert (full[away] == ids[away]).mean() > 0.97


# ----------------------------------------------------------------------------------------- detection

def _same(a: Detection, b: Detection, tol: float = 1.5) -> bool:
    return a.category == b.category and np.hypot(a.cx_px - b.cx_px, a.cy_px - b.cy_px) <= tol


def test_detect_tiled_merges_boxes_across_borders(scene_png):
    img = read_image(scene_png, gsd_m=0.2)
    full = local_detector(img, None, 0)
    assert sum(d.category == "boat" for d in full) == len(BOATS)
    src = tiling.open_source(scene_png, gsd_m=0.2)
    tiled = tiling.detect_tiled(src, tile_px=TILE, overlap_px=OVERLAP, detector=local_detector)
    boats = [d for d in tiled if d.category == "boat"]
    assert len(boats) == len(BOATS)  # no duplicates, no fragments of boats cut by a tile edge
    for d in [d for d in full if d.category == "boat"]:
        m = [b for b in boats if _same(d, b)]
        assert len(m) == 1
        assert m[0].length_px == pytest.approx(d.length_px, abs=0.5)
    # the walkway (longer than the overlap) is cut in every tile, and is joined back into one box
    walks = [d for d in tiled if d.category == "pier_walkway"]
    ref = [d for d in full if d.category == "pier_walkway"]
    assert len(walks) == 1 and len(ref) == 1
    assert walks[0].length_px == pytest.approx(ref[0].length_px, rel=0.05)
    assert np.hypot(walks[0].cx_px - ref[0].cx_px, walks[0].cy_px - ref[0].cy_px) < 4


def test_detect_tiled_without_merge_would_duplicate(scene_png):
    """The merge is what removes the pieces: the raw per-tile lists hold more boats than the image."""
    src = tiling.open_source(scene_png, gsd_m=0.2)
    raw = 0
    for t in tiling.iter_windows(600, 600, TILE, OVERLAP):
        raw += sum(d.category == "boat" for d in local_detector(tiling.read_window(src, t), None, 0))
    assert raw > len(BOATS)


def test_merge_cut_fragments_joins_collinear_pieces_only():
    a = Detection("pier_walkway", 0.8, 100.0, 50.0, 80.0, 6.0, 0.0)
    b = Detection("pier_walkway", 0.7, 170.0, 50.5, 70.0, 6.0, 180.0)  # overlaps a along the same axis
    c = Detection("pier_walkway", 0.7, 100.0, 80.0, 80.0, 6.0, 0.0)  # parallel, 30 px aside
    d = Detection("pier_walkway", 0.7, 150.0, 50.0, 40.0, 6.0, 90.0)  # crossing
    out = tiling.merge_cut_fragments([a, b, c, d])
    assert len(out) == 3
    joined = max(out, key=lambda x: x.length_px)
    assert joined.length_px == pytest.approx(145.0, abs=0.01)  # from x = 60 to x = 205
    assert joined.cx_px == pytest.approx(132.5, abs=0.01)


def _random_boxes(n, size, seed, cats=("boat", "vehicle")):
    rng = np.random.default_rng(seed)
    return [Detection(str(rng.choice(cats)), float(rng.random()), float(rng.random() * size),
                      float(rng.random() * size), float(rng.uniform(10, 60)), float(rng.uniform(4, 15)),
                      float(rng.uniform(-180, 180))) for _ in range(n)]


def test_indexed_nms_equals_rotated_nms():
    from coastforge.detection.nms import rotated_nms

    dets = _random_boxes(600, 900, seed=3)  # dense: many overlaps, both categories
    ref = rotated_nms(dets, 0.3, class_aware=True, ioa_threshold=0.6)
    got = tiling.indexed_nms(dets, 0.3, ioa_threshold=0.6, cell_px=64.0)  # boxes span several cells
    assert [id(d) for d in got] == [id(d) for d in ref]
    assert 0 < len(got) < len(dets)
    assert tiling.indexed_nms([]) == []


def test_grouped_fragment_merge_equals_the_global_merge():
    rng = np.random.default_rng(5)
    pieces = []
    for _k in range(25):  # broken walkways (three pieces each, slightly overlapping) and lone fingers
        x0, y0 = rng.random(2) * 3000
        yaw = float(rng.choice([0.0, 90.0, 37.0]))
        ux, uy = np.cos(np.radians(yaw)), -np.sin(np.radians(yaw))
        for m in range(3):
            pieces.append(Detection("pier_walkway", float(rng.random()), float(x0 + ux * m * 28.5),
                                    float(y0 + uy * m * 28.5), 30.0, 8.0, yaw))
        pieces.append(Detection("pier_finger", 0.5, float(x0 + 10), float(y0 + 10), 20.0, 3.0, yaw + 90.0))
    rng.shuffle(pieces)
    grouped = tiling.merge_cut_fragments(pieces)
    ref = tiling._merge_fragment_group(list(pieces), 6.0)  # the all-pairs loop over everything at once

    def key(d):
        return (d.category, round(d.cx_px, 3), round(d.cy_px, 3), round(d.length_px, 3), round(d.width_px, 3))

    assert sorted(map(key, grouped)) == sorted(map(key, ref))
    assert len(grouped) < len(pieces)


def test_detect_tiled_classical_finds_the_same_boats(scene_png):
    from coastforge.detection import detect

    cfg = Config(detect=DetectConfig(backend="classical"))
    img = read_image(scene_png, gsd_m=0.2)
    water = (local_segmenter(img, 0).ids == WATER)
    ids = np.where(water, WATER, ASPHALT).astype(np.uint8)
    full = [d for d in detect(img, cfg.detect, class_map=ClassMap(ids, img.grid), seed=0) if d.category == "boat"]
    tiled = [d for d in tiling.detect_tiled(scene_png, Grid(600, 600, 0.2), cfg.detect, ids, TILE, 96, seed=0)
             if d.category == "boat"]
    found = [d for d in full if any(_same(d, t, 3.0) for t in tiled)]
    assert len(full) >= 4 and len(found) == len(full)
    for i, a in enumerate(tiled):  # no duplicates
        assert not any(_same(a, b, 0.5 * a.length_px) for b in tiled[i + 1:])


# ------------------------------------------------------------------------------------------- terrain

def test_terrain_tiled_matches_untiled_with_enough_overlap():
    from coastforge.terrain import estimate_terrain

    h = w = 400
    yy, xx = np.mgrid[0:h, 0:w]
    ids = np.where(xx + 0.5 * yy > 260, WATER, GRASS).astype(np.uint8)
    grid = Grid(w, h, 0.5)
    cfg = TerrainConfig(noise_m=0.0, depth_scale_m=10.0, land_rise_scale_m=10.0)
    full = estimate_terrain(ClassMap(ids, grid), cfg, seed=0).height.z_m
    assert tiling.terrain_overlap_px(cfg, 0.5) == 60
    z = tiling.terrain_tiled(ids, grid, cfg, tile_px=128, seed=0)
    assert np.abs(z - full).max() < 0.05 * cfg.max_depth_m
    assert np.array_equal(z < 0, full < 0)
    z0 = tiling.terrain_tiled(ids, grid, cfg, tile_px=128, seed=0, overlap_px=0)
    assert np.abs(z0 - full).max() > np.abs(z - full).max()


def test_downsample_classes_majority():
    ids = np.zeros((40, 60), np.uint8)
    ids[:, 30:] = GRASS
    ids[0:4, 0:3] = ASPHALT  # exactly the first 4 x 3 block
    ids[0, 3] = ASPHALT  # one pixel of the next block: a minority there
    out = tiling.downsample_classes(ids, 20, 10, band_rows=8)
    assert out.shape == (10, 20)
    assert (out[:, 10:] == GRASS).all() and out[0, 0] == ASPHALT and (out[1:, :10] == WATER).all()


# -------------------------------------------------------------------------------------------- piers

def test_piers_tiled_matches_build_piers():
    from types import SimpleNamespace

    from coastforge.config import PierConfig
    from coastforge.pier_chains import build_piers

    walk = SimpleNamespace(id="walk", category="pier", dims_m=(4.0, 2.0, 0.5), floating=False, tags=())
    finger = SimpleNamespace(id="finger", category="pier", dims_m=(3.0, 1.0, 0.4), floating=False, tags=())
    h = w = 500
    ids = np.full((h, w), WATER, np.uint8)
    ids[:, :60] = ASPHALT  # the quay along the west edge
    grid = Grid(w, h, 0.5)
    dets = []
    for row in (120.0, 380.0):  # two walkways from the quay across the region border at col 256
        dets.append(Detection("pier_walkway", 0.9, 60 + 180.0, row, 360.0, 5.0, 0.0))
        for col in range(100, 420, 40):  # fingers on both sides
            dets.append(Detection("pier_finger", 0.8, float(col), row - 16.0, 24.0, 3.0, 90.0))
            dets.append(Detection("pier_finger", 0.8, float(col), row + 16.0, 24.0, 3.0, 90.0))
    cfg = PierConfig()
    full = build_piers(dets, ClassMap(ids, grid), walk, finger, cfg)
    objs, rep = tiling.piers_tiled(dets, ClassMap(ids, grid), walk, finger, cfg, tile_px=256, margin_m=40.0)
    assert rep["tiles"] == 4 and rep["n_segments"] == len(objs)
    assert len({o.id for o in objs}) == len(objs)  # ids stay unique across regions
    a = np.array([[o.x_m, o.y_m] for o in full.objects])
    b = np.array([[o.x_m, o.y_m] for o in objs])
    d = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1))
    assert abs(len(objs) - len(full.objects)) <= 2
    assert (d.min(1) < 0.5).mean() > 0.95 and (d.min(0) < 0.5).mean() > 0.95


def test_detection_windows_overlap_by_half_the_longest_boat(scene_png, tmp_path):
    """Detection reads its windows with its own overlap (an object is whole in the tile owning its centre),
    not the segmentation's context."""
    from coastforge.pipeline import GenerateRequest
    from coastforge.pipeline.tiled import TiledImage

    req = GenerateRequest(image=str(scene_png), out=str(tmp_path / "t"), gsd_m=0.2, report=False)
    cfg = Config()
    want = int(np.ceil(cfg.detect.max_boat_length_m / 2 / 0.2)) + 8
    for overlap in (OVERLAP, 256):
        front = TiledImage.open(req, cfg, tile_px=320, overlap_px=overlap, scene_max_px=300)
        assert front.overlap_px == overlap and front.detect_overlap_px == want


def test_generate_tiled_writes_the_scene_contract(scene_png, tmp_path):
    """The whole tiled generate on a 600 px image in 2 x 2 tiles with a 300 px scene grid: the scene rasters
    are on the coarse grid, detections stay in input pixels, side rasters and the World-Partition tiles
    (through the export registry) are written."""
    import json

    from coastforge.fsio import read_png
    from coastforge.pipeline import GenerateRequest
    from coastforge.scene import load_scene

    out = tmp_path / "tiled"
    req = GenerateRequest(image=str(scene_png), out=str(out), gsd_m=0.2, report=False, exports=("ue5_tiles",))
    res = generate_tiled(req, Config(), tile_px=320, overlap_px=OVERLAP, scene_max_px=300)
    scene = load_scene(res.scene_path)
    assert scene.height.shape == scene.classes.shape == (300, 300)
    assert scene.extent_m == pytest.approx((120.0, 120.0)) and scene.gsd_m == pytest.approx(0.2)
    prov = json.loads(res.scene_path.read_text())["provenance"]
    assert prov["tiled"]["scene_grid_px"] == [300, 300] and prov["input"]["size_px"] == [600, 600]
    assert {"cleaned", "segmentation", "terrain_outputs", "pcg", "scene_rasters"} <= set(prov["background_s"])
    for rel in ("cleaned.png", "segmentation/classes.png", "segmentation/weights/water.png", "segmentation/biome.png",
                "terrain_outputs/hillshade.png", "terrain/height.tif", "vegetation.csv", "detections.json"):
        assert (out / rel).is_file(), rel
    assert read_png(out / "cleaned.png").shape == (300, 300, 3)
    dets = json.loads((out / "detections.json").read_text())
    dets = dets.get("detections", dets) if isinstance(dets, dict) else dets
    assert dets and max(d["cx_px"] for d in dets) > 300  # full-resolution input pixels, not scene-grid ones
    spec = json.loads((out / "ue5_tiles" / "landscape_tiles.json").read_text())
    assert spec["tile_list"] and res.exports["ue5_tiles"]
    assert sum(v for k, v in res.n_objects.items() if k != "vegetation") > 0


def test_generate_tiled_reconciles_and_self_checks_like_a_whole_image_run(scene_png, tmp_path, monkeypatch):
    """A tiled run whose segmenter missed a marina's water (all asphalt) gets it back from the moored boats,
    on the whole scene grid, and the self-check runs: as in a whole-image run (issue #26)."""
    import json

    from coastforge.pipeline import GenerateRequest

    monkeypatch.setattr("coastforge.pipeline.tiled.segment_tiled", lambda src, **kw: np.full(
        (src.grid.height_px, src.grid.width_px), ASPHALT, np.uint8))
    rows = [Detection("boat", 0.9, 300.0 + 14.0 * k, 300.0 + 40.0 * r, 30.0, 10.0, 90.0)
            for k in range(6) for r in range(2)]  # two bow-in rows of six 6 m boats (0.2 m/px)
    monkeypatch.setattr("coastforge.pipeline.tiled.detect_tiled", lambda src, **kw: list(rows))
    req = GenerateRequest(image=str(scene_png), out=str(tmp_path / "tiled"), gsd_m=0.2, report=False)
    res = generate_tiled(req, Config(), tile_px=320, overlap_px=OVERLAP, scene_max_px=300)
    prov = json.loads(res.scene_path.read_text())["provenance"]
    assert prov["consistency"]["boat_clusters_made_water"] == 1 and prov["consistency"]["water_from_boats_m2"] > 100
    from coastforge.scene import load_scene

    ids = load_scene(res.scene_path).classes
    assert ids[155:165, 160:175].tolist() == np.full((10, 15), WATER).tolist()  # the cluster, on the 300 px grid
    assert any(w["code"] for w in prov["warnings"])  # the self-check ran (a nearly single-class scene)
    assert res.warnings and res.warnings[0].message


def test_tiled_and_whole_image_runs_share_one_stage_order(scene_png, tmp_path):
    """The whole-image run and the tiled run are one chain (pipeline.run_chain): the same stages in the same
    order, the same background jobs, the same provenance entries (the tiled run adds how it tiled)."""
    import json

    from coastforge.pipeline import GenerateRequest, run_generate

    started: dict[str, list[str]] = {"whole": [], "tiled": []}

    def record(key):
        return lambda stage, frac: started[key].append(stage) if frac == 0.0 else None

    req = GenerateRequest(image=str(scene_png), out=str(tmp_path / "whole"), gsd_m=0.2, report=False)
    whole = run_generate(req, Config(), record("whole"))
    tiled = generate_tiled(GenerateRequest(image=str(scene_png), out=str(tmp_path / "tiled"), gsd_m=0.2,
                                                  report=False), Config(), record("tiled"),
                                  tile_px=320, overlap_px=OVERLAP, scene_max_px=300)
    assert started["whole"] == started["tiled"]
    assert started["whole"][:4] == ["read", "segment", "detect", "clean"]
    assert started["whole"].index("piers") < started["whole"].index("vegetation") < started["whole"].index("match")
    pw, pt = (json.loads(r.scene_path.read_text())["provenance"] for r in (whole, tiled))
    assert set(pw["background_s"]) == set(pt["background_s"])
    assert set(pt) - set(pw) == {"tiled"} and set(pw) <= set(pt)


def test_detect_tiled_leaves_out_objects_cut_by_the_image_edge_not_by_a_tile_edge(scene_png):
    """Each tile reports a boat half past its left edge: on the image's left edge that boat is mostly outside
    the picture and goes (``detect.min_inside``); on a tile edge inside the image it is kept."""
    def half_out(image: GeoImage, class_map, seed: int) -> list[Detection]:
        return [Detection("boat", 0.9, 1.0, image.grid.height_px / 2, 40.0, 10.0, 0.0)]

    src = tiling.open_source(scene_png, gsd_m=0.2)
    tiled = tiling.detect_tiled(src, tile_px=TILE, overlap_px=OVERLAP, detector=half_out)
    offsets = sorted({t.col_off for t in tiling.iter_windows(600, 600, TILE, OVERLAP)})
    assert len(offsets) > 1
    assert not [d for d in tiled if d.cx_px < 20]
    assert {round(d.cx_px) for d in tiled} == {o + 1 for o in offsets[1:]}
    kept = tiling.detect_tiled(src, tile_px=TILE, overlap_px=OVERLAP, detector=half_out,
                               config=DetectConfig(min_inside=0.0))
    assert [d for d in kept if d.cx_px < 20]
