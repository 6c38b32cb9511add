"""report.html: what a user looks at — one self-contained page that works offline from the file system.

Images are embedded as data URIs; the 3D preview is the scene's GLB (base64) shown by a vendored three.js
bundle (a classic script: browsers refuse ES-module imports from file:// pages). Nothing is fetched.
"""

from __future__ import annotations

import base64
import html
import json
import math
import time
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..classes import CLASS_NAMES, EVALUATED_CATEGORIES, N_CLASSES, PALETTE, colorize
from ..errors import InputError, OutputExistsError
from ..fsio import atomic_write_text
from ..scene import Scene, SceneObject, load_scene

MAX_PX = 1400  # big pictures are shown at most this wide: keeps a 100-object report far under 15 MB
TOP_MAX_PX = 768  # the generated scene rendered from above (shown at half the page width; costs per pixel)
THUMB_PX = 96  # crop / asset thumbnails in the objects table
SECTIONS = ("overview", "classes", "detections", "objects", "terrain", "piers", "vegetation", "metrics",
            "provenance",
            "preview3d")
TITLES = {"overview": "Input and generated scene", "classes": "Terrain classes", "detections": "Detections",
          "objects": "Objects and their assets", "terrain": "Height map and shore profile",
          "piers": "Pier structures", "vegetation": "Vegetation density per class",
          "metrics": "Metrics against the truth", "provenance": "Timings, command and versions",
          "preview3d": "3D preview"}
DET_COLOURS = {"boat": (255, 90, 40), "vehicle": (255, 215, 0), "pier_walkway": (40, 200, 255),
               "pier_finger": (120, 255, 200), "buoy": (255, 0, 255)}
SHORE_COLOURS = {"beach": "#d99a1e", "revetment": "#8c5a3c", "quay": "#d62728", "bank": "#2ca02c"}


# ----------------------------------------------------------------------------- small helpers


def _data_uri(rgb: np.ndarray, fmt: str = "jpeg", quality: int = 85) -> str:
    import cv2

    a = rgb if rgb.ndim == 2 else np.ascontiguousarray(rgb[:, :, ::-1])
    ok, buf = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", a,
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
    return cv2.resize(rgb, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def _upscale_small(rgb: np.ndarray, min_px: int = 700) -> np.ndarray:
    """Small images (tests, tiny scenes) upscaled with nearest pixels: overlays drawn on them stay legible."""
    import cv2

    f = int(np.ceil(min_px / max(rgb.shape[:2])))
    if f <= 1:
        return rgb
    return cv2.resize(rgb, (rgb.shape[1] * f, rgb.shape[0] * f), interpolation=cv2.INTER_NEAREST)


def _resize_to(a: np.ndarray, shape: tuple[int, int], nearest: bool = False) -> np.ndarray:
    import cv2

    if a.shape[:2] == shape:
        return a
    return cv2.resize(a, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_AREA)


def _img(uri: str, caption: str, cls: str = "") -> str:
    return (f'<figure class="{cls}"><img decoding="async" src="{uri}" alt="{html.escape(caption)}" '
            'title="click to enlarge"/>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _table(header: list[str] | None, rows: list[list], cls: str = "") -> str:
    th = "<thead><tr>" + "".join(f"<th>{h}</th>" for h in header) + "</tr></thead>" if header else ""
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}">{th}<tbody>{body}</tbody></table>'


def _fmt(v, nd: int = 3) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        return "—" if not np.isfinite(v) else f"{float(v):.{nd}f}"
    return html.escape(str(v))


def _note(text: str) -> str:
    return f'<p class="note">{text}</p>'


def _rgb_css(c) -> str:
    return "rgb({},{},{})".format(*(int(v) for v in c))


# ----------------------------------------------------------------------------- inputs


def _read_rgb(path: Path) -> np.ndarray | None:
    import cv2

    a = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return None if a is None else a[:, :, ::-1].copy()


def _input_image(scene: Scene, scene_dir: Path) -> tuple[np.ndarray | None, str]:
    """The input image (from provenance, else image.png beside the scene) and where it came from."""
    src = (scene.provenance.get("input") or {}).get("image")
    cands = []
    if src:
        p = Path(src)
        cands += [p] if p.is_absolute() else [p, scene_dir / p]
    for im in scene.provenance.get("images") or []:  # a synth truth folder: its rendered images
        if isinstance(im, dict) and im.get("path"):
            cands.append(scene_dir / str(im["path"]))
    cands.append(scene_dir / "image.png")
    for c in cands:
        if c.is_file():
            a = _read_rgb(c)
            if a is not None:
                return a, str(c)
    return None, ""


def _detections(scene_dir: Path) -> list[dict]:
    p = scene_dir / "detections.json"
    if not p.is_file():
        return []
    try:
        return list(json.loads(p.read_text()).get("detections", []))
    except (ValueError, AttributeError):
        return []


def match_objects_to_decisions(objects: list[SceneObject], matches: list[dict]) -> dict[str, dict]:
    """Object id → its entry of ``provenance["matches"]``.

    An explicit link wins (``attrs["match"]``: the decision's detection ``index``); otherwise objects made
    from detections are paired with the decisions in order (generate places them in decision order), and
    an object whose asset disagrees takes the first unused decision with its asset and the closest yaw."""
    by_det = {m.get("index"): m for m in matches if isinstance(m, dict)}
    out: dict[str, dict] = {}
    used: set[int] = set()
    rest = []
    for o in objects:
        k = o.attrs.get("match")
        m = by_det.get(k) if isinstance(k, int) else None
        if m is not None and m.get("asset_id") == o.asset_id:
            out[o.id] = m
            used.add(id(m))
        elif o.source == "detection":
            rest.append(o)
    free = [m for m in matches if isinstance(m, dict) and id(m) not in used]
    j = 0
    for o in rest:
        if j < len(free) and free[j].get("asset_id") == o.asset_id and id(free[j]) not in used:
            m = free[j]
            j += 1
        else:
            same = [m for m in free if id(m) not in used and m.get("asset_id") == o.asset_id]
            if not same:
                continue
            m = min(same, key=lambda m: abs(((float(m.get("yaw_deg", 0)) - o.yaw_deg + 180) % 360) - 180))
        out[o.id] = m
        used.add(id(m))
    return out


def _library_config(provenance: dict):
    """The scene's ``config.library`` (the defaults when it has none or one this version cannot read)."""
    from ..config import Config, LibraryConfig, apply_settings
    from ..errors import ConfigError

    given = (provenance.get("config") or {}).get("library") or {}
    try:
        return apply_settings(Config(), {"library": given}).library
    except ConfigError:
        return LibraryConfig()


class _Assets:
    """Meshes and top views of the scene's assets: its library when it can be loaded, else the starter kit."""

    def __init__(self, scene: Scene, library=None):
        self.lib = library
        self._views: dict = {}
        if library is not None:  # the caller's (generate's), already loaded
            return
        lib_path = scene.provenance.get("library")
        try:
            from ..assets import library as lib_mod

            if lib_path and lib_path not in ("starter-kit", "kit") and Path(lib_path).is_dir():
                self.lib = lib_mod.Library.load(lib_path)
            else:  # the starter kit as the run built it (its config.library)
                self.lib = lib_mod.default_library(_library_config(scene.provenance))
        except Exception:  # noqa: BLE001 - the report still renders without asset pictures
            self.lib = None
        self._views: dict = {}

    def mesh(self, asset_id: str):
        if self.lib is not None:
            try:
                return self.lib.mesh(asset_id)
            except Exception:  # noqa: BLE001 - fall back to the kit below
                pass
        from ..assets.kit import load_kit_mesh

        return load_kit_mesh(asset_id)

    def view(self, asset_id: str, background: str) -> np.ndarray | None:
        key = (asset_id, background)
        if key not in self._views:
            v = None
            if self.lib is not None:
                try:
                    from ..matching import asset_top_view

                    v = asset_top_view(self.lib, asset_id, background)[0]
                except Exception:  # noqa: BLE001 - an asset without a view only loses its thumbnail
                    v = None
            self._views[key] = v
        return self._views[key]


# ----------------------------------------------------------------------------- sections


def top_gsd(gsd_m: float, extent_m) -> float:
    """The metres per pixel of the report's render from above. It is shown beside the input at half the page
    width (~550 px; ``TOP_MAX_PX`` leaves room to enlarge it), and the procedural terrain costs per pixel."""
    return max(float(gsd_m), max(float(v) for v in extent_m) / TOP_MAX_PX)


def _render_top(scene: Scene, assets: _Assets, terrain=None) -> np.ndarray | None:
    try:
        from ..render import render_scene
    except ImportError:
        return None
    gsd = top_gsd(scene.gsd_m, scene.extent_m)
    cache: dict = {}

    def mesh_for(aid):
        if aid not in cache:
            cache[aid] = assets.mesh(aid)
        return cache[aid]

    try:
        return render_scene(scene, mesh_for, gsd, seed=scene.seed, terrain=terrain)
    except Exception:  # noqa: BLE001 - no top render (e.g. a missing mesh) rather than no report
        return None


def _overview(image, top) -> str:
    row = []
    if image is not None:
        row.append(_img(_data_uri(_fit(image)), "Input image"))
    if top is not None:
        row.append(_img(_data_uri(_fit(top)),
                        "Generated scene rendered from above (terrain, assets, vegetation)"))
    if not row:
        return _note("Neither the input image nor a render is available.")
    return '<div class="pair">' + "".join(row) + "</div>"


def _confidence_figure(scene_dir: Path, shape: tuple[int, int] | None) -> str:
    """The segmentation's per-pixel confidence and which source decided each pixel, when written."""
    import cv2

    from ..fsio import read_png
    from ..segmentation.learned import SOURCE_NAMES

    seg = scene_dir / "segmentation"
    figs = []
    if (seg / "confidence.png").is_file():
        conf = read_png(seg / "confidence.png")
        col = cv2.applyColorMap(255 - np.ascontiguousarray(conf, np.uint8), cv2.COLORMAP_INFERNO)[..., ::-1]
        if shape is not None:
            col = _resize_to(col, shape)
        figs.append(_img(_data_uri(_fit(col)), f"Segmentation confidence (dark = sure, light = unsure; mean "
                                              f"{np.mean(conf) / 2.55:.0f} %)"))
    if (seg / "source.png").is_file():
        src = read_png(seg / "source.png")
        pal = np.array([[200, 200, 200], [40, 110, 220], [230, 130, 30], [220, 40, 160]], np.uint8)
        col = pal[np.clip(src, 0, 3)]
        if shape is not None:
            col = _resize_to(col, shape, nearest=True)
        share = ", ".join(f"{n} {100 * np.mean(src == i):.1f} %" for i, n in enumerate(SOURCE_NAMES))
        figs.append(_img(_data_uri(_fit(col), "png"), "Who decided each pixel: grey both agree, blue the "
                         "network (outvoting the classical segmenter, or alone at GSDs where the rules get no "
                         "weight), orange the classical segmenter outvoted the network, magenta moored boats "
                         f"made it water ({share})"))
    return '<div class="pair">' + "".join(figs) + "</div>" if figs else ""


def _warnings_block(scene: Scene) -> str:
    """The self-check's warnings (``coastforge.selfcheck``) and what the stages' reconciliation changed."""
    prov = scene.provenance or {}
    items = [f"<li><b>{html.escape(w.get('message', ''))}</b> {html.escape(w.get('hint', ''))}</li>"
             for w in prov.get("warnings") or []]
    out = ""
    if items:
        out += ('<div class="warnbox"><b>This scene looks implausible:</b><ul>' + "".join(items) + "</ul></div>")
    rec = prov.get("consistency") or {}
    if rec:
        out += _note("Segmentation and detection reconciled: " + html.escape(
            ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in rec.items())) + ".")
    return out


def _classes_section(scene: Scene, base: np.ndarray | None, cleaned: np.ndarray | None,
                     scene_dir: Path | None = None) -> str:
    if scene.classes is None:
        return _note("No class map.")
    grid = scene.grid
    counts = np.bincount(scene.classes.ravel(), minlength=N_CLASSES)
    total = max(int(counts.sum()), 1)
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{_rgb_css(PALETTE[c])}"></i>{CLASS_NAMES[c]} '
        f'<small>{100 * counts[c] / total:.1f}% · {counts[c] * grid.gsd_m ** 2:,.0f} m²</small></span>'
        for c in range(N_CLASSES) if counts[c]) + "</div>"
    cm = colorize(scene.classes)
    if base is not None:
        cm = _resize_to(cm, base.shape[:2], nearest=True)
        # the class map sits on the image; a slider fades between them
        overlay = ('<figure><div class="stack"><img src="' + _data_uri(base) + '" alt="input image"/>'
                   '<img class="top" id="classmap-img" style="opacity:.55" src="' + _data_uri(cm, "png") +
                   '" alt="class map"/></div><figcaption>Terrain classes over the image — opacity '
                   '<input type="range" id="classmap-opacity" min="0" max="100" value="55"/>'
                   '</figcaption></figure>')
    else:
        overlay = _img(_data_uri(_fit(cm), "png"), "Terrain classes")
    figs = [overlay]
    if cleaned is not None:
        figs.append(_img(_data_uri(_fit(cleaned)), "Cleaned image (boats and vehicles removed, inpainted)"))
    conf = _confidence_figure(scene_dir, base.shape[:2] if base is not None else None) if scene_dir else ""
    return legend + '<div class="pair">' + "".join(figs) + "</div>" + conf


def _draw_detections(img: np.ndarray, dets: list[dict], scale: float, labels: dict[int, str]) -> np.ndarray:
    import cv2

    out = img.copy()
    th = max(1, round(out.shape[1] / 700))
    for i, d in enumerate(dets):
        try:
            c = DET_COLOURS.get(d["category"], (255, 255, 255))
            pts = np.round(np.asarray(d["corners_px"], float) * scale).astype(np.int32)
            cx, cy = float(d["cx_px"]) * scale, float(d["cy_px"]) * scale
        except (KeyError, TypeError, ValueError):
            continue
        cv2.polylines(out, [pts], True, c, th, cv2.LINE_AA)
        if d["category"] in ("boat", "vehicle"):
            r = np.deg2rad(float(d.get("yaw_deg", 0.0)))
            ln = max(float(d.get("length_px", 10)) * scale * 0.75, 8.0)
            tip = (round(cx + np.cos(r) * ln), round(cy - np.sin(r) * ln))  # image rows point south
            known = bool(d.get("heading_known"))
            cv2.arrowedLine(out, (round(cx), round(cy)), tip, c if known else (235, 235, 235), th + 1,
                            cv2.LINE_AA, tipLength=0.3)
        if i in labels:
            org = (round(pts[:, 0].max()) + 2, round(pts[:, 1].min()) + 8)
            font = cv2.FONT_HERSHEY_SIMPLEX
            cv2.putText(out, labels[i], org, font, 0.38 * th, (0, 0, 0), th + 2, cv2.LINE_AA)
            cv2.putText(out, labels[i], org, font, 0.38 * th, (255, 255, 255), th, cv2.LINE_AA)
    return out


def _detections_section(base, dets, scale, labels) -> str:
    if base is None:
        return _note("The input image is not available.")
    if not dets:
        return _note("No detections.json in the scene folder (or no detections).")
    cats: dict[str, int] = {}
    for d in dets:
        cats[d.get("category", "?")] = cats.get(d.get("category", "?"), 0) + 1
    known = sum(1 for d in dets if d.get("category") in ("boat", "vehicle") and d.get("heading_known"))
    movable = sum(1 for d in dets if d.get("category") in ("boat", "vehicle"))
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{_rgb_css(DET_COLOURS.get(k, (255, 255, 255)))}"></i>{html.escape(k)} '
        f"<small>{v}</small></span>" for k, v in sorted(cats.items())) + "</div>"
    return (legend + _note(f"{len(dets)} detections; heading known for {known} of {movable} boats/vehicles "
                           "(coloured arrow: known heading, white arrow: heading from the asset or "
                           "unresolved). "
                           "Labels are the row numbers of the objects table.")
            + _img(_data_uri(_draw_detections(base, dets, scale, labels)), "Detections with heading arrows",
                   "wide"))


def _objects_section(scene: Scene, image, assets: _Assets, links: dict[str, dict],
                     dets: list[dict]) -> tuple[str, str]:
    """The objects table and the CSS holding each asset view once (rows refer to it by class)."""
    from ..matching import crop_rotated

    objs = [o for o in scene.objects if o.category in EVALUATED_CATEGORIES]
    if not objs:
        return _note("No boats, vehicles or buoys were placed."), ""
    grid = scene.grid
    img_scale = (image.shape[1] / grid.width_px) if image is not None else 1.0
    img_gsd = grid.gsd_m / img_scale
    css: dict[tuple[str, str], str] = {}

    def asset_thumb(aid: str, bg: str, small: bool = False) -> str:
        key = (aid, bg)
        if key not in css:
            v = assets.view(aid, bg)
            css[key] = "" if v is None else _data_uri(_resize_to(v, (THUMB_PX, THUMB_PX)))
        if not css[key]:
            return '<span class="muted">no view</span>'
        n = list(css).index(key)
        return f'<span class="av av{n}{" small" if small else ""}" title="{html.escape(aid)}"></span>'

    rows = []
    for k, o in enumerate(objs):
        m = links.get(o.id)
        bg = "ground" if o.category == "vehicle" else "water"
        crop_html = '<span class="muted">—</span>'
        if image is not None:
            col, row = grid.to_pixel(o.x_m, o.y_m)
            side_px = max(o.length_m, o.width_m, 1.0) * 1.3 / img_gsd  # the asset views' framing
            crop = crop_rotated(image, float(col) * img_scale, float(row) * img_scale, o.yaw_deg, THUMB_PX,
                                THUMB_PX, THUMB_PX / side_px)
            crop_html = (f'<img class="thumb" decoding="async" src="{_data_uri(crop, quality=80)}" '
                         f'alt="crop of {html.escape(o.id)}"/>')
        runners = []
        for c in (m or {}).get("candidates", [])[:4]:
            if c.get("asset_id") == o.asset_id:
                continue
            runners.append(f'<div class="cand">{asset_thumb(c["asset_id"], bg, True)}'
                           f'<span>{html.escape(str(c["asset_id"]))}<br/>'
                           f'<small>{float(c.get("score", 0)):.3f}'
                           f'</small></span></div>')
            if len(runners) == 3:
                break
        ix = m.get("index") if m else None
        det = dets[ix] if isinstance(ix, int) and 0 <= ix < len(dets) else {}
        heading = (m or {}).get("heading_source") or o.attrs.get("heading") or "—"
        rows.append([
            f'<b>{k + 1}</b>', f'{html.escape(o.id)}<br/><small>{html.escape(o.category)}</small>',
            crop_html, asset_thumb(o.asset_id, bg), html.escape(o.asset_id),
            _fmt(float(m["score"]) if m and "score" in m else o.score, 3),
            _fmt(det.get("score", o.attrs.get("detector_score")), 2),
            f"{o.length_m:.1f} × {o.width_m:.1f}", f"{o.yaw_deg:.0f}°", html.escape(str(heading)),
            ('<div class="cands">' + "".join(runners) + "</div>") if runners
            else '<span class="muted">—</span>',
        ])
    linked = sum(1 for o in objs if o.id in links)
    head = ["#", "object", "image crop", "chosen asset", "asset id", "match score", "det. score",
            "size L × W (m)",
            "yaw", "heading from", "runner-up candidates (score)"]
    note = _note(f"{len(objs)} objects; {linked} linked to their matching decision. Crops are rotated so the "
                 "detected bow/front points right, like the asset views (seen from above at yaw 0).")
    style = "".join(f".av{n}{{background-image:url({uri})}}" for n, uri in enumerate(css.values()) if uri)
    return note + '<div class="scroll">' + _table(head, rows, "objects") + "</div>", style


def _load_sections(scene_dir: Path) -> list[dict]:
    p = scene_dir / "terrain_outputs" / "cross_section.json"
    if not p.is_file():
        return []
    try:
        secs = json.loads(p.read_text()).get("sections", [])
        return [s for s in secs
                if len(s.get("distance_m", [])) >= 2 and len(s["distance_m"]) == len(s["height_m"])]
    except (ValueError, AttributeError, KeyError, TypeError):
        return []


def _nice_ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    """About ``n`` round tick values (steps of 1, 2, 2.5 or 5 x 10^k) covering [lo, hi]."""
    span = hi - lo
    if not span > 0:
        return [lo]
    raw = span / max(n, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9))
    k0, k1 = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    return [round(k * step, 10) + 0.0 for k in range(k0, k1 + 1)]


def _tick(v: float) -> str:
    return f"{v:g}".replace("-", "\u2212")


def _svg_uri(body: str, width: float, height: float) -> str:
    """A self-contained SVG figure as a data URI (an <img>, so the page's lightbox enlarges it); text in
    the browser's own sans-serif font: nothing to embed or download."""
    svg = (f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
           f'viewBox="0 0 {width:.0f} {height:.0f}" width="{width:.0f}" height="{height:.0f}" '
           f'font-family="DejaVu Sans, Helvetica, Arial, sans-serif" font-size="12">'
           f'<rect width="100%" height="100%" fill="white"/>{body}</svg>')
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def _svg_axes(ml: float, mt: float, pw: float, ph: float, xr, yr, xlabel: str, ylabel: str, title: str,
              grid: bool = False) -> tuple[str, Callable, Callable]:
    """Frame, ticks, labels and title of a plot area; returns them and the data → SVG maps for x and y."""
    (x0, x1), (y0, y1) = xr, yr
    sx = lambda x: ml + (np.asarray(x, float) - x0) / (x1 - x0) * pw  # noqa: E731
    sy = lambda y: mt + (y1 - np.asarray(y, float)) / (y1 - y0) * ph  # noqa: E731
    out = []
    for t in _nice_ticks(x0, x1):
        u = float(sx(t))
        if grid:
            out.append(f'<line x1="{u:.1f}" y1="{mt}" x2="{u:.1f}" y2="{mt + ph}" stroke="#000" '
                       'stroke-opacity="0.12"/>')
        out.append(f'<line x1="{u:.1f}" y1="{mt + ph}" x2="{u:.1f}" y2="{mt + ph + 5}" stroke="#333"/>'
                   f'<text x="{u:.1f}" y="{mt + ph + 18}" text-anchor="middle">{_tick(t)}</text>')
    for t in _nice_ticks(y0, y1):
        v = float(sy(t))
        if grid:
            out.append(f'<line x1="{ml}" y1="{v:.1f}" x2="{ml + pw}" y2="{v:.1f}" stroke="#000" '
                       'stroke-opacity="0.12"/>')
        out.append(f'<line x1="{ml - 5}" y1="{v:.1f}" x2="{ml}" y2="{v:.1f}" stroke="#333"/>'
                   f'<text x="{ml - 8}" y="{v + 4:.1f}" text-anchor="end">{_tick(t)}</text>')
    out.append(f'<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>'
               f'<text x="{ml + pw / 2:.1f}" y="{mt + ph + 36}" text-anchor="middle">{html.escape(xlabel)}</text>'
               f'<text transform="translate({ml - 44},{mt + ph / 2:.1f}) rotate(-90)" text-anchor="middle">'
               f'{html.escape(ylabel)}</text>'
               f'<text x="{ml + pw / 2:.1f}" y="{mt - 10}" text-anchor="middle" font-size="14">'
               f'{html.escape(title)}</text>')
    return "".join(out), sx, sy


def _hillshade_figure(scene: Scene, sections: list[dict]) -> str:
    """The height map as a shaded relief (the terrain stage's colours), in metres, with a colour bar and the
    cross-section transects as arrows: an SVG data URI."""
    from ..terrain.outputs import colour_relief, hillshade_rgb

    z = np.nan_to_num(scene.height.astype(np.float32))
    grid = scene.grid
    step = max(1, int(np.ceil(max(z.shape) / 900)))
    zs = z[::step, ::step]
    w, h = scene.extent_m
    dmax = max(float(-zs.min()), 0.5)
    hmax = max(float(zs.max()), 2.0)  # hillshade_rgb's land ramp spans at least 2 m
    relief = _data_uri(hillshade_rgb(zs, grid.gsd_m * step, max_depth_m=dmax), quality=88)
    ml, mt, pw = 64.0, 34.0, 560.0
    ph = float(np.clip(pw * h / w, 200.0, 900.0))
    axes, sx, sy = _svg_axes(ml, mt, pw, ph, (-w / 2, w / 2), (-h / 2, h / 2), "x east (m)", "y north (m)",
                             f"Height map (shaded relief): {float(z.min()):.1f} m to {float(z.max()):.1f} m")
    body = [f'<image x="{ml}" y="{mt}" width="{pw}" height="{ph:.1f}" preserveAspectRatio="none" '
            f'href="{relief}" xlink:href="{relief}"/>', axes]
    for s in sections:
        (c0, r0), (c1, r1) = s["start_px"], s["end_px"]
        u0, v0 = ml + c0 / grid.width_px * pw, mt + r0 / grid.height_px * ph
        u1, v1 = ml + c1 / grid.width_px * pw, mt + r1 / grid.height_px * ph
        col = SHORE_COLOURS.get(s["shore_type"], "#d62728")
        ang = math.atan2(v1 - v0, u1 - u0)
        head = [(u1, v1), (u1 - 12 * math.cos(ang - 0.4), v1 - 12 * math.sin(ang - 0.4)),
                (u1 - 12 * math.cos(ang + 0.4), v1 - 12 * math.sin(ang + 0.4))]
        tu, tv = u0 + 0.25 * (u1 - u0), v0 + 0.25 * (v1 - v0)  # a quarter along: inside, off the shoreline
        label = html.escape(str(s["shore_type"]))
        body.append(f'<line x1="{u0:.1f}" y1="{v0:.1f}" x2="{u1:.1f}" y2="{v1:.1f}" stroke="{col}" '
                    f'stroke-width="2.4"/><polygon points="{" ".join(f"{a:.1f},{b:.1f}" for a, b in head)}" '
                    f'fill="{col}"/><circle cx="{u0:.1f}" cy="{v0:.1f}" r="4" fill="{col}" stroke="white"/>'
                    f'<rect x="{tu - 4 - 3.4 * len(label):.1f}" y="{tv - 9:.1f}" width="{8 + 6.8 * len(label):.1f}" '
                    f'height="17" rx="2" fill="{col}" fill-opacity="0.85"/><text x="{tu:.1f}" y="{tv + 4:.1f}" '
                    f'text-anchor="middle" fill="white" font-weight="bold" font-size="11">{label}</text>')
    # colour bar: water (depth) below the middle, land (height) above, as the relief's two ramps
    bx, bw, bh = ml + pw + 18, 16.0, ph * 0.85
    by = mt + (ph - bh) / 2
    fr = np.linspace(0.0, 1.0, 25)  # position up the bar
    vals = np.where(fr < 0.5, -dmax * (1 - 2 * fr), hmax * (2 * fr - 1)).astype(np.float32)
    vals[12] = -1e-6  # the middle: the shallowest water colour
    cols = colour_relief(vals[None], dmax, max_height_m=hmax)[0]
    stops = "".join(f'<stop offset="{1 - f:.3f}" stop-color="rgb({r:.0f},{g:.0f},{b:.0f})"/>'
                    for f, (r, g, b) in zip(fr[::-1], cols[::-1]))
    body.append(f'<defs><linearGradient id="cbar" x1="0" y1="0" x2="0" y2="1">{stops}'
                f'</linearGradient></defs><rect x="{bx}" y="{by:.1f}" width="{bw}" height="{bh:.1f}" '
                f'fill="url(#cbar)" stroke="#333"/>')
    for t in [*_nice_ticks(-dmax, 0.0, 4), *_nice_ticks(0.0, hmax, 4)[1:]]:
        f = 0.5 * (1 + t / hmax) if t > 0 else 0.5 * (1 - t / -dmax) if t < 0 else 0.5
        v = by + (1 - f) * bh
        body.append(f'<line x1="{bx + bw}" y1="{v:.1f}" x2="{bx + bw + 4}" y2="{v:.1f}" stroke="#333"/>'
                    f'<text x="{bx + bw + 7}" y="{v + 4:.1f}">{_tick(t)}</text>')
    body.append(f'<text transform="translate({bx + bw + 58},{mt + ph / 2:.1f}) rotate(-90)" '
                'text-anchor="middle" font-size="11">height (m); 0 = water level, below = bathymetry</text>')
    return _svg_uri("".join(body), ml + pw + 120, mt + ph + 48)


def _profiles_figure(scene: Scene, sections: list[dict]) -> tuple[str, str]:
    """The shore cross-sections in side view (or, without them, the centre row and column where they cross
    the shore): an SVG data URI and its caption."""
    z = scene.height
    w, h = scene.extent_m
    lines = []  # (label, colour, distances, heights)
    if sections:
        for s in sections:
            lines.append((f"{s['shore_type']} shore", SHORE_COLOURS.get(s["shore_type"], "#1f77b4"),
                          np.asarray(s["distance_m"], float), np.asarray(s["height_m"], float)))
        title = "Shore cross-sections (side view), one per shore type"
        xlabel = "distance from the shoreline (m): \u2190 inland | offshore \u2192"
        cap = "Shore cross-sections from the terrain stage (transects drawn as arrows on the height map)"
    else:
        for label, prof, length, col in (("west \u2192 east through the centre", z[z.shape[0] // 2, :], w, "#1f77b4"),
                                         ("south \u2192 north through the centre", z[::-1, z.shape[1] // 2], h,
                                          "#ff7f0e")):
            prof = np.nan_to_num(np.asarray(prof, float))
            if prof.min() < 0 < prof.max():
                lines.append((label, col, np.linspace(-length / 2, length / 2, prof.size), prof))
        title = "Cross-section through the scene centre" + ("" if lines else ": no line crosses the shore")
        xlabel = "position along the line (m)"
        cap = "Cross-section through the scene centre (no terrain_outputs/cross_section.json found)"
    if lines:
        d0 = min(float(d.min()) for _, _, d, _ in lines)
        d1 = max(float(d.max()) for _, _, d, _ in lines)
        lo = min(float(hh.min()) for *_, hh in lines)
        hi = max(float(hh.max()) for *_, hh in lines)
    else:
        d0, d1, lo, hi = -w / 2, w / 2, -1.0, 1.0
    y0, y1 = min(lo, 0.0) - 0.5, max(hi, 0.0) + 0.5
    if d1 <= d0:
        d1 = d0 + 1.0
    ml, mt, pw, ph = 64.0, 34.0, 620.0, 300.0
    axes, sx, sy = _svg_axes(ml, mt, pw, ph, (d0, d1), (y0, y1), xlabel, "height (m)", title, grid=True)
    v0 = float(sy(0.0))
    body = [f'<rect x="{ml}" y="{v0:.1f}" width="{pw}" height="{mt + ph - v0:.1f}" fill="#9ecae1" '
            'fill-opacity="0.35"/>', axes,
            f'<line x1="{ml}" y1="{v0:.1f}" x2="{ml + pw}" y2="{v0:.1f}" stroke="#1f77b4" stroke-dasharray="6 4"/>']
    if d0 < 0 < d1 and sections:
        u = float(sx(0.0))
        body.append(f'<line x1="{u:.1f}" y1="{mt}" x2="{u:.1f}" y2="{mt + ph}" stroke="#555" '
                    'stroke-dasharray="2 3"/>')
    for _, col, d, hh in lines:
        keep = np.linspace(0, d.size - 1, min(d.size, 800)).astype(int)  # plenty for 620 px
        pts = " ".join(f"{u:.1f},{v:.1f}" for u, v in zip(sx(d[keep]), sy(hh[keep])))
        body.append(f'<polyline points="{pts}" fill="none" stroke="{col}" stroke-width="2" '
                    'stroke-linejoin="round"/>')
    legend = [(label, col, "") for label, col, _, _ in lines] + [("water level", "#1f77b4", "6 4")]
    lw = 14 + 6.6 * max(len(lb) for lb, _, _ in legend) + 34
    lx, ly = ml + pw - lw - 8, mt + 8
    body.append(f'<rect x="{lx:.1f}" y="{ly}" width="{lw:.1f}" height="{8 + 17 * len(legend)}" fill="white" '
                'fill-opacity="0.85" stroke="#bbb"/>')
    for k, (label, col, dash) in enumerate(legend):
        yy = ly + 14 + 17 * k
        body.append(f'<line x1="{lx + 8:.1f}" y1="{yy - 4}" x2="{lx + 34:.1f}" y2="{yy - 4}" stroke="{col}" '
                    f'stroke-width="2" stroke-dasharray="{dash or "none"}"/>'
                    f'<text x="{lx + 40:.1f}" y="{yy}" font-size="11">{html.escape(label)}</text>')
    return _svg_uri("".join(body), ml + pw + 20, mt + ph + 48), cap


def _terrain_section(scene: Scene, scene_dir: Path) -> str:
    """The height map with the shore transects, and the transects in side view: inline SVG figures (no
    plotting library: they cost milliseconds and stay sharp when enlarged)."""
    if scene.height is None:
        return _note("No height map.")
    sections = _load_sections(scene_dir)
    hill = _hillshade_figure(scene, sections)
    prof, cap = _profiles_figure(scene, sections)
    return ('<div class="pair">' + _img(hill, "Height map with land and bathymetry") + _img(prof, cap)
            + "</div>")


def _pier_graph(piers: list[SceneObject], tol_m: float = 0.5):
    from shapely import STRtree
    from shapely.geometry import Polygon

    polys = [o.footprint_m() for o in piers]
    shp = [Polygon(p) for p in polys]
    src, dst = STRtree(shp).query(shp, predicate="dwithin", distance=tol_m)
    edges = sorted((int(i), int(j)) for i, j in zip(src, dst) if i < j)
    return polys, edges


def _piers_section(scene: Scene, base: np.ndarray | None) -> str:
    import cv2

    from ..evaluate import pier_connectivity

    piers = [o for o in scene.objects if o.category == "pier"]
    if not piers:
        return _note("No pier structures in this scene.")
    conn = pier_connectivity(scene)
    grid = scene.grid
    polys, edges = _pier_graph(piers)
    # structures = connected components of the touch graph
    comp = list(range(len(piers)))

    def root(i):
        while comp[i] != i:
            comp[i] = comp[comp[i]]
            i = comp[i]
        return i

    for i, j in edges:
        comp[root(i)] = root(j)
    roots = sorted({root(i) for i in range(len(piers))})
    sid = {r: k for k, r in enumerate(roots)}
    bad = set(conn.get("disconnected_ids", []))
    # crop the picture to the piers (+ margin) so the segments are legible
    allp = np.concatenate(polys)
    x0, y0 = allp.min(0) - 12
    x1, y1 = allp.max(0) + 12
    img = base if base is not None else colorize(scene.classes if scene.classes is not None
                                                 else np.zeros(grid.shape, np.uint8))
    s = img.shape[1] / grid.width_px
    c0, r0 = grid.to_pixel(x0, y1)
    c1, r1 = grid.to_pixel(x1, y0)
    c0, r0 = max(0, int(c0 * s)), max(0, int(r0 * s))
    c1, r1 = min(img.shape[1], int(np.ceil(c1 * s))), min(img.shape[0], int(np.ceil(r1 * s)))
    crop = img[r0:r1, c0:c1]
    k = max(1.0, 1000 / max(crop.shape[:2]))
    crop = cv2.resize(crop, (round(crop.shape[1] * k), round(crop.shape[0] * k)),
                      interpolation=cv2.INTER_CUBIC)
    canvas = (crop * 0.6 + 100).astype(np.uint8)  # faded so the overlay reads

    def px(xy):
        c, r = grid.to_pixel(xy[..., 0], xy[..., 1])
        return np.stack([(c * s - c0) * k, (r * s - r0) * k], -1)

    cmap = [(31, 119, 180), (44, 160, 44), (148, 103, 189), (23, 190, 207), (188, 189, 34), (140, 86, 75),
            (227, 119, 194), (127, 127, 127), (255, 127, 14)]
    fill = canvas.copy()
    for i, (o, p) in enumerate(zip(piers, polys)):
        pts = np.round(px(p)).astype(np.int32)
        cv2.fillPoly(fill, [pts], cmap[sid[root(i)] % len(cmap)])
    canvas = cv2.addWeighted(fill, 0.75, canvas, 0.25, 0)
    for i, (o, p) in enumerate(zip(piers, polys)):
        pts = np.round(px(p)).astype(np.int32)
        cv2.polylines(canvas, [pts], True, (220, 30, 30) if o.id in bad else (20, 20, 20),
                      3 if o.id in bad else 1,
                      cv2.LINE_AA)
    centres = px(np.array([[o.x_m, o.y_m] for o in piers]))
    for i, j in edges:
        cv2.line(canvas, tuple(np.round(centres[i]).astype(int)), tuple(np.round(centres[j]).astype(int)),
                 (255, 255, 255), 2, cv2.LINE_AA)
    for c in centres:
        cv2.circle(canvas, tuple(np.round(c).astype(int)), 4, (0, 0, 0), -1, cv2.LINE_AA)
        cv2.circle(canvas, tuple(np.round(c).astype(int)), 3, (255, 255, 255), -1, cv2.LINE_AA)
    rows = []
    from ..evaluate import touches_land  # the same land test as the metric
    from shapely.geometry import Polygon

    for r in roots:
        members = [i for i in range(len(piers)) if root(i) == r]
        land = any(touches_land(scene, Polygon(polys[i]).buffer(0.5)) for i in members)
        kinds: dict[str, int] = {}
        for i in members:
            kinds[piers[i].asset_id] = kinds.get(piers[i].asset_id, 0) + 1
        swatch = f'<i class="sw" style="background:{_rgb_css(cmap[sid[r] % len(cmap)])}"></i>'
        rows.append([f"{swatch}{sid[r] + 1}", str(len(members)),
                     f"{sum(piers[i].length_m * piers[i].width_m for i in members):.0f}",
                     ", ".join(f"{html.escape(a)} × {n}" for a, n in kinds.items()),
                     '<span class="ok">yes</span>' if land else '<span class="bad">no</span>',
                     str(sum(1 for i in members if piers[i].id in bad))])
    ok = conn.get("all_connected")
    text = _note(f"{conn['n_segments']} segments in {conn['n_structures']} structures; segments connected "
                 f"{100 * (conn['segments_connected'] or 0):.0f}%, structures reaching land "
                 f"{100 * (conn['structures_on_land'] or 0):.0f}%: "
                 + ('<b class="ok">all connected</b>' if ok else '<b class="bad">not all connected</b>')
                 + ". Colours: one per structure; white lines join touching segments; red outlines: "
                 "disconnected segments.")
    return (text + '<div class="pair">' + _img(_data_uri(canvas), "Pier segments, structures and connections")
            + "<div>" + _table(["structure", "segments", "deck area (m²)", "assets", "reaches land",
                                "disconnected"], rows) + "</div></div>")


def _vegetation_section(scene: Scene) -> str:
    import cv2

    v = scene.vegetation
    if v is None or not len(v) or scene.classes is None:
        return _note("No vegetation or rock instances in this scene.")
    grid = scene.grid
    col, row = grid.to_pixel(v.x_m, v.y_m)
    ci = np.clip(np.asarray(col, float).astype(int), 0, grid.width_px - 1)
    ri = np.clip(np.asarray(row, float).astype(int), 0, grid.height_px - 1)
    cls = scene.classes[ri, ci]
    area = np.bincount(scene.classes.ravel(), minlength=N_CLASSES) * grid.gsd_m ** 2
    cats = sorted(set(str(a) for a in v.category))
    dens = {}
    rows = []
    for c in range(N_CLASSES):
        n = int(np.sum(cls == c))
        if area[c] == 0 and n == 0:
            continue
        d = 100 * n / area[c] if area[c] else 0.0
        dens[c] = d
        per = ", ".join(f"{html.escape(a)} {int(np.sum((cls == c) & (v.category == a)))}" for a in cats
                        if np.any((cls == c) & (v.category == a)))
        rows.append([f'<i class="sw" style="background:{_rgb_css(PALETTE[c])}"></i>{CLASS_NAMES[c]}',
                     f"{area[c]:,.0f}", str(n), f"{d:.2f}", per or '<span class="muted">—</span>'])
    top = max(dens.values()) or 1.0
    bars = "".join(
        f'<div class="bar"><span class="lab">{CLASS_NAMES[c]}</span><span class="track">'
        f'<span class="b" style="width:{100 * d / top:.1f}%;'
        f'background:{_rgb_css(PALETTE[c])}"></span></span><span class="val">{d:.2f}</span></div>'
        for c, d in dens.items())
    # instances over the (faded) class map, coloured by category
    base = _upscale_small(_fit(colorize(scene.classes), 900))
    s = base.shape[1] / grid.width_px
    pic = (base * 0.55 + 115).astype(np.uint8)
    ccols = [(0, 90, 0), (200, 30, 30), (120, 60, 200), (0, 0, 0), (230, 120, 0)]
    for k, a in enumerate(cats):
        sel = v.category == a
        for x, y in zip(np.asarray(col, float)[sel] * s, np.asarray(row, float)[sel] * s):
            cv2.circle(pic, (int(x), int(y)), 3, ccols[k % len(ccols)], -1, cv2.LINE_AA)
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{_rgb_css(ccols[k % len(ccols)])}"></i>{html.escape(a)} '
        f"<small>{int(np.sum(v.category == a))}</small></span>" for k, a in enumerate(cats)) + "</div>"
    return ('<div class="pair"><div>'
            + _note(f"{len(v)} instances; density in instances per 100 m² of each class.")
            + f'<div class="bars">{bars}</div>'
            + _table(["class", "area (m²)", "instances", "per 100 m²", "by category"], rows) + "</div>"
            + "<div>" + legend
            + _img(_data_uri(pic), "Vegetation and rock instances over the class map", "narrow")
            + "</div></div>")


METRIC_LABELS = {"n_truth": "truth objects", "n_pred": "predicted objects", "n_matched": "matched",
                 "xy_rmse_m": "position RMSE (m)", "rotation_rmse_deg": "rotation RMSE (°, mod 180)",
                 "orientation_rmse_deg": "orientation RMSE (°, full heading)", "recall": "recall",
                 "match_precision": "asset match precision", "match_precision_category": "category precision",
                 "detection_precision": "detection precision"}


def _metrics_section(scene: Scene, truth_path: str | None) -> str:
    if not truth_path:
        return _note("No truth scene given: run <code>coastforge report DIR --truth truth.json</code> "
                     "to compare.")
    from ..evaluate import evaluate_scenes

    m = evaluate_scenes(load_scene(truth_path), scene)
    cats = list(m.get("per_category", {}))
    rows = [[METRIC_LABELS.get(k, k), _fmt(m.get(k))] + [_fmt(m["per_category"][c].get(k)) for c in cats]
            for k in METRIC_LABELS if k in m]
    t = m.get("terrain") or {}
    trows = []
    for k, v in t.items():
        if isinstance(v, dict):  # e.g. per-class IoU: one line per class
            sw = lambda c: _rgb_css(PALETTE[CLASS_NAMES.index(c)])  # noqa: E731
            trows += [[f'{html.escape(k)}: <i class="sw" style="background:{sw(c)}"></i>{html.escape(c)}'
                       if c in CLASS_NAMES else f"{html.escape(k)}: {html.escape(str(c))}",
                       _fmt(x)] for c, x in v.items()]
        else:
            trows.append([html.escape(k), _fmt(v) if not isinstance(v, list) else html.escape(json.dumps(v))])
    p = m.get("piers") or {}
    prow = [[html.escape(k), _fmt(v) if not isinstance(v, list) else str(len(v))] for k, v in p.items()]
    return (_note(f"Against <code>{html.escape(str(truth_path))}</code>.") + '<div class="pair">'
            + "<div><h3>Objects</h3>" + _table(["metric", "all", *map(html.escape, cats)], rows) + "</div>"
            + "<div><h3>Terrain</h3>" + _table(["metric", "value"], trows)
            + "<h3>Piers</h3>" + _table(["metric", "value"], prow) + "</div></div>")


def _versions(scene: Scene) -> list[list[str]]:
    import platform
    import sys

    from .. import __version__

    p = scene.provenance
    three = ""
    try:
        lic = static_text("THREE_LICENSE.txt")
        three = lic.split("—")[0].strip()
    except (OSError, FileNotFoundError):
        pass
    return [["scene made by", _fmt(p.get("version") or p.get("tool"))],
            ["report made by", f"coastforge {__version__}"],
            ["python (scene / report)", f"{_fmt(p.get('python'))} / {platform.python_version()}"],
            ["numpy", np.__version__], ["3D viewer", html.escape(three or "three.js")],
            ["platform", _fmt(p.get("platform") or sys.platform)]]


def _provenance_section(scene: Scene, report_s: float) -> str:
    p = scene.provenance
    t = {k: float(v) for k, v in (p.get("timings_s") or {}).items() if isinstance(v, (int, float))}
    total = t.pop("total", None)
    top = max(t.values()) if t else 1.0
    bars = "".join(f'<div class="bar"><span class="lab">{html.escape(k)}</span><span class="track">'
                   f'<span class="b" style="width:'
                   f'{100 * v / top if top else 0:.1f}%"></span></span><span class="val">{v:.2f} s</span>'
                   '</div>'
                   for k, v in t.items())
    total_s = f"{total:.2f} s" if total is not None else f"{sum(t.values()) - report_s:.2f} s"
    info = [["command", f"<code>{html.escape(str(p.get('command') or '—'))}</code>"],
            ["seed", _fmt(scene.seed)],
            ["input", _fmt((p.get("input") or {}).get("image"))], ["library", _fmt(p.get("library"))],
            ["backends", html.escape(", ".join(f"{k}: {v}" for k, v in (p.get("backends") or {}).items())
                                     or "—")],
            *_versions(scene)]
    cfg = p.get("config")
    cfg_html = (f'<details><summary>configuration</summary>'
                f'<pre>{html.escape(json.dumps(cfg, indent=1))}</pre>'
                "</details>") if cfg else ""
    return ('<div class="pair"><div><h3>Stage timings</h3>'
            + (f'<div class="bars timings">{bars}</div>' if bars else _note("No timings recorded."))
            + _note(f"pipeline total {total_s}; this report took {report_s:.2f} s (wall clock on the machine "
                    "that ran it)")
            + "</div><div><h3>Run</h3>" + _table(None, info, "prov") + cfg_html + "</div></div>")


PREVIEW_MAX_BYTES = 4_500_000  # an exported GLB bigger than this is replaced by a lighter preview build
PREVIEW_VERTICES = 30_000
PREVIEW_TEXTURE_PX = 1024


def _glb_bytes(scene: Scene, scene_dir: Path, assets: _Assets,
               cleaned: np.ndarray | None = None) -> tuple[bytes | None, str]:
    """The GLB shown in the 3D view: the exported one when small enough, else one built with a lighter
    terrain (fewer vertices, smaller texture) so that the page stays light and loads fast."""
    d = scene_dir / "gltf"
    files = sorted(d.glob("*.glb")) if d.is_dir() else []
    if files and files[0].stat().st_size <= PREVIEW_MAX_BYTES:
        return files[0].read_bytes(), str(files[0].relative_to(scene_dir))
    why = (f"a lighter preview of {files[0].relative_to(scene_dir)} ({files[0].stat().st_size / 1e6:.1f} MB)"
           if files else "built for the report (no gltf export in the folder)")
    try:
        from ..config import ExportConfig
        from ..export import DefaultResolver, run_exporter

        cfg = ExportConfig(gltf_max_vertices=PREVIEW_VERTICES, texture_max_px=PREVIEW_TEXTURE_PX)
        resolver = DefaultResolver(library=assets.lib, scene_dir=scene_dir, texture=cleaned)
        built = run_exporter("gltf", scene, resolver, cfg)
        for name, data in built.items():
            if name.endswith(".glb"):
                return data, why
    except Exception:  # noqa: BLE001 - no 3D preview rather than no report
        pass
    return None, ""


def static_text(name: str) -> str:
    """A file of ``report/static``: the page's stylesheet and script, the 3D viewer bundle and its licence."""
    return resources.files(__package__).joinpath("static").joinpath(name).read_text(encoding="utf-8")


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
    assets = _Assets(scene, library)
    if image is not None:
        image_src = str((scene.provenance.get("input") or {}).get("image", ""))
    else:
        image, image_src = _input_image(scene, scene_dir)
    dets = _detections(scene_dir)
    objs = [o for o in scene.objects if o.category in EVALUATED_CATEGORIES]
    matches = [m for m in scene.provenance.get("matches", []) if isinstance(m, dict)]
    links = match_objects_to_decisions(objs, matches)
    row_of_det = {}
    for k, o in enumerate(objs):
        m = links.get(o.id)
        if m is not None and isinstance(m.get("index"), int):
            row_of_det[m["index"]] = str(k + 1)
    parts: dict[str, str] = {}
    base = _fit(image) if image is not None else None

    # The render from above and the 3D preview need the meshes, the class-map section and the preview the
    # inpainted image: a generate may still be making those beside the report. They are built in two
    # threads (mostly OpenCV and NumPy, which release the GIL), the other sections here meanwhile.
    def top_part() -> str:
        if wait is not None:
            wait("meshes")
        return _overview(image, _render_top(scene, assets, top_terrain))

    def cleaned_part():
        if wait is not None:
            wait("meshes")
        # the inpainted image: shown beside the class map and textures the 3D preview (None when absent)
        cleaned = wait("cleaned") if wait is not None else _read_rgb(scene_dir / "cleaned.png")
        if wait is not None:
            wait("segmentation")  # its confidence and source rasters
        return _guard("classes", _classes_section, scene, base, cleaned, scene_dir), _glb_bytes(scene, scene_dir, assets,
                                                                                    cleaned)

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="coastforge-report") as pool:
        top_job, cleaned_job = pool.submit(top_part), pool.submit(cleaned_part)
        say("detections")
        det_base = _upscale_small(base) if base is not None else None
        img_w = image.shape[1] if image is not None else grid.width_px
        det_scale = (det_base.shape[1] / img_w) if det_base is not None else 1.0
        parts["detections"] = _guard("detections", _detections_section, det_base, dets, det_scale,
                                     row_of_det)
        say("objects and asset views")
        objects_part = _guard("objects", _objects_section, scene, image, assets, links, dets)
        parts["objects"], asset_css = objects_part if isinstance(objects_part, tuple) else (objects_part, "")
        say("terrain")
        if wait is not None:
            wait("terrain")
        parts["terrain"] = _guard("terrain", _terrain_section, scene, scene_dir)
        say("piers and vegetation")
        parts["piers"] = _guard("piers", _piers_section, scene, base)
        parts["vegetation"] = _guard("vegetation", _vegetation_section, scene)
        if truth is not None:
            say("metrics against the truth")
        parts["metrics"] = _metrics_section(scene, str(truth) if truth is not None else None)
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
        parts["preview3d"] = _note("No GLB could be built for the 3D preview (run "
                                   "<code>coastforge export DIR "
                                   "--format gltf</code>).")
    parts["provenance"] = _provenance_section(scene, time.perf_counter() - t_start)
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
    warn = _warnings_block(scene)
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
