"""Common body colours: vehicles and small boats are also viewed repainted in them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


# Common body colours (sRGB): cars and small boats come in any of them, so the library also embeds
# each paintable asset repainted, and a red car in a query still finds its shape.
PAINTS = ((236, 236, 232), (22, 24, 28), (172, 174, 178), (30, 50, 110), (160, 25, 30), (30, 70, 45),
          (235, 190, 30))


def is_paintable(category: str, dims_m: Sequence[float]) -> bool:
    return category == "vehicle" or (category == "boat" and float(dims_m[0]) <= 8.0)


def repaint(mesh, rgb):
    """A copy of ``mesh`` with its body colour (the colour of most of its top-facing area) set to ``rgb``."""
    m = mesh.copy()
    fc = np.asarray(m.visual.face_colors).copy()
    if not len(fc):
        return m
    cols, inv = np.unique(fc[:, :3], axis=0, return_inverse=True)
    inv = inv.ravel()
    top = np.asarray(m.area_faces) * (np.asarray(m.face_normals)[:, 2] > 0.3)
    body = inv == int(np.argmax(np.bincount(inv, weights=top, minlength=len(cols))))
    fc[body, :3] = np.asarray(rgb, np.uint8)
    m.visual.face_colors = fc
    return m


def cover(mesh, rgb, along: float = 0.8, across: float = 0.8):
    """A copy of boat ``mesh`` under a canvas cover of colour ``rgb``: every top-facing face whose centre lies
    inside an ellipse of ``along`` x ``across`` of the footprint (the long axis along the longer side) takes
    the cover's colour, deck, cabin and windows alike; the hull's rim and sides keep theirs. Covered and
    laid-up boats are common in real marinas and look nothing like a white deck with a cabin."""
    m = mesh.copy()
    fc = np.asarray(m.visual.face_colors).copy()
    if not len(fc):
        return m
    lo, hi = np.asarray(m.bounds, np.float64)
    c, half = (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1e-9)
    ax = (0, 1) if half[0] >= half[1] else (1, 0)
    ctr = np.asarray(m.triangles_center, np.float64)
    r2 = ((ctr[:, ax[0]] - c[ax[0]]) / (along * half[ax[0]])) ** 2 \
        + ((ctr[:, ax[1]] - c[ax[1]]) / (across * half[ax[1]])) ** 2
    sel = (np.asarray(m.face_normals)[:, 2] > 0.3) & (r2 <= 1.0)
    fc[sel, :3] = np.asarray(rgb, np.uint8)
    m.visual.face_colors = fc
    return m
