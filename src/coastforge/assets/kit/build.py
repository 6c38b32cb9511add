"""The procedural starter asset kit: low-poly boats, vehicles, pier segments, a buoy and vegetation.

The asset table (``ASSET_SPECS``: id, category, builder, tags) and ``generate_kit``, which writes each
asset's GLB and the ``kit.json`` manifest; ``python -m coastforge.assets.kit --out DIR`` runs it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable, Sequence

from ...errors import CoastforgeError
from ...fsio import atomic_write_bytes, atomic_write_text, prepare_output_dir
from .boats import (build_cabin_cruiser, build_catamaran, build_center_console, build_dinghy,
                    build_fishing_boat, build_kayak, build_rowboat, build_runabout, build_sailboat,
                    build_yacht)
from .encoding import glb_bytes
from .manifest import FLOATING_CATEGORIES, KIT_FORMAT, MANIFEST_NAME
from .scenery import (build_broadleaf, build_buoy, build_buoy_channel, build_bush_round, build_bush_spreading,
                      build_conifer, build_grass_clump, build_grass_dry, build_palm, build_pier_finger,
                      build_pier_walkway, build_rock_large, build_rock_medium, build_rock_small,
                      build_seaweed_eelgrass, build_seaweed_kelp)
from .shapes import Model
from .vehicles import (build_box_truck, build_bus, build_hatchback, build_pickup, build_sedan, build_suv,
                       build_van)


def generate_kit(out_dir: str | Path, overwrite: bool = False) -> Path:
    """Build every asset and write ``<out_dir>/<id>.glb`` plus ``kit.json``; returns the manifest path.

    Deterministic: the same bytes on every run. Every file is written atomically; ``kit.json`` last,
    so a manifest never points at a missing mesh.
    """
    out = prepare_output_dir(out_dir, overwrite=overwrite)
    entries = []
    for spec in ASSET_SPECS:
        model = spec.build()
        if spec.category not in ("boat", "vehicle", "pier"):
            model.long_axis_x()  # round things too: length_m is the longest horizontal extent
        model.recentre(spec.category in FLOATING_CATEGORIES or spec.category == "pier")
        data = glb_bytes(model, spec.id)
        name = f"{spec.id}.glb"
        atomic_write_bytes(out / name, data)
        os.chmod(out / name, 0o644)  # package data: readable by everyone (temporary files are 0600)
        lo, hi = model.bounds()
        dims = [round(float(v), 3) for v in hi - lo]
        floating = spec.category in FLOATING_CATEGORIES
        entries.append({
            "id": spec.id, "category": spec.category, "mesh": name, "length_m": dims[0], "dims_m": dims,
            "up_axis": "y", "forward_axis": "+x", "draft_m": round(float(-lo[2]), 3) if floating else 0.0,
            "floating": floating, "tags": list(spec.tags),
        })
    manifest = {"format": KIT_FORMAT, "generator": "coastforge.assets.kit", "assets": entries}
    path = out / MANIFEST_NAME
    atomic_write_text(path, json.dumps(manifest, indent=1) + "\n")
    os.chmod(path, 0o644)
    return path


@dataclass(frozen=True)
class AssetSpec:
    id: str
    category: str
    build: Callable[[], Model]
    tags: tuple[str, ...]


ASSET_SPECS: tuple[AssetSpec, ...] = (
    AssetSpec("dinghy", "boat", build_dinghy, ("inflatable", "tender", "outboard", "grey", "orange")),
    AssetSpec("kayak", "boat", build_kayak, ("paddle", "yellow", "narrow", "small")),
    AssetSpec("runabout", "boat", build_runabout, ("motorboat", "outboard", "windscreen", "red_stripe")),
    AssetSpec("cabin_cruiser", "boat", build_cabin_cruiser, ("motorboat", "cabin", "white", "navy", "teak")),
    AssetSpec("sailboat", "boat", build_sailboat, ("sail", "mast", "monohull", "navy_hull", "cockpit")),
    AssetSpec("catamaran", "boat", build_catamaran, ("sail", "mast", "multihull", "trampoline", "white")),
    AssetSpec("yacht", "boat", build_yacht, ("motor_yacht", "flybridge", "tiered", "white", "dark_windows")),
    AssetSpec("fishing_boat", "boat", build_fishing_boat, ("work_boat", "wheelhouse", "blue_hull")),
    AssetSpec("rowboat", "boat", build_rowboat, ("oars", "wooden", "open_boat", "small")),
    AssetSpec("center_console", "boat", build_center_console, ("motorboat", "t_top", "twin_outboard")),
    AssetSpec("sedan", "vehicle", build_sedan, ("car", "red")),
    AssetSpec("suv", "vehicle", build_suv, ("car", "dark_blue", "tall")),
    AssetSpec("pickup", "vehicle", build_pickup, ("truck", "open_bed", "silver")),
    AssetSpec("van", "vehicle", build_van, ("van", "boxy", "white")),
    AssetSpec("bus", "vehicle", build_bus, ("bus", "yellow", "large")),
    AssetSpec("hatchback", "vehicle", build_hatchback, ("car", "green", "compact")),
    AssetSpec("box_truck", "vehicle", build_box_truck, ("truck", "box", "white", "red_cab")),
    AssetSpec("pier_walkway", "pier", build_pier_walkway, ("walkway", "timber", "piles", "modular_x")),
    AssetSpec("pier_finger", "pier", build_pier_finger, ("finger", "timber", "piles", "cleats", "modular_x")),
    AssetSpec("buoy", "buoy", build_buoy, ("mooring", "white", "blue_band")),
    AssetSpec("buoy_channel", "buoy", build_buoy_channel, ("lateral_mark", "can", "red")),
    AssetSpec("tree_conifer", "tree", build_conifer, ("conifer", "evergreen")),
    AssetSpec("tree_broadleaf", "tree", build_broadleaf, ("broadleaf", "deciduous")),
    AssetSpec("tree_palm", "tree", build_palm, ("palm", "tropical")),
    AssetSpec("bush_round", "bush", build_bush_round, ("shrub", "dark_green")),
    AssetSpec("bush_spreading", "bush", build_bush_spreading, ("shrub", "olive", "low")),
    AssetSpec("rock_small", "rock", build_rock_small, ("boulder", "small")),
    AssetSpec("rock_medium", "rock", build_rock_medium, ("boulder", "medium")),
    AssetSpec("rock_large", "rock", build_rock_large, ("boulder", "large")),
    AssetSpec("grass_clump", "grass", build_grass_clump, ("tuft", "green")),
    AssetSpec("grass_dry", "grass", build_grass_dry, ("tuft", "dry", "straw")),
    AssetSpec("seaweed_kelp", "seaweed", build_seaweed_kelp, ("kelp", "underwater", "brown")),
    AssetSpec("seaweed_eelgrass", "seaweed", build_seaweed_eelgrass, ("eelgrass", "underwater", "green")),
)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m coastforge.assets.kit",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True,
                        help="output folder (the committed kit: src/coastforge/data/kit)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the kit files in a non-empty folder")
    args = parser.parse_args(argv)
    try:
        manifest = generate_kit(args.out, overwrite=args.overwrite)
    except CoastforgeError as exc:
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    size = sum(p.stat().st_size for p in manifest.parent.glob("*.glb"))
    print(f"wrote {len(ASSET_SPECS)} assets ({size / 1e6:.2f} MB of GLB) and {manifest}")
    return 0
