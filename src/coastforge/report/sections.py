"""The report's sections, each an HTML fragment built from the scene and what the run wrote beside it."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from ..classes import CLASS_NAMES, EVALUATED_CATEGORIES, N_CLASSES, PALETTE, colorize
from ..scene import Scene, SceneObject, load_scene
from .figures import hillshade_figure, profiles_figure
from .inputs import ReportAssets, read_cross_sections
from .markup import data_uri, figure, fit, fmt_value, note, resize_to, rgb_css, static_text, table, upscale_small

THUMB_PX = 96  # crop / asset thumbnails in the objects table
DET_COLOURS = {"boat": (255, 90, 40), "vehicle": (255, 215, 0), "pier_walkway": (40, 200, 255),
               "pier_finger": (120, 255, 200), "buoy": (255, 0, 255)}


def overview_section(image, top) -> str:
    row = []
    if image is not None:
        row.append(figure(data_uri(fit(image)), "Input image"))
    if top is not None:
        row.append(figure(data_uri(fit(top)),
                        "Generated scene rendered from above (terrain, assets, vegetation)"))
    if not row:
        return note("Neither the input image nor a render is available.")
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
            col = resize_to(col, shape)
        figs.append(figure(data_uri(fit(col)), f"Segmentation confidence (dark = sure, light = unsure; mean "
                                              f"{np.mean(conf) / 2.55:.0f} %)"))
    if (seg / "source.png").is_file():
        src = read_png(seg / "source.png")
        pal = np.array([[200, 200, 200], [40, 110, 220], [230, 130, 30], [220, 40, 160]], np.uint8)
        col = pal[np.clip(src, 0, 3)]
        if shape is not None:
            col = resize_to(col, shape, nearest=True)
        share = ", ".join(f"{n} {100 * np.mean(src == i):.1f} %" for i, n in enumerate(SOURCE_NAMES))
        figs.append(figure(data_uri(fit(col), "png"), "Who decided each pixel: grey both agree, blue the "
                         "network (outvoting the classical segmenter, or alone at GSDs where the rules get no "
                         "weight), orange the classical segmenter outvoted the network, magenta moored boats "
                         f"made it water ({share})"))
    return '<div class="pair">' + "".join(figs) + "</div>" if figs else ""


def warnings_block(scene: Scene) -> str:
    """The self-check's warnings (``coastforge.selfcheck``) and what the stages' reconciliation changed."""
    prov = scene.provenance or {}
    items = [f"<li><b>{html.escape(w.get('message', ''))}</b> {html.escape(w.get('hint', ''))}</li>"
             for w in prov.get("warnings") or []]
    out = ""
    if items:
        out += ('<div class="warnbox"><b>This scene looks implausible:</b><ul>' + "".join(items) + "</ul></div>")
    rec = prov.get("consistency") or {}
    if rec:
        out += note("Segmentation and detection reconciled: " + html.escape(
            ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in rec.items())) + ".")
    return out


def classes_section(scene: Scene, base: np.ndarray | None, cleaned: np.ndarray | None,
                     scene_dir: Path | None = None) -> str:
    if scene.classes is None:
        return note("No class map.")
    grid = scene.grid
    counts = np.bincount(scene.classes.ravel(), minlength=N_CLASSES)
    total = max(int(counts.sum()), 1)
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{rgb_css(PALETTE[c])}"></i>{CLASS_NAMES[c]} '
        f'<small>{100 * counts[c] / total:.1f}% · {counts[c] * grid.gsd_m ** 2:,.0f} m²</small></span>'
        for c in range(N_CLASSES) if counts[c]) + "</div>"
    cm = colorize(scene.classes)
    if base is not None:
        cm = resize_to(cm, base.shape[:2], nearest=True)
        # the class map sits on the image; a slider fades between them
        overlay = ('<figure><div class="stack"><img src="' + data_uri(base) + '" alt="input image"/>'
                   '<img class="top" id="classmap-img" style="opacity:.55" src="' + data_uri(cm, "png") +
                   '" alt="class map"/></div><figcaption>Terrain classes over the image — opacity '
                   '<input type="range" id="classmap-opacity" min="0" max="100" value="55"/>'
                   '</figcaption></figure>')
    else:
        overlay = figure(data_uri(fit(cm), "png"), "Terrain classes")
    figs = [overlay]
    if cleaned is not None:
        figs.append(figure(data_uri(fit(cleaned)), "Cleaned image (boats and vehicles removed, inpainted)"))
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


def detections_section(base, dets, scale, labels) -> str:
    if base is None:
        return note("The input image is not available.")
    if not dets:
        return note("No detections.json in the scene folder (or no detections).")
    cats: dict[str, int] = {}
    for d in dets:
        cats[d.get("category", "?")] = cats.get(d.get("category", "?"), 0) + 1
    known = sum(1 for d in dets if d.get("category") in ("boat", "vehicle") and d.get("heading_known"))
    movable = sum(1 for d in dets if d.get("category") in ("boat", "vehicle"))
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{rgb_css(DET_COLOURS.get(k, (255, 255, 255)))}"></i>{html.escape(k)} '
        f"<small>{v}</small></span>" for k, v in sorted(cats.items())) + "</div>"
    return (legend + note(f"{len(dets)} detections; heading known for {known} of {movable} boats/vehicles "
                           "(coloured arrow: known heading, white arrow: heading from the asset or "
                           "unresolved). "
                           "Labels are the row numbers of the objects table.")
            + figure(data_uri(_draw_detections(base, dets, scale, labels)), "Detections with heading arrows",
                   "wide"))


def objects_section(scene: Scene, image, assets: ReportAssets, links: dict[str, dict],
                     dets: list[dict]) -> tuple[str, str]:
    """The objects table and the CSS holding each asset view once (rows refer to it by class)."""
    from ..matching import crop_rotated

    objs = [o for o in scene.objects if o.category in EVALUATED_CATEGORIES]
    if not objs:
        return note("No boats, vehicles or buoys were placed."), ""
    grid = scene.grid
    img_scale = (image.shape[1] / grid.width_px) if image is not None else 1.0
    img_gsd = grid.gsd_m / img_scale
    css: dict[tuple[str, str], str] = {}

    def asset_thumb(aid: str, bg: str, small: bool = False) -> str:
        key = (aid, bg)
        if key not in css:
            v = assets.view(aid, bg)
            css[key] = "" if v is None else data_uri(resize_to(v, (THUMB_PX, THUMB_PX)))
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
            crop_html = (f'<img class="thumb" decoding="async" src="{data_uri(crop, quality=80)}" '
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
            fmt_value(float(m["score"]) if m and "score" in m else o.score, 3),
            fmt_value(det.get("score", o.attrs.get("detector_score")), 2),
            f"{o.length_m:.1f} × {o.width_m:.1f}", f"{o.yaw_deg:.0f}°", html.escape(str(heading)),
            ('<div class="cands">' + "".join(runners) + "</div>") if runners
            else '<span class="muted">—</span>',
        ])
    linked = sum(1 for o in objs if o.id in links)
    head = ["#", "object", "image crop", "chosen asset", "asset id", "match score", "det. score",
            "size L × W (m)",
            "yaw", "heading from", "runner-up candidates (score)"]
    intro = note(f"{len(objs)} objects; {linked} linked to their matching decision. Crops are rotated so the "
                 "detected bow/front points right, like the asset views (seen from above at yaw 0).")
    style = "".join(f".av{n}{{background-image:url({uri})}}" for n, uri in enumerate(css.values()) if uri)
    return intro + '<div class="scroll">' + table(head, rows, "objects") + "</div>", style


def terrain_section(scene: Scene, scene_dir: Path) -> str:
    """The height map with the shore transects, and the transects in side view: inline SVG figures (no
    plotting library: they cost milliseconds and stay sharp when enlarged)."""
    if scene.height is None:
        return note("No height map.")
    sections = read_cross_sections(scene_dir)
    hill = hillshade_figure(scene, sections)
    prof, cap = profiles_figure(scene, sections)
    return ('<div class="pair">' + figure(hill, "Height map with land and bathymetry") + figure(prof, cap)
            + "</div>")


def _pier_graph(piers: list[SceneObject], tol_m: float = 0.5):
    from shapely import STRtree
    from shapely.geometry import Polygon

    polys = [o.footprint_m() for o in piers]
    shp = [Polygon(p) for p in polys]
    src, dst = STRtree(shp).query(shp, predicate="dwithin", distance=tol_m)
    edges = sorted((int(i), int(j)) for i, j in zip(src, dst) if i < j)
    return polys, edges


def piers_section(scene: Scene, base: np.ndarray | None) -> str:
    import cv2

    from ..evaluate import pier_connectivity

    piers = [o for o in scene.objects if o.category == "pier"]
    dropped = int(((scene.provenance or {}).get("piers") or {}).get("dropped_floating") or 0)
    dropped_text = (f" {dropped} floating pier piece{'s' if dropped > 1 else ''} left out: the walkway to land "
                    "would have been longer than the deck found, so more likely a hull or a wake than a pier."
                    if dropped else "")
    if not piers:
        return note("No pier structures in this scene." + dropped_text)
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
    for i, (_o, p) in enumerate(zip(piers, polys)):
        pts = np.round(px(p)).astype(np.int32)
        cv2.fillPoly(fill, [pts], cmap[sid[root(i)] % len(cmap)])
    canvas = cv2.addWeighted(fill, 0.75, canvas, 0.25, 0)
    for o, p in zip(piers, polys):
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
        swatch = f'<i class="sw" style="background:{rgb_css(cmap[sid[r] % len(cmap)])}"></i>'
        rows.append([f"{swatch}{sid[r] + 1}", str(len(members)),
                     f"{sum(piers[i].length_m * piers[i].width_m for i in members):.0f}",
                     ", ".join(f"{html.escape(a)} × {n}" for a, n in kinds.items()),
                     '<span class="ok">yes</span>' if land else '<span class="bad">no</span>',
                     str(sum(1 for i in members if piers[i].id in bad))])
    ok = conn.get("all_connected")
    text = note(f"{conn['n_segments']} segments in {conn['n_structures']} structures; segments connected "
                 f"{100 * (conn['segments_connected'] or 0):.0f}%, structures reaching land "
                 f"{100 * (conn['structures_on_land'] or 0):.0f}%: "
                 + ('<b class="ok">all connected</b>' if ok else '<b class="bad">not all connected</b>')
                 + ". Colours: one per structure; white lines join touching segments; red outlines: "
                 "disconnected segments." + dropped_text)
    return (text + '<div class="pair">' + figure(data_uri(canvas), "Pier segments, structures and connections")
            + "<div>" + table(["structure", "segments", "deck area (m²)", "assets", "reaches land",
                                "disconnected"], rows) + "</div></div>")


def vegetation_section(scene: Scene) -> str:
    import cv2

    v = scene.vegetation
    if v is None or not len(v) or scene.classes is None:
        return note("No vegetation or rock instances in this scene.")
    grid = scene.grid
    col, row = grid.to_pixel(v.x_m, v.y_m)
    ci = np.clip(np.asarray(col, float).astype(int), 0, grid.width_px - 1)
    ri = np.clip(np.asarray(row, float).astype(int), 0, grid.height_px - 1)
    cls = scene.classes[ri, ci]
    area = np.bincount(scene.classes.ravel(), minlength=N_CLASSES) * grid.gsd_m ** 2
    cats = sorted({str(a) for a in v.category})
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
        rows.append([f'<i class="sw" style="background:{rgb_css(PALETTE[c])}"></i>{CLASS_NAMES[c]}',
                     f"{area[c]:,.0f}", str(n), f"{d:.2f}", per or '<span class="muted">—</span>'])
    top = max(dens.values()) or 1.0
    bars = "".join(
        f'<div class="bar"><span class="lab">{CLASS_NAMES[c]}</span><span class="track">'
        f'<span class="b" style="width:{100 * d / top:.1f}%;'
        f'background:{rgb_css(PALETTE[c])}"></span></span><span class="val">{d:.2f}</span></div>'
        for c, d in dens.items())
    # instances over the (faded) class map, coloured by category
    base = upscale_small(fit(colorize(scene.classes), 900))
    s = base.shape[1] / grid.width_px
    pic = (base * 0.55 + 115).astype(np.uint8)
    ccols = [(0, 90, 0), (200, 30, 30), (120, 60, 200), (0, 0, 0), (230, 120, 0)]
    for k, a in enumerate(cats):
        sel = v.category == a
        for x, y in zip(np.asarray(col, float)[sel] * s, np.asarray(row, float)[sel] * s):
            cv2.circle(pic, (int(x), int(y)), 3, ccols[k % len(ccols)], -1, cv2.LINE_AA)
    legend = '<div class="legend">' + "".join(
        f'<span><i style="background:{rgb_css(ccols[k % len(ccols)])}"></i>{html.escape(a)} '
        f"<small>{int(np.sum(v.category == a))}</small></span>" for k, a in enumerate(cats)) + "</div>"
    return ('<div class="pair"><div>'
            + note(f"{len(v)} instances; density in instances per 100 m² of each class.")
            + f'<div class="bars">{bars}</div>'
            + table(["class", "area (m²)", "instances", "per 100 m²", "by category"], rows) + "</div>"
            + "<div>" + legend
            + figure(data_uri(pic), "Vegetation and rock instances over the class map", "narrow")
            + "</div></div>")


METRIC_LABELS = {"n_truth": "truth objects", "n_pred": "predicted objects", "n_matched": "matched",
                 "xy_rmse_m": "position RMSE (m)", "rotation_rmse_deg": "rotation RMSE (°, mod 180)",
                 "orientation_rmse_deg": "orientation RMSE (°, full heading)", "recall": "recall",
                 "match_precision": "asset match precision", "match_precision_category": "category precision",
                 "detection_precision": "detection precision"}


def metrics_section(scene: Scene, truth_path: str | None) -> str:
    if not truth_path:
        return note("No truth scene given: run <code>coastforge report DIR --truth truth.json</code> "
                     "to compare.")
    from ..evaluate import evaluate_scenes

    m = evaluate_scenes(load_scene(truth_path), scene)
    cats = list(m.get("per_category", {}))
    rows = [[METRIC_LABELS.get(k, k), fmt_value(m.get(k))] + [fmt_value(m["per_category"][c].get(k)) for c in cats]
            for k in METRIC_LABELS if k in m]
    t = m.get("terrain") or {}
    trows = []
    for k, v in t.items():
        if isinstance(v, dict):  # e.g. per-class IoU: one line per class
            sw = lambda c: rgb_css(PALETTE[CLASS_NAMES.index(c)])  # noqa: E731
            trows += [[f'{html.escape(k)}: <i class="sw" style="background:{sw(c)}"></i>{html.escape(c)}'
                       if c in CLASS_NAMES else f"{html.escape(k)}: {html.escape(str(c))}",
                       fmt_value(x)] for c, x in v.items()]
        else:
            trows.append([html.escape(k), fmt_value(v) if not isinstance(v, list) else html.escape(json.dumps(v))])
    p = m.get("piers") or {}
    prow = [[html.escape(k), fmt_value(v) if not isinstance(v, list) else str(len(v))] for k, v in p.items()]
    return (note(f"Against <code>{html.escape(str(truth_path))}</code>.") + '<div class="pair">'
            + "<div><h3>Objects</h3>" + table(["metric", "all", *map(html.escape, cats)], rows) + "</div>"
            + "<div><h3>Terrain</h3>" + table(["metric", "value"], trows)
            + "<h3>Piers</h3>" + table(["metric", "value"], prow) + "</div></div>")


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
    return [["scene made by", fmt_value(p.get("version") or p.get("tool"))],
            ["report made by", f"coastforge {__version__}"],
            ["python (scene / report)", f"{fmt_value(p.get('python'))} / {platform.python_version()}"],
            ["numpy", np.__version__], ["3D viewer", html.escape(three or "three.js")],
            ["platform", fmt_value(p.get("platform") or sys.platform)]]


def provenance_section(scene: Scene, report_s: float) -> str:
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
            ["seed", fmt_value(scene.seed)],
            ["input", fmt_value((p.get("input") or {}).get("image"))], ["library", fmt_value(p.get("library"))],
            ["backends", html.escape(", ".join(f"{k}: {v}" for k, v in (p.get("backends") or {}).items())
                                     or "—")],
            *_versions(scene)]
    cfg = p.get("config")
    cfg_html = (f'<details><summary>configuration</summary>'
                f'<pre>{html.escape(json.dumps(cfg, indent=1))}</pre>'
                "</details>") if cfg else ""
    return ('<div class="pair"><div><h3>Stage timings</h3>'
            + (f'<div class="bars timings">{bars}</div>' if bars else note("No timings recorded."))
            + note(f"pipeline total {total_s}; this report took {report_s:.2f} s (wall clock on the machine "
                    "that ran it)")
            + "</div><div><h3>Run</h3>" + table(None, info, "prov") + cfg_html + "</div></div>")
