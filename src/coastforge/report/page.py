"""report.html: what a user looks at — one self-contained page that works offline from the file system.

Images are embedded as data URIs; the 3D preview is the scene's GLB (base64) shown by a vendored three.js
bundle (a classic script: browsers refuse ES-module imports from file:// pages). Nothing is fetched. The
page's stylesheet and script are ``static/report.css`` and ``static/report.js``.
"""

from __future__ import annotations

import base64
import html
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable

import numpy as np

from ..classes import EVALUATED_CATEGORIES
from ..errors import InputError, OutputExistsError
from ..fsio import atomic_write_text
from ..scene import Scene, load_scene
from .inputs import ReportAssets, input_image, match_objects_to_decisions, read_detections, read_rgb
from .markup import fit, note, static_text, upscale_small
from .previews import glb_bytes, render_top
from .sections import (classes_section, detections_section, metrics_section, objects_section, overview_section,
                       piers_section, provenance_section, terrain_section, vegetation_section, warnings_block)

SECTIONS = ("overview", "classes", "detections", "objects", "terrain", "piers", "vegetation", "metrics",
            "provenance",
            "preview3d")
TITLES = {"overview": "Input and generated scene", "classes": "Terrain classes", "detections": "Detections",
          "objects": "Objects and their assets", "terrain": "Height map and shore profile",
          "piers": "Pier structures", "vegetation": "Vegetation density per class",
          "metrics": "Metrics against the truth", "provenance": "Timings, command and versions",
          "preview3d": "3D preview"}
SECTION_FAILED = "This section could not be built"


def _guard(name: str, fn, *args):
    """One section's HTML; an unexpected failure inside it becomes a visible note (and a warning) instead of
    costing the whole report. Coastforge errors (bad input) still propagate to the user."""
    import warnings

    from ..errors import CoastforgeError

    try:
        return fn(*args)
    except CoastforgeError:
        raise
    except Exception as exc:  # noqa: BLE001 - see above
        warnings.warn(f"report section {name!r} failed: {type(exc).__name__}: {exc}", RuntimeWarning,
                      stacklevel=2)
        return (f'<p class="bad">{SECTION_FAILED}: {html.escape(type(exc).__name__)}: '
                f'{html.escape(str(exc))}</p>')


def build_report(scene_dir: str | Path, truth: str | Path | None = None, out: str | Path | None = None,
                 overwrite: bool = False, progress: Callable[[str], None] | None = None, *,
                 scene: Scene | None = None, image: np.ndarray | None = None,
                 library=None, top_terrain=None, wait: Callable[[str], Any] | None = None) -> Path:
    """Write the offline ``report.html`` of the scene in ``scene_dir`` and return its path.

    ``out`` defaults to ``scene_dir/report.html``, which is always rebuilt (it is a view of the scene);
    another existing ``out`` is replaced only with ``overwrite``. ``truth`` (a truth scene) adds the
    metrics. ``progress(step)`` is told which part is being built. ``scene`` and ``image`` (the input
    RGB) are what ``generate`` already holds in memory: given, they are not read back from disk. ``library`` (the
    scene's, loaded) and ``top_terrain`` (``render.scene_terrain_layer`` at ``top_gsd``) spare loading and
    rendering them again. ``wait(part)`` waits for what a ``generate`` is still making beside the report,
    which builds the sections that need none of it first: "meshes" (``library``'s meshes of the scene's
    assets), "cleaned" (returns the inpainted image, instead of reading ``cleaned.png``), "terrain" (the
    terrain stage's outputs, for the cross-sections) and "all" (every output: called before the page is
    written, so a failed run leaves no report)."""
    t_start = time.perf_counter()
    say = progress or (lambda _msg: None)
    scene_path = Path(scene_dir)
    scene_dir = scene_path.parent if scene_path.is_file() else scene_path
    if not scene_path.is_file():
        scene_path = scene_dir / "scene.json"
    if scene is None and not scene_path.is_file():  # (generate hands its scene over before writing the JSON)
        raise InputError(f"{scene_dir} holds no scene.json; give the --out folder of `coastforge generate` "
                         "(or a scene / truth JSON file)")
    if truth is not None and not Path(truth).exists():
        raise InputError(f"truth scene {truth} does not exist; give a truth.json written by "
                         "`coastforge synth` "
                         "or a scene.json")
    out_path = Path(out) if out else scene_dir / "report.html"
    default_out = (scene_dir / "report.html").resolve()
    from ..fsio import same_file

    if out_path.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"--out {out_path} must end in .html (the report is one HTML page)")
    for what, p in (("the scene file", scene_path), ("the truth scene", truth)):
        if p is not None and same_file(out_path, p):
            raise InputError(f"--out {out_path} is {what}; write the report to another file (e.g. report.html)")
    if out and out_path.exists() and not overwrite and out_path.resolve() != default_out:
        raise OutputExistsError(f"{out_path} exists; pass --overwrite to replace it, or choose another --out")
    say("loading the scene")
    if scene is None:
        scene = load_scene(scene_path)
    grid = scene.grid
    assets = ReportAssets(scene, library)
    if image is not None:
        image_src = str((scene.provenance.get("input") or {}).get("image", ""))
    else:
        image, image_src = input_image(scene, scene_dir)
    dets = read_detections(scene_dir)
    objs = [o for o in scene.objects if o.category in EVALUATED_CATEGORIES]
    matches = [m for m in scene.provenance.get("matches", []) if isinstance(m, dict)]
    links = match_objects_to_decisions(objs, matches)
    row_of_det = {}
    for k, o in enumerate(objs):
        m = links.get(o.id)
        if m is not None and isinstance(m.get("index"), int):
            row_of_det[m["index"]] = str(k + 1)
    parts: dict[str, str] = {}
    base = fit(image) if image is not None else None

    # The render from above and the 3D preview need the meshes, the class-map section and the preview the
    # inpainted image: a generate may still be making those beside the report. They are built in two
    # threads (mostly OpenCV and NumPy, which release the GIL), the other sections here meanwhile.
    def top_part() -> str:
        if wait is not None:
            wait("meshes")
        return overview_section(image, render_top(scene, assets, top_terrain))

    def cleaned_part():
        if wait is not None:
            wait("meshes")
        # the inpainted image: shown beside the class map and textures the 3D preview (None when absent)
        cleaned = wait("cleaned") if wait is not None else read_rgb(scene_dir / "cleaned.png")
        if wait is not None:
            wait("segmentation")  # its confidence and source rasters
        return _guard("classes", classes_section, scene, base, cleaned, scene_dir), glb_bytes(scene, scene_dir, assets,
                                                                                    cleaned)

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="coastforge-report") as pool:
        top_job, cleaned_job = pool.submit(top_part), pool.submit(cleaned_part)
        say("detections")
        det_base = upscale_small(base) if base is not None else None
        img_w = image.shape[1] if image is not None else grid.width_px
        det_scale = (det_base.shape[1] / img_w) if det_base is not None else 1.0
        parts["detections"] = _guard("detections", detections_section, det_base, dets, det_scale,
                                     row_of_det)
        say("objects and asset views")
        objects_part = _guard("objects", objects_section, scene, image, assets, links, dets)
        parts["objects"], asset_css = objects_part if isinstance(objects_part, tuple) else (objects_part, "")
        say("terrain")
        if wait is not None:
            wait("terrain")
        parts["terrain"] = _guard("terrain", terrain_section, scene, scene_dir)
        say("piers and vegetation")
        parts["piers"] = _guard("piers", piers_section, scene, base)
        parts["vegetation"] = _guard("vegetation", vegetation_section, scene)
        if truth is not None:
            say("metrics against the truth")
        parts["metrics"] = metrics_section(scene, str(truth) if truth is not None else None)
        say("rendering the scene from above, class map and 3D preview")
        parts["overview"] = top_job.result()
        parts["classes"], (glb, glb_src) = cleaned_job.result()
    bundle = static_text("viewer.bundle.js")
    if glb is not None:
        parts["preview3d"] = (
            '<div id="viewer"></div><div class="vbar"><button data-view="top">top view</button>'
            '<button data-view="oblique">oblique</button><button data-view="low">low, from the water</button>'
            '<span class="muted">Drag to orbit, right-drag to pan, scroll to zoom. '
            f'GLB: {html.escape(glb_src)}, '
            f"{len(glb) / 1e6:.1f} MB.</span></div>"
            '<script id="glb-data" type="application/octet-stream">'
            f'{base64.b64encode(glb).decode("ascii")}</script>')
    else:
        parts["preview3d"] = note("No GLB could be built for the 3D preview (run "
                                   "<code>coastforge export DIR "
                                   "--format gltf</code>).")
    parts["provenance"] = provenance_section(scene, time.perf_counter() - t_start)
    nav = "".join(f'<a href="#sec-{k}">{TITLES[k]}</a>' for k in SECTIONS)
    body = "".join(f'<section id="sec-{k}" data-section="{k}"><h2>{TITLES[k]}</h2>{parts[k]}</section>'
                   for k in SECTIONS)
    counts: dict[str, int] = {}
    for o in scene.objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    chips = [f"{scene.extent_m[0]:.0f} × {scene.extent_m[1]:.0f} m", f"{grid.gsd_m:.3f} m/px",
             *(f"{v} {k}{'s' if v != 1 else ''}" for k, v in counts.items()),
             f"{len(scene.vegetation) if scene.vegetation is not None else 0} plants/rocks",
             f"seed {scene.seed}"]
    src = f" · input: {html.escape(image_src)}" if image_src else ""
    warn = warnings_block(scene)
    page = f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"/>
<meta name="viewport" content="width=device-width, initial-scale=1"/>
<title>coastforge report: {html.escape(scene.name)}</title><style>
{static_text("report.css")}{asset_css}</style></head><body>
<header><h1>coastforge — {html.escape(scene.name)}</h1>
<div class="chips">{"".join(f"<span>{c}</span>" for c in chips)}</div>
<p>Generated environment report{src}</p>{warn}</header><nav>{nav}</nav>{body}
<footer>Self-contained page: works offline; the 3D view uses three.js (MIT licence), bundled.</footer>
<div id="lightbox"><img alt="enlarged picture"/></div>
<script>{bundle}</script>
<script>
{static_text("report.js")}</script></body></html>"""
    if wait is not None:
        wait("all")
    say("writing")
    if out and out_path.parent and not out_path.parent.exists():
        raise InputError(f"folder {out_path.parent} does not exist; create it or choose another --out")
    atomic_write_text(out_path, page)
    return out_path
