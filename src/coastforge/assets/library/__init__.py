"""Asset libraries: ingest 3D models (or Unreal thumbnails), render top-down views, embed, index."""

from .store import (CATEGORY_WORDS, CROWD_MAX_LENGTH_M, CROWD_MAX_PX, FLOATING, FORMAT, INDEX_FILE, LIBRARY_JSON,
                    PAINTS, QUERY_MIN_PX, QUERY_PAD, THUMBNAILS_FORMAT, Z_UP_TO_GLTF, AssetRecord, AssetSpec,
                    BuildReport, Library, SkippedAsset, build_library, cache_root, choose_view_gsd, crowd_mesh,
                    crowded_view, default_library, estimate_draft, guess_category, is_paintable, library_info,
                    open_library, parse_asset_entry, query_image, query_view_plan, read_manifest, read_query_views,
                    read_thumbnails, render_query_views, repaint, scale_variants, scan_folder, view_conditions,
                    view_lightings, view_settings, write_query_views)

__all__ = ["CATEGORY_WORDS", "CROWD_MAX_LENGTH_M", "CROWD_MAX_PX", "FLOATING", "FORMAT", "INDEX_FILE",
           "LIBRARY_JSON", "PAINTS", "QUERY_MIN_PX", "QUERY_PAD", "THUMBNAILS_FORMAT", "Z_UP_TO_GLTF",
           "AssetRecord", "AssetSpec", "BuildReport", "Library", "SkippedAsset", "build_library", "cache_root",
           "choose_view_gsd", "crowd_mesh", "crowded_view", "default_library", "estimate_draft",
           "guess_category", "is_paintable", "library_info", "open_library", "parse_asset_entry",
           "query_image", "query_view_plan", "read_manifest", "read_query_views", "read_thumbnails",
           "render_query_views", "repaint", "scale_variants", "scan_folder", "view_conditions",
           "view_lightings", "view_settings", "write_query_views"]
