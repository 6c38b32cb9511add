"""report.html: what a user looks at — one self-contained page that works offline from the file system.

Modules: ``page`` (``build_report``: the page and the order its sections are built in), ``sections`` (each
section's HTML), ``figures`` (the terrain figures as inline SVG), ``previews`` (the render from above and the
3D preview's GLB), ``inputs`` (what the report reads beside the scene), ``markup`` (data URIs, figures,
tables, the static files); ``static/`` holds the page's stylesheet and script and the 3D viewer bundle.
"""

from .inputs import match_objects_to_decisions
from .page import SECTION_FAILED, SECTIONS, TITLES, build_report
from .previews import top_gsd

__all__ = ["SECTIONS", "SECTION_FAILED", "TITLES", "build_report", "match_objects_to_decisions", "top_gsd"]
