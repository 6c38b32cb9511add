"""report.html: what a user looks at — one self-contained page that works offline from the file system."""

from .page import SECTION_FAILED, SECTIONS, TITLES, build_report, match_objects_to_decisions, top_gsd

__all__ = ["SECTION_FAILED", "SECTIONS", "TITLES", "build_report", "match_objects_to_decisions", "top_gsd"]
