"""The starter kit as a library, built once into the user cache and reused."""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
from pathlib import Path

from ... import __version__
from ...config import LibraryConfig
from ...errors import LibraryError
from .build import build_library, config_dict
from .store import LIBRARY_JSON, Library, make_embedder, sha
from .views import view_settings


def cache_root() -> Path:
    """``$COASTFORGE_CACHE``, else ``$XDG_CACHE_HOME/coastforge``, else ``~/.cache/coastforge``."""
    if os.environ.get("COASTFORGE_CACHE"):
        return Path(os.environ["COASTFORGE_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "coastforge"


_DEFAULT: dict[str, Library] = {}


def default_library(config: LibraryConfig = LibraryConfig()) -> Library:
    """The starter kit as a library, built once into the user cache (atomically) and reused."""
    from ..kit import MANIFEST_NAME, kit_dir

    manifest = kit_dir() / MANIFEST_NAME
    if not manifest.is_file():
        raise LibraryError(f"the starter kit manifest {manifest} is missing; reinstall coastforge")
    kit_hash = hashlib.sha256(manifest.read_bytes())
    for p in sorted(kit_dir().glob("*.glb")):
        kit_hash.update(p.name.encode())
        kit_hash.update(p.read_bytes())
    emb = make_embedder(config.embedder)
    key = sha(kit_hash.hexdigest(), config_dict(config), emb.settings, view_settings(config), __version__)[:16]
    if key in _DEFAULT:
        return _DEFAULT[key]
    root = cache_root() / f"kit-{key}"
    lib = None
    if (root / LIBRARY_JSON).is_file():
        try:
            lib = Library.load(root)
        except LibraryError:
            lib = None  # corrupted cache: rebuild beside it and swap
    if lib is None:
        root.parent.mkdir(parents=True, exist_ok=True)
        tmp = root.parent / f".kit-{key}.tmp-{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        build_library(manifest, tmp, embedder=config.embedder, config=config, strict=True, keep_origin=True)
        if root.exists():
            try:  # another process finished first: keep its copy (it may be in use)
                Library.load(root)
            except LibraryError:  # the corrupted cache we could not load: replace it
                shutil.rmtree(root, ignore_errors=True)
        with contextlib.suppress(OSError):
            os.rename(tmp, root)
        shutil.rmtree(tmp, ignore_errors=True)
        lib = Library.load(root)
    _DEFAULT[key] = lib
    return lib


def open_library(path: str | Path | None = None, config: LibraryConfig = LibraryConfig()) -> Library:
    """The library at ``path``, or the starter-kit library when ``path`` is None (what ``--library`` means)."""
    return default_library(config) if path is None else Library.load(path)
