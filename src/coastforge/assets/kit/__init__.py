"""The procedural starter asset kit: low-poly boats, vehicles, pier segments, buoys and vegetation."""

from .build import (ASSET_SPECS, FLOATING_CATEGORIES, KIT_CATEGORIES, KIT_FORMAT, MANIFEST_NAME, AssetSpec, KitAsset,
                    generate_kit, glb_bytes, kit_asset, kit_assets, kit_dir, load_glb_mesh, load_kit_mesh, read_glb,
                    read_manifest)

__all__ = ["ASSET_SPECS", "FLOATING_CATEGORIES", "KIT_CATEGORIES", "KIT_FORMAT", "MANIFEST_NAME", "AssetSpec",
           "KitAsset", "generate_kit", "glb_bytes", "kit_asset", "kit_assets", "kit_dir", "load_glb_mesh",
           "load_kit_mesh", "read_glb", "read_manifest"]
