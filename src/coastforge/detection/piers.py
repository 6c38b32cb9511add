"""Pier structures over water: long thin walkways and short fingers perpendicular to them.

Piers are found in a binary "structure over water" mask by morphological line openings: the mask is
rotated to each candidate direction, opened with a long horizontal line (the segment must fit
inside the structure) and the part too wide to be a deck is removed with a wide rectangle opening.
Candidate directions are the dominant edge directions of the mask (marinas are built on a few
directions) plus their perpendiculars, so the cost stays at a handful of rotations.
"""

from __future__ import annotations

import numpy as np

from ..frames import wrap_half_deg, yaw_from_direction_px
from ..types import Detection


def labels_in(lab: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """``np.isin(lab, ids)`` for labels in [0, n), by a lookup table (several times faster)."""
    table = np.zeros(n, bool)
    table[ids] = True
    return table[lab]


def add_angles(angles: list[float], more, apart_deg: float = 3.0) -> list[float]:
    """``angles`` with each of ``more`` (degrees, mod 180) appended unless it lies within ``apart_deg`` of one
    already there (in place; returned for convenience)."""
    for b in more:
        b = round(float(b) % 180.0, 1)
        if all(abs(wrap_half_deg(b - c)) > apart_deg for c in angles):
            angles.append(b)
    return angles


def dominant_angles(mask: np.ndarray, n_peaks: int = 4, min_share: float = 0.3) -> list[float]:
    """Dominant line directions (image angle in degrees, [0, 180), CCW from image-right with row up)
    of a binary mask, from the histogram of its edge orientations; each with its perpendicular."""
    import cv2

    f = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.hypot(gx, gy)
    sel = mag > 0.1
    if sel.sum() < 50:
        return list(np.arange(0.0, 180.0, 6.0))
    # edge direction is perpendicular to the gradient; image rows point down, so negate gy
    ang = (np.rad2deg(np.arctan2(-gy[sel], gx[sel])) + 90.0) % 180.0
    hist, _ = np.histogram(ang, bins=180, range=(0, 180), weights=mag[sel])
    hist = np.convolve(np.r_[hist[-3:], hist, hist[:3]], np.ones(7) / 7.0, mode="same")[3:-3]
    out: list[float] = []
    h = hist.copy()
    top = float(hist.max())
    for _ in range(n_peaks):
        k = int(np.argmax(h))
        if out and h[k] < min_share * top:
            break
        out.append(float(k) + 0.5)
        for d in range(-10, 11):
            h[(k + d) % 180] = 0
    angles: list[float] = []
    for a in out:
        add_angles(angles, (a, a + 90.0))
    return sorted(angles)


def component_axes(mask: np.ndarray, min_len_px: float, min_elongation: float = 4.0) -> list[float]:
    """The long-axis directions (image angle in degrees, [0, 180), as ``dominant_angles``) of the elongated
    connected parts of ``mask`` at least ``min_len_px`` long, each with its perpendicular. A clean deck mask's
    parts give their own directions directly, where the edge histogram of a small or ragged mask peaks to
    either side of them."""
    import cv2

    n, lbl, st, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    angles: list[float] = []
    for k in range(1, n):
        if np.hypot(st[k, 2], st[k, 3]) < min_len_px:
            continue
        x, y, w, h = st[k, :4]
        rr, cc = np.nonzero(lbl[y:y + h, x:x + w] == k)
        pts = np.stack([cc, rr], 1).astype(np.float64)
        rel = pts - pts.mean(0)
        ev, evec = np.linalg.eigh(rel.T @ rel)
        if ev[1] < (min_elongation ** 2) * max(ev[0], 1e-9) or 4.0 * np.sqrt(ev[1] / len(pts)) < min_len_px:
            continue
        a = float(yaw_from_direction_px(evec[0, 1], evec[1, 1]))
        add_angles(angles, (a, a + 90.0))
    return sorted(angles)


def _largest_part(mask: np.ndarray) -> int:
    """Pixels of the largest 8-connected part of ``mask`` (0 when empty)."""
    import cv2

    if not mask.any():
        return 0
    n, _lbl, st, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    return int(st[1:, cv2.CC_STAT_AREA].max()) if n > 1 else 0


def _components_where(mask: np.ndarray, keep) -> np.ndarray:
    """The 8-connected components of ``mask`` whose stats rows (cv2: x, y, w, h, area) pass ``keep``."""
    import cv2

    n, lbl, st, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    ok = np.zeros(n, bool)
    ok[1:] = keep(st[1:].astype(np.float64))
    if ok[1:].all():
        return mask.astype(bool)
    return ok[lbl]


def _rotate(img: np.ndarray, angle_deg: float, interp) -> tuple[np.ndarray, np.ndarray]:
    """Rotate so that image direction ``angle_deg`` becomes horizontal (+col); returns (rotated, matrix)."""
    import cv2

    h, w = img.shape[:2]
    diag = int(np.ceil(np.hypot(h, w))) + 2
    # cv2's positive angle turns the content counter-clockwise on screen; a direction at +a (CCW on
    # screen, as our yaw) becomes horizontal after turning the content by -a
    m = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), -angle_deg, 1.0)
    m[0, 2] += (diag - w) / 2.0
    m[1, 2] += (diag - h) / 2.0
    return cv2.warpAffine(img, m, (diag, diag), flags=interp, borderValue=0), m


def line_open(mask: np.ndarray, angle_deg: float, length_px: int, max_width_px: int,
              clear_px: int = 1) -> np.ndarray:
    """Pixels of ``mask`` on a straight segment of ``length_px`` at ``angle_deg`` whose cross-section
    is at most ``max_width_px`` wide (long thin structures along that direction)."""
    import cv2

    h, w = mask.shape
    full, m = _rotate(mask.astype(np.uint8), angle_deg, cv2.INTER_NEAREST)
    # work only inside the bounding box of the structure (sparse masks: most of the image is empty)
    bx, by, bw, bh = cv2.boundingRect(full)
    pad = 2
    x0, y0 = max(0, bx - pad), max(0, by - pad)
    x1, y1 = min(full.shape[1], bx + bw + pad), min(full.shape[0], by + bh + pad)
    if bw == 0 or bh == 0:
        return np.zeros((h, w), bool)
    rot = full[y0:y1, x0:x1]
    line = cv2.morphologyEx(rot, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_RECT, (length_px, 1)))
    wide = cv2.morphologyEx(rot, cv2.MORPH_OPEN,
                            cv2.getStructuringElement(cv2.MORPH_RECT, (max(3, length_px // 3), max_width_px + 1)))
    # a thin line must keep ``clear_px`` from wide blobs (so the rim of a boat is not a finger)
    wide = cv2.dilate(wide, np.ones((2 * clear_px + 1, 2 * clear_px + 1), np.uint8))
    thin = line & (1 - wide)
    # the thin part must still be a long segment after removing the wide blocks
    thin = cv2.morphologyEx(thin, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_RECT, (length_px, 1)))
    if not thin.any():
        return np.zeros((h, w), bool)
    full[:] = 0
    full[y0:y1, x0:x1] = thin
    mi = cv2.invertAffineTransform(m)
    return cv2.warpAffine(full, mi, (w, h), flags=cv2.INTER_NEAREST, borderValue=0).astype(bool)


def _rescale(d: Detection, scale: float) -> Detection:
    if scale == 1.0:
        return d
    return Detection(d.category, d.score, d.cx_px / scale, d.cy_px / scale, d.length_px / scale,
                     d.width_px / scale, d.yaw_deg)


def water_both_sides(water: np.ndarray, d: Detection, gsd_m: float, offsets_m=(3.0, 6.0, 10.0, 15.0),
                     min_frac: float = 0.3) -> bool:
    """Is there water on both long sides of a box (a pier over water, not a quay or a shore path)?
    Samples lines parallel to the box at several offsets; boats moored along a pier hide the water
    at small offsets, hence the range."""
    h, w = water.shape
    f = np.array([np.cos(np.deg2rad(d.yaw_deg)), -np.sin(np.deg2rad(d.yaw_deg))])
    lft = np.array([-f[1], f[0]])
    t = np.linspace(-0.45, 0.45, 15) * d.length_px
    for side in (1.0, -1.0):
        best = 0.0
        for off in offsets_m:
            o = d.width_px / 2.0 + off / gsd_m
            pts = np.array([d.cx_px, d.cy_px]) + t[:, None] * f + side * o * lft
            c = np.clip(pts[:, 0].astype(int), 0, w - 1)
            r = np.clip(pts[:, 1].astype(int), 0, h - 1)
            inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
            if inside.sum() < 3:
                best = max(best, 0.5)  # off the image: unknown, do not reject on it
                continue
            best = max(best, float(water[r[inside], c[inside]].mean()))
        if best < min_frac:
            return False
    return True


def _segments(lines: np.ndarray, angle_deg: float, min_len_px: float, category: str, scale: float,
              score: float, water: np.ndarray | None = None,
              gsd_m: float = 1.0) -> tuple[list[Detection], np.ndarray]:
    """Connected runs of a line mask → oriented boxes (in image pixels via ``scale``) and the mask of
    the runs kept (those with water on both sides when ``water`` is given)."""
    import cv2

    full = lines.astype(np.uint8)
    bx, by, bw, bh = cv2.boundingRect(full)
    kept_mask = np.zeros(lines.shape, bool)
    if bw == 0 or bh == 0:
        return [], kept_mask
    n, lbl, st, _ = cv2.connectedComponentsWithStats(full[by:by + bh, bx:bx + bw], connectivity=8)
    st = st.copy()
    st[:, 0] += bx
    st[:, 1] += by
    out = []
    keep = np.zeros(n, bool)
    for k in range(1, n):
        if st[k, cv2.CC_STAT_AREA] < min_len_px:
            continue
        x, y, w, h = st[k, :4]
        rr, cc = np.nonzero(lbl[y - by:y - by + h, x - bx:x - bx + w] == k)
        pts = np.stack([cc + x, rr + y], 1).astype(np.float32)
        (cx, cy), (a, b), _ang = cv2.minAreaRect(pts)
        length, width = max(a, b) + 1.0, min(a, b) + 1.0
        if length < min_len_px:
            continue
        # direction: the run's own axis (second moments) when it is clearly elongated, else the line angle
        yaw = float(wrap_half_deg(angle_deg))
        if length > 4 * width:
            rel = pts - pts.mean(0)
            _ev, evec = np.linalg.eigh(rel.T @ rel)
            own = float(wrap_half_deg(yaw_from_direction_px(evec[0, 1], evec[1, 1])))
            if abs(wrap_half_deg(own - yaw)) < 4.0:
                yaw = own
        d = Detection(category, score, (cx + 0.5) / scale, (cy + 0.5) / scale, length / scale, width / scale, yaw)
        if water is not None and not water_both_sides(water, d, gsd_m):
            continue
        keep[k] = True
        out.append(d)
    kept_mask[by:by + bh, bx:bx + bw] = keep[lbl]
    return out, kept_mask


def detect_piers(structure: np.ndarray, gsd_m: float, scale: float = 1.0, angles: list[float] | None = None,
                 water: np.ndarray | None = None,
                 walkway_min_m: float = 18.0, walkway_max_width_m: float = 4.0, finger_min_m: float = 5.0,
                 finger_max_width_m: float = 1.6, finger_clear_m: float = 0.8,
                 walk_factor: int = 1, longest_run: bool = False) -> tuple[list[Detection], np.ndarray]:
    """Walkways and fingers in a structure mask at ``gsd_m`` metres per mask pixel.

    ``scale`` converts mask pixels to image pixels (mask = image * scale). Returns the detections
    (in image pixels) and the union mask of pier pixels (mask grid). Walkways (wide enough) are
    searched on a grid ``walk_factor`` times coarser, which divides their cost by its square. Where two
    directions' walkways cross, the one with more pixels takes the crossing, or with ``longest_run`` the one with
    the longest straight run (for clean deck masks, see the loop)."""
    import cv2

    if angles is None:
        angles = dominant_angles(structure)
    full_shape = structure.shape
    full_structure, full_water, full_gsd, full_scale = structure, water, gsd_m, scale
    if walk_factor > 1:
        hh, ww_ = full_shape[0] // walk_factor, full_shape[1] // walk_factor
        structure = cv2.resize(structure.astype(np.float32), (ww_, hh), interpolation=cv2.INTER_AREA) > 0.4
        if water is not None:
            water = cv2.resize(water.astype(np.float32), (ww_, hh), interpolation=cv2.INTER_AREA) > 0.5
        gsd_m, scale = gsd_m * walk_factor, scale / walk_factor
    wl = max(5, int(round(walkway_min_m / gsd_m)))
    ww = max(2, int(round(walkway_max_width_m / gsd_m)))
    fl = max(4, int(round(finger_min_m / gsd_m)))
    fw = max(1, int(round(finger_max_width_m / gsd_m)))
    walk_union = np.zeros(structure.shape, bool)
    dets: list[Detection] = []
    per_angle = []
    # a blob whose bounding box has a diagonal shorter than a walkway holds no walkway: dropping those
    # first (boats, most clutter) leaves the line openings little to do
    long_structure = _components_where(structure, lambda st: np.hypot(st[:, 2], st[:, 3]) >= wl)
    if not long_structure.any():
        angles = []
    for a in angles:
        wm = line_open(long_structure, a, wl, ww)
        per_angle.append((a, wm))
        walk_union |= wm
    # one direction per pixel: the angle with the most support wins (duplicates from the +-2 deg spread); with
    # ``longest_run``, the angle with the longest straight run: where long fingers cross a walkway, the many
    # fingers add up to more deck than the walkway, but each is shorter than it. Only on the pier-deck network's
    # clean decks: in the colour mask, rows of moored boats make long runs too (ships_aerial boat280: a 20 m
    # "walkway" of hulls across the water between two piers)
    support = _largest_part if longest_run else (lambda m: int(m.sum()))
    best: dict[float, np.ndarray] = {}
    taken = np.zeros(structure.shape, bool)
    for a, wm in sorted(per_angle, key=lambda t: -support(t[1])):
        own = wm & ~taken
        if own.sum() >= wl:
            best[a] = own
            taken |= wm
    walk_union = np.zeros(structure.shape, bool)
    finger_angles: list[float] = []
    for a, own in best.items():
        segs, kept = _segments(own, a, wl * 0.9, "pier_walkway", 1.0, 0.8, water=water, gsd_m=gsd_m)
        walk_union |= kept
        dets += [_rescale(d, scale) for d in segs]
        if segs:  # fingers leave a walkway at right angles
            b = round((a + 90.0) % 180.0, 1)
            if all(abs(wrap_half_deg(b - c)) > 1.0 for c in finger_angles):
                finger_angles.append(b)
    # fingers: short thin lines touching a walkway, outside walkways (on the full grid)
    if walk_factor > 1:
        walk_union = cv2.resize(walk_union.astype(np.uint8), (full_shape[1], full_shape[0]),
                                interpolation=cv2.INTER_NEAREST).astype(bool) & full_structure
        structure, water, gsd_m, scale = full_structure, full_water, full_gsd, full_scale
    fl = max(4, int(round(finger_min_m / gsd_m)))
    fw = max(1, int(round(finger_max_width_m / gsd_m)))
    near_walk = cv2.dilate(walk_union.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    rest = structure & ~walk_union
    if finger_angles:  # a finger is part of a blob that touches a walkway (the others cannot hold one)
        n, lbl = cv2.connectedComponents(rest.astype(np.uint8), connectivity=8)
        touch = np.unique(lbl[near_walk & (lbl > 0)])
        rest = labels_in(lbl, touch[touch > 0], n) if len(touch) else np.zeros_like(rest)
    finger_union = np.zeros(structure.shape, bool)
    for a in finger_angles:
        fm = line_open(rest, a, fl, fw, clear_px=max(1, int(round(finger_clear_m / gsd_m)))) & ~finger_union
        if not fm.any():
            continue
        n, lbl = cv2.connectedComponents(fm.astype(np.uint8), connectivity=8)
        touch = np.unique(lbl[near_walk & (lbl > 0)])
        keep = labels_in(lbl, touch[touch > 0], n)
        if keep.sum() >= fl:
            segs, kept = _segments(keep, a, fl * 0.9, "pier_finger", 1.0, 0.6)
            finger_union |= kept
            dets += [_rescale(d, scale) for d in segs]
    return dets, walk_union | finger_union


def deck_spines(deck: np.ndarray, covered: np.ndarray, gsd_m: float, scale: float = 1.0,
                water: np.ndarray | None = None, walkway_min_m: float = 18.0, walkway_max_width_m: float = 4.0,
                piece_m: float = 8.0) -> list[Detection]:
    """Walkways the straight line openings missed, along the spine of each deck part left over.

    ``deck`` (the pier-deck network's decks) and ``covered`` (the pier boxes already found) are masks at
    ``gsd_m``; ``scale`` converts mask pixels to image pixels. For every deck part outside ``covered`` long
    enough for a walkway, the longest path through its skeleton (the walkway; fingers are its shorter
    branches) is cut into pieces of about ``piece_m`` and each piece becomes a box along its own chord: a
    curved walkway is chained from short straight segments, as the pier stage chains any walkway."""
    import cv2
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components
    from skimage.morphology import skeletonize

    left = deck & ~covered
    n, lbl, st, _ = cv2.connectedComponentsWithStats(left.astype(np.uint8), connectivity=8)
    min_px = walkway_min_m / gsd_m
    dist = cv2.distanceTransform(left.astype(np.uint8), cv2.DIST_L2, 3)
    out: list[Detection] = []
    for k in range(1, n):
        if np.hypot(st[k, cv2.CC_STAT_WIDTH], st[k, cv2.CC_STAT_HEIGHT]) < min_px:
            continue
        x0, y0, w, h = st[k, :4]
        part = lbl[y0:y0 + h, x0:x0 + w] == k
        ys, xs = np.nonzero(skeletonize(part))
        if len(ys) < min_px:
            continue
        # the skeleton as a graph of 8-connected pixels; its longest path runs between the two ends found by
        # two breadth-first searches (exact on a tree, close enough on a skeleton's few small loops)
        index = -np.ones(part.shape, np.int64)
        index[ys, xs] = np.arange(len(ys))
        src, dst = [], []
        for dy, dx in ((0, 1), (1, -1), (1, 0), (1, 1)):
            yy, xx = ys + dy, xs + dx
            ok = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
            j = np.full(len(ys), -1)
            j[ok] = index[yy[ok], xx[ok]]
            i = np.flatnonzero(j >= 0)
            src += [i, j[i]]
            dst += [j[i], i]
        a, b = np.concatenate(src), np.concatenate(dst)
        graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(len(ys), len(ys))).tocsr()
        _nc, comp = connected_components(graph, directed=False)
        start = int(np.argmax(np.bincount(comp)[comp]))  # a pixel of the largest piece of skeleton
        order, _ = breadth_first_order(graph, start, directed=False)
        order, pred = breadth_first_order(graph, int(order[-1]), directed=False)
        path = [int(order[-1])]
        while pred[path[-1]] >= 0:
            path.append(int(pred[path[-1]]))
        if len(path) < min_px:
            continue
        px = np.stack([xs[path] + x0, ys[path] + y0], 1).astype(np.float64)
        # path length in pixels (diagonal steps count 1.41) and where to cut it
        step = np.r_[0.0, np.hypot(*np.diff(px, axis=0).T)]
        along = np.cumsum(step)
        if along[-1] < min_px:
            continue
        pieces = max(1, int(round(along[-1] * gsd_m / piece_m)))
        edges = np.linspace(0.0, along[-1], pieces + 1)
        for i in range(pieces):
            sel = (along >= edges[i]) & (along <= edges[i + 1])
            p = px[sel]
            if len(p) < 2:
                continue
            width = 2.0 * float(np.median(dist[p[:, 1].astype(int), p[:, 0].astype(int)]))
            if width * gsd_m > walkway_max_width_m:
                continue
            chord = p[-1] - p[0]
            length = float(np.hypot(*chord)) + width  # the deck runs on half a width past each cut
            yaw = float(yaw_from_direction_px(chord[0], chord[1]))
            c = p.mean(0)
            d = Detection("pier_walkway", 0.6, c[0] + 0.5, c[1] + 0.5, length, max(width, 1.0), yaw)
            if water is None or water_both_sides(water, d, gsd_m):
                out.append(_rescale(d, scale))
    return out
