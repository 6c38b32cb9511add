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
