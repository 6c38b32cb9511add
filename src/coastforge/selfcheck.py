"""A plausibility check of a generated scene that the user sees (console and report): warnings when the
result looks unlike any real coast, each with what to try.

The limits are loose on purpose (they flag gross failures such as a marina built as a car park or a
wrong ``--gsd``, not taste): a real marina packs at most about one boat per 40 m² of water (bow-in rows
of 3 m-wide boats on 10 m fingers), a packed car park one car per ~12 m² of pavement (2.5 x 5 m bays).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .classes import CLASS_NAMES, PAVED, WATER

MIN_BOATS_FOR_WATER_CHECK = 10
LITTLE_WATER = 0.03  # share of the image
ONE_CLASS = 0.92  # share of the image
MAX_BOATS_PER_WATER_M2 = 1 / 40.0
MAX_VEHICLES_PER_PAVED_M2 = 1 / 12.0
# median detected length in metres far outside a category's usual range says the GSD is wrong
USUAL_LENGTH_M = {"boat": (2.5, 40.0), "vehicle": (3.0, 12.0)}
MIN_FOR_LENGTH_CHECK = 5


@dataclass(frozen=True)
class SceneWarning:
    code: str
    message: str
    hint: str

    def to_dict(self) -> dict:
        return {"code": self.code, "message": self.message, "hint": self.hint}

    def __str__(self) -> str:
        return f"{self.message} {self.hint}"


def check_scene(class_ids: np.ndarray, gsd_m: float, dets) -> list[SceneWarning]:
    """Warnings for a class map (ids on a grid of ``gsd_m``) and its detections (``Detection``s)."""
    out: list[SceneWarning] = []
    n = max(int(class_ids.size), 1)
    counts = np.bincount(np.asarray(class_ids, np.uint8).ravel(), minlength=len(CLASS_NAMES))[:len(CLASS_NAMES)]
    share = counts / n
    px_m2 = gsd_m * gsd_m
    boats = [d for d in dets if d.category == "boat"]
    vehicles = [d for d in dets if d.category == "vehicle"]
    water_m2 = float(counts[WATER]) * px_m2
    paved_m2 = float(sum(counts[c] for c in PAVED)) * px_m2
    if len(boats) >= MIN_BOATS_FOR_WATER_CHECK and share[WATER] < LITTLE_WATER:
        out.append(SceneWarning(
            "boats_without_water",
            f"{len(boats)} boats were found but only {100 * share[WATER]:.1f} % of the image is water.",
            "The segmenter probably missed the water (an unusual colour?): look at segmentation/classes_preview.png; "
            "try --set segment.learned_water=net, or give a class raster with --segment-backend labels."))
    top = int(np.argmax(share))
    # open water with boats on it (an anchorage, a marina seen from high up) is a plausible scene
    if share[top] >= ONE_CLASS and not (top == WATER and boats):
        out.append(SceneWarning(
            "one_class",
            f"{100 * share[top]:.0f} % of the image is one class ({CLASS_NAMES[top]}).",
            "Real coasts mix classes: check the image and its --gsd, and segmentation/confidence.png for where "
            "the segmenter was unsure."))
    if water_m2 > 0 and len(boats) > max(20, MAX_BOATS_PER_WATER_M2 * water_m2):
        out.append(SceneWarning(
            "boat_density",
            f"{len(boats)} boats on {water_m2:,.0f} m² of water is denser than any marina "
            f"(> 1 per {1 / MAX_BOATS_PER_WATER_M2:.0f} m²).",
            "Is --gsd right? Too coarse a GSD makes everything look small and packed."))
    if paved_m2 > 0 and len(vehicles) > max(20, MAX_VEHICLES_PER_PAVED_M2 * paved_m2):
        out.append(SceneWarning(
            "vehicle_density",
            f"{len(vehicles)} vehicles on {paved_m2:,.0f} m² of pavement is denser than a packed car park.",
            "Is --gsd right? Or is water taken for pavement (boats as cars)? See the report's detections."))
    for cat, dd in (("boat", boats), ("vehicle", vehicles)):
        if len(dd) >= MIN_FOR_LENGTH_CHECK:
            med = float(np.median([d.length_px for d in dd])) * gsd_m
            lo, hi = USUAL_LENGTH_M[cat]
            if not lo / 1.6 <= med <= hi * 1.6:
                out.append(SceneWarning(
                    f"{cat}_size",
                    f"the median {cat} is {med:.1f} m long (usual: {lo:g}-{hi:g} m).",
                    f"The GSD ({gsd_m:g} m/px) is probably wrong by about x{med / np.sqrt(lo * hi):.1f}: "
                    "check --gsd / --size-m."))
    return out
