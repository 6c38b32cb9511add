"""The run's asset libraries: the user's (``--library``) or the starter kit, and the kit standing in for the
categories a user's library lacks."""

from __future__ import annotations

from ..config import LibraryConfig


def load_library(path: str | None, config: LibraryConfig = LibraryConfig()):
    """The library at ``path``, else the starter kit built with ``config`` (a built library keeps its own)."""
    from ..assets import library as lib_mod

    return lib_mod.Library.load(path) if path else lib_mod.default_library(config)


def fallback_kit(library, path: str | None, config: LibraryConfig = LibraryConfig()):
    """``(starter kit, categories it stands in for)`` when the user's library (``path``) lacks asset
    categories a scene may need, else ``(None, ())``: a missing category never aborts a run. The kit is
    built with ``config``."""
    from ..classes import ASSET_CATEGORIES

    if path is None:
        return None, ()
    have = {a.category for a in library.assets}
    missing = tuple(c for c in ASSET_CATEGORIES if c not in have)
    if not missing:
        return None, ()
    from ..assets.library import default_library

    return default_library(config), missing


def fallback_warning(path: str | None, missing: tuple[str, ...]):
    from ..selfcheck import SceneWarning

    return SceneWarning("library_fallback", f"The library {path} has no {', '.join(missing)} asset; the starter "
                        "kit's were used for these categories.",
                        "Add such assets to the library (coastforge library build) to use your own.")


def pier_assets(library):
    piers = [a for a in library.assets if a.category == "pier"]
    if not piers:
        return None, None

    def pick(word):
        for a in piers:
            if word in a.id or word in tuple(getattr(a, "tags", ()) or ()):
                return a
        return None

    walk = pick("walkway") or max(piers, key=lambda a: a.dims_m[1])
    finger = pick("finger") or min(piers, key=lambda a: a.dims_m[1])
    return walk, finger


def assets_by_category(library, kit=None) -> dict[str, list[str]]:
    """Asset ids per category; the categories ``library`` lacks come from ``kit`` (if given)."""
    out: dict[str, list[str]] = {}
    for a in library.assets:
        out.setdefault(a.category, []).append(a.id)
    own = set(out)
    for a in (kit.assets if kit is not None else ()):
        if a.category not in own:
            out.setdefault(a.category, []).append(a.id)
    return out
