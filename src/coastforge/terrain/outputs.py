"""Terrain outputs: hillshade with a depth/elevation colour ramp, shore-type map, and shore cross-sections
(JSON + CSV data and a PNG side view). The heights themselves go into the scene (terrain/height.tif)."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from ..fsio import atomic_write_text, write_png

_TYPE_RGB = {"beach": (230, 210, 150), "revetment": (130, 120, 110), "quay": (70, 70, 70),
             "bank": (90, 170, 60)}
_TYPE_LINE = {"beach": (200, 150, 40), "revetment": (110, 100, 95), "quay": (30, 30, 30),
              "bank": (60, 140, 40)}


# ----------------------------------------------------------------------------- cross-sections


def _pick_transect(z, sd_px, weights_t, dominant, t, gsd, land_m, water_m):
    """The best straight transect through a shore stretch of type ``t``: perpendicular to the coast, crossing
    it once, staying in that type's zone. Returns (distances, heights, start, end) or None."""
    from scipy.ndimage import map_coordinates

    h, w = z.shape
    cand = np.flatnonzero(((np.abs(sd_px + 0.5) < 1e-3) & (dominant == t) & (weights_t >= 0.9)).ravel())
    if cand.size == 0:
        cand = np.flatnonzero(((np.abs(sd_px + 0.5) < 1e-3) & (dominant == t)).ravel())
    if cand.size == 0:
        return None
    cand = cand[np.linspace(0, cand.size - 1, min(cand.size, 200)).astype(int)]
    rows, cols = np.divmod(cand, w)
    k = 3  # the normal from the signed distance a few pixels either side (robust to pixel staircases)
    r0, r1 = np.clip(rows - k, 0, h - 1), np.clip(rows + k, 0, h - 1)
    c0, c1 = np.clip(cols - k, 0, w - 1), np.clip(cols + k, 0, w - 1)
    gx = (sd_px[rows, c1] - sd_px[rows, c0]) / np.maximum(c1 - c0, 1)
    gy = (sd_px[r1, cols] - sd_px[r0, cols]) / np.maximum(r1 - r0, 1)
    norm = np.hypot(gx, gy)
    ok = norm > 1e-6
    if not ok.any():
        return None
    rows, cols, gx, gy, norm = rows[ok], cols[ok], gx[ok] / norm[ok], gy[ok] / norm[ok], norm[ok]
    step = 1.0  # one sample per pixel
    s_px = np.arange(-land_m / gsd, water_m / gsd + step, step)
    # the shoreline is half a pixel offshore of the shore-land pixel centre
    pc = cols[:, None] + 0.5 * gx[:, None] + s_px[None] * gx[:, None]
    pr = rows[:, None] + 0.5 * gy[:, None] + s_px[None] * gy[:, None]
    inside = (pc >= 0) & (pc <= w - 1) & (pr >= 0) & (pr <= h - 1)
    ic, ir = np.clip(np.rint(pc), 0, w - 1).astype(int), np.clip(np.rint(pr), 0, h - 1).astype(int)
    sd_s = sd_px[ir, ic]
    # a good transect follows the distance field (|sd| ≈ |s|, one crossing) and stays in this type's zone
    follows = np.abs(sd_s - s_px[None]) <= 2.0 + 0.1 * np.abs(s_px[None])
    in_type = weights_t[ir, ic] >= 0.5
    good = inside & follows & in_type
    # keep, per transect, the unbroken run of good samples through the shoreline (s = 0)
    i0 = int(np.argmin(np.abs(s_px)))
    bad = ~good
    n = s_px.size
    left = np.where(bad[:, :i0 + 1].any(axis=1), i0 - np.argmax(bad[:, i0::-1], axis=1) + 1, 0)
    right = np.where(bad[:, i0:].any(axis=1), i0 + np.argmax(bad[:, i0:], axis=1), n)
    # prefer transects with a long land side: offshore runs are long almost everywhere
    length = np.where(good[:, i0], 2 * (i0 - left) + (right - i0), 0)
    i = int(np.argmax(length))
    if length[i] < 4:
        return None
    keep = np.zeros(n, bool)
    keep[left[i]:right[i]] = True
    s = s_px[keep] * gsd
    zz = map_coordinates(z, [pr[i][keep], pc[i][keep]], order=1, mode="nearest")
    idx = np.flatnonzero(keep)
    start = (float(pc[i][idx[0]]), float(pr[i][idx[0]]))
    end = (float(pc[i][idx[-1]]), float(pr[i][idx[-1]]))
    return s, zz.astype(np.float32), start, end


def cross_sections(z: np.ndarray, shore, ids: np.ndarray | None = None, land_m: float = 40.0,
                   water_m: float = 80.0) -> tuple:
    """One shore-perpendicular transect per shore type present (empty when the image has no coastline)."""
    from . import CrossSection
    from .default import SHORE_TYPES

    if not shore.has_shore:
        return ()
    gsd = shore.gsd_m
    sd_px = np.where(shore.water, shore.dist_m, -shore.dist_m) / gsd
    out = []
    for t in shore.present():
        picked = _pick_transect(z, sd_px, shore.weights[t], shore.dominant, t, gsd, land_m, water_m)
        if picked is None:
            continue
        s, zz, start, end = picked
        out.append(CrossSection(SHORE_TYPES[t], s.astype(np.float32), zz, start, end))
    return tuple(out)


def cross_section_json(sections) -> str:
    return json.dumps({"format": "coastforge.cross_section/1", "distance": "metres, negative inland, "
                       "positive offshore, 0 at the shoreline", "height": "metres above the water level",
                       "sections": [s.to_dict() for s in sections]}, indent=1) + "\n"


def cross_section_csv(sections) -> str:
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(["shore_type", "distance_m", "height_m"])
    for s in sections:
        for d, zz in zip(s.distance_m, s.height_m):
            wr.writerow([s.shore_type, f"{float(d):.3f}", f"{float(zz):.4f}"])
    return buf.getvalue()


def cross_section_plot(sections, width_px: int = 900, height_px: int = 450,
                       engine: str = "opencv") -> np.ndarray:
    """A side view of the cross-sections (RGB uint8). ``engine``: "opencv" (fast, always there),
    "matplotlib", or "auto" (matplotlib when installed; its import costs ~1.5 s of CPU)."""
    if engine not in ("opencv", "matplotlib", "auto"):
        raise ValueError(f"plot engine {engine!r} must be opencv, matplotlib or auto")
    if engine == "opencv":
        return _plot_cv2(sections, width_px, height_px)
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError:
        if engine == "matplotlib":
            from ..errors import BackendUnavailable

            raise BackendUnavailable("the matplotlib plot engine needs matplotlib; pip install matplotlib") from None
        return _plot_cv2(sections, width_px, height_px)
    fig, ax = plt.subplots(figsize=(width_px / 100, height_px / 100), dpi=100)
    try:
        lo = min([float(s.height_m.min()) for s in sections] + [-1.0])
        ax.axhspan(lo - 0.5, 0.0, color=(0.75, 0.88, 0.97), zorder=0)
        ax.axhline(0.0, color=(0.2, 0.4, 0.8), lw=1, label="water level")
        ax.axvline(0.0, color="0.6", lw=0.8, ls="--")
        for s in sections:
            ax.plot(s.distance_m, s.height_m, lw=2, color=np.array(_TYPE_LINE[s.shore_type]) / 255,
                    label=s.shore_type)
        ax.set_xlabel("distance from the shoreline (m; offshore →)")
        ax.set_ylabel("height (m)")
        ax.set_title("shore cross-sections")
        ax.legend(loc="upper right")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[:, :, :3])
    finally:
        plt.close(fig)


def _nice_ticks(lo: float, hi: float, n: int = 6) -> np.ndarray:
    span = max(hi - lo, 1e-6)
    raw = span / n
    mag = 10 ** np.floor(np.log10(raw))
    step = mag * min((m for m in (1, 2, 5, 10) if m * mag >= raw), default=10)
    return np.arange(np.ceil(lo / step) * step, hi + 1e-9, step)


def _plot_cv2(sections, width_px: int, height_px: int) -> np.ndarray:
    import cv2

    img = np.full((height_px, width_px, 3), 255, np.uint8)
    ml, mr, mt, mb = 62, 20, 30, 46
    font = cv2.FONT_HERSHEY_SIMPLEX
    black, grey = (0, 0, 0), (225, 225, 225)
    if not sections:
        cv2.putText(img, "no shoreline in the scene", (ml, height_px // 2), font, 0.6, black, 1, cv2.LINE_AA)
        return img
    x_lo = min(float(s.distance_m.min()) for s in sections)
    x_hi = max(float(s.distance_m.max()) for s in sections)
    y_lo = min(min(float(s.height_m.min()) for s in sections), -1.0) - 0.5
    y_hi = max(max(float(s.height_m.max()) for s in sections), 1.0) + 0.5

    def px(x, y):
        u = ml + (np.asarray(x, float) - x_lo) / max(x_hi - x_lo, 1e-6) * (width_px - ml - mr)
        v = mt + (y_hi - np.asarray(y, float)) / max(y_hi - y_lo, 1e-6) * (height_px - mt - mb)
        return u, v

    (u0, v0), (u1, vb) = px(x_lo, 0.0), px(x_hi, y_lo)
    cv2.rectangle(img, (int(u0), int(v0)), (int(u1), int(vb)), (197, 224, 247), -1)  # water (RGB order)
    for xt in _nice_ticks(x_lo, x_hi):
        u, _ = px(xt, 0)
        cv2.line(img, (int(u), mt), (int(u), height_px - mb), grey, 1)
        cv2.putText(img, f"{xt:g}", (int(u) - 10, height_px - mb + 16), font, 0.4, black, 1, cv2.LINE_AA)
    for yt in _nice_ticks(y_lo, y_hi):
        _, v = px(0, yt)
        cv2.line(img, (ml, int(v)), (width_px - mr, int(v)), grey, 1)
        cv2.putText(img, f"{yt:g}", (ml - 34, int(v) + 4), font, 0.4, black, 1, cv2.LINE_AA)
    cv2.line(img, (int(u0), int(v0)), (int(u1), int(v0)), (51, 102, 204), 1)  # water level
    uz, _ = px(0.0, 0.0)
    cv2.line(img, (int(uz), mt), (int(uz), height_px - mb), (150, 150, 150), 1)  # shoreline
    cv2.rectangle(img, (ml, mt), (width_px - mr, height_px - mb), black, 1)
    for k, s in enumerate(sections):
        u, v = px(s.distance_m, s.height_m)
        pts = np.round(np.stack([u, v], 1)).astype(np.int32)
        cv2.polylines(img, [pts], False, _TYPE_LINE[s.shore_type], 2, cv2.LINE_AA)
        y = mt + 18 + 18 * k
        cv2.line(img, (width_px - mr - 120, y - 4), (width_px - mr - 95, y - 4), _TYPE_LINE[s.shore_type], 2)
        cv2.putText(img, s.shore_type, (width_px - mr - 88, y), font, 0.45, black, 1, cv2.LINE_AA)
    cv2.putText(img, "shore cross-sections", (ml + 90, mt - 10), font, 0.55, black, 1, cv2.LINE_AA)
    cv2.putText(img, "distance from the shoreline (m, offshore ->)", (ml + 150, height_px - 8), font, 0.45,
                black, 1, cv2.LINE_AA)
    cv2.putText(img, "height (m)", (4, mt - 10), font, 0.45, black, 1, cv2.LINE_AA)
    return img


# ----------------------------------------------------------------------------- hillshade


def hillshade(z: np.ndarray, gsd_m: float, azimuth_deg: float = 315.0, altitude_deg: float = 45.0,
              z_factor: float = 1.0) -> np.ndarray:
    """Lambertian shading in [0, 1] (sun azimuth clockwise from north, altitude above the horizon)."""
    dz_drow, dz_dcol = np.gradient(z.astype(np.float32) * np.float32(z_factor), gsd_m)
    dz_dx, dz_dy = dz_dcol, -dz_drow  # x east = columns, y north = up the image
    az, alt = np.deg2rad(azimuth_deg), np.deg2rad(altitude_deg)
    lx, ly, lz = np.sin(az) * np.cos(alt), np.cos(az) * np.cos(alt), np.sin(alt)
    shade = (-dz_dx * lx - dz_dy * ly + lz) / np.sqrt(1.0 + dz_dx * dz_dx + dz_dy * dz_dy)
    return np.clip(shade, 0.0, 1.0).astype(np.float32)


def colour_relief(z: np.ndarray, max_depth_m: float = 8.0, max_height_m: float | None = None,
                  lut_size: int = 2048) -> np.ndarray:
    """Depth (light cyan → navy) and elevation (sand → green → brown → grey) colours, RGB float32.

    Both ramps are piecewise linear and saturate at their ends, so they are tabulated (``lut_size``
    entries each, i.e. to 1/2048 of the span) and looked up in one gather instead of six full-size
    interpolations."""
    z = np.asarray(z, np.float32)
    hi = float(max_height_m) if max_height_m else max(float(np.nanmax(z)) if z.size else 0.0, 2.0)
    depth = max(max_depth_m, 1e-3)
    dk = [0.0, 0.5 * max_depth_m, depth]
    wk = np.array([(170, 225, 235), (60, 140, 200), (15, 35, 95)], np.float32)
    lk = [0.0, 0.15 * hi, 0.5 * hi, hi]
    lc = np.array([(225, 212, 160), (120, 170, 85), (145, 115, 75), (235, 235, 235)], np.float32)
    n = int(lut_size)
    tw, tl = np.linspace(0.0, depth, n), np.linspace(0.0, hi, n)
    lut = np.empty((2 * n, 3), np.float32)  # water entries first, then land
    for ch in range(3):
        lut[:n, ch] = np.interp(tw, dk, wk[:, ch])
        lut[n:, ch] = np.interp(tl, lk, lc[:, ch])
    zz = np.nan_to_num(z, nan=0.0)
    water = zz < 0
    iw = np.clip(zz * np.float32(-(n - 1) / depth) + np.float32(0.5), 0, n - 1)
    il = np.clip(zz * np.float32((n - 1) / hi) + np.float32(n + 0.5), n, 2 * n - 1)
    idx = np.where(water, iw, il).astype(np.int32)
    return lut[idx]


def hillshade_rgb(z: np.ndarray, gsd_m: float, max_depth_m: float = 8.0, shade_levels: int = 256) -> np.ndarray:
    """Colour relief modulated by the hillshade (softer shading under water), RGB uint8.

    The colour depends on the height bin of ``colour_relief`` and the shade, so both are quantised and the
    result read from one (height bin x shade level) table: a single uint8 gather per pixel."""
    z = np.asarray(z, np.float32)
    shade = hillshade(z, gsd_m)
    hi = max(float(np.nanmax(z)) if z.size else 0.0, 2.0)
    n, depth = 2048, max(max_depth_m, 1e-3)
    # the height bins colour_relief uses: water bins 0..n-1 (depth), land bins n..2n-1 (height)
    zz = np.nan_to_num(z, nan=0.0)
    water = zz < 0
    iw = np.clip(zz * np.float32(-(n - 1) / depth) + np.float32(0.5), 0, n - 1)
    il = np.clip(zz * np.float32((n - 1) / hi) + np.float32(n + 0.5), n, 2 * n - 1)
    zbin = np.where(water, iw, il).astype(np.int32)
    bins = np.concatenate([-np.linspace(0.0, depth, n), np.linspace(0.0, hi, n)]).astype(np.float32)
    bins[0] = -1e-6  # bin 0 is water (depth 0): keep it on the water side for the shading rule
    col = colour_relief(bins[None], max_depth_m, max_height_m=hi)[0]  # (2n, 3)
    s_lv = np.linspace(0.0, 1.0, shade_levels, dtype=np.float32)
    k = np.where((bins < 0)[:, None], 0.65 + 0.35 * s_lv[None], 0.35 + 0.65 * s_lv[None])  # (2n, levels)
    table = np.clip(col[:, None, :] * k[..., None], 0, 255).astype(np.uint8).reshape(-1, 3)
    sbin = (shade * np.float32(shade_levels - 1) + np.float32(0.5)).astype(np.int32)
    zbin *= shade_levels
    zbin += sbin
    return table[zbin]


def shore_type_rgb(shore_type: np.ndarray, water: np.ndarray | None = None) -> np.ndarray:
    """The dominant shore type per pixel in colour (water side darker), RGB uint8."""
    from .default import SHORE_TYPES

    import cv2

    n = len(SHORE_TYPES) + 1
    lut = np.zeros((1, 256, 3), np.uint8)  # land colours, then the darker water side; an OpenCV table
    for i, name in enumerate(SHORE_TYPES):
        lut[0, i] = _TYPE_RGB[name]
    lut[0, n:2 * n] = (lut[0, :n] * 0.55).astype(np.uint8)
    st = np.asarray(shore_type)
    idx = np.where(st < 0, n - 1, st).astype(np.uint8)
    if water is not None:
        idx += np.asarray(water, bool).view(np.uint8) * np.uint8(n)
    return cv2.LUT(cv2.merge([idx, idx, idx]), lut)


# ----------------------------------------------------------------------------- files


def output_paths(folder: str | Path) -> dict[str, Path]:
    """The files ``write_terrain_outputs`` writes into ``folder``."""
    t = Path(folder)
    return {"hillshade": t / "hillshade.png", "shore_types": t / "shore_types.png",
            "cross_section_json": t / "cross_section.json", "cross_section_csv": t / "cross_section.csv",
            "cross_section_png": t / "cross_section.png"}


def write_terrain_outputs(folder: str | Path, result, plot_engine: str = "opencv") -> dict[str, Path]:
    """Write the hillshade, shore-type map and cross-sections of a ``TerrainResult`` into ``folder``.
    (Callers check ``output_paths`` for existing files first: these are replaced.)"""
    paths = output_paths(folder)
    z = result.height.z_m
    max_depth = max(float(-np.nanmin(z)), 1.0) if z.size else 1.0
    write_png(paths["hillshade"], hillshade_rgb(z, result.height.grid.gsd_m, max_depth))
    write_png(paths["shore_types"], shore_type_rgb(result.shore_type, z < 0))
    atomic_write_text(paths["cross_section_json"], cross_section_json(result.cross_sections))
    atomic_write_text(paths["cross_section_csv"], cross_section_csv(result.cross_sections))
    write_png(paths["cross_section_png"], cross_section_plot(result.cross_sections, engine=plot_engine))
    return paths
