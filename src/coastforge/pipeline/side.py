"""The side process's jobs (module-level functions, so a spawned process can run them by name)."""

from __future__ import annotations

from collections.abc import Callable

from ..config import Config, LibraryConfig
from ..types import Detection
from .libraries import fallback_kit, load_library


def warm_up() -> None:
    """Imports the side process needs first, done while the main process segments."""
    import cv2  # noqa: F401

    from .. import matching  # noqa: F401
    from ..assets import library  # noqa: F401
    from ..detection import classical, hybrid  # noqa: F401
    from ..segmentation import clean  # noqa: F401


_HERE: dict = {}  # the side process's own library, kept between its jobs


def preload_library(path: str | None, lib_config: LibraryConfig = LibraryConfig()) -> None:
    """Load the library into the side process ahead of its matching job."""
    _library_here(path, lib_config)


def _library_here(path: str | None, lib_config: LibraryConfig = LibraryConfig()):
    """The library in this process: loaded once in the side process (which lives for one run only); loaded
    afresh in the main process (where it runs only when the side process died)."""
    import multiprocessing

    if multiprocessing.parent_process() is None:
        return load_library(path, lib_config)
    key = (str(path or ""), lib_config)
    if key not in _HERE:
        _HERE[key] = load_library(path, lib_config)
    return _HERE[key]


def match_job(match: Callable, library_path: str | None, dets: list[Detection], config: Config) -> list:
    """``match`` (a front end's ``matcher()``) with this process's library (a module-level function for the
    side process)."""
    lib = _library_here(library_path, config.library)
    return match(dets, lib, config, fallback_kit(lib, library_path, config.library)[0])
