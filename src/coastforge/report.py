"""report.html: what a user looks at — one self-contained page that works offline from the file system.

Images are embedded as data URIs, the 3D preview is the scene's GLB (base64) shown by a vendored three.js
bundle (classic script: browsers refuse module imports from file:// pages). Nothing is fetched.
"""

from __future__ import annotations

import base64
import html
import io
import json
from importlib import resources
from pathlib import Path

import numpy as np

from .classes import CLASS_NAMES, EVALUATED_CATEGORIES, PALETTE, WATER, colorize
from .fsio import atomic_write_text
from .scene import Scene, load_scene

MAX_PX = 1400  # images are shown at most this wide: keeps a 100-object report far under 15 MB
SECTIONS = ("overview", "classes", "detections", "objects", "terrain", "piers", "vegetation", "metrics", "provenance",
            "preview3d")


def _data_uri(rgb: np.ndarray, fmt: str = "jpeg", quality: int = 85) -> str:
    import cv2

    a = rgb if rgb.ndim == 2 else rgb[:, :, ::-1]
    ok, buf = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", np.ascontiguousarray(a),
                           [cv2.IMWRITE_JPEG_QUALITY, quality] if fmt == "jpeg" else [])
    if not ok:
        raise OSError("could not encode an image for the report")
    return f"data:image/{fmt};base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def _fit(rgb: np.ndarray, max_px: int = MAX_PX) -> np.ndarray:
    import cv2

    h, w = rgb.shape[:2]
    s = min(1.0, max_px / max(h, w))
    if s >= 1.0:
        return rgb
    return cv2.resize(rgb, (max(1, int(w * s)), max(1, int(h * s))), interpolation=cv2.INTER_AREA)


def _fig_uri(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _img(uri: str, caption: str, cls: str = "") -> str:
    return (f'<figure class="{cls}"><img src="{uri}" alt="{html.escape(caption)}"/>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _table(header: list[str], rows: list[list], cls: str = "") -> str:
    th = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>'


def _fmt(v, nd=3) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{nd}f}"
    return html.escape(str(v))


def _input_image(scene: Scene, scene_dir: Path) -> np.ndarray | None:
    from .fsio import read_png

    src = scene.provenance.get("input", {}).get("image")
    for cand in ([Path(src)] if src else []) + [scene_dir / "image.png"]:
        if cand.is_file():
            try:
                import cv2

                a = cv2.imread(str(cand), cv2.IMREAD_COLOR)
                if a is not None:
                    return a[:, :, ::-1].copy()
            except Exception:  # noqa: BLE001 - an unreadable input only drops a picture from the report
                pass
    p = scene_dir / "cleaned.png"
    return read_png(p) if p.is_file() else None


def _resize_to(a: np.ndarray, shape: tuple[int, int], nearest=False) -> np.ndarray:
    import cv2

    if a.shape[:2] == shape:
        return a
    return cv2.resize(a, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_AREA)


class _Assets:
    """Meshes and views of the scene's assets: its library when it can be loaded, else the starter kit."""

    def __init__(self, scene: Scene):
        self.lib = None
        lib_path = scene.provenance.get("library")
        try:
            from .assets import library as lib_mod

            if lib_path and lib_path != "starter-kit" and Path(lib_path).is_dir():
                self.lib = lib_mod.Library.load(lib_path)
            else:
                self.lib = lib_mod.default_library()
        except Exception:  # noqa: BLE001 - the report still renders without asset pictures
            self.lib = None

    def mesh(self, asset_id: str):
        if self.lib is not None:
            try:
                return self.lib.mesh(asset_id)
            except Exception:  # noqa: BLE001
                pass
        from .assets.kit import load_kit_mesh

        return load_kit_mesh(asset_id)

    def view(self, asset_id: str, background: str):
        if self.lib is None:
            return None
        try:
            from .matching import asset_top_view

            return asset_top_view(self.lib, asset_id, background)[0]
        except Exception:  # noqa: BLE001
            return None


def _render_top(scene: Scene, assets: _Assets) -> np.ndarray | None:
    try:
        from .render import render_scene
    except ImportError:
        return None
    w, h = scene.extent_m
    gsd = max(scene.gsd_m, max(w, h) / MAX_PX)
    mesh_cache: dict = {}

    def mesh_for(aid):
        if aid not in mesh_cache:
            mesh_cache[aid] = assets.mesh(aid)
        return mesh_cache[aid]

    return render_scene(scene, mesh_for, gsd, seed=scene.seed)


def _draw_detections(img: np.ndarray, scene_dir: Path, scale: float) -> np.ndarray:
    import cv2

    out = img.copy()
    p = scene_dir / "detections.json"
    if not p.is_file():
        return out
    dets = json.loads(p.read_text()).get("detections", [])
    colours = {"boat": (255, 80, 40), "vehicle": (255, 220, 0), "pier_walkway": (60, 200, 255),
               "pier_finger": (120, 255, 200), "buoy": (255, 0, 255)}
    for d in dets:
        c = colours.get(d["category"], (255, 255, 255))
        pts = np.round(np.array(d["corners_px"]) * scale).astype(np.int32)
        cv2.polylines(out, [pts], True, c, 1, cv2.LINE_AA)
        if d["category"] in ("boat", "vehicle"):
            r = np.deg2rad(d["yaw_deg"])
            cx, cy = d["cx_px"] * scale, d["cy_px"] * scale
            L = d["length_px"] * scale * 0.6
            tip = (int(cx + np.cos(r) * L), int(cy - np.sin(r) * L))
            cv2.arrowedLine(out, (int(cx), int(cy)), tip, c if d.get("heading_known") else (200, 200, 200), 1,
                            cv2.LINE_AA, tipLength=0.35)
    return out


def _objects_table(scene: Scene, image: np.ndarray | None, assets: _Assets) -> str:
    from .matching import crop_rotated

    matches = {m["asset_id"] + f"@{i}": m for i, m in enumerate(scene.provenance.get("matches", []))}
    by_index = scene.provenance.get("matches", [])
    objs = [o for o in scene.objects if o.category in EVALUATED_CATEGORIES]
    rows = []
    grid = scene.grid
    img_scale = (image.shape[1] / grid.width_px) if image is not None else 1.0
    views: dict = {}
    for k, o in enumerate(objs):
        crop_html = view_html = ""
        if image is not None:
            col, row = grid.to_pixel(o.x_m, o.y_m)
            side_m = max(o.length_m, o.width_m) * 1.4
            side = int(np.clip(side_m / grid.gsd_m * img_scale, 8, 4000))
            s = 72 / side
            crop = crop_rotated(image, col * img_scale, row * img_scale, o.yaw_deg, 72, 72, s)
            crop_html = f'<img class="thumb" src="{_data_uri(crop)}" alt="crop {html.escape(o.id)}"/>'
        key = (o.asset_id, "ground" if o.category == "vehicle" else "water")
        if key not in views:
            v = assets.view(*key)
            views[key] = None if v is None else _data_uri(_resize_to(v, (72, 72)))
        if views[key]:
            view_html = f'<img class="thumb" src="{views[key]}" alt="asset {html.escape(o.asset_id)}"/>'
        m = by_index[k] if k < len(by_index) and by_index[k].get("asset_id") == o.asset_id else None
        runners = ", ".join(f"{html.escape(c['asset_id'])} ({c['score']:.2f})" for c in (m or {}).get("candidates", [])[1:4])
        rows.append([html.escape(o.id), crop_html, view_html, html.escape(o.asset_id), _fmt(o.score, 2),
                     f"{o.length_m:.1f} × {o.width_m:.1f}", f"{o.yaw_deg:.0f}°",
                     html.escape(str(o.attrs.get("heading", ""))), runners or "—"])
    del matches
    return _table(["id", "crop", "asset", "asset id", "score", "size (m)", "yaw", "heading", "runner-ups"], rows,
                  "objects")


def _terrain_plots(scene: Scene) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LightSource

    if scene.height is None:
        return "<p>No height map.</p>"
    z = scene.height
    step = max(1, int(max(z.shape) / 900))
    zs = z[::step, ::step]
    w, h = scene.extent_m
    fig, ax = plt.subplots(figsize=(7, 6))
    ls = LightSource(azdeg=315, altdeg=45)
    lim = float(max(abs(zs.min()), abs(zs.max()), 0.5))
    cmap = plt.get_cmap("gist_earth")
    rgb = ls.shade(zs, cmap=cmap, vert_exag=3, blend_mode="soft", vmin=-lim, vmax=lim,
                   dx=scene.gsd_m * step, dy=scene.gsd_m * step)
    ax.imshow(rgb, extent=(-w / 2, w / 2, -h / 2, h / 2))
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(-lim, lim))
    fig.colorbar(sm, ax=ax, label="height (m), 0 = water level")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_title("height map (hillshade)")
    hill = _fig_uri(fig)
    # shore cross-section: the row through the scene centre... and a column, whichever crosses the shore
    fig, ax = plt.subplots(figsize=(7, 3))
    drawn = False
    for label, prof, axis_len in (("west→east through centre", z[z.shape[0] // 2, :], w),
                                  ("south→north through centre", z[::-1, z.shape[1] // 2], h)):
        if prof.min() < 0 < prof.max():
            ax.plot(np.linspace(-axis_len / 2, axis_len / 2, prof.size), prof, label=label)
            drawn = True
    ax.axhline(0, color="#1f77b4", lw=0.8, ls="--", label="water level")
    ax.set_xlabel("distance (m)")
    ax.set_ylabel("height (m)")
    ax.set_title("shore cross-section (side view)" + ("" if drawn else ": no transect crosses the shore"))
    ax.legend(fontsize=8)
    sec = _fig_uri(fig)
    return _img(hill, "Height map with land and bathymetry") + _img(sec, "Shore cross-section")


def _piers_section(scene: Scene, base: np.ndarray | None) -> str:
    import cv2

    from .evaluate import pier_connectivity

    conn = pier_connectivity(scene)
    if not conn["n_segments"]:
        return "<p>No pier structures.</p>"
    grid = scene.grid
    img = base.copy() if base is not None else colorize(scene.classes if scene.classes is not None
                                                        else np.zeros(grid.shape, np.uint8))
    s = img.shape[1] / grid.width_px
    bad = set(conn.get("disconnected_ids", []))
    for o in scene.objects:
        if o.category != "pier":
            continue
        r = np.deg2rad(o.yaw_deg)
        u, n = np.array([np.cos(r), np.sin(r)]), np.array([-np.sin(r), np.cos(r)])
        c = np.array([o.x_m, o.y_m])
        pts = np.array([c + u * o.length_m / 2 + n * o.width_m / 2, c - u * o.length_m / 2 + n * o.width_m / 2,
                        c - u * o.length_m / 2 - n * o.width_m / 2, c + u * o.length_m / 2 - n * o.width_m / 2])
        col, row = grid.to_pixel(pts[:, 0], pts[:, 1])
        poly = np.round(np.stack([col * s, row * s], 1)).astype(np.int32)
        cv2.fillPoly(img, [poly], (255, 40, 40) if o.id in bad else (40, 220, 90))
    text = (f"<p>{conn['n_segments']} segments in {conn['n_structures']} structures; segments connected: "
            f"{_fmt(conn['segments_connected'])}; structures reaching land: {_fmt(conn['structures_on_land'])}; "
            f"<b>all connected: {_fmt(conn['all_connected'])}</b> (green: connected, red: not).</p>")
    return text + _img(_data_uri(_fit(img)), "Pier segments by connectivity")


def _vegetation_section(scene: Scene) -> str:
    v = scene.vegetation
    if v is None or not len(v) or scene.classes is None:
        return "<p>No vegetation instances.</p>"
    grid = scene.grid
    col, row = grid.to_pixel(v.x_m, v.y_m)
    cls = scene.classes[np.clip(row.astype(int), 0, grid.height_px - 1), np.clip(col.astype(int), 0, grid.width_px - 1)]
    area = np.bincount(scene.classes.ravel(), minlength=8) * grid.gsd_m ** 2
    cats = sorted(set(str(a) for a in v.asset_id))
    rows = []
    for c in range(8):
        n = int(np.sum(cls == c))
        if n == 0 and area[c] == 0:
            continue
        per = ", ".join(f"{a}: {int(np.sum((cls == c) & (v.asset_id == a)))}" for a in cats
                        if np.any((cls == c) & (v.asset_id == a)))
        rows.append([CLASS_NAMES[c], f"{area[c]:.0f}", str(n), f"{(100 * n / area[c]) if area[c] else 0:.2f}",
                     per or "—"])
    return _table(["class", "area (m²)", "instances", "per 100 m²", "by asset"], rows)


def _metrics_section(scene: Scene, truth_path: str | None) -> str:
    if not truth_path:
        return "<p>No truth scene given (<code>coastforge report DIR --truth truth.json</code>).</p>"
    from .evaluate import evaluate_scenes

    m = evaluate_scenes(load_scene(truth_path), scene)
    keys = ["n_truth", "n_pred", "n_matched", "xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "recall",
            "match_precision", "match_precision_category", "detection_precision"]
    cats = list(m["per_category"])
    rows = [[k, _fmt(m[k])] + [_fmt(m["per_category"][c][k]) for c in cats] for k in keys]
    t = m["terrain"]
    extra = (f"<p>Terrain: mIoU {_fmt(t.get('miou'))}; height RMSE land {_fmt(t.get('height_rmse_land_m'))} m, "
             f"water {_fmt(t.get('height_rmse_water_m'))} m. Piers all connected: "
             f"{_fmt(m['piers'].get('all_connected'))}.</p>")
    return _table(["metric", "all", *cats], rows) + extra


def _provenance_section(scene: Scene) -> str:
    p = scene.provenance
    t = p.get("timings_s", {})
    rows = [[html.escape(k), f"{v:.2f} s"] for k, v in t.items()]
    info = [["command", f"<code>{html.escape(str(p.get('command', '')))}</code>"], ["seed", _fmt(scene.seed)],
            ["coastforge", _fmt(p.get("version"))], ["python", _fmt(p.get("python"))],
            ["platform", _fmt(p.get("platform"))], ["backends", html.escape(json.dumps(p.get("backends", {})))],
            ["library", _fmt(p.get("library"))]]
    return _table(["stage", "wall time"], rows, "timings") + _table(["", ""], info, "prov")


def _glb_bytes(scene: Scene, scene_dir: Path) -> bytes | None:
    for p in (scene_dir / "gltf" / "scene.glb", *sorted((scene_dir / "gltf").glob("*.glb"))
              if (scene_dir / "gltf").is_dir() else ()):
        if Path(p).is_file():
            return Path(p).read_bytes()
    try:
        from .export import scene_glb_bytes

        return scene_glb_bytes(scene, scene_dir)
    except Exception:  # noqa: BLE001 - no 3D preview rather than no report
        return None


CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;background:#f4f6f8;color:#1d2733}
header{background:#0b3954;color:#fff;padding:14px 24px}header h1{margin:0;font-size:22px}
header p{margin:4px 0 0;opacity:.85}nav{padding:6px 24px;background:#e3ecf2;font-size:14px}
nav a{margin-right:14px;color:#0b3954}section{background:#fff;margin:16px 24px;padding:12px 18px;border-radius:8px;
box-shadow:0 1px 3px rgba(0,0,0,.08)}h2{margin-top:4px;font-size:18px;color:#0b3954}
.row{display:flex;flex-wrap:wrap;gap:12px}figure{margin:0;flex:1 1 420px;max-width:100%}
figure img{width:100%;height:auto;border:1px solid #ccd;border-radius:4px}figcaption{font-size:13px;color:#556}
table{border-collapse:collapse;font-size:13px;margin:6px 0}td,th{border:1px solid #dde;padding:3px 7px;
text-align:left;vertical-align:middle}th{background:#eef3f7}img.thumb{width:72px;height:72px;border-radius:3px}
.legend span{display:inline-block;margin:2px 10px 2px 0;font-size:13px}.legend i{display:inline-block;width:14px;
height:14px;margin-right:4px;vertical-align:-2px;border:1px solid #888}#viewer{width:100%;min-height:520px}
.objects-wrap{max-height:640px;overflow:auto}
"""


def build_report(scene_dir: str | Path, truth: str | None = None, out: str | Path | None = None) -> Path:
    """Write ``report.html`` for the scene in ``scene_dir`` and return its path."""
    scene_dir = Path(scene_dir)
    scene = load_scene(scene_dir)
    grid = scene.grid
    assets = _Assets(scene)
    image = _input_image(scene, scene_dir)
    parts: dict[str, str] = {}
    top = _render_top(scene, assets)
    row = []
    if image is not None:
        row.append(_img(_data_uri(_fit(image)), "Input image"))
    if top is not None:
        row.append(_img(_data_uri(_fit(top)), "Generated scene rendered from above"))
    parts["overview"] = '<div class="row">' + "".join(row) + "</div>"
    base = _fit(image) if image is not None else None
    if scene.classes is not None:
        cm = colorize(scene.classes)
        if base is not None:
            cm_small = _resize_to(cm, base.shape[:2], nearest=True)
            overlay = (0.55 * base + 0.45 * cm_small).astype(np.uint8)
        else:
            overlay = _fit(cm)
        legend = '<div class="legend">' + "".join(
            f'<span><i style="background:rgb{tuple(int(v) for v in PALETTE[c])}"></i>{n}</span>'
            for c, n in enumerate(CLASS_NAMES)) + "</div>"
        cleaned = scene_dir / "cleaned.png"
        imgs = [_img(_data_uri(overlay), "Terrain classes over the image")]
        if cleaned.is_file():
            from .fsio import read_png

            imgs.append(_img(_data_uri(_fit(read_png(cleaned))), "Cleaned image (boats and vehicles removed)"))
        parts["classes"] = legend + '<div class="row">' + "".join(imgs) + "</div>"
    else:
        parts["classes"] = "<p>No class map.</p>"
    if base is not None:
        s = base.shape[1] / grid.width_px
        parts["detections"] = _img(_data_uri(_draw_detections(base, scene_dir, s)),
                                   "Detections (arrows: heading; grey arrows: heading not known)")
    else:
        parts["detections"] = "<p>The input image is not available.</p>"
    parts["objects"] = '<div class="objects-wrap">' + _objects_table(scene, image, assets) + "</div>"
    parts["terrain"] = _terrain_plots(scene)
    parts["piers"] = _piers_section(scene, base)
    parts["vegetation"] = _vegetation_section(scene)
    parts["metrics"] = _metrics_section(scene, truth)
    parts["provenance"] = _provenance_section(scene)
    glb = _glb_bytes(scene, scene_dir)
    bundle = resources.files("coastforge.report_assets").joinpath("viewer.bundle.js").read_text(encoding="utf-8")
    if glb is not None:
        glb_b64 = base64.b64encode(glb).decode("ascii")
        parts["preview3d"] = ('<div id="viewer"></div><p>Drag to orbit, scroll to zoom.</p>'
                              f'<script id="glb-data" type="application/octet-stream">{glb_b64}</script>')
    else:
        parts["preview3d"] = "<p>No GLB could be built for the 3D preview.</p>"
    titles = {"overview": "Input and generated scene", "classes": "Terrain classes", "detections": "Detections",
              "objects": "Objects and their assets", "terrain": "Height map and shore profile",
              "piers": "Pier structures", "vegetation": "Vegetation density per class",
              "metrics": "Metrics against the truth", "provenance": "Timings, command and versions",
              "preview3d": "3D preview"}
    nav = "".join(f'<a href="#sec-{k}">{titles[k]}</a>' for k in SECTIONS)
    body = "".join(f'<section id="sec-{k}"><h2>{titles[k]}</h2>{parts[k]}</section>' for k in SECTIONS)
    counts: dict[str, int] = {}
    for o in scene.objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    summary = ", ".join(f"{v} {k}" for k, v in counts.items()) or "no objects"
    page = f"""<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"/>
<title>coastforge report: {html.escape(scene.name)}</title><style>{CSS}</style></head><body>
<header><h1>coastforge — {html.escape(scene.name)}</h1><p>{scene.extent_m[0]:.0f} × {scene.extent_m[1]:.0f} m at
{scene.gsd_m:.3f} m/px · {summary} · {len(scene.vegetation) if scene.vegetation is not None else 0} vegetation
instances</p></header><nav>{nav}</nav>{body}
<script>{bundle}</script>
<script>
(function () {{
  var data = document.getElementById('glb-data');
  var el = document.getElementById('viewer');
  if (!data || !el || !window.CoastforgeViewer) return;
  window.CoastforgeViewer.show(el, data.textContent.trim()).catch(function (e) {{ console.error(e); }});
}})();
</script></body></html>"""
    out_path = Path(out) if out else scene_dir / "report.html"
    atomic_write_text(out_path, page)
    return out_path
