"""Report benchmark: ``python -m coastforge.bench.report`` builds the report of a ~100-object scene, opens it
in headless Chromium and prints its weight and its load time (navigation start → 3D view drawn).

Targets (issue 9): under 3 s and under 15 MB. ``open_report`` is also what tests/test_report.py uses.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--no-first-run", "--disable-sync",
                 # WebGL without a GPU: SwiftShader (software) through ANGLE
                 "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
BACKGROUND = (0xDD, 0xE6, 0xEE)  # the viewer's clear colour


def browser_missing() -> str | None:
    """Why the browser check cannot run here, or None when it can."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright Python package is not installed (pip install playwright)"
    exe = shutil.which(CHROMIUM) or shutil.which("chromium")
    if not exe:
        return f"no chromium at {CHROMIUM} (apt-get install chromium)"
    return None


def _png_rgb(png: bytes):
    import cv2
    import numpy as np

    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1].astype(int)


def open_report(path: str | Path, screenshot: str | Path | None = None, timeout_s: float = 60.0,
                width: int = 1400) -> dict:
    """Open a report in headless Chromium from the file system and collect what a test needs to know:
    console errors, failed or non-file requests, the sections seen, whether the 3D canvas drew something
    other than its background, and the load timing. Saves a full-page screenshot when asked."""
    import numpy as np
    from playwright.sync_api import sync_playwright

    path = Path(path).resolve()
    url = path.as_uri()
    errors: list[str] = []
    failed: list[str] = []
    foreign: list[str] = []
    with sync_playwright() as p:
        exe = shutil.which(CHROMIUM) or shutil.which("chromium")
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": width, "height": 1000})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.on("requestfailed", lambda r: failed.append(f"{r.url[:120]} ({r.failure})"))
            local = ("file:", "data:", "blob:")
            page.on("request", lambda r: None if r.url.startswith(local) else foreign.append(r.url[:120]))
            t0 = time.perf_counter()
            page.goto(url, wait_until="load", timeout=timeout_s * 1000)
            state = page.wait_for_function(
                "() => { const v = document.getElementById('viewer');"
                " return !v ? 'none' : (v.dataset.drawnMs ? 'drawn' :"
                " (v.dataset.error ? 'error' : false)); }",
                timeout=timeout_s * 1000).json_value()
            wall_s = time.perf_counter() - t0
            timing = page.evaluate(
                "() => { const n = performance.getEntriesByType('navigation')[0] || {};"
                " const v = document.getElementById('viewer');"
                " return {load_ms: n.loadEventEnd || 0, dom_ms: n.domContentLoadedEventEnd || 0,"
                " drawn_ms: v && v.dataset.drawnMs ? Number(v.dataset.drawnMs) : null,"
                " error: v ? (v.dataset.error || null) : null}; }")
            sections = page.evaluate(
                "() => Array.from(document.querySelectorAll('section[data-section]')).map(s => {"
                " const r = s.getBoundingClientRect();"
                " return [s.dataset.section,"
                " r.height > 30 && r.width > 100 && getComputedStyle(s).display !== 'none',"
                " s.querySelector('h2') ? s.querySelector('h2').textContent : '']; })")
            # every picture must decode (the page marks them decoding="async": wait for them too)
            broken_imgs = page.evaluate(
                "async () => { const bad = []; await Promise.all(Array.from(document.images)"
                ".filter(i => i.getAttribute('src')).map(i => i.decode().then(() => {"
                " if (!i.naturalWidth) bad.push(i.alt); }, () => bad.push(i.alt)))); return bad; }")
            canvas = None
            non_bg = orbit_changed = 0.0
            if state == "drawn":
                page.locator("#viewer").scroll_into_view_if_needed()
                page.wait_for_timeout(200)
                cv = page.locator("#viewer canvas")
                a = _png_rgb(cv.screenshot())
                non_bg = float(np.mean(np.abs(a - np.array(BACKGROUND)).sum(-1) > 24))
                canvas = a.shape[:2]
            if screenshot:
                page.evaluate("window.scrollTo(0, 0)")
                page.screenshot(path=str(screenshot), full_page=True)
            if state == "drawn":  # orbit: drag across the canvas; the view must change
                page.locator("#viewer").scroll_into_view_if_needed()
                cv = page.locator("#viewer canvas")
                a = _png_rgb(cv.screenshot())
                box = cv.bounding_box()
                cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
                page.mouse.move(cx, cy)
                page.mouse.down()
                page.mouse.move(cx + 160, cy + 40, steps=2)
                page.mouse.up()
                page.wait_for_timeout(400)
                b = _png_rgb(cv.screenshot())
                orbit_changed = float(np.mean(np.abs(a - b).sum(-1) > 24)) if b.shape == a.shape else 1.0
        finally:
            browser.close()
    return {"url": url, "bytes": path.stat().st_size, "console_errors": errors, "failed_requests": failed,
            "foreign_requests": foreign, "sections": {s: ok for s, ok, _ in sections},
            "titles": {s: t for s, _, t in sections}, "broken_images": broken_imgs, "viewer_state": state,
            "canvas_px": canvas, "canvas_non_background": non_bg,
            "orbit_changed": orbit_changed, "wall_s": wall_s, **timing}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", help="A generated scene folder (or scene JSON) to report on "
                    "(default: generate a marina level).")
    ap.add_argument("--truth", help="Its truth scene (adds metrics).")
    ap.add_argument("--work", default="/tmp/coastforge_bench_report",
                    help="Work folder for the generated level.")
    ap.add_argument("--preset", default="marina")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--gsd", type=float, default=0.2)
    ap.add_argument("--screenshot", default="/tmp/report_bench.png")
    ap.add_argument("--runs", type=int, default=3,
                    help="Browser loads to time (the best and median are printed).")
    args = ap.parse_args(argv)
    why = browser_missing()
    if why:
        print(f"cannot run: {why}", file=sys.stderr)
        return 2
    work = Path(args.work)
    if args.scene:
        scene_dir = Path(args.scene)
        truth = args.truth
    else:
        from ..config import load_config
        from ..pipeline import GenerateRequest, run_generate
        from ..synth import image_name, synth_to_dir

        print(f"synthesizing {args.preset} seed {args.seed} and generating its scene (takes a minute or two)")
        res = synth_to_dir(args.preset, args.seed, work / "truth", gsds=(args.gsd,), overwrite=True)
        truth = str(res.truth_path)
        print(f"  {res.n_objects} objects in the truth level")
        scene_dir = work / "gen"
        req = GenerateRequest(image=str(work / "truth" / image_name(args.gsd)), gsd_m=args.gsd,
                              out=str(scene_dir), exports=(), overwrite=True, report=False)
        run_generate(req, load_config("default", None, [], args.seed))
    targets = [(scene_dir, truth)]
    if not args.scene:
        targets.append((Path(truth), None))  # the truth level itself: every object of the layout (~170)
    ok = True
    for k, (target, tr) in enumerate(targets):
        shot = args.screenshot if k == 0 else str(Path(args.screenshot).with_suffix("")) + "_truth.png"
        ok &= _measure(target, tr, shot, args.runs)
    return 0 if ok else 1


def _measure(target, truth, screenshot, runs: int) -> bool:
    from ..report import build_report
    from ..scene import load_scene

    t0 = time.perf_counter()
    out = None if Path(target).is_dir() else Path(target).with_name("report.html")
    path = build_report(target, truth, out, overwrite=True)
    build_s = time.perf_counter() - t0
    scene_file = target if Path(target).is_file() else Path(target) / "scene.json"
    objs = load_scene(scene_file, rasters=False).objects
    loads = []
    info = {}
    for i in range(max(1, runs)):
        info = open_report(path, screenshot if i == 0 else None)
        if info["drawn_ms"] is None:
            print(f"{path}: the 3D view did not draw: {info['viewer_state']} {info.get('error')}",
                  file=sys.stderr)
            return False
        loads.append(info["drawn_ms"] / 1000)
    mb = info["bytes"] / 1e6
    med = sorted(loads)[len(loads) // 2]
    n_eval = sum(1 for o in objs if o.category in ("boat", "vehicle", "buoy"))
    print(f"report: {path} ({len(objs)} objects, {n_eval} boats/vehicles/buoys in the table), "
          f"built in {build_s:.1f} s")
    print(f"  weight: {mb:.2f} MB (target < 15 MB) {'OK' if mb < 15 else 'MISS'}")
    print(f"  load -> 3D drawn: best {min(loads):.2f} s, median {med:.2f} s over {len(loads)} loads "
          f"(target < 3 s) {'OK' if med < 3 else 'MISS'}; DOMContentLoaded {info['dom_ms'] / 1000:.2f} s")
    print(f"  console errors {len(info['console_errors'])}, failed requests {len(info['failed_requests'])}, "
          f"sections shown {sum(info['sections'].values())}/{len(info['sections'])}, "
          f"3D canvas non-background {100 * info['canvas_non_background']:.0f}%"
          + (f"; screenshot {screenshot}" if screenshot else ""))
    return mb < 15 and med < 3 and not info["console_errors"]

if __name__ == "__main__":
    sys.exit(main())
