"""Box refinement after any detect backend (``DetectConfig.refine``); ``refine_boxes`` runs it and the
checks of ``verify``.

Detectors place boxes to a few pixels and a few degrees (the learned net: 2-3° on renders). Here:

- **Axis** (boats, vehicles): seen from above both are mirror-symmetric about their long axis, while
  their shadows and neighbours are not. The box's crop is resampled rotation-normalised (finely across
  the axis) at angles within ±10° of the detector's, and the angle and lateral offset whose mirror
  image best matches the crop (mean Lab difference of the rows either side) win, refined to a parabola
  minimum. This took the synthetic orientation RMSE from 2.7-2.9° to 0.7-1.7°. Vehicles, small and
  blurred at 0.2 m/px, search a 1° grid with a lightness cost beside the colour one and a small cost
  per degree turned (``_vehicle_axis``).
- **Silhouette** (vehicles seen ≥ 30 px long, buoys): the background is modelled from a ring around
  the box (a few Lab colour modes: water and pier deck, pavement and grass; a mode that also fills the
  box's core is a neighbour's colour and dropped); object = far from every mode, except cast shadows
  (darker than a mode with its chromaticity) unless they lie between object pixels (dark glass). The
  mask's extents give a vehicle's length and centre along its axis (each end trusted only when the
  commonest background or a shadow lies beyond it) and a buoy's centre. For boats and widths the
  detector's measures were better than the silhouette's on the synthetic truth, so they are kept.
- **Small boats** (under ``SMALL_BOAT_MAX_M``): the detector boxes them short; the box is lengthened
  to where the hull's contrast along its axis fades into the water (``boat_ends``).
- **Rows**: a boat whose mirror axis is unclear takes the axis of its clear, parallel neighbours
  (``align_with_neighbours``).

The front (heading and its confidence) stays what the detector said; a refinement that fails a
plausibility check leaves the detector's value. ``refine_boxes`` then drops the boxes ``verify`` finds
implausible (glints, dark water, wakes, pier pieces, shifted cars) and specks: boat boxes shorter than
any boat (``BOAT_MIN_M``), vehicle boxes shorter than a car (``VEHICLE_MIN_M``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..types import Detection
from .crops import LabCache, background_modes, crop_box, lab_window, sq_dist
from .verify import drop_shifted_cars, drop_wakes, is_blank_ground, is_buoy, is_dark_water, is_structure_piece

REFINED = ("boat", "vehicle", "buoy")
_MIN_UP_PX = 24.0  # silhouette crops are upsampled until the box is this many samples wide
SYM_PX, SYM_HV = 48.0, 0.45  # samples across the box; mirror rows each side (x width)
# rows of moored boats (``align_with_neighbours``): a boat whose mirror axis is this unclear ...
ROW_UNCLEAR, ROW_CLEAR = 1.15, 1.3  # ... takes the axis of neighbours at least this clear
ROW_REACH, ROW_MAX_DEG, ROW_AGREE_DEG, ROW_MIN_TURN_DEG = 3.0, 20.0, 4.0, 6.0
ROW_MIN_N = 1
# vehicles shorter than this (m) once refined are specks (a stone, a bush): the synthetic cars are 4.4 m
# and longer, the net boxes them 3.6 m and longer; the two such specks on seeds 0-1 were 1.4 and 2.0 m
VEHICLE_MIN_M = 2.25
# boats shorter than this (m) once refined (small ones lengthened to their ends) are specks: the
# synthetic boats are 2.95 m and longer, the shortest true one boxed 1.87 m; a dark 1.4 m bush on
# grass was the one shorter false boat on seeds 0-2 (0.8 x DetectConfig.min_boat_length_m)
BOAT_MIN_M = 1.6
# small boats (``_small_boat_ends``): up to this long (m); their ends where the hull's contrast has
# fallen this fraction of the way to the water's; at most this much longer than the detector's box
SMALL_BOAT_MAX_M, SMALL_BOAT_EDGE, SMALL_BOAT_MAX_GROW = 4.5, 0.2, 1.4
SILHOUETTE_MIN_PX = 30.0  # vehicles' lengths are taken from their silhouette from this size up
SYM_MAX_DEG = 12.0  # the axis is searched this far either side of the detector's
# a turn of more than 5° needs a clear optimum (mean / best mirror cost): on the synthetic levels every
# such turn with >= 1.25 helped; on the real marina the harmful ones had 1.08-1.22
SYM_BIG_TURN_CONTRAST = 1.25
# an optimum at the edge of the search (up to SYM_MAX_DEG + 1.5 after the fine step) is kept when this
# clear: the detector's axis was off by more than the search reaches and the turn goes the right way
# (synthetic seeds 0-1: 3-m boats at 0.2 m/px off by 9-14°, edge turns with contrast >= 1.4 all helped,
# the one harmful edge turn had 1.29)
SYM_EDGE_CONTRAST = 1.4
# vehicles (``_vehicle_axis``): at 0.2 m/px a car is ~23 x 9 blurred pixels, its shadow, the parking
# lines and the neighbours a pixel or two away; the mirror cost's minimum there is shallow and a
# fraction of the cars turned 3-8° the wrong way (synthetic seeds 0-2: orientation RMSE 1.5-2.0°
# while the median error was 0.8°). The colour cost's mirror rows reach to the car's edges
# (VEH_SYM_HV x width: the outline carries the axis), a lightness-only cost over the usual rows
# (SYM_HV) is averaged with it (each over its mean on the grid), and a turn costs a little (the cost
# grows by VEH_SYM_PRIOR x (turn / 10°)²; the net's axis is within 3° RMS). Seeds 0-2 were used to choose
# among a dozen such variants, seed 3 held out (figures: docs/benchmarks.md)
VEH_SYM_HV, VEH_SYM_PRIOR, VEH_SYM_STEP = 0.55, 0.3, 1.0


def _between(mask: np.ndarray, axis: int) -> np.ndarray:
    """Pixels lying between the first and last set pixel of their row (axis=1) or column (axis=0)."""
    n = mask.shape[axis]
    idx = np.arange(n)
    idx = idx[None, :] if axis == 1 else idx[:, None]
    any_ = mask.any(axis, keepdims=True)
    first = np.argmax(mask, axis, keepdims=True)
    last = n - 1 - np.argmax(np.flip(mask, axis), axis, keepdims=True)
    return any_ & (idx >= first) & (idx <= last)


def _extents(mask: np.ndarray) -> tuple[float, float, float, float] | None:
    """(first, last) sample edges of a mask along the columns and the rows, ignoring thin fringes
    (columns/rows holding less than a tenth of the fullest one), or None when it is too small."""
    if mask.sum() < 30:
        return None
    cols = mask.sum(0)
    rows = mask.sum(1)
    jj = np.nonzero(cols >= max(1.0, 0.1 * cols.max()))[0]
    ii = np.nonzero(rows >= max(1.0, 0.1 * rows.max()))[0]
    if len(jj) < 4 or len(ii) < 3:
        return None
    # a sample is in when its centre is: the edge lies half a sample outside the outermost one
    return jj[0] - 0.5, jj[-1] + 0.5, ii[0] - 0.5, ii[-1] + 0.5


def _mirror_rows(n_rows: int, ci: float, half_v: int, shifts: np.ndarray):
    """The row pairs ``_mirror_cost`` compares in a crop of ``n_rows`` rows: (rows above, rows below)
    for each distinct mirror row that fits, which of those fit, and each shift's distinct row. The
    mirror rows ``ci + shift`` are rounded, so half-sample centres give each row twice: it is
    compared once."""
    rows, inv = np.unique(np.round(ci + shifts).astype(int), return_inverse=True)
    k = np.arange(1, half_v + 1)
    up, dn = rows[:, None] - k[None], rows[:, None] + k[None]
    ok = (up[:, -1] >= 0) & (dn[:, -1] < n_rows)
    return up[ok], dn[ok], ok, inv.reshape(-1)


def _mirror_cost_rows(crop: np.ndarray, pairs) -> np.ndarray:
    """``_mirror_cost`` with the row pairs from ``_mirror_rows``."""
    up, dn, ok, inv = pairs
    out = np.full(len(ok), np.inf)
    if len(up):
        d = np.take(crop, up, axis=0)  # (rows, k, columns, 3)
        np.subtract(d, np.take(crop, dn, axis=0), out=d)
        np.abs(d, out=d)
        out[ok] = d.reshape(d.shape[0], -1).mean(1)
    return out[inv]


def _mirror_cost(crop: np.ndarray, ci: float, half_v: int, shifts: np.ndarray) -> np.ndarray:
    """For each lateral shift (samples), the mean colour difference between the crop's rows above and
    below the row ``ci + shift``, ``half_v`` rows each side."""
    return _mirror_cost_rows(crop, _mirror_rows(crop.shape[0], ci, half_v, shifts))


def symmetry_axis(rgb: np.ndarray | LabCache, det: Detection,
                  max_deg: float = SYM_MAX_DEG) -> tuple[float, float, float] | None:
    """The long axis as the object's mirror axis: boats and vehicles are symmetric about it seen from
    above, shadows and neighbours are not. Returns (yaw correction in degrees, lateral offset of the
    axis in image pixels toward the left, contrast of the best over the mean cost), or None."""
    L, W = det.length_px, det.width_px
    if W < 3 or L < 5:
        return None
    if det.category == "vehicle":
        return _vehicle_axis(rgb, det, max_deg)
    # fine across the axis (the mirror line's position and tilt), coarse along it (speed)
    scale = max(1.0, min(8.0, SYM_PX / W))
    su = max(0.5, min(2.0, 32.0 / L))
    half_u = 0.47 * L
    hv = max(2, int(round(SYM_HV * W * scale)))  # rows each side: the hull, short of side shadows
    max_t = max(1, int(round(0.2 * W * scale)))
    half_v = (hv + max_t + 2) / scale
    shifts = np.arange(-max_t, max_t + 1)
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    pairs = None  # the crops' size does not depend on the angle: their row pairs are found once
    done: dict[float, tuple[float, float]] = {}  # the fine search starts at the coarse optimum

    def cost(delta: float) -> tuple[float, float]:
        nonlocal pairs
        if delta in done:
            return done[delta]
        crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg + delta, half_u, half_v, su, scale)
        if pairs is None:
            pairs = _mirror_rows(crop.shape[0], (crop.shape[0] - 1) / 2.0, hv, shifts)
        c = _mirror_cost_rows(crop, pairs)
        n = int(np.argmin(c))
        done[delta] = float(c[n]), float(shifts[n])
        return done[delta]

    step = 0.5
    coarse = np.arange(-max_deg, max_deg + 1e-6, 2.0)
    cs = np.array([cost(float(d))[0] for d in coarse])
    b = int(np.argmin(cs))
    fine = coarse[b] + np.arange(-1.5, 1.51, step)
    fs = [cost(float(d)) for d in fine]
    vals = np.array([f[0] for f in fs])
    n = int(np.argmin(vals))
    best = float(fine[n]) + _parabola_offset(vals, n, step)
    t = fs[n][1]
    contrast = float(np.mean(cs) / max(vals[n], 1e-6))
    return best, -t / scale, contrast


def _parabola_offset(vals: np.ndarray, n: int, step: float) -> float:
    """Sub-step offset of the minimum ``vals[n]`` of a cost sampled every ``step``: the vertex of the
    parabola through it and its neighbours (0 at either end, or when the three are not convex)."""
    if not 0 < n < len(vals) - 1:
        return 0.0
    a, b, c = float(vals[n - 1]), float(vals[n]), float(vals[n + 1])
    den = a - 2 * b + c
    return step * 0.5 * (a - c) / den if den > 1e-9 else 0.0


def _vehicle_axis(rgb: np.ndarray | LabCache, det: Detection,
                  max_deg: float = SYM_MAX_DEG) -> tuple[float, float, float]:
    """``symmetry_axis`` for a vehicle (see ``VEH_SYM_*``): the mirror cost on a 1° grid within
    ``max_deg`` of the detector's axis, in colour and in lightness alone (each over its own mean, then
    averaged), times the turn's cost, its minimum refined to a parabola. Same return values."""
    L, W = det.length_px, det.width_px
    scale = max(1.0, min(8.0, SYM_PX / W))
    su = max(0.5, min(2.0, 32.0 / L))
    half_u = 0.47 * L
    hv = max(2, int(round(VEH_SYM_HV * W * scale)))
    max_t = max(1, int(round(0.2 * W * scale)))
    half_v = (hv + max_t + 2) / scale
    shifts = np.arange(-max_t, max_t + 1)
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    deltas = np.arange(-max_deg, max_deg + 1e-6, VEH_SYM_STEP)
    hv_l = max(2, int(round(SYM_HV * W * scale)))  # lightness: the rows of the other axes' search
    pairs = pairs_l = None
    lab_cost, l_cost, best_shift = [], [], []
    for delta in deltas:
        crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg + float(delta), half_u, half_v, su, scale)
        if pairs is None:
            pairs = _mirror_rows(crop.shape[0], (crop.shape[0] - 1) / 2.0, hv, shifts)
            pairs_l = _mirror_rows(crop.shape[0], (crop.shape[0] - 1) / 2.0, hv_l, shifts)
        c = _mirror_cost_rows(crop, pairs)
        cl = _mirror_cost_rows(np.ascontiguousarray(crop[..., :1]), pairs_l)
        n = int(np.argmin(c + 1e-9 * np.abs(shifts)))  # ties (a flat crop): no shift
        lab_cost.append(float(c[n]))
        l_cost.append(float(cl.min()))
        best_shift.append(float(shifts[n]))
    a, b = np.array(lab_cost), np.array(l_cost)
    # + 1e-6: on a flat cost (nothing there) the turn's cost still decides, and keeps the detector's axis
    cost = 0.5 * (a / max(a.mean(), 1e-9) + b / max(b.mean(), 1e-9)) + 1e-6
    penal = cost * (1.0 + VEH_SYM_PRIOR * (deltas / 10.0) ** 2)
    n = int(np.argmin(penal))
    best = float(deltas[n]) + _parabola_offset(penal, n, VEH_SYM_STEP)
    contrast = float(cost.mean() / max(cost[n], 1e-9))
    return best, -best_shift[n] / scale, contrast


def silhouette(rgb: np.ndarray, det: Detection, gsd_m: float, trace: list | None = None):
    """The object's mask in a crop aligned with ``det`` (see the module doc): (mask, samples per pixel,
    centre column, centre row of the crop, where the commonest background or a shadow is), or a reason
    string when there is no clean silhouette."""
    import cv2
    from scipy import ndimage as ndi

    from .piers import labels_in

    L, W = det.length_px, det.width_px
    scale = max(1.0, min(8.0, _MIN_UP_PX / max(W, 1.0)))
    pad = max(3.0, 0.6 / gsd_m)  # the background ring starts this far out (pixels)
    half_u = 0.5 * L * 1.35 + 2 * pad
    half_v = 0.5 * W * 1.6 + 2 * pad
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, scale)
    nv, nu = crop.shape[:2]
    cj, ci = (nu - 1) / 2.0, (nv - 1) / 2.0
    U = np.abs((np.arange(nu) - cj) / scale)[None, :]  # |u| of each column, image pixels
    V = np.abs((np.arange(nv) - ci) / scale)[:, None]
    inner_u, inner_v = 0.5 * L * 1.2 + pad * 0.5, 0.5 * W * 1.3 + pad * 0.5
    ring = (U > inner_u + pad) | (V > inner_v + pad)
    prior = (U <= inner_u) & (V <= inner_v)
    core = (U <= 0.3 * L) & (V <= 0.3 * W)
    found = background_modes(crop[ring], crop[core])
    if not found:
        return "no background around the box"
    modes = [m for m, _share in found]
    # distance to the nearest background mode (water, pier deck, pavement, grass...)
    dists = np.stack([np.sqrt(sq_dist(crop, m)) for m in modes])
    dist = dists.min(0)
    main_bg = np.argmin(dists, 0) == 0  # the commonest background (water for a boat, pavement for a car)
    spread = float(np.percentile(dist[ring], 50))  # the background's own texture
    core_d = float(np.percentile(dist[core], 60))
    if core_d < max(6.0, 3.0 * spread):
        return f"low contrast {core_d:.1f} vs spread {spread:.1f}"
    thr = max(3.0 * spread, 0.45 * core_d, 5.0)
    obj = (dist > thr) & prior
    # shadows: darker than a background mode with its chromaticity (a, b shrink with L toward grey)
    shadow = np.zeros(obj.shape, bool)
    for m in modes:
        dark = crop[..., 0] < m[0] - thr * 0.5
        ratio = np.clip((crop[..., 0] + 16.0) / (m[0] + 16.0), 0.0, 1.0)  # Lab: f(kY) = k^(1/3) f(Y)
        ab_dev = np.hypot(crop[..., 1] - m[1] * ratio, crop[..., 2] - m[2] * ratio)
        shadow |= dark & (ab_dev < max(6.0, 1.5 * spread))
    if shadow[core].mean() <= 0.5:  # else a dark object: its shadow cannot be told from it
        # dark glass looks like shadow too: keep shadow-like pixels lying between solid object
        # pixels along the axis or across it (a cast shadow lies outside, on one side)
        solid = obj & ~shadow
        obj = solid | (obj & (_between(solid, 1) | _between(solid, 0)))
    # windscreens, cabins, seams: close along the axis, fill holes, keep what touches the core
    k = max(3, int(round(0.25 * W * scale)) | 1)
    obj = cv2.morphologyEx(obj.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((1, k), np.uint8)) > 0
    obj = ndi.binary_fill_holes(obj)
    op = max(1, int(round(0.08 * W * scale)))
    obj = cv2.morphologyEx(obj.astype(np.uint8), cv2.MORPH_OPEN,
                           cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * op + 1, 2 * op + 1))) > 0
    if trace is not None:
        trace.append((crop, obj, dist, shadow))
    lab_cc, n = ndi.label(obj)
    hit = np.unique(lab_cc[core & obj])
    hit = hit[hit > 0]
    if len(hit) == 0:
        return "nothing at the core"
    # a silhouette end is trusted when the commonest background or a shadow lies just beyond it; a
    # part coloured like a rarer one (a teak deck like the pier) may have been cut off there
    return labels_in(lab_cc, hit, n + 1), scale, cj, ci, main_bg | shadow


def _shift(det: Detection, du: float, dv: float, **changes) -> Detection:
    """``det`` moved ``du`` pixels forward and ``dv`` to the left (and other fields changed)."""
    r = math.radians(det.yaw_deg)
    c = (det.cx_px + du * math.cos(r) - dv * math.sin(r), det.cy_px - du * math.sin(r) - dv * math.cos(r))
    return replace(det, cx_px=float(c[0]), cy_px=float(c[1]), **changes)


def refine_box(rgb: np.ndarray, det: Detection, gsd_m: float, min_fill: float = 0.45,
               trace: list | None = None, axis: bool = True, evidence: dict | None = None) -> Detection:
    """One detection fitted to the object in the uint8 RGB image: the axis from its mirror symmetry,
    the size and centre from its silhouette; each part kept from the detector when implausible.
    ``trace`` (a list) collects what happened (and the crop and mask) for debugging; ``evidence`` (a
    dict) receives ``axis_contrast``, how clear the mirror axis was (see ``symmetry_axis``)."""

    def note(what) -> None:
        if trace is not None:
            trace.append(what)

    if det.category not in REFINED or det.length_px < 3 or det.width_px < 2:
        return det
    L0, W0 = float(det.length_px), float(det.width_px)
    cur = det
    if axis and det.category != "buoy" and L0 >= 1.3 * W0:  # round things have no axis
        sym = symmetry_axis(rgb, det)
        if evidence is not None:
            evidence["axis_contrast"] = 0.0 if sym is None else sym[2]
        inside = sym is not None and (abs(sym[0]) < SYM_MAX_DEG - 0.25 or sym[2] >= SYM_EDGE_CONTRAST)
        if inside and (abs(sym[0]) <= 5.0 or sym[2] >= SYM_BIG_TURN_CONTRAST):
            cur = _shift(det, 0.0, sym[1], yaw_deg=float((det.yaw_deg + sym[0] + 180.0) % 360.0 - 180.0))
            note(f"axis {sym[0]:+.2f} deg")
        else:
            note("no symmetry axis")
    # the silhouette's extents: measured against the synthetic truth they help only for buoys' centres
    # and for the length of vehicles seen large enough (car ends are square and sharp); for boats
    # (decks coloured like the pier, wakes, blur at the bow) and for widths the detector does better
    if det.category == "vehicle" and cur.length_px < SILHOUETTE_MIN_PX:
        return cur
    if det.category == "boat":
        return _small_boat_ends(rgb, cur, gsd_m, note)
    got = silhouette(rgb, cur, gsd_m, trace)
    if isinstance(got, str):
        note(got)
        return cur
    mask, scale, cj, ci, clear = got
    ext = _extents(mask)
    if ext is None:
        note("mask too small")
        return cur
    j0, j1, i0, i1 = ext
    if det.category == "buoy":
        du, dv = ((j0 + j1) / 2.0 - cj) / scale, -((i0 + i1) / 2.0 - ci) / scale
        if math.hypot(du, dv) > 0.5 * L0:
            note("moved too far")
            return cur
        note("refined")
        return _shift(cur, du, dv, mask=None, mask_origin_px=None)
    band = slice(max(0, int(ci - 0.3 * cur.width_px * scale)), int(ci + 0.3 * cur.width_px * scale) + 1)
    reach = max(2, int(round(0.08 * cur.length_px * scale)))
    bj0, bj1 = cj - 0.5 * cur.length_px * scale, cj + 0.5 * cur.length_px * scale  # the box's ends
    beyond0 = clear[band, max(0, int(j0) - reach):max(0, int(j0))]
    beyond1 = clear[band, int(j1) + 1:int(j1) + 1 + reach]
    if beyond0.size == 0 or beyond0.mean() < 0.6:
        j0 = min(j0, bj0)
        note("back end from the box")
    if beyond1.size == 0 or beyond1.mean() < 0.6:
        j1 = max(j1, bj1)
        note("front end from the box")
    length, du = (j1 - j0) / scale, ((j0 + j1) / 2.0 - cj) / scale
    if length < 0.8 * cur.length_px:
        # a much shorter silhouette usually misses a part coloured like the background (a dark
        # bonnet like the shadow): keep the box's length and centre
        note("kept the length")
        return cur
    fill = mask.sum() / (scale * scale) / max(length * cur.width_px, 1e-6)
    if fill < min_fill:
        note(f"fill {fill:.2f}")
        return cur
    if not 0.6 * L0 <= length <= 1.4 * L0 or length < cur.width_px:
        note(f"length {length:.1f} vs {L0:.1f}")
        return cur
    note("refined")
    return _shift(cur, du, 0.0, length_px=float(length), mask=None, mask_origin_px=None)


def boat_ends(rgb: np.ndarray, det: Detection, frac: float = SMALL_BOAT_EDGE) -> tuple[float, float] | None:
    """Where a boat's ends lie along its box's axis (pixels from the box centre, back and front), or
    None: the median colour distance to the commonest background colour (the water) across the middle
    of the hull, followed outward from its highest value in each half of the box to where it falls
    ``frac`` of the way back to the water's own texture, to a sub-sample."""
    L, W = det.length_px, det.width_px
    s = 4.0  # samples per pixel: sub-pixel ends
    half_u, half_v = 0.75 * L + 3, 0.9 * W + 3
    win = lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = crop_box(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, s)
    nv, nu = crop.shape[:2]
    u = (np.arange(nu) - (nu - 1) / 2.0) / s
    V = np.abs((np.arange(nv) - (nv - 1) / 2.0) / s)[:, None]
    ring = (np.abs(u)[None, :] > 0.625 * L + 1) | (V > 0.65 * W + 1)
    core = (np.abs(u)[None, :] <= 0.3 * L) & (V <= 0.3 * W)
    found = background_modes(crop[ring], crop[core])
    band = V[:, 0] <= 0.3 * W
    if not found or not band.any():
        return None
    dist = np.sqrt(sq_dist(crop, found[0][0]))
    prof = np.median(dist[band], 0)
    water = float(np.median(dist[ring]))
    ends = []
    for sgn in (-1, 1):
        half = (sgn * u >= 0.1 * L) & (sgn * u <= 0.5 * L)
        if not half.any():
            return None
        idx = np.nonzero(half)[0]
        k = int(idx[np.argmax(prof[half])])
        thr = water + frac * (float(prof[k]) - water)
        while 0 <= k + sgn < nu and prof[k + sgn] >= thr:
            k += sgn
        if not 0 <= k + sgn < nu:
            return None  # no water beyond this end within the crop
        a, b = float(prof[k]), float(prof[k + sgn])
        ends.append(float(u[k]) + sgn * (a - thr) / max(a - b, 1e-6) / s)
    return ends[0], ends[1]


def _small_boat_ends(rgb: np.ndarray, det: Detection, gsd_m: float, note) -> Detection:
    """A small boat's box lengthened to its hull's ends (``boat_ends``). The detector boxes dinghies
    and other boats under ``SMALL_BOAT_MAX_M`` short (synthetic levels, seeds 0 and 1: by 16 % at
    0.2 m/px, their bow and stern blur into the water); their visible ends only ever lengthen the box
    (up to ``SMALL_BOAT_MAX_GROW``), as for larger boats the detector's length was the better one."""
    L0 = float(det.length_px)
    if L0 * gsd_m > SMALL_BOAT_MAX_M or L0 < 4:
        return det
    got = boat_ends(rgb, det)
    if got is None:
        note("no boat ends")
        return det
    length = got[1] - got[0]
    if not L0 < length <= SMALL_BOAT_MAX_GROW * L0:
        note(f"ends {length:.1f} vs {L0:.1f}")
        return det
    note("lengthened")
    return _shift(det, (got[0] + got[1]) / 2.0, 0.0, length_px=float(length), mask=None, mask_origin_px=None)


def refine_boxes(rgb: np.ndarray, detections: list[Detection], gsd_m: float,
                 axis: bool = True) -> list[Detection]:
    """Every boat / vehicle / buoy box fitted to the object (others unchanged); buoys that are glints,
    boats that are dark water, pier pieces (``is_structure_piece``) or wakes (``drop_wakes``) and
    vehicles shorter than ``VEHICLE_MIN_M`` dropped; unclear boat axes aligned with their row
    (``align_with_neighbours``). ``axis=False`` keeps the detector's axes (see
    ``coastforge.detection.detect``). See the module doc."""
    rgb = rgb if isinstance(rgb, LabCache) else LabCache(rgb)  # each pixel's Lab computed once
    out, clear = [], []
    for d in detections:
        if d.category == "buoy" and not is_buoy(rgb, d, gsd_m):
            continue
        if d.category == "boat" and is_dark_water(rgb, d, gsd_m):
            continue
        ev: dict = {}
        r = refine_box(rgb, d, gsd_m, axis=axis, evidence=ev) if d.category in REFINED else d
        if r.category == "vehicle" and r.length_px * gsd_m < VEHICLE_MIN_M:
            continue
        if r.category == "boat" and r.length_px * gsd_m < BOAT_MIN_M:
            continue
        if r.category == "vehicle" and is_blank_ground(rgb, r, gsd_m):
            continue
        if r.category == "boat" and is_structure_piece(rgb, r, gsd_m):
            continue
        out.append(r)
        clear.append(ev.get("axis_contrast"))
    if axis:
        out = align_with_neighbours(out, clear)
    return drop_shifted_cars(rgb, drop_wakes(rgb, out, gsd_m))


def align_with_neighbours(dets: list[Detection], clear: list[float | None]) -> list[Detection]:
    """Boats moored side by side lie parallel (synthetic truth: neighbours within 20° of each other
    differ by 1.2° median, 3.2° at the 90th percentile): a boat whose own axis is unclear (mirror
    contrast ``clear`` below ``ROW_UNCLEAR``; None: not measured, left alone) and off by more than
    ``ROW_MIN_TURN_DEG`` from the axes of at least ``ROW_MIN_N`` clear neighbours (``ROW_CLEAR``;
    centres within ``ROW_REACH`` times the shorter one's length: a dinghy 10 m from a yacht is not
    moored beside it; axes within ``ROW_MAX_DEG`` of its own and within ``ROW_AGREE_DEG`` of each other)
    takes their mean axis, its front kept. Rare by design (docs/benchmarks.md): a longer reach also turned
    free dinghies near yachts."""
    boats = [i for i, d in enumerate(dets) if d.category == "boat" and clear[i] is not None]
    if len(boats) < 1 + ROW_MIN_N:
        return dets
    out = list(dets)
    cs = np.array([[dets[i].cx_px, dets[i].cy_px] for i in boats])
    lengths = np.array([dets[i].length_px for i in boats])
    for k, i in enumerate(boats):
        d = dets[i]
        if clear[i] >= ROW_UNCLEAR:
            continue
        dist = np.hypot(*(cs - cs[k]).T)
        axes = []
        for m in np.nonzero((dist > 0) & (dist <= ROW_REACH * np.minimum(lengths, d.length_px)))[0]:
            j = boats[m]
            n = dets[j]
            if clear[j] < ROW_CLEAR:
                continue
            rel = (n.yaw_deg - d.yaw_deg + 90.0) % 180.0 - 90.0  # n's axis relative to d's, (-90, 90]
            if abs(rel) <= ROW_MAX_DEG:
                axes.append(rel)
        if len(axes) < ROW_MIN_N or max(axes) - min(axes) > ROW_AGREE_DEG:
            continue
        turn = float(np.mean(axes))
        if abs(turn) > ROW_MIN_TURN_DEG:
            out[i] = replace(d, yaw_deg=float((d.yaw_deg + turn + 180.0) % 360.0 - 180.0))
    return out
