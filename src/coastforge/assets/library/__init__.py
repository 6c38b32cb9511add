"""Asset libraries: ingest 3D models (or Unreal thumbnails), render top-down views, embed, index.

A library is a folder::

    library.json        format coastforge.library/1: assets, embedder, settings, content hashes
    index.faiss         one row per (asset, view, scale): L2-normalised embeddings, inner product
    meshes/<id>.glb     each model normalised to the scene frame (metres, z up, forward +x;
                        z = 0 at the waterline for floating assets, at the base for the rest)
    views/<id>/l<k>_<background>.png   top-down renders, lighting k of 3, background water|ground
    views/<id>/paint<k>_<background>.png   vehicles and small boats repainted in common body colours
    views/<id>/query_views.npz  small assets also rendered as a query sees them: at coarse GSDs (a few
                        pixels long), random yaw, cropped like the matcher's crops
                        (LibraryConfig.query_view_*); vehicles and boats also between copies of
                        themselves (LibraryConfig.crowded_views)
    views/<id>/silhouette.png   the footprint (255 = object), aligned with the views

``build_library`` re-renders only assets whose mesh or settings changed and re-embeds only what the
embedder has not seen. ``Library.load`` checks the format, the index hash and shape, and the
embedder; a query with another embedder is refused.

Modules: ``store`` (``Library``), ``build`` (``build_library``), ``manifest`` (what a library is built from),
``ingest`` (one asset's model and views, in a worker), ``thumbnails`` (Unreal thumbnails instead of models),
``views`` (the views kept of each asset), ``paints`` (body colours), ``cache`` (the starter kit's library),
``queries`` (``library query`` and ``library info``).
"""

from .build import BuildReport, build_library
from .cache import cache_root, default_library, open_library
from .ingest import FLOATING, estimate_draft
from .manifest import (CATEGORY_WORDS, AssetSpec, SkippedAsset, guess_category, parse_asset_entry,
                       read_manifest, scan_folder)
from .paints import PAINTS, cover, is_paintable, repaint
from .queries import library_info, query_image
from .store import FORMAT, INDEX_FILE, LIBRARY_JSON, Z_UP_TO_GLTF, AssetRecord, Library
from .thumbnails import THUMBNAILS_FORMAT, read_thumbnails
from .views import (CROWD_MAX_LENGTH_M, CROWD_MAX_PX, QUERY_MIN_PX, QUERY_PAD, choose_view_gsd, crowd_mesh,
                    crowded_view, query_view_plan, random_lit_view, read_query_views, render_query_views,
                    scale_variants, view_conditions, view_lightings, view_settings, write_query_views)

__all__ = [
                       "CATEGORY_WORDS",
                       "CROWD_MAX_LENGTH_M",
                       "CROWD_MAX_PX",
                       "FLOATING",
                       "FORMAT",
                       "INDEX_FILE",
                       "LIBRARY_JSON",
                       "PAINTS",
                       "QUERY_MIN_PX",
                       "QUERY_PAD",
                       "THUMBNAILS_FORMAT",
                       "Z_UP_TO_GLTF",
                       "AssetRecord",
                       "AssetSpec",
                       "BuildReport",
                       "Library",
                       "SkippedAsset",
                       "build_library",
                       "cache_root",
                       "choose_view_gsd",
                       "cover",
                       "crowd_mesh",
                       "crowded_view",
                       "default_library",
                       "estimate_draft",
                       "guess_category",
                       "is_paintable",
                       "library_info",
                       "open_library",
                       "parse_asset_entry",
                       "query_image",
                       "query_view_plan",
                       "random_lit_view",
                       "read_manifest",
                       "read_query_views",
                       "read_thumbnails",
                       "render_query_views",
                       "repaint",
                       "scale_variants",
                       "scan_folder",
                       "view_conditions",
                       "view_lightings",
                       "view_settings",
                       "write_query_views",
]
