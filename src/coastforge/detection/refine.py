"""Box refinement and verification after any detect backend (``DetectConfig.refine``).

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
- **Verification**: buoy boxes on sun glints / whitecaps (small, streaked, faint; or the water's own
  colour brightened with no shadow beside it, ``is_glint``) and boat boxes on dark water (weed,
  submerged rocks: darker water of the same chromaticity) or on mostly water (broken wakes, weed
  patches with water between them) are dropped; so are boat boxes on a piece of a pier (a uniform
  core continuing past one end, water on both sides: ``is_structure_piece``), on a boat's foam wake
  (``drop_wakes``), boat boxes shorter than any boat (``BOAT_MIN_M``), vehicle boxes shorter than a
  car (``VEHICLE_MIN_M``), vehicle boxes on blank ground (``is_blank_ground``) and weaker vehicle boxes
  on the empty bay beside a car (``drop_shifted_cars``).
- **Rows**: a boat whose mirror axis is unclear takes the axis of its clear, parallel neighbours
  (``align_with_neighbours``).

The front (heading and its confidence) stays what the detector said; a refinement that fails a
plausibility check leaves the detector's value.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..types import Detection

REFINED = ("boat", "vehicle", "buoy")
_MIN_UP_PX = 24.0  # silhouette crops are upsampled until the box is this many samples wide
SYM_PX, SYM_HV = 48.0, 0.45  # samples across the box; mirror rows each side (x width)
BUOY_MAX_ASPECT, BUOY_MIN_AREA_M2, BUOY_MIN_PEAK = 1.4, 0.25, 24.0  # see ``is_buoy``
# sun glints (``is_glint``): the ring (m from the centre) where a buoy darkens the water, how dark its
# 10th percentile must get (Lab L) and how close to the water's chromaticity a glint's colour stays
GLINT_RING_M, GLINT_MAX_SHADOW, GLINT_MAX_TINT = (0.6, 0.95), -1.4, 0.1
# ... white glints on a wavy sea have another tint than the water, but where the ring lies at least
# GLINT_RING_MIN_PX from the centre (finer than 0.15 m/px: the blur does not spill the blob into it) a
# ring brighter than the water by GLINT_BRIGHT_RING on average, with no shadow, is a field of glints:
# synthetic seeds 0-3 at 0.1 m/px, the 88 true buoys' rings -0.2 and darker, the 2 such glints' +2.4
GLINT_RING_MIN_PX, GLINT_BRIGHT_RING = 4.0, 1.0
DARK_WATER_SHADOW, DARK_WATER_CONTRAST = 0.8, 0.8  # see ``is_dark_water``
# ... unless its ring is clearly darker (mean, 10th percentile) and its colour its own (tint), when 0.8 of
# the area and peak will do (synthetic seeds 0-2: 2 of the 3 true buoys the shape checks dropped kept,
# none of 99 glints; every such glint was smaller, or had a brighter ring or the water's tint)
BUOY_SURE_SHAPE, BUOY_SURE_RING, BUOY_SURE_TINT = 0.8, (-1.0, -3.0), 0.1
# wakes (``drop_wakes``): a boat box in line behind a boat (axes within WAKE_MAX_DEG, centre within half
# its width of the boat's axis, at most WAKE_GAP_M or half the boat's length beyond its stern) whose
# core is partly water (>= WAKE_MIN_WATER) and far less contrasted than the boat's (WAKE_REL_CONTRAST)
WAKE_MAX_DEG, WAKE_GAP_M, WAKE_REL_CONTRAST, WAKE_MIN_WATER = 20.0, 2.0, 0.3, 0.25
# pier pieces (``is_structure_piece``): the colour (Lab distance of medians) beyond one end within
# PIECE_END_DE of the core's, beside both sides at least PIECE_SIDE_DE from it, a core more uniform than
# PIECE_MAX_STD_L (Lab L); bands from PIECE_BAND_M[0] to PIECE_BAND_M[1] metres outside the box
PIECE_END_DE, PIECE_SIDE_DE, PIECE_MAX_STD_L, PIECE_BAND_M = 4.0, 15.0, 10.0, (0.5, 2.0)
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
# a vehicle box beside a clearly stronger one (score ratio >= SHIFTED_SCORE_RATIO), parallel (axes
# within SHIFTED_MAX_DEG), level with it (centres within half a length along the axis) and at most
# SHIFTED_MAX_LAT widths to the side, with a uniform core (Lab L std < SHIFTED_MAX_STD_L), is that
# car seen shifted onto its shadow or the empty bay beside it (``drop_shifted_cars``)
SHIFTED_SCORE_RATIO, SHIFTED_MAX_DEG, SHIFTED_MAX_LAT, SHIFTED_MAX_STD_L = 1.3, 15.0, 1.3, 4.0
# vehicle boxes on blank ground (``is_blank_ground``)
BLANK_MAX_CONTRAST, BLANK_MIN_SAME = 0.8, 0.5
# ... and a box whose core is more than this share water-coloured (within this Lab distance)
CORE_WATER_MAX, CORE_WATER_DE = 0.5, 8.0
# ... dark hulls: a box at least this long (m) must be darker water on nearly all its core to go
DARK_HULL_MIN_M, DARK_HULL_MIN_PX, DARK_HULL_SHADOW = 7.5, 20.0, 0.95  # ... seen this many pixels long
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
# grows by VEH_SYM_PRIOR x (turn / 10°)²; the net's axis is within 3° RMS): orientation RMSE at
# 0.2 m/px seeds 0+1 1.49 -> 1.18°, seed 2 2.04 -> 1.48°; at 0.1 m/px 0.75 -> 0.62° (seed 2 0.57 ->
# 0.55°). Seeds 0-2 were used to choose among a dozen such variants (seed 3 held out)
VEH_SYM_HV, VEH_SYM_PRIOR, VEH_SYM_STEP = 0.55, 0.3, 1.0


def _to_lab(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)


class LabCache:
    """An RGB image whose Lab is converted block by block as ``_lab_window`` asks for it, each pixel
    once: the checks of ``refine_boxes`` look at several overlapping windows around every box (speed).
    The conversion is per pixel, so the windows are the same as converting each on its own. Pass it
    wherever these functions take ``rgb`` (read-only views are returned: do not write into them)."""

    BLOCK = 32
    MAX_PIXELS = 40_000_000  # larger images (a 0.5 GB float cache) convert each window on its own

    def __init__(self, rgb: np.ndarray):
        self.rgb = rgb
        self.shape = rgb.shape
        h, w = rgb.shape[:2]
        self.lab = np.empty((h, w, 3), np.float32) if h * w <= self.MAX_PIXELS else None
        b = self.BLOCK
        self.done = np.zeros((-(-h // b), -(-w // b)), bool)

    def window(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        if self.lab is None:
            return _to_lab(self.rgb[r0:r1, c0:c1])
        b = self.BLOCK
        h, w = self.shape[:2]
        br0, bc0 = r0 // b, c0 // b
        todo = ~self.done[br0:-(-r1 // b), bc0:-(-c1 // b)]
        for i in np.nonzero(todo.any(1))[0]:  # each row of blocks: from its first to its last missing one
            js = np.nonzero(todo[i])[0]
            ra, rb = (br0 + i) * b, min(h, (br0 + i + 1) * b)
            ca, cb = (bc0 + js[0]) * b, min(w, (bc0 + js[-1] + 1) * b)
            self.lab[ra:rb, ca:cb] = _to_lab(self.rgb[ra:rb, ca:cb])
            self.done[br0 + i, bc0 + js[0]:bc0 + js[-1] + 1] = True
        v = self.lab[r0:r1, c0:c1]
        v.flags.writeable = False
        return v


def _lab_window(rgb: np.ndarray | LabCache, cx: float, cy: float,
                reach: float) -> tuple[np.ndarray, tuple[int, int]]:
    """The Lab (float32, L 0-100) window of ``rgb`` (or of a ``LabCache``) within ``reach`` pixels of
    (cx, cy), and its origin."""
    h, w = rgb.shape[:2]
    c0, r0 = max(0, int(cx - reach)), max(0, int(cy - reach))
    c1, r1 = min(w, int(cx + reach) + 2), min(h, int(cy + reach) + 2)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return np.zeros((2, 2, 3), np.float32), (c0, r0)
    if isinstance(rgb, LabCache):
        return rgb.window(r0, r1, c0, c1), (c0, r0)
    return _to_lab(rgb[r0:r1, c0:c1]), (c0, r0)


def _crop(win: tuple[np.ndarray, tuple[int, int]], cx: float, cy: float, yaw_deg: float, half_u: float,
          half_v: float, scale: float, scale_v: float | None = None) -> np.ndarray:
    """Bilinear crop of a Lab window (``_lab_window``) on a grid aligned with ``yaw_deg`` (u forward
    along the columns, v to the left = up the rows), centred on (cx, cy): (2*half_v*scale,
    2*half_u*scale) samples, ``scale`` samples per image pixel (``scale_v`` across, if given)."""
    import cv2

    lab, (c0, r0) = win
    sv = scale if scale_v is None else scale_v
    nu, nv = int(math.ceil(2 * half_u * scale)), int(math.ceil(2 * half_v * sv))
    r = math.radians(yaw_deg)
    cr, sr = math.cos(r), math.sin(r)  # forward (cr, -sr) and its left (-sr, -cr) in (col, row)
    a = np.array([[cr / scale, sr / sv], [-sr / scale, cr / sv]])  # 2x2: d(col,row)/d(j,i) (forward, -left)
    c = np.array([cx - 0.5 - c0, cy - 0.5 - r0])  # continuous image coords → window pixel index
    m = np.empty((2, 3))
    m[:, :2] = a
    m[:, 2] = c - a @ np.array([(nu - 1) / 2.0, (nv - 1) / 2.0])
    return cv2.warpAffine(lab, m, (nu, nv), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REFLECT)


def _between(mask: np.ndarray, axis: int) -> np.ndarray:
    """Pixels lying between the first and last set pixel of their row (axis=1) or column (axis=0)."""
    n = mask.shape[axis]
    idx = np.arange(n)
    idx = idx[None, :] if axis == 1 else idx[:, None]
    any_ = mask.any(axis, keepdims=True)
    first = np.argmax(mask, axis, keepdims=True)
    last = n - 1 - np.argmax(np.flip(mask, axis), axis, keepdims=True)
    return any_ & (idx >= first) & (idx <= last)


def _sq_dist(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``((a - m) ** 2).sum(-1)`` for colours ``a`` (..., 3) and one colour ``m``, channel by channel:
    the same values, several times faster than numpy's reduction over a short last axis (speed)."""
    m = np.asarray(m)
    t = a[..., 0] - m[0]
    acc = t * t
    for c in range(1, a.shape[-1]):
        t = a[..., c] - m[c]
        acc += t * t
    return acc


def _median0(a: np.ndarray) -> np.ndarray:
    """``np.median(a, 0)`` of a non-empty (n, c) array, the same values without its overhead (speed:
    called in every k-means step of ``background_modes``)."""
    n = a.shape[0]
    h = n // 2
    if n % 2:
        return np.partition(a, h, axis=0)[h]
    p = np.partition(a, (h - 1, h), axis=0)
    return (p[h - 1] + p[h]) / 2


def background_modes(ring: np.ndarray, core: np.ndarray, k: int = 3, iters: int = 6,
                     min_share: float = 0.12, max_in_core: float = 0.3,
                     tol: float = 8.0) -> list[tuple[np.ndarray, float]]:
    """The background's colours (Lab) from the ring pixels: a small deterministic k-means (water and a
    pier deck, pavement and grass...). A mode that also covers much of the box's core is the object's
    own colour seen on a neighbour (rafted boats, cars in a row) and is dropped. Returns (colour,
    share of the ring) pairs, the commonest first."""
    x = ring.reshape(-1, 3)
    if len(x) > 1200:
        x = x[:: len(x) // 1200 + 1]
    if len(x) < 10:
        return []
    centres = np.quantile(x, np.linspace(0.15, 0.85, k), axis=0)  # spread along all channels
    prev = None
    for _ in range(iters):
        lab = np.argmin(np.stack([_sq_dist(x, m) for m in centres], 1), 1)
        if prev is not None and np.array_equal(lab, prev):
            break  # converged: the same members give the same medians from here on
        prev = lab
        for j in range(k):
            sel = x[lab == j]
            if len(sel):
                centres[j] = _median0(sel)
    else:
        lab = np.argmin(np.stack([_sq_dist(x, m) for m in centres], 1), 1)
    c = core.reshape(-1, 3)
    out = []
    for j in range(k):
        share = float((lab == j).mean())
        if share < min_share:
            continue
        if len(c) and (np.sqrt(_sq_dist(c, centres[j])) < tol).mean() > max_in_core:
            continue
        out.append((centres[j].copy(), share))
    return sorted(out, key=lambda m: -m[1])


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
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    pairs = None  # the crops' size does not depend on the angle: their row pairs are found once
    done: dict[float, tuple[float, float]] = {}  # the fine search starts at the coarse optimum

    def cost(delta: float) -> tuple[float, float]:
        nonlocal pairs
        if delta in done:
            return done[delta]
        crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg + delta, half_u, half_v, su, scale)
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
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    deltas = np.arange(-max_deg, max_deg + 1e-6, VEH_SYM_STEP)
    hv_l = max(2, int(round(SYM_HV * W * scale)))  # lightness: the rows of the other axes' search
    pairs = pairs_l = None
    lab_cost, l_cost, best_shift = [], [], []
    for delta in deltas:
        crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg + float(delta), half_u, half_v, su, scale)
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
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, scale)
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
    dists = np.stack([np.sqrt(_sq_dist(crop, m)) for m in modes])
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


def core_evidence(rgb: np.ndarray, det: Detection, gsd_m: float) -> dict[str, float]:
    """How much the middle of a box looks like an object rather than background: ``contrast`` (the
    core's median colour distance to the nearest background mode over the background's own spread)
    and ``shadow`` (the fraction of the core that is darker than the background with its
    chromaticity: a dark patch of water, weed, a shadow) and ``water`` (the fraction of the core within
    ``CORE_WATER_DE`` of the median colour around the box)."""
    L, W = det.length_px, det.width_px
    scale = max(1.0, min(4.0, 12.0 / max(W, 1.0)))
    pad = max(3.0, 0.6 / gsd_m)
    half_u, half_v = 0.5 * L * 1.35 + 2 * pad, 0.5 * W * 1.6 + 2 * pad
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, scale)
    nv, nu = crop.shape[:2]
    U = np.abs((np.arange(nu) - (nu - 1) / 2.0) / scale)[None, :]
    V = np.abs((np.arange(nv) - (nv - 1) / 2.0) / scale)[:, None]
    ring = (U > 0.6 * L + 1.5 * pad) | (V > 0.65 * W + 1.5 * pad)
    core = (U <= 0.35 * L) & (V <= 0.3 * W)
    found = background_modes(crop[ring], crop[core], max_in_core=1.01)
    if not found or not core.any():
        return {"contrast": 0.0, "shadow": 1.0, "water": 1.0}
    modes = [m for m, _ in found]
    dist = np.stack([np.sqrt(_sq_dist(crop, m)) for m in modes]).min(0)
    spread = max(2.0, float(np.percentile(dist[ring], 50)))
    shadow = np.zeros(dist.shape, bool)
    for m in modes:
        ratio = np.clip((crop[..., 0] + 16.0) / (m[0] + 16.0), 0.0, 1.0)  # Lab: f(kY) = k^(1/3) f(Y)
        ab_dev = np.hypot(crop[..., 1] - m[1] * ratio, crop[..., 2] - m[2] * ratio)
        shadow |= (crop[..., 0] < m[0] - 3.0 * spread) & (ab_dev < max(6.0, 1.5 * spread))
    # the share of the core coloured like the water around the box (its ring's median colour)
    water = float((np.sqrt(_sq_dist(crop[core], np.median(crop[ring], 0))) < CORE_WATER_DE).mean())
    return {"contrast": float(np.median(dist[core])) / spread, "shadow": float(shadow[core].mean()),
            "water": water}


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
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, s)
    nv, nu = crop.shape[:2]
    u = (np.arange(nu) - (nu - 1) / 2.0) / s
    V = np.abs((np.arange(nv) - (nv - 1) / 2.0) / s)[:, None]
    ring = (np.abs(u)[None, :] > 0.625 * L + 1) | (V > 0.65 * W + 1)
    core = (np.abs(u)[None, :] <= 0.3 * L) & (V <= 0.3 * W)
    found = background_modes(crop[ring], crop[core])
    band = V[:, 0] <= 0.3 * W
    if not found or not band.any():
        return None
    dist = np.sqrt(_sq_dist(crop, found[0][0]))
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


def buoy_features(rgb: np.ndarray, det: Detection, gsd_m: float) -> dict[str, float]:
    """Shape and contrast of the blob at a buoy box, measured on a 4 m square resampled to 5 cm:
    ``peak`` (Lab distance from the water around, 95th percentile within 0.6 m), ``area`` (m², of the
    blob brighter than half the peak within 1 m), ``aspect`` (long/short axis from its moments), and
    for ``is_glint``: ``ring_p10`` and ``ring_mean`` (10th percentile and mean of the lightness minus
    the water's in the annulus ``GLINT_RING_M`` around the blob) and ``tint`` (how far the blob's
    chromaticity is from the water's, over the water's chroma)."""
    sample = 0.05
    win = _lab_window(rgb, det.cx_px, det.cy_px, 2.5 / gsd_m + 3)
    crop = _crop(win, det.cx_px, det.cy_px, 0.0, 2.0 / gsd_m, 2.0 / gsd_m, gsd_m / sample)
    n0, n1 = crop.shape[:2]
    yy, xx = np.mgrid[:n0, :n1]
    rr = np.hypot(yy - (n0 - 1) / 2.0, xx - (n1 - 1) / 2.0) * sample
    bg = np.median(crop[rr > 1.2], 0)
    dist = np.sqrt(_sq_dist(crop, bg))
    peak = float(np.percentile(dist[rr < 0.6], 95))
    blob = (dist > 0.5 * peak) & (rr < 1.0)
    ys, xs = np.nonzero(blob)
    aspect = math.inf
    if len(xs) > 3:
        ev = np.linalg.eigvalsh(np.cov(np.stack([xs, ys]).astype(float)))
        aspect = float(math.sqrt(ev[1] / max(ev[0], 1e-6)))
    dl = crop[..., 0] - bg[0]
    r0, r1 = GLINT_RING_M
    ring = (rr >= r0) & (rr < r1)
    # the blob's colour: the core weighted by how much brighter than the water it is
    w = np.clip(dl, 0.0, None) * (rr < 0.3)
    ab = (crop[..., 1:] * w[..., None]).sum((0, 1)) / w.sum() if w.sum() > 1e-6 else bg[1:]
    chroma = float(math.hypot(bg[1], bg[2]))
    tint = (float(math.hypot(ab[0] - bg[1], ab[1] - bg[2])) - 1.5) / max(chroma, 1e-6)
    return {"peak": peak, "area": float(blob.sum() * sample * sample), "aspect": aspect,
            "ring_p10": float(np.percentile(dl[ring], 10)) if ring.any() else 0.0,
            "ring_mean": float(dl[ring].mean()) if ring.any() else 0.0, "tint": tint}


def is_glint(f: dict[str, float], gsd_m: float | None = None) -> bool:
    """``buoy_features`` of a sun glint: a glint is the water's own colour made brighter, and the
    ripples around it catch some of the sun too, so the water around it is, if anything, brighter; a
    floating buoy stands out in its own colour and darkens the water beside it (its shadow, its
    waterline). On the synthetic levels (seeds 0 and 1) every glint left by the shape checks had a
    10th percentile of the ring at -1.15 or more, a brighter ring on average and a tint <= 0.06; the
    true buoys' ring reached -1.61 or less at both resolutions (so each test alone separates them;
    a glint must pass all three). White glints on a wavy sea differ in tint but show their field of
    glints in a well resolved ring (``GLINT_BRIGHT_RING``, ``gsd_m`` given)."""
    if f["ring_p10"] <= GLINT_MAX_SHADOW or f["ring_mean"] <= 0.0:
        return False
    if f["tint"] <= GLINT_MAX_TINT:
        return True
    return gsd_m is not None and GLINT_RING_M[0] / gsd_m >= GLINT_RING_MIN_PX and f["ring_mean"] > GLINT_BRIGHT_RING


def is_buoy(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A buoy is a bright, round float at least ~0.5 m across. Sun glints and whitecaps, which the
    learned detector takes for buoys, are small, streaked along the wind and fainter (on the
    synthetic levels: 0.1 m/px all 25 buoys kept, 64 of 65 glints dropped; 0.2 m/px 25/26 and 21/27);
    the glints left are told apart by their surroundings and colour (``is_glint``: 0.2 m/px, seeds 0
    and 1, the last 6 of 6 dropped, no buoy)."""
    f = buoy_features(rgb, det, gsd_m)
    if f["aspect"] <= BUOY_MAX_ASPECT and f["area"] >= BUOY_MIN_AREA_M2 and f["peak"] >= BUOY_MIN_PEAK:
        return not is_glint(f, gsd_m)
    # a float casting a clear shadow in its own colour (far from any glint) may be a little smaller,
    # fainter or less round than the shape checks want: at 0.2 m/px a 1 m buoy is 5 px, blurred
    return (f["area"] >= BUOY_SURE_SHAPE * BUOY_MIN_AREA_M2 and f["peak"] >= BUOY_SURE_SHAPE * BUOY_MIN_PEAK
            and f["ring_mean"] <= BUOY_SURE_RING[0] and f["ring_p10"] <= BUOY_SURE_RING[1]
            and f["tint"] >= BUOY_SURE_TINT)


def is_dark_water(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A boat box whose middle is only darker water (weed, a submerged rock, a cloud or tree shadow:
    darker than the water around with its chromaticity), or hardly differs from it. Hulls and decks
    seen from above are brighter or of another colour; a yacht-sized box needs a darker core
    throughout (``DARK_HULL_*``: dark hulls are large, weed patches on the synthetic levels small). On
    the synthetic levels this drops 13 of 22 false boats and no true one."""
    # fast path (speed): a core clearly brighter than the box's surroundings is no dark patch
    win = _lab_window(rgb, det.cx_px, det.cy_px, 0.5 * math.hypot(det.length_px, det.width_px) + 2 * max(
        3.0, 0.6 / gsd_m) + 3)
    lab = win[0]
    h, w = lab.shape[:2]
    dh, dw = max(1, h // 8), max(1, w // 8)
    mid = lab[h // 2 - dh:h // 2 + dh + 1, w // 2 - dw:w // 2 + dw + 1]
    if float(np.median(mid[..., 0])) > float(np.median(lab[..., 0])) + 15.0:
        return False
    e = core_evidence(rgb, det, gsd_m)
    if e["contrast"] < DARK_WATER_CONTRAST:
        return True
    if e["water"] > CORE_WATER_MAX:
        # a hull or deck covers the middle of its box; weed patches seen with gaps of water between
        # them, and foam trails, leave at least half of it the water's colour (synthetic seeds 0-2:
        # true boats at most 0.47, the kayaks whose boxes are wider than they are)
        return True
    # dark patches on the synthetic levels are small (2-7 m, weed and rocks); a yacht-sized dark box
    # with contrast is a dark hull (real marina: 2 of 2 such true boats, 0 false at 7.5 m and up)
    # (seen large enough: not a satellite speck)
    big = det.length_px * gsd_m >= DARK_HULL_MIN_M and det.length_px >= DARK_HULL_MIN_PX
    return e["shadow"] >= (DARK_HULL_SHADOW if big else DARK_WATER_SHADOW)


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


def is_blank_ground(rgb: np.ndarray | LabCache, det: Detection, gsd_m: float) -> bool:
    """A vehicle box on nothing: its core has the colour of the ground around it (at least
    ``BLANK_MIN_SAME`` of it within ``CORE_WATER_DE``) and no contrast with it (``core_evidence``
    contrast below ``BLANK_MAX_CONTRAST``): sand, a lawn, an empty bay. Dark cars on dark asphalt have
    as little contrast but their own colour (synthetic seeds 0-3: the 2 lowest-contrast true cars, 0.71
    and 0.74, shared none of their core with the ground; the 3 such false boxes 0.58-0.88 of it)."""
    e = core_evidence(rgb, det, gsd_m)
    return e["contrast"] < BLANK_MAX_CONTRAST and e["water"] >= BLANK_MIN_SAME


def _box_crop(rgb: np.ndarray | LabCache, det: Detection, half_u: float,
              half_v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Lab crop aligned with ``det`` (±``half_u`` px along its axis, ±``half_v`` across, sampled
    so the box is about 12 samples wide) and each sample's (u, v) offset from the centre in image px
    (broadcastable: u (1, nu), v (nv, 1))."""
    s = max(1.0, min(4.0, 12.0 / max(det.width_px, 1.0)))
    win = _lab_window(rgb, det.cx_px, det.cy_px, math.hypot(half_u, half_v) + 3)
    crop = _crop(win, det.cx_px, det.cy_px, det.yaw_deg, half_u, half_v, s)
    nv, nu = crop.shape[:2]
    u = ((np.arange(nu) - (nu - 1) / 2.0) / s)[None, :]
    v = ((np.arange(nv) - (nv - 1) / 2.0) / s)[:, None]
    return crop, u, v


def core_std_l(rgb: np.ndarray | LabCache, det: Detection) -> float:
    """The std of the Lab lightness (0-100) in the box's core (within 0.35 of its length and 0.3 of
    its width from the centre)."""
    L, W = det.length_px, det.width_px
    crop, u, v = _box_crop(rgb, det, 0.35 * L + 1.0, 0.3 * W + 1.0)
    core = crop[(np.abs(u) <= 0.35 * L) & (np.abs(v) <= 0.3 * W)]
    return float(core[:, 0].std()) if len(core) >= 4 else math.inf


def drop_shifted_cars(rgb: np.ndarray | LabCache, dets: list[Detection]) -> list[Detection]:
    """Vehicle boxes that are a stronger neighbour's car seen shifted sideways onto its shadow or the
    empty bay beside it (``SHIFTED_*``): parallel, level with it, touching it and scored well below
    it, with a uniform core (asphalt or shadow: no roof edge, no glass). Overlapping ones are merged
    by the learned backend already (``learned.VEHICLE_MAX_IOA``); these only touch. Synthetic seeds
    0-2: 4 of 4 such false cars (core std 1.9-3.3, score ratio 1.35-1.61, 1.0-1.26 widths aside);
    true neighbours that close scored alike (ratio <= 1.1) or had a varied core (std >= 8)."""
    cars = [i for i, d in enumerate(dets) if d.category == "vehicle"]
    if len(cars) < 2:
        return dets
    cs = np.array([[dets[i].cx_px, dets[i].cy_px] for i in cars])
    drop: set[int] = set()
    for k, i in enumerate(cars):
        d = dets[i]
        r = math.radians(d.yaw_deg)
        f, lft = (math.cos(r), -math.sin(r)), (-math.sin(r), -math.cos(r))
        near = np.hypot(*(cs - cs[k]).T) <= SHIFTED_MAX_LAT * d.width_px + 0.5 * d.length_px + 1.0
        for m in np.nonzero(near)[0]:
            e = dets[cars[m]]
            if m == k or e.score < SHIFTED_SCORE_RATIO * d.score:
                continue
            if abs((e.yaw_deg - d.yaw_deg + 90.0) % 180.0 - 90.0) > SHIFTED_MAX_DEG:
                continue
            du, dv = e.cx_px - d.cx_px, e.cy_px - d.cy_px
            u, v = du * f[0] + dv * f[1], du * lft[0] + dv * lft[1]
            if abs(u) > 0.25 * (d.length_px + e.length_px) or abs(v) > SHIFTED_MAX_LAT * 0.5 * (d.width_px + e.width_px):
                continue
            if core_std_l(rgb, d) < SHIFTED_MAX_STD_L:
                drop.add(i)
                break
    return [d for i, d in enumerate(dets) if i not in drop]


def align_with_neighbours(dets: list[Detection], clear: list[float | None]) -> list[Detection]:
    """Boats moored side by side lie parallel (synthetic truth: neighbours within 20° of each other
    differ by 1.2° median, 3.2° at the 90th percentile): a boat whose own axis is unclear (mirror
    contrast ``clear`` below ``ROW_UNCLEAR``; None: not measured, left alone) and off by more than
    ``ROW_MIN_TURN_DEG`` from the axes of at least ``ROW_MIN_N`` clear neighbours (``ROW_CLEAR``;
    centres within ``ROW_REACH`` times the shorter one's length: a dinghy 10 m from a yacht is not
    moored beside it; axes within ``ROW_MAX_DEG`` of its own and within ``ROW_AGREE_DEG`` of each other)
    takes their mean axis, its front kept. Rare by design: on synthetic seeds 0-4 (both resolutions) it
    turns one boat (a 4.6 m boat at 0.2 m/px, 8.2° -> 0.6° off), on the real marina one (4.6° -> 2.4°).
    Reaching 3 x the longer one's length had also turned a free dinghy 12 m from a yacht 21° -> 29° off
    (with the previous net: a sailboat on the real marina 80° -> 85°)."""
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


def is_structure_piece(rgb: np.ndarray, det: Detection, gsd_m: float) -> bool:
    """A boat box on a piece of a longer structure (a pier finger, a walkway's end, a pier head): its
    uniform core continues in the same colour past one end while both its sides are another colour
    (water). A hull ends in the water or at the pier it is moored to, which is coloured otherwise, and
    shows a cabin, a cockpit, a deck line (a less uniform core). On the synthetic levels (seeds 0-1)
    this drops 4 pier decks and a streak of water between weed patches taken for boats (end within
    2.7 of the core's colour, sides 20-37 away, core std 3.9-7.7), no true boat (the nearest: end 4.6
    but sides 12.3, or end 5.4 and core std 15-18); on held-out seed 2, 3 pier decks and no true boat."""
    L, W = det.length_px, det.width_px
    if L < 4 or W < 2:
        return False
    a, b = PIECE_BAND_M[0] / gsd_m, PIECE_BAND_M[1] / gsd_m
    crop, u, v = _box_crop(rgb, det, 0.5 * L + b, 0.5 * W + b)
    core = crop[(np.abs(u) <= 0.35 * L) & (np.abs(v) <= 0.3 * W)]
    if len(core) < 4 or float(core[:, 0].std()) >= PIECE_MAX_STD_L:
        return False
    cm = np.median(core, 0)

    def de(band: np.ndarray) -> float:
        return float(np.linalg.norm(np.median(crop[band], 0) - cm)) if band.any() else math.inf

    ends = [de((sg * u >= 0.5 * L + a) & (sg * u <= 0.5 * L + b) & (np.abs(v) <= 0.3 * W)) for sg in (-1, 1)]
    if min(ends) >= PIECE_END_DE:
        return False
    sides = [de((sg * v >= 0.5 * W + a) & (sg * v <= 0.5 * W + b) & (np.abs(u) <= 0.35 * L)) for sg in (-1, 1)]
    return min(sides) > PIECE_SIDE_DE


def _in_line_behind(b: Detection, a: Detection, gsd_m: float) -> bool:
    """Whether box ``b`` lies in line behind boat ``a`` (either end when ``a``'s heading is unknown):
    axes within ``WAKE_MAX_DEG``, centre within half ``a``'s width of its axis, at most ``WAKE_GAP_M``
    (or half ``a``'s length) beyond its end and not overlapping it by more than a quarter of ``b``."""
    turn = abs((b.yaw_deg - a.yaw_deg + 90.0) % 180.0 - 90.0)
    if turn > WAKE_MAX_DEG:
        return False
    r = math.radians(a.yaw_deg)
    du, dv = b.cx_px - a.cx_px, b.cy_px - a.cy_px
    u, v = du * math.cos(r) - dv * math.sin(r), -du * math.sin(r) - dv * math.cos(r)
    if abs(v) > 0.5 * a.width_px or (a.heading_known and u > 0):
        return False
    gap = abs(u) - 0.5 * (a.length_px + b.length_px)
    return -0.25 * b.length_px <= gap <= max(WAKE_GAP_M / gsd_m, 0.5 * a.length_px)


def drop_wakes(rgb: np.ndarray, dets: list[Detection], gsd_m: float) -> list[Detection]:
    """Boat boxes that are a boat's wake: in line behind it (``_in_line_behind``), their core partly the
    water's colour (foam over water) and far less contrasted than the boat's (``WAKE_*``). The learned
    detector takes the foam trail of a moving boat for a second boat (synthetic seeds 0-1: 2 false
    boats, core contrast 0.14-0.17 of their boat's); boats moored stern to stern across a finger are
    as contrasted as each other (0.5 and up)."""
    boats = [i for i, d in enumerate(dets) if d.category == "boat"]
    if len(boats) < 2:
        return dets
    drop: set[int] = set()
    evidence: dict[int, dict[str, float]] = {}

    def ev(i: int) -> dict[str, float]:
        if i not in evidence:
            evidence[i] = core_evidence(rgb, dets[i], gsd_m)
        return evidence[i]

    cs = np.array([[dets[i].cx_px, dets[i].cy_px] for i in boats])
    longest = max(dets[i].length_px for i in boats)
    for k, i in enumerate(boats):
        b = dets[i]
        # only boats close enough to be ``_in_line_behind`` are looked at (speed)
        near = np.hypot(*(cs - cs[k]).T) <= 0.5 * b.length_px + longest + WAKE_GAP_M / gsd_m + 1.0
        for m in np.nonzero(near)[0]:
            j = boats[m]
            if j == i or not _in_line_behind(b, dets[j], gsd_m):
                continue
            e = ev(i)
            if e["water"] >= WAKE_MIN_WATER and e["contrast"] < WAKE_REL_CONTRAST * ev(j)["contrast"]:
                drop.add(i)
                break
    return [d for i, d in enumerate(dets) if i not in drop]
