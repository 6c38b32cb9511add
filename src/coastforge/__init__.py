"""coastforge: one overhead image of a coastline in, a marine-robotics simulation environment out.

The Python API (``coastforge.api``; the commands are thin calls of it)::

    import coastforge

    run = coastforge.generate("harbor.jpg", gsd=0.2, out="my_scene", export=["gltf"])
    scene = coastforge.Scene.load("my_scene")
    coastforge.export_scene("my_scene", ["sdf"])
    metrics = coastforge.evaluate_scenes("truth.json", "my_scene")

Its names are loaded on first use (PEP 562), so ``import coastforge`` imports nothing heavy and
``coastforge --help`` answers instantly.
"""

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> (module, attribute), imported on first access
_LAZY: dict[str, tuple[str, str]] = {
    "generate": ("api", "generate"),
    "export_scene": ("api", "export_scene"),
    "evaluate_scenes": ("api", "evaluate_scenes"),
    "make_config": ("api", "make_config"),
    "ExportResult": ("api", "ExportResult"),
    "GenerateResult": ("pipeline", "GenerateResult"),
    "Scene": ("scene", "Scene"),
    "SceneObject": ("scene", "SceneObject"),
    "Config": ("config", "Config"),
    "CoastforgeError": ("errors", "CoastforgeError"),
}

__all__ = ["__version__", *_LAZY]

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time __getattr__ imports on first use
    # `import X as X`: an explicit re-export (these names are the package's API)
    from .api import ExportResult as ExportResult
    from .api import evaluate_scenes as evaluate_scenes
    from .api import export_scene as export_scene
    from .api import generate as generate
    from .api import make_config as make_config
    from .config import Config as Config
    from .errors import CoastforgeError as CoastforgeError
    from .pipeline import GenerateResult as GenerateResult
    from .scene import Scene as Scene
    from .scene import SceneObject as SceneObject


def __getattr__(name: str) -> Any:
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), attr)
    globals()[name] = value  # later look-ups skip __getattr__
    return value


def __dir__() -> list[str]:
    # the API, loaded or not, and the submodules imported so far (not this file's own imports)
    subs = {n for n, v in globals().items() if getattr(v, "__name__", "").startswith(f"{__name__}.")}
    return sorted({*__all__, *subs})
