"""Synthetic ground-truth coastal levels (``coastforge synth``): the benchmark's truth scenes.

``synthesize(preset, seed)`` lays out a level (terrain classes, truth heights, piers, moored and
anchored boats, parked cars, buoys, vegetation) and returns it as a ``Scene``; ``synth_to_dir`` also
renders one aerial image per GSD and writes ``truth.json`` + rasters + ``inputs.json``.

Modules: ``level`` (a level's scene and its files), ``layout`` (geometry and placement rules),
``presets`` (the levels), ``terrain`` (the truth height model), ``render`` (images with variety and
clutter).
"""

from .level import (CAR_PAINTS, DEFAULT_GRID_M, DEFAULT_GSDS, PIER_DECK_M, PRESETS, REPAINTED, SMALL_BOAT_PAINTS,
                    VEG_RULES, SynthLevel, SynthResult, asset_catalog, check_preset, image_name, kit_catalog,
                    parse_gsds, rasterize, sample_raster, scatter_vegetation, synth_many, synth_to_dir, synthesize,
                    synthesize_level)

__all__ = ["CAR_PAINTS", "DEFAULT_GRID_M", "DEFAULT_GSDS", "PIER_DECK_M", "PRESETS", "REPAINTED",
           "SMALL_BOAT_PAINTS", "VEG_RULES", "SynthLevel", "SynthResult", "asset_catalog", "check_preset",
           "image_name", "kit_catalog", "parse_gsds", "rasterize", "sample_raster", "scatter_vegetation",
           "synth_many", "synth_to_dir", "synthesize", "synthesize_level"]
