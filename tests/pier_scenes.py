"""Scenes for the pier tests: decks faint against the water, and the pier-deck network stood in for by the
known deck mask (so the classical detector's use of it is tested without a trained model)."""

from __future__ import annotations

import cv2
import numpy as np

from coastforge.types import GeoImage, Grid

WATER_RGB, DECK_RGB = (40, 90, 110), (44, 94, 112)  # a deck the colour thresholds cannot tell from water


class StandNet:
    """The network, stood in for by a known deck mask (probability 1 on it, 0 elsewhere)."""

    max_gsd_m = 0.4

    def __init__(self, deck: np.ndarray):
        self.deck = deck

    def probability(self, rgb, gsd_m, shape):
        return cv2.resize(self.deck.astype(np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)


def curved_pier_scene(gsd: float = 0.2, radius_m: float = 14.0) -> tuple[GeoImage, np.ndarray]:
    """A 2.4 m wide walkway leaving the land on the left and bending through a half circle of ``radius_m``
    over open water (no straight run of 18 m in it), faint against the water."""
    h = w = 500
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[:] = WATER_RGB
    rgb[:, :20] = (120, 140, 90)  # land
    deck = np.zeros((h, w), np.uint8)
    r_px = radius_m / gsd
    cv2.ellipse(deck, (10, int(h / 2)), (int(r_px), int(r_px)), 0, -90, 90, 1, int(round(2.4 / gsd)))
    deck = deck.astype(bool)
    rgb[deck] = DECK_RGB
    return GeoImage(rgb=rgb, grid=Grid(w, h, gsd)), deck
