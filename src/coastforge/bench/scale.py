"""Scale benchmark: ``python -m coastforge.bench.scale``.

1. Image size: peak memory (the process tree's resident set, sampled with psutil, and the child's own
   ``ru_maxrss``) and wall time of ``pipeline.generate_tiled`` on synthetic GeoTIFF squares (1k, 4k, 8k,
   16k px by default). Each run is a fresh child process, so its peak is its own.
2. Cost per pixel: a tiled run (4096² in 2048 px tiles by default) against a whole-image run (2048²) of the
   same synthetic coast, per pixel: wall time and the CPU of the process tree, in total and per stage
   (DESIGN.md: the tiled path within 1.3x of the whole-image path).
3. Workers: a batch of 20 small synthetic scenes plus one corrupted input on a local Dask cluster
   (``coastforge.batch.run_batch``) with 1 and with 2 workers, then a re-run that must skip what is done.

Every generate runs as the CLI runs it: the default preset, with its side process.

The big images are mirrored tilings of one rendered synthetic level (``coastforge.synth``), written band by
band (never whole in memory), georeferenced in UTM. Timings on a shared machine vary: the load average
is printed beside them.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

DEFAULT_SIZES = (1024, 4096, 8192, 16384)
GSD_M = 0.2


def base_render(work: Path, size_m: float = 200.0, preset: str = "marina", seed: int = 7) -> np.ndarray:
    """One rendered synthetic level (RGB uint8), cached in ``work``."""
    cache = work / f"base_{preset}_{int(size_m)}_{seed}.npy"
    if cache.is_file():
        return np.load(cache)
    try:
        from ..synth import synthesize_level
        from ..synth.render import mesh_source, render_level

        level = synthesize_level(preset, seed, size_m=size_m, grid_m=GSD_M)
        rgb = render_level(level, mesh_source(None), GSD_M, seed)
    except ImportError:  # no synth module: a procedural coast with bright "boats"
        rgb = procedural_scene(int(size_m / GSD_M), seed)
    np.save(cache, rgb)
    return rgb


def procedural_scene(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:n, 0:n]
    water = xx + 0.3 * yy > 0.5 * n
    img = np.where(water[..., None], np.array([28, 78, 120]), np.array([95, 95, 92])).astype(np.float32)
    img += rng.normal(0, 3, img.shape)
    for _ in range(n // 40):
        cx, cy = rng.integers(0, n, 2)
        if water[cy, cx]:
            img[max(0, cy - 6):cy + 6, max(0, cx - 20):cx + 20] = 235
    return np.clip(img, 0, 255).astype(np.uint8)


def write_mirrored_geotiff(path: Path, base: np.ndarray, size_px: int, band_rows: int = 512) -> Path:
    """A size x size RGB GeoTIFF tiling ``base`` with alternate mirroring (seamless), written by row bands."""
    import rasterio
    from affine import Affine

    _bh, _bw = base.shape[:2]
    ext_x = np.concatenate([base, base[:, ::-1]], axis=1)  # one period along x: base + its mirror
    ext = np.concatenate([ext_x, ext_x[::-1]], axis=0)  # and along y
    ph, pw = ext.shape[:2]
    cols = np.arange(size_px) % pw
    profile = dict(driver="GTiff", width=size_px, height=size_px, count=3, dtype="uint8", crs="EPSG:32633",
                   transform=Affine(GSD_M, 0.0, 500000.0, 0.0, -GSD_M, 4100000.0), tiled=True, blockxsize=512,
                   blockysize=512, compress="deflate", predictor=2, BIGTIFF="IF_SAFER")
    tmp = path.with_suffix(".part.tif")
    with rasterio.open(tmp, "w", **profile) as dst:
        from rasterio.windows import Window

        for r0 in range(0, size_px, band_rows):
            r1 = min(size_px, r0 + band_rows)
            rows = np.arange(r0, r1) % ph
            band = ext[rows][:, cols]
            dst.write(np.moveaxis(band, -1, 0), window=Window(0, r0, size_px, r1 - r0))
    os.replace(tmp, path)
    return path


class TreePeak:
    """Peak resident memory of a process and its children, sampled in a thread, and the CPU seconds each
    process of the tree had used when last seen (``cpu_s``)."""

    def __init__(self, pid: int, every_s: float = 0.25):
        import psutil

        self.proc = psutil.Process(pid)
        self.every = every_s
        self.peak = 0
        self.cpu_s: dict[int, float] = {}
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        import psutil

        t0 = time.perf_counter()
        while not self._stop.is_set():
            try:
                procs = [self.proc] + self.proc.children(recursive=True)
                rss = 0
                for p in procs:
                    try:
                        rss += p.memory_info().rss
                        t = p.cpu_times()
                        self.cpu_s[p.pid] = t.user + t.system
                    except psutil.Error:
                        pass
                self.peak = max(self.peak, rss)
            except psutil.Error:
                break
            # listing the process tree costs CPU: sample often at first, then once a second (memory of a long
            # run grows slowly, and the monitor must not steal the cores it measures)
            self._stop.wait(self.every if time.perf_counter() - t0 < 30.0 else max(self.every, 1.0))

    def stop(self) -> int:
        self._stop.set()
        self._t.join()
        return self.peak


def _child(image: str, out: str, tile_px: int, overlap_px: int, scene_max_px: int, mode: str = "tiled") -> None:
    """Runs in the child process: one generate (``mode`` "tiled": ``generate_tiled`` with these tiles;
    "whole": ``run_generate``, which holds an image up to 4096² whole), figures as JSON on the last line of
    stdout."""
    import resource

    from ..config import load_config
    from ..pipeline import GenerateRequest, run_generate
    from ..pipeline import generate_tiled

    t0 = time.perf_counter()

    def progress(stage: str, frac: float) -> None:
        # one line per finished stage (and per tile of the tiled stages) on stderr: a run stopped early
        # still leaves its figures, and equal CPU per tile shows the tiled stages are linear in the area
        if 0.0 < frac < 1.0:
            ru = resource.getrusage(resource.RUSAGE_SELF)
            print(json.dumps({"tile": stage, "frac": round(frac, 4), "elapsed_s": round(time.perf_counter() - t0, 2),
                              "cpu_s": round(ru.ru_utime + ru.ru_stime, 2),
                              "maxrss_mb": round(ru.ru_maxrss / 1024.0, 1)}), file=sys.stderr, flush=True)
        if frac >= 1.0:
            ru = resource.getrusage(resource.RUSAGE_SELF)
            print(json.dumps({"stage": stage, "elapsed_s": round(time.perf_counter() - t0, 2),
                              "cpu_s": round(ru.ru_utime + ru.ru_stime, 2),
                              "maxrss_mb": round(ru.ru_maxrss / 1024.0, 1), "load": round(os.getloadavg()[0], 2)}),
                  file=sys.stderr, flush=True)

    # the configuration `coastforge generate` runs: the default preset (hybrid detector), a side process
    req = GenerateRequest(image=image, out=out, overwrite=True, report=False, side_process=True)
    config = load_config("default", None, [], None)
    if mode == "whole":
        r = run_generate(req, config, progress)
    else:
        r = generate_tiled(req, config, progress, tile_px=tile_px, overlap_px=overlap_px, scene_max_px=scene_max_px)
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_SELF)
    print(json.dumps({"wall_s": wall, "maxrss_mb": ru.ru_maxrss / 1024.0, "cpu_s": ru.ru_utime + ru.ru_stime,
                      "pid": os.getpid(), "timings_s": r.timings_s, "n_objects": r.n_objects}))


def _json_lines(text: str, key: str) -> list[dict]:
    """The child's JSON progress lines whose first key is ``key`` (``{"tile": ...}``, ``{"stage": ...}``)."""
    out = []
    for line in text.splitlines():
        if line.startswith(f'{{"{key}"'):
            with contextlib.suppress(json.JSONDecodeError):
                out.append(json.loads(line))
    return out


def run_size(work: Path, base: np.ndarray, size: int, tile_px: int, overlap_px: int, scene_max_px: int,
             timeout_s: float | None = None, mode: str = "tiled") -> dict:
    """One child run (``mode``: see ``_child``); on ``timeout_s`` it is stopped and the stages it finished
    are reported."""
    img = work / f"scale_{size}.tif"
    if not img.is_file():
        t0 = time.perf_counter()
        write_mirrored_geotiff(img, base, size)
        print(f"  wrote {img.name} in {time.perf_counter() - t0:.1f} s", flush=True)
    out = work / (f"out_{size}" if mode == "tiled" else f"out_{mode}_{size}")
    cmd = [sys.executable, "-m", "coastforge.bench.scale", "--child", str(img), str(out), str(tile_px),
           str(overlap_px), str(scene_max_px), mode]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    mon = TreePeak(p.pid)
    timed_out = False
    try:
        stdout, stderr = p.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        p.kill()
        stdout, stderr = p.communicate()
        timed_out = True
    peak = mon.stop()
    wall = time.perf_counter() - t0
    stages = _json_lines(stderr, "stage")
    per_tile = tile_cpu(_json_lines(stderr, "tile"), stages)
    if timed_out or p.returncode != 0:
        why = f"stopped after {timeout_s:.0f} s" if timed_out else (stderr.strip().splitlines() or ["?"])[-1]
        return {"size": size, "error": why, "wall_s": wall, "peak_tree_mb": peak / 2**20, "stages": stages,
                "tile_cpu_s": per_tile}
    fig = json.loads(stdout.strip().splitlines()[-1])
    t = fig["timings_s"]
    proc = sum(v for k, v in t.items() if k not in ("library", "total", "report"))
    # the child's own CPU at its end, plus what its side process had used when last sampled
    tree_cpu = fig["cpu_s"] + sum(v for pid, v in mon.cpu_s.items() if pid != fig.get("pid", p.pid))
    return {"size": size, "mode": mode, "wall_s": wall, "generate_s": fig["wall_s"], "peak_tree_mb": peak / 2**20,
            "maxrss_mb": fig["maxrss_mb"], "cpu_s": fig["cpu_s"], "tree_cpu_s": tree_cpu, "processing_s": proc,
            "no_piers_s": proc - t.get("piers", 0.0), "timings_s": t, "n_objects": fig["n_objects"],
            "stages": stages, "tile_cpu_s": per_tile}


def tile_cpu(tiles: list[dict], stages: list[dict]) -> dict:
    """Median CPU seconds per tile of each tiled stage (from the cumulative CPU at each tile's end; the
    first tile of a stage is measured from the previous stage's end), with the tile count."""
    out: dict = {}
    ends = {st["stage"]: st.get("cpu_s") for st in stages}
    order = [st["stage"] for st in stages]
    for name in dict.fromkeys(t["tile"] for t in tiles):
        rows = [t for t in tiles if t["tile"] == name]
        prev_stage = order[order.index(name) - 1] if name in order and order.index(name) > 0 else None
        start = ends.get(prev_stage) if prev_stage else None
        cpu = ([start] if start is not None else []) + [t["cpu_s"] for t in rows]
        d = np.diff(cpu)
        if d.size:
            out[name] = {"tiles": len(rows), "median_s": round(float(np.median(d)), 2)}
    return out


def bench_sizes(work: Path, sizes, tile_px: int, overlap_px: int, scene_max_px: int,
                timeout_s: float | None = None, json_path: str | None = None) -> list[dict]:
    base = base_render(work)
    print(f"== tiled generate vs image size (tile {tile_px}, overlap {overlap_px}, scene grid <= {scene_max_px}, "
          f"{GSD_M} m/px) ==", flush=True)
    rows = []
    for s in sizes:
        load = os.getloadavg()[0]
        r = run_size(work, base, s, tile_px, overlap_px, scene_max_px, timeout_s)
        r["load"] = load
        rows.append(r)
        if json_path:  # after every size: a long run stopped later keeps what it measured
            Path(json_path).write_text(json.dumps({"sizes": rows}, indent=1, default=str))
        if "error" in r:
            done = ", ".join(f"{st['stage']} at {st['elapsed_s']:.0f} s" for st in r["stages"])
            for st in r["stages"]:
                print(f"        {st['stage']:<11} done at {st['elapsed_s']:8.1f} s wall, "
                      f"{st.get('cpu_s', 0):8.1f} s CPU, maxrss {st['maxrss_mb']:6.0f} MB", flush=True)
            print(f"{s:6d} px  INCOMPLETE after {r['wall_s']:.1f} s ({r['error']}); peak tree RSS "
                  f"{r['peak_tree_mb']:.0f} MB; stages finished: {done or 'none'}", flush=True)
            continue
        for st in r["stages"]:  # cumulative wall / CPU at the end of each stage
            print(f"        {st['stage']:<11} done at {st['elapsed_s']:8.1f} s wall, {st.get('cpu_s', 0):8.1f} s CPU, "
                  f"maxrss {st['maxrss_mb']:6.0f} MB, load {st.get('load', 0):.1f}", flush=True)
        for name, v in r.get("tile_cpu_s", {}).items():
            print(f"        {name}: {v['tiles']} tiles, median {v['median_s']:.2f} s CPU per tile", flush=True)
        t = r["timings_s"]
        print(f"{s:6d} px  wall {r['wall_s']:7.1f} s  cpu {r['cpu_s']:7.1f} s  processing {r['processing_s']:7.1f} s "
              f"(without piers {r['no_piers_s']:7.1f} s)  "
              f"peak tree RSS {r['peak_tree_mb']:7.0f} MB  (maxrss {r['maxrss_mb']:.0f} MB)  load {load:.1f}  "
              f"seg {t.get('segment', 0):.1f} det {t.get('detect', 0):.1f} terrain {t.get('terrain', 0):.1f} "
              f"match {t.get('match', 0):.1f} s; objects {sum(v for k, v in r['n_objects'].items() if k != 'vegetation')}",
              flush=True)
    ok = {r["size"]: r for r in rows if "error" not in r}
    for a, b in ((4096, 16384), (4096, 8192), (1024, 4096)):
        if a in ok and b in ok:
            area = (b / a) ** 2
            for key, what in (("processing_s", "processing"), ("no_piers_s", "processing without piers"),
                              ("cpu_s", "CPU")):
                ratio = ok[b][key] / max(ok[a][key], 1e-9)
                print(f"{what} time {b}/{a}: {ratio:.2f}x for {area:.0f}x the area "
                      f"(linear within 1.3x: {ratio <= 1.3 * area})")
    return rows


# ------------------------------------------------------------------------------------- cost per pixel

def bench_per_pixel(work: Path, whole_px: int = 2048, tiled_px: int = 4096, tile_px: int = 2048,
                    overlap_px: int = 256, scene_max_px: int = 4096, timeout_s: float | None = None,
                    json_path: str | None = None) -> dict:
    """The tiled path's cost per pixel against the whole-image path's: ``run_generate`` on a ``whole_px``²
    image (held whole) and ``generate_tiled`` on a ``tiled_px``² one, cut from the same synthetic coast,
    each in a fresh child process. Ratios above 1: the tiled path costs more per pixel."""
    base = base_render(work)
    print(f"\n== cost per pixel: tiled {tiled_px}² (tiles {tile_px}, overlap {overlap_px}, scene grid <= "
          f"{scene_max_px}) against whole image {whole_px}² ==", flush=True)
    runs = {}
    for mode, size in (("whole", whole_px), ("tiled", tiled_px)):
        load = os.getloadavg()[0]
        r = run_size(work, base, size, tile_px, overlap_px, scene_max_px, timeout_s, mode=mode)
        r["load"] = load
        runs[mode] = r
        if "error" in r:
            print(f"{mode:<6} {size:6d} px  FAILED ({r['error']})", flush=True)
            return {"runs": runs}
        px = float(size) ** 2
        print(f"{mode:<6} {size:6d} px  generate {r['generate_s']:7.1f} s wall ({1e6 * r['generate_s'] / px:.2f} µs/px), "
              f"CPU {r['tree_cpu_s']:7.1f} s ({1e6 * r['tree_cpu_s'] / px:.2f} µs/px), peak tree RSS "
              f"{r['peak_tree_mb']:.0f} MB, load {load:.1f}", flush=True)
    w, t = runs["whole"], runs["tiled"]
    area = (tiled_px / whole_px) ** 2
    ratios = {"wall": t["generate_s"] / w["generate_s"] / area, "cpu": t["tree_cpu_s"] / w["tree_cpu_s"] / area}
    stages = {}
    for k in dict.fromkeys([*w["timings_s"], *t["timings_s"]]):
        if k in ("total",):
            continue
        a, b = w["timings_s"].get(k, 0.0), t["timings_s"].get(k, 0.0)
        stages[k] = {"whole_s": a, "tiled_s": b, "per_px_ratio": (b / area / a) if a > 0 else None}
        print(f"        {k:<11} whole {a:7.2f} s  tiled {b:7.2f} s  per pixel "
              f"{format(stages[k]['per_px_ratio'], '.2f') + 'x' if a > 0 else '-'}", flush=True)
    print(f"tiled / whole cost per pixel: wall {ratios['wall']:.2f}x, CPU {ratios['cpu']:.2f}x "
          f"(within 1.3x: wall {ratios['wall'] <= 1.3}, CPU {ratios['cpu'] <= 1.3})", flush=True)
    res = {"runs": runs, "ratio_per_px": ratios, "stages": stages}
    if json_path:
        Path(json_path).write_text(json.dumps(res, indent=1, default=str))
    return res


# --------------------------------------------------------------------------------------------- batch

def make_batch(work: Path, n: int = 20, crop_px: int = 400) -> Path:
    """``n`` small scenes cropped from the base render at different offsets and flips, plus one corrupted file."""
    from ..fsio import write_png

    base = base_render(work)
    folder = work / "batch_inputs"
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    h, w = base.shape[:2]
    items = []
    for k in range(n):
        r0, c0 = int(rng.integers(0, h - crop_px)), int(rng.integers(0, w - crop_px))
        crop = base[r0:r0 + crop_px, c0:c0 + crop_px]
        if k % 2:
            crop = crop[:, ::-1]
        if k % 3 == 1:
            crop = crop[::-1]
        p = write_png(folder / f"scene_{k:02d}.png", np.ascontiguousarray(crop))
        items.append({"image": p.name, "gsd_m": GSD_M})
    bad = folder / "corrupted.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(rng.integers(0, 256, 4000, dtype=np.uint8)))
    items.insert(n // 2, {"image": bad.name, "gsd_m": GSD_M})
    lst = folder / "batch.json"
    lst.write_text(json.dumps({"items": items}, indent=1))
    return lst


def bench_batch(work: Path, n: int = 20) -> list[dict]:
    import shutil

    from ..batch import read_batch_list, run_batch
    from ..config import Config

    lst = make_batch(work, n)
    items = read_batch_list(lst)
    cfg = Config()
    print(f"\n== batch of {n} scenes (400x400 px) + 1 corrupted input on a local Dask cluster ==", flush=True)
    rows = []
    for workers, fresh in ((1, True), (2, True), (2, False)):
        out = work / f"batch_out_{workers}"
        if fresh and out.exists():
            shutil.rmtree(out)
        load = os.getloadavg()[0]
        rep = run_batch(items, out, cfg, workers=workers)
        failed = [it["name"] for it in rep["items"] if it["status"] == "failed"]
        rows.append({"workers": workers, "rerun": not fresh, "wall_s": rep["wall_s"], "done": rep["done"],
                     "skipped": rep["skipped"], "failed": rep["failed"], "failed_items": failed, "load": load})
        print(f"workers {workers} {'re-run' if not fresh else 'fresh '}: wall {rep['wall_s']:7.1f} s  "
              f"done {rep['done']}  skipped {rep['skipped']}  failed {rep['failed']} {failed}  load {load:.1f}",
              flush=True)
    if len(rows) >= 2 and rows[0]["done"] and rows[1]["done"]:
        print(f"speed-up 2 vs 1 workers: {rows[0]['wall_s'] / rows[1]['wall_s']:.2f}x")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.scale", description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default=",".join(map(str, DEFAULT_SIZES)),
                    help="comma-separated square sizes in px (default %(default)s)")
    ap.add_argument("--tile", type=int, default=2048)
    ap.add_argument("--overlap", type=int, default=256)
    ap.add_argument("--scene-max", type=int, default=4096, help="scene grid side limit (terrain, classes)")
    ap.add_argument("--timeout", type=float, default=None,
                    help="stop a size run after this many seconds and report the stages it finished")
    ap.add_argument("--work", default=None, help="folder for the synthetic inputs and outputs (default: a temp dir)")
    ap.add_argument("--no-sizes", action="store_true", help="skip the image-size runs")
    ap.add_argument("--no-per-pixel", action="store_true", help="skip the tiled vs whole-image cost per pixel")
    ap.add_argument("--whole-size", type=int, default=2048,
                    help="side of the whole-image run of the per-pixel comparison (default %(default)s)")
    ap.add_argument("--tiled-size", type=int, default=4096,
                    help="side of the tiled run of the per-pixel comparison (default %(default)s)")
    ap.add_argument("--no-batch", action="store_true", help="skip the Dask batch runs")
    ap.add_argument("--batch-n", type=int, default=20)
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    ap.add_argument("--child", nargs=6, metavar=("IMAGE", "OUT", "TILE", "OVERLAP", "SCENE_MAX", "MODE"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        image, out, tile, ov, smax, mode = args.child
        _child(image, out, int(tile), int(ov), int(smax), mode)
        return
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="coastforge_scale_"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"work folder: {work}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}", flush=True)
    figures: dict = {}
    if not args.no_sizes:
        sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
        figures["sizes"] = bench_sizes(work, sizes, args.tile, args.overlap, args.scene_max, args.timeout, args.json)
    if not args.no_per_pixel:
        figures["per_pixel"] = bench_per_pixel(work, args.whole_size, args.tiled_size, args.tile, args.overlap,
                                               args.scene_max, args.timeout)
    if not args.no_batch:
        figures["batch"] = bench_batch(work, args.batch_n)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1, default=str))


if __name__ == "__main__":
    main()
