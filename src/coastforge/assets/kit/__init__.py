"""The procedural starter asset kit: low-poly boats, vehicles, pier segments, a buoy and vegetation.

Every mesh is built here from a few primitives (lofts of rings, sweeps, convex hulls) with real-world
dimensions in metres, forward = +x, origin at the footprint centre, z = 0 at the waterline (floating
things) or the ground. ``python -m coastforge.assets.kit --out DIR`` writes one GLB per asset plus the
``kit.json`` manifest (format ``coastforge.kit/1``).

The GLB files follow the glTF convention (y up): a scene point (x, y, z) is stored as (x, z, -y). Each
colour is one primitive with a PBR material (``baseColorFactor`` in linear RGB), so glTF viewers and
Unreal show the colours; vertices carry flat normals and a box-projected UV set (metres). The GLB
writer is ``export.glb``'s (no exporter version in the bytes) and all coordinates are rounded to 0.1 mm, so
regenerating gives byte-identical files (tests/test_kit.py checks the committed kit against a fresh one).

Modules: ``manifest`` (the installed kit, loaded), ``build`` (the asset table, ``generate_kit``), ``encoding``
(GLB files and back), ``shapes`` (colours, primitives, ``Model``), ``boats``, ``vehicles``, ``scenery``
(piers, buoys, vegetation).
"""

from .build import ASSET_SPECS, AssetSpec, generate_kit
from .encoding import glb_bytes, read_glb
from .manifest import (FLOATING_CATEGORIES, KIT_CATEGORIES, KIT_FORMAT, MANIFEST_NAME, KitAsset, kit_asset,
                       kit_assets, kit_dir, load_glb_mesh, load_kit_mesh, read_manifest)

__all__ = ["ASSET_SPECS", "FLOATING_CATEGORIES", "KIT_CATEGORIES", "KIT_FORMAT", "MANIFEST_NAME", "AssetSpec",
           "KitAsset", "generate_kit", "glb_bytes", "kit_asset", "kit_assets", "kit_dir", "load_glb_mesh",
           "load_kit_mesh", "read_glb", "read_manifest"]
