"""One root exception; subclasses also inherit the matching builtin so callers can catch either.

Every message says what was wrong, the value, and what to do about it. The CLI prints
``CoastforgeError`` messages without a traceback.
"""

from __future__ import annotations


class CoastforgeError(Exception):
    """Root of every error coastforge raises on purpose."""


class InputError(CoastforgeError, ValueError):
    """A user input (file, option, value) is missing, unreadable or invalid."""


class ConfigError(CoastforgeError, ValueError):
    """A configuration key or value is unknown or of the wrong type."""


class SceneFormatError(CoastforgeError, ValueError):
    """A scene file (scene.json or its rasters) does not follow the coastforge.scene/1 contract."""


class BackendUnavailable(CoastforgeError, ImportError):
    """A backend needs a package, weights file or API key that is not present here."""


class OutputExistsError(CoastforgeError, FileExistsError):
    """An output would overwrite something that exists; pass --overwrite to replace it."""


class LibraryError(CoastforgeError, ValueError):
    """An asset library or one of its assets is invalid, corrupted or mismatched."""


class CoastforgeWarning(UserWarning):
    """Non-fatal problems users may want to filter (``warnings.filterwarnings``)."""


class GeoreferenceWarning(CoastforgeWarning):
    """The georeference was converted (e.g. a geographic CRS reprojected to metres)."""
