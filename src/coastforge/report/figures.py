"""The terrain figures as inline SVG (no plotting library): the height map with the shore transects, and
the transects in side view."""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Callable

import numpy as np

from ..scene import Scene
from .markup import data_uri

SHORE_COLOURS = {"beach": "#d99a1e", "revetment": "#8c5a3c", "quay": "#d62728", "bank": "#2ca02c"}


def nice_ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    """About ``n`` round tick values (steps of 1, 2, 2.5 or 5 x 10^k) covering [lo, hi]."""
    span = hi - lo
    if not span > 0:
        return [lo]
    raw = span / max(n, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9))
    k0, k1 = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    return [round(k * step, 10) + 0.0 for k in range(k0, k1 + 1)]


def tick(v: float) -> str:
    return f"{v:g}".replace("-", "\u2212")


def svg_uri(body: str, width: float, height: float) -> str:
    """A self-contained SVG figure as a data URI (an <img>, so the page's lightbox enlarges it); text in
    the browser's own sans-serif font: nothing to embed or download."""
    svg = (f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
           f'viewBox="0 0 {width:.0f} {height:.0f}" width="{width:.0f}" height="{height:.0f}" '
           f'font-family="DejaVu Sans, Helvetica, Arial, sans-serif" font-size="12">'
           f'<rect width="100%" height="100%" fill="white"/>{body}</svg>')
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def svg_axes(ml: float, mt: float, pw: float, ph: float, xr, yr, xlabel: str, ylabel: str, title: str,
              grid: bool = False) -> tuple[str, Callable, Callable]:
    """Frame, ticks, labels and title of a plot area; returns them and the data → SVG maps for x and y."""
    (x0, x1), (y0, y1) = xr, yr
    sx = lambda x: ml + (np.asarray(x, float) - x0) / (x1 - x0) * pw  # noqa: E731
    sy = lambda y: mt + (y1 - np.asarray(y, float)) / (y1 - y0) * ph  # noqa: E731
    out = []
    for t in nice_ticks(x0, x1):
        u = float(sx(t))
        if grid:
            out.append(f'<line x1="{u:.1f}" y1="{mt}" x2="{u:.1f}" y2="{mt + ph}" stroke="#000" '
                       'stroke-opacity="0.12"/>')
        out.append(f'<line x1="{u:.1f}" y1="{mt + ph}" x2="{u:.1f}" y2="{mt + ph + 5}" stroke="#333"/>'
                   f'<text x="{u:.1f}" y="{mt + ph + 18}" text-anchor="middle">{tick(t)}</text>')
    for t in nice_ticks(y0, y1):
        v = float(sy(t))
        if grid:
            out.append(f'<line x1="{ml}" y1="{v:.1f}" x2="{ml + pw}" y2="{v:.1f}" stroke="#000" '
                       'stroke-opacity="0.12"/>')
        out.append(f'<line x1="{ml - 5}" y1="{v:.1f}" x2="{ml}" y2="{v:.1f}" stroke="#333"/>'
                   f'<text x="{ml - 8}" y="{v + 4:.1f}" text-anchor="end">{tick(t)}</text>')
    out.append(f'<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>'
               f'<text x="{ml + pw / 2:.1f}" y="{mt + ph + 36}" text-anchor="middle">{html.escape(xlabel)}</text>'
               f'<text transform="translate({ml - 44},{mt + ph / 2:.1f}) rotate(-90)" text-anchor="middle">'
               f'{html.escape(ylabel)}</text>'
               f'<text x="{ml + pw / 2:.1f}" y="{mt - 10}" text-anchor="middle" font-size="14">'
               f'{html.escape(title)}</text>')
    return "".join(out), sx, sy


def hillshade_figure(scene: Scene, sections: list[dict]) -> str:
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
    relief = data_uri(hillshade_rgb(zs, grid.gsd_m * step, max_depth_m=dmax), quality=88)
    ml, mt, pw = 64.0, 34.0, 560.0
    ph = float(np.clip(pw * h / w, 200.0, 900.0))
    axes, _sx, _sy = svg_axes(ml, mt, pw, ph, (-w / 2, w / 2), (-h / 2, h / 2), "x east (m)", "y north (m)",
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
    for t in [*nice_ticks(-dmax, 0.0, 4), *nice_ticks(0.0, hmax, 4)[1:]]:
        f = 0.5 * (1 + t / hmax) if t > 0 else 0.5 * (1 - t / -dmax) if t < 0 else 0.5
        v = by + (1 - f) * bh
        body.append(f'<line x1="{bx + bw}" y1="{v:.1f}" x2="{bx + bw + 4}" y2="{v:.1f}" stroke="#333"/>'
                    f'<text x="{bx + bw + 7}" y="{v + 4:.1f}">{tick(t)}</text>')
    body.append(f'<text transform="translate({bx + bw + 58},{mt + ph / 2:.1f}) rotate(-90)" '
                'text-anchor="middle" font-size="11">height (m); 0 = water level, below = bathymetry</text>')
    return svg_uri("".join(body), ml + pw + 120, mt + ph + 48)


def profiles_figure(scene: Scene, sections: list[dict]) -> tuple[str, str]:
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
    axes, sx, sy = svg_axes(ml, mt, pw, ph, (d0, d1), (y0, y1), xlabel, "height (m)", title, grid=True)
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
    return svg_uri("".join(body), ml + pw + 20, mt + ph + 48), cap
