"""Asset-library benchmarks: retrieval accuracy, build time, query time.

    python -m coastforge.bench.library                       # starter-kit library, all benchmarks
    python -m coastforge.bench.library --models MANIFEST     # a library built from a manifest (e.g. Quaternius)
    python -m coastforge.bench.library --library LIB --skip-build

Retrieval queries are renders of library assets at a random yaw, a random lighting (sun, water colour,
haze), a random background (water or ground) and a random GSD in 0.05-0.3 m, cropped like the matcher
crops detections (1.5 x the object's size), 12 per asset and seed over seeds 0-9 (one seed's figure moves by
about a percent from seed to seed); results are also split by the object's length in pixels, and a
category confusion matrix (query category x top-1 category) is reported. Crops of the labelled ships and
vehicles of the real photos in ../shared/data are scored by category only (no asset is known for a real
object). When ``coastforge.synth`` is available: crops of the objects of synthetic benchmark scenes (embedding
top-1; cars and boats there stand in rows and berths with their neighbours in the crop, in random paint),
and the matcher itself (embedding + shape fit + size,
``coastforge.matching``) on the scenes' truth boxes, per category and GSD. Build time: a 159-asset library
(models repeated with slightly different real sizes, so every one is rendered) x 6 views (plus the query-like
views of its small assets, see ``LibraryConfig.query_view_gsds_m``, and the crowded views of its cars and
boats, ``LibraryConfig.crowded_views``), rendered, embedded and indexed.

Searches without a category weigh the embedding's category vote by the category head
(``coastforge.assets.category_net``, ``Library.CATEGORY_PRIOR_BETA``). The head was trained on renders of the
starter kit at seeds 100 and up (``coastforge.train.category_data``): these queries (seeds 0-9, synthetic
seeds 0-2) are new views of the same assets, not new assets; the real crops are neither.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from collections.abc import Sequence

from ..rng import stage_rng
from .segmentation import SHARED as SHARED_DATA  # ../shared/data beside the project

MATCHED = ("boat", "vehicle", "buoy")  # the categories the matcher assigns assets to
MAX_QUERY_PX = 1024  # rendered queries are at most this many pixels across (the kit's largest: 544)


def render_queries(lib, per_asset: int, seed: int, gsd_range=(0.05, 0.3)):
    """(crop, gsd, asset_id, category) tuples rendered from the library's own meshes."""
    from ..render import random_lighting, render_mesh_view

    out = []
    for a in lib.assets:
        if a.mesh_path is None:
            continue
        mesh = lib.mesh(a.id)
        rng = stage_rng(seed, "bench-library", a.id)
        for _q in range(per_asset):
            gsd = float(math.exp(rng.uniform(math.log(gsd_range[0]), math.log(gsd_range[1]))))
            yaw = float(rng.uniform(-180, 180))
            bg = str(rng.choice(["water", "ground"]))
            light = random_lighting(rng)
            side = max(a.dims_m[0], a.dims_m[1]) * 1.5
            # a huge object at a fine GSD (a 250 m cruise ship at 0.05 m/px: 7,500 px, 14 GB to render) is
            # seen coarser, as the matcher resamples a detection's crop (to 256 px) and the embedder (to 128)
            gsd = max(gsd, side / (MAX_QUERY_PX - 4))
            size = int(max(12, math.ceil(side / gsd) + 4))
            img = render_mesh_view(mesh, gsd, size, light, bg, yaw_deg=yaw, seed=int(rng.integers(1 << 30)))
            out.append((img, gsd, a.id, a.category))
    return out


def synth_levels(seed: int, presets=("marina", "pier_parking"), gsds=(0.1, 0.2), size_m: float = 100.0):
    """Rendered synthetic benchmark levels as (rgb, gsd, scene objects) per preset and GSD; empty (with the
    reason) when ``coastforge.synth`` is unavailable."""
    try:
        from ..synth import synthesize_level
        from ..synth.render import mesh_source, render_level
    except ImportError as exc:
        return [], f"coastforge.synth is not available ({exc})"
    out = []
    meshes = mesh_source(None)
    for i, preset in enumerate(presets):
        level = synthesize_level(preset, seed + i, size_m=size_m)
        for g in gsds:
            rgb = render_level(level, meshes, g, seed + i)
            out.append((rgb, level.scene.extent_m[0] / rgb.shape[1], level.scene.objects))
    return out, ""


def synth_queries(lib, levels):
    """Crops of the boats, vehicles and buoys of rendered synthetic levels, cut like the matcher cuts
    detections (axis-aligned here: the embedder is rotation-invariant); only objects whose asset is in ``lib``."""
    from ..matching import crop_rotated

    out = []
    for rgb, gsd, objects in levels:
        h, w = rgb.shape[:2]
        for o in objects:
            if o.category == "pier" or o.asset_id not in lib:
                continue
            col = o.x_m / gsd + w / 2.0
            row = h / 2.0 - o.y_m / gsd
            side = int(math.ceil(max(o.length_m, o.width_m) * 1.5 / gsd)) + 4
            crop = crop_rotated(rgb, col, row, 0.0, side, side, 1.0)
            out.append((crop, gsd, o.asset_id, lib.asset(o.asset_id).category))
    return out


# the real DOTA crops of ../shared/data: folder, its (estimated) GSD, DOTA class -> our category
REAL_SETS = (("marina_p0861", 0.2, {"ship": "boat"}),
             ("vehicles_p1053", 0.125, {"small vehicle": "vehicle", "large vehicle": "vehicle"}))


def real_queries(data: Path = SHARED_DATA) -> tuple[list, str]:
    """Crops of the labelled ships and vehicles of the real aerial photos in ``data`` (DOTA oriented boxes),
    cut like the synthetic crops (axis-aligned, 1.5 x the object's longer side): (crop, gsd, None, category).
    No asset is known for a real object, so only the category is scored. Empty (with the reason) when the
    data is absent."""
    from ..io import read_image
    from ..matching import crop_rotated
    from .detection import read_dota_yolo

    out, missing = [], []
    for name, gsd, wanted in REAL_SETS:
        folder = Path(data) / "aerial" / name
        if not (folder / "image.jpg").is_file() or not (folder / "labels_yolo_obb.txt").is_file():
            missing.append(name)
            continue
        img = read_image(folder / "image.jpg", gsd_m=gsd)
        rgb = img.rgb
        for cls, t in read_dota_yolo(folder / "labels_yolo_obb.txt", img.grid.width_px, img.grid.height_px):
            if cls in wanted:
                side = int(math.ceil(max(t.length, t.width) * 1.5)) + 4
                out.append((crop_rotated(rgb, t.cx, t.cy, 0.0, side, side, 1.0), gsd, None, wanted[cls]))
    why = f"{', '.join(missing)} not found under {Path(data) / 'aerial'}" if missing else ""
    return out, why


def real_category(lib, queries) -> dict:
    """Top-1 category of real crops searched without a category (what ``library query`` prints first)."""
    vecs = lib.embed([q[0] for q in queries], [q[1] for q in queries])
    hits = lib.search(vecs, k=1, prior=lib.category_prior([q[0] for q in queries], [q[1] for q in queries]))
    matrix: dict = defaultdict(lambda: defaultdict(int))
    for q, h in zip(queries, hits):
        matrix[q[3]][lib.asset(h[0][0]).category if h else "none"] += 1
    per = {c: {"n": sum(row.values()), "category": round(row.get(c, 0) / sum(row.values()), 3)}
           for c, row in sorted(matrix.items())}
    ok = sum(matrix[c].get(c, 0) for c in matrix)
    confusion = {c: dict(sorted(row.items())) for c, row in sorted(matrix.items())}
    return {"queries": len(queries), "top1_category": round(ok / len(queries), 4), "per_category": per,
            "category_confusion": confusion,
            "note": "DOTA crops: marina ~0.2 m/px, car park ~0.125 m/px (GSDs estimated); no asset truth"}


def synth_matching(lib, levels, match_config=None) -> dict:
    """What ``generate`` does with perfect boxes: the matcher (embedding + shape fit + size) on the truth
    boxes (centre, yaw, length, width) of the levels' boats, vehicles and buoys; top-1 asset accuracy and
    how often the final heading is flipped, per category and GSD."""
    from ..config import MatchConfig
    from ..matching import match_detections
    from ..types import Detection, GeoImage, Grid

    cfg = match_config or MatchConfig()
    stats: dict = defaultdict(lambda: [0, 0, 0])
    t_total, n_total = 0.0, 0
    for rgb, gsd, objects in levels:
        h, w = rgb.shape[:2]
        objs = [o for o in objects if o.category in MATCHED]
        dets = [Detection(o.category, 1.0, o.x_m / gsd + w / 2.0 - 0.5, h / 2.0 - o.y_m / gsd - 0.5, o.length_m / gsd,
                          o.width_m / gsd, o.yaw_deg, True, 1.0) for o in objs]
        t0 = time.perf_counter()
        decisions = match_detections(GeoImage(rgb, Grid(w, h, gsd)), dets, lib, cfg, seed=0)
        t_total += time.perf_counter() - t0
        n_total += len(dets)
        for dec in decisions:
            o = objs[dec.index]
            key = f"{o.category}@{gsd:.2f}"
            stats[key][0] += 1
            stats[key][1] += dec.asset_id == o.asset_id
            stats[key][2] += abs((dec.yaw_deg - o.yaw_deg + 180.0) % 360.0 - 180.0) > 90.0 and o.category != "buoy"
    n = sum(v[0] for v in stats.values())
    return {"objects": n, "top1_asset": round(sum(v[1] for v in stats.values()) / max(1, n), 4),
            "per_category": {k: {"n": v[0], "asset": round(v[1] / v[0], 3), "heading_flipped": v[2]}
                             for k, v in sorted(stats.items())},
            "ms_per_object": round(1000 * t_total / max(1, n_total), 2),
            "note": "truth boxes; the embedding-only figure above ignores shape, paint and size priors"}


PX_BANDS = ("<3 px", "3-5 px", "5-8 px", "8-16 px", "16-32 px", ">=32 px")  # the object's length in pixels


def pixel_band(length_px: float) -> str:
    for b, hi in zip(PX_BANDS, (3, 5, 8, 16, 32)):
        if length_px < hi:
            return b
    return PX_BANDS[-1]


def retrieval(lib, queries, seeds: Sequence[int] | None = None) -> dict:
    """Top-1 asset and category accuracy of (crop, gsd, asset_id, category) queries, split by category,
    object length and (given ``seeds``, one per query) by seed."""
    if not queries:
        return {"queries": 0}
    t0 = time.perf_counter()
    vecs = lib.embed([q[0] for q in queries], [q[1] for q in queries])
    t_embed = time.perf_counter() - t0
    t0 = time.perf_counter()
    prior = lib.category_prior([q[0] for q in queries], [q[1] for q in queries])
    t_prior = time.perf_counter() - t0
    t0 = time.perf_counter()
    hits = lib.search(vecs, k=1, prior=prior)
    t_search = time.perf_counter() - t0
    per_cat = defaultdict(lambda: [0, 0, 0])
    per_seed = defaultdict(lambda: [0, 0, 0])
    confusions = defaultdict(int)
    ok_asset = ok_cat = 0
    for i, ((_img, _gsd, aid, cat), h) in enumerate(zip(queries, hits)):
        top = h[0][0] if h else None
        tcat = lib.asset(top).category if top else None
        ok_asset += top == aid
        ok_cat += tcat == cat
        for tally, key in ((per_cat, cat),) + (((per_seed, seeds[i]),) if seeds is not None else ()):
            tally[key][0] += 1
            tally[key][1] += top == aid
            tally[key][2] += tcat == cat
        if top != aid:
            confusions[f"{aid}->{top}"] += 1
    n = len(queries)
    # tiny objects (a 0.5 m grass tuft at 0.3 m/px is 2 px) carry little more than a colour: report apart
    by_px: dict = defaultdict(lambda: [0, 0, 0])
    by_px_cat: dict = defaultdict(lambda: defaultdict(lambda: [0, 0]))
    matrix: dict = defaultdict(lambda: defaultdict(int))
    for (_img, gsd, aid, cat), h in zip(queries, hits):
        top = h[0][0] if h else None
        tcat = lib.asset(top).category if top else "none"
        band = pixel_band(max(lib.asset(aid).dims_m[:2]) / gsd)
        by_px[band][0] += 1
        by_px[band][1] += top == aid
        by_px[band][2] += tcat == cat
        by_px_cat[cat][band][0] += 1
        by_px_cat[cat][band][1] += tcat == cat
        matrix[cat][tcat] += 1
    # what the matcher does: boats, vehicles and buoys, searched within the detected category
    matched = [i for i, q in enumerate(queries) if q[3] in MATCHED]
    within = 0
    for i in matched:
        h = lib.search(vecs[i:i + 1], k=1, category=queries[i][3])[0]
        within += bool(h) and h[0][0] == queries[i][2]
    m_asset = sum(1 for i in matched if hits[i] and hits[i][0][0] == queries[i][2])
    m_cat = sum(1 for i in matched if hits[i] and lib.asset(hits[i][0][0]).category == queries[i][3])
    return {
        "matched_categories": {"categories": list(MATCHED), "queries": len(matched),
                               "top1_asset": round(m_asset / max(1, len(matched)), 4),
                               "top1_category": round(m_cat / max(1, len(matched)), 4),
                               "top1_asset_within_category": round(within / max(1, len(matched)), 4)},
        "queries": n, "top1_asset": round(ok_asset / n, 4), "top1_category": round(ok_cat / n, 4),
        "per_category": {c: {"n": v[0], "asset": round(v[1] / v[0], 3), "category": round(v[2] / v[0], 3)}
                         for c, v in sorted(per_cat.items())},
        "by_object_pixels": {b: {"n": by_px[b][0], "asset": round(by_px[b][1] / by_px[b][0], 3),
                                 "category": round(by_px[b][2] / by_px[b][0], 3)} for b in PX_BANDS if b in by_px},
        # rows: the query's category, columns: the top-1's category (counts)
        "category_confusion": {c: dict(sorted(row.items())) for c, row in sorted(matrix.items())},
        # per category and length band: correct category / queries
        "category_by_pixels": {c: {b: f"{v[b][1]}/{v[b][0]}" for b in PX_BANDS if b in v}
                               for c, v in sorted(by_px_cat.items())},
        "per_seed": {str(k): {"queries": v[0], "top1_asset": round(v[1] / v[0], 4),
                              "top1_category": round(v[2] / v[0], 4)} for k, v in sorted(per_seed.items())},
        "ms_per_query": round(1000 * (t_embed + t_prior + t_search) / n, 3),
        "ms_embed_per_query": round(1000 * t_embed / n, 3),
        "ms_category_head_per_query": round(1000 * t_prior / n, 3),
        "category_head": prior is not None,
        "top_confusions": dict(sorted(confusions.items(), key=lambda t: -t[1])[:10]),
    }


def single_query_ms(lib, queries, n: int = 50) -> float:
    """Wall time of lib.query on one crop at a time (what the matcher pays per object)."""
    sel = queries[:n]
    t0 = time.perf_counter()
    for img, gsd, _aid, _cat in sel:
        lib.query(img, gsd, k=5)
    return round(1000 * (time.perf_counter() - t0) / max(1, len(sel)), 3)


def build_benchmark(manifest: Path | None, n_assets: int, workers: int | None, seed: int) -> dict:
    """Build a ``n_assets`` library by repeating the models of ``manifest`` (or the starter kit) with
    slightly different real sizes (so each is really rendered), 6 views each."""
    from ..assets.library import build_library, read_manifest

    if manifest is None:
        from ..assets.kit import MANIFEST_NAME, kit_dir

        manifest = kit_dir() / MANIFEST_NAME
    specs, _ = read_manifest(manifest)
    rng = stage_rng(seed, "bench-library-build")
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "src"
        src.mkdir()
        entries = []
        for i in range(n_assets):
            s = specs[i % len(specs)]
            link = src / f"{i:03d}_{s.mesh.name}"
            shutil.copyfile(s.mesh, link)  # a copy: manifests refuse links to files outside their folder
            e = {"id": f"{s.id}_{i:03d}", "category": s.category, "mesh": link.name,
                 "up_axis": s.up_axis, "forward_axis": s.forward_axis}
            jitter = float(rng.uniform(0.9, 1.1)) if i >= len(specs) else 1.0
            if s.length_m:
                e["length_m"] = round(s.length_m * jitter, 4)
            elif s.height_m:
                e["height_m"] = round(s.height_m * jitter, 4)
            entries.append({k: v for k, v in e.items() if v is not None})
        (src / "manifest.json").write_text(json.dumps({"assets": entries}))
        cpu0 = _cpu_seconds()
        t0 = time.perf_counter()
        lib = build_library(src / "manifest.json", Path(tmp) / "lib", workers=workers)
        seconds = time.perf_counter() - t0
        cpu = _cpu_seconds() - cpu0
        return {"assets": len(lib.assets), "views": sum(len(a.views) for a in lib.assets),
                "query_like_views": sum(len(r.get("query_views", [])) for r in lib.doc["assets"]),
                "rows": lib.index.rows,
                "seconds": round(seconds, 2), "cpu_seconds": round(cpu, 2),
                "cpu_seconds_per_core_of_2": round(cpu / 2, 2), "skipped": len(lib.build_report.skipped)}


def _cpu_seconds() -> float:
    """CPU time of this process and its finished children: a figure that contention does not inflate much."""
    import resource

    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.library", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--library", help="An existing library folder (default: build from --models or the kit).")
    ap.add_argument("--models", help="A manifest to build the benchmark library from (e.g. Quaternius).")
    ap.add_argument("--per-asset", type=int, default=12, help="Rendered queries per asset.")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(10)),
                    help="Seeds of the rendered queries (default 0-9: one seed's figure moves by about a "
                         "percent from seed to seed).")
    ap.add_argument("--synth-seeds", type=int, nargs="+", default=[0, 1, 2],
                    help="Seeds of the synthetic levels whose objects are cropped and matched (default 0-2).")
    ap.add_argument("--build-assets", type=int, default=159)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--skip-build", action="store_true", help="Skip the build-time benchmark.")
    ap.add_argument("--skip-synth", action="store_true", help="Skip the synthetic-scene crops.")
    ap.add_argument("--data", default=str(SHARED_DATA),
                    help="Folder with the real aerial photos (default ../shared/data); skipped when absent.")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from ..assets.library import Library, build_library, default_library

    report: dict = {"note": "timings on a shared 2-core machine (under contention)",
                    "load_average_at_start": [round(x, 2) for x in os.getloadavg()]}
    tmp = None
    t0 = time.perf_counter()
    if args.library:
        lib = Library.load(args.library)
    elif args.models:
        tmp = tempfile.mkdtemp(prefix="cf-bench-lib-")
        lib = build_library(args.models, Path(tmp) / "lib", workers=args.workers)
    else:
        lib = default_library()
    report["library"] = {"root": str(lib.root), "assets": len(lib.assets), "rows": lib.index.rows,
                         "load_or_build_s": round(time.perf_counter() - t0, 2),
                         "category_vote_t": getattr(lib, "CATEGORY_VOTE_T", None)}
    try:
        queries, seeds = [], []
        for s in args.seeds:
            qs = render_queries(lib, args.per_asset, s)
            queries += qs
            seeds += [s] * len(qs)
        report["rendered_queries"] = retrieval(lib, queries, seeds)
        report["rendered_queries"]["seeds"] = list(args.seeds)
        report["rendered_queries"]["ms_single_query"] = single_query_ms(lib, queries)
        if not args.skip_synth:
            levels, why = [], ""
            for s in args.synth_seeds:
                try:
                    more, why = synth_levels(s)
                except Exception as exc:  # noqa: BLE001 - another stage's code: report, do not lose the other figures
                    more, why = [], f"synthetic levels failed: {type(exc).__name__}: {exc}"
                levels += more
            sq = synth_queries(lib, levels) if levels else []
            report["synthetic_crops"] = retrieval(lib, sq) if sq else {"queries": 0, "why": why}
            if levels:
                report["synthetic_matcher_truth_boxes"] = synth_matching(lib, levels)
                report["synthetic_matcher_truth_boxes"]["seeds"] = list(args.synth_seeds)
        rq, why = real_queries(Path(args.data))
        report["real_crops"] = real_category(lib, rq) if rq else {"queries": 0, "skipped": why}
        if not args.skip_build:
            report["build"] = build_benchmark(Path(args.models) if args.models else None, args.build_assets,
                                              args.workers, args.seeds[0])
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    report["load_average_at_end"] = [round(x, 2) for x in os.getloadavg()]
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
