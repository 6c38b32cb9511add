"""The Python API: what the ``generate``, ``export`` and ``evaluate`` commands do, callable from a script or a
notebook. ``import coastforge`` offers these names (loaded on first use)::

    import coastforge

    run = coastforge.generate("harbor.jpg", gsd=0.2, out="my_scene", export=["gltf"], preset="fast")
    scene = run.scene                                   # or coastforge.Scene.load("my_scene")
    coastforge.export_scene("my_scene", ["sdf"])        # adds my_scene/sdf/
    metrics = coastforge.evaluate_scenes("truth.json", scene)

The commands are thin calls of these functions, so a call writes exactly what its command writes: all or
nothing (``fsio.output_folder``: a staging folder beside ``out`` swapped in when complete; one writer per
folder; nothing of the user's replaced), with every input checked before the first write. Bad input raises
an error of ``coastforge.errors`` (``CoastforgeError`` and its subclasses, which also derive from the
matching builtin, e.g. ``InputError`` from ``ValueError``) whose message is the one the command prints; it
names the command's option, and each option is the keyword of the same name here (``--overwrite``:
``overwrite=True``).

Configuration is the commands' too: ``preset`` (``--preset``), ``config`` (a ``Config`` object, or a TOML
file as ``--config``), ``settings`` (``--set``: a mapping of dotted keys to values, or ``KEY=VALUE``
strings) and ``seed`` (``--seed``), applied in that order (``make_config``).

``coastforge.export`` and ``coastforge.evaluate`` are modules, and importing a submodule makes it an
attribute of its package, so the functions of those commands are ``export_scene`` and ``evaluate_scenes``.
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

from .errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from .config import Config
    from .pipeline import GenerateResult
    from .scene import Scene

PathLike = Union[str, "os.PathLike[str]"]
Settings = Mapping[str, Any] | Iterable[str]  # {"terrain.max_depth_m": 12} or ["terrain.max_depth_m=12"]

__all__ = ["ExportResult", "evaluate_scenes", "export_scene", "generate", "make_config"]


def make_config(config: Config | PathLike | None = None, *, preset: str | None = None,
                settings: Settings | None = None, seed: int | None = None) -> Config:
    """The run's config as the commands build it: the ``preset`` (default ``"default"``; see
    ``coastforge.config.preset_names()``) or a ``Config`` object, then a TOML file (``config`` as a path),
    then ``settings``, then ``seed``. Raises ``ConfigError`` naming a bad key or value."""
    from .config import Config, apply_settings, load_config, preset_names, validate_config, with_seed
    from .errors import ConfigError

    if isinstance(config, Config):
        if preset is not None:
            raise ConfigError(f"preset {preset!r} and a Config object were both given; pass one of them (a "
                              "preset is only a starting Config: coastforge.make_config(preset=...))")
        cfg = config
    elif config is None or isinstance(config, (str, os.PathLike)):
        if preset is not None and not isinstance(preset, str):
            raise ConfigError(f"preset {preset!r} must be a preset name, one of "
                              f"{', '.join(preset_names())}")
        cfg = load_config(preset or "default", config)
    else:
        raise ConfigError(f"config must be a coastforge.Config, the path of a TOML file or None, got "
                          f"{type(config).__name__}")
    cfg = apply_settings(cfg, settings)
    if seed is not None:
        cfg = with_seed(cfg, seed)
    return validate_config(cfg)


def generate(image: PathLike, *, out: PathLike, gsd: float | None = None,
             size_m: tuple[float, float] | None = None, export: str | Iterable[str] = (),
             library: PathLike | None = None, dem: PathLike | Iterable[PathLike] = (), report: bool = True,
             overwrite: bool = False, config: Config | PathLike | None = None, preset: str | None = None,
             settings: Settings | None = None, seed: int | None = None,
             progress: Callable[[str, float], None] | None = None, side_process: bool = False,
             command: str | None = None) -> GenerateResult:
    """Turn ``image`` (a PNG/JPEG with ``gsd`` metres per pixel or its ``size_m`` (width, height), or a
    GeoTIFF) into a scene in the folder ``out``, as ``coastforge generate`` does; returns a
    ``GenerateResult``: ``scene`` (loaded on first use), ``scene_path``, ``exports`` (files per format),
    ``report_path``, ``warnings`` (the self-check), ``timings_s``, ``n_objects`` and ``notes``.

    ``export``: formats (``["gltf", "usd"]`` or ``"gltf,usd"``; see ``coastforge.export.FORMATS``).
    ``library``: an asset library folder (default: the starter kit). ``dem``: DEM / bathymetry GeoTIFFs to
    fuse (``FILE`` or ``FILE:offset=-0.3,scale=0.3048``). ``report``: write ``report.html``. ``progress``:
    called with (stage name, fraction done). ``side_process``: on big images, run part of the side work in
    a spawned process, as the command does; Python starts it by re-importing the caller's ``__main__``,
    so a script that sets it needs an ``if __name__ == "__main__":`` guard. ``command``: what made the scene,
    for its provenance (default: this call, written out)."""
    from . import pipeline
    from .config import Config

    cfg = make_config(config, preset=preset, settings=settings, seed=seed)
    image, out, exports, dems = _path(image, "image"), _path(out, "out"), _generate_formats(export), _dems(dem)
    library = None if library is None else _path(library, "library")
    if command is None:
        command = _call("generate", image, out=out, gsd=gsd, size_m=size_m, export=exports, library=library,
                        dem=dems, config=None if isinstance(config, Config) else config, preset=preset,
                        settings=settings, seed=seed)
    req = pipeline.GenerateRequest(image=image, out=out, gsd_m=_gsd(gsd), size_m=_size(size_m), library=library,
                                   exports=exports, dems=dems, overwrite=_flag(overwrite, "overwrite"),
                                   report=_flag(report, "report"), command=command,
                                   side_process=_flag(side_process, "side_process"))
    return pipeline.run_generate(req, cfg, progress)


@dataclass(frozen=True)
class ExportResult:
    """What ``export_scene`` wrote: each format's files under ``out_dir/<format>/``."""

    out_dir: Path
    files: dict[str, list[Path]]  # per format, in the order asked
    notes: tuple[str, ...] = ()  # what the output folder's recovery did (an earlier run's leftovers removed)


def export_scene(scene: Scene | PathLike, formats: str | Iterable[str] | None = None, *,
                 out: PathLike | None = None, library: PathLike | None = None, overwrite: bool = False,
                 config: Config | PathLike | None = None, preset: str | None = None,
                 settings: Settings | None = None, command: str | None = None) -> ExportResult:
    """Export a scene to simulator formats, each under ``out/<format>/``, as ``coastforge export`` does.

    ``scene``: a scene folder (or its scene.json), whose cleaned image textures the terrain, or a ``Scene``
    object (e.g. one changed in memory), which needs ``out`` and whose terrain takes the class colours.
    ``formats``: ``["ue5", "gltf"]`` or ``"ue5,gltf"`` (default: ``export.formats`` of the config). ``out``:
    default, the scene folder. ``library``: the asset library holding the scene's assets (default: the
    starter kit). An existing export is replaced only with ``overwrite``; all formats are written, or none."""
    from .errors import OutputExistsError
    from .export import export_scene as write_exports
    from .export import parse_formats, require_rasters
    from .fsio import output_folder
    from .scene import Scene, load_scene

    cfg = make_config(config, preset=preset, settings=settings)
    overwrite = _flag(overwrite, "overwrite")
    lib = None
    if library is not None:
        from .assets.library import Library

        lib = Library.load(_path(library, "library"))
    # checked before any write
    fmts = parse_formats(_names(formats, "formats") if formats is not None else cfg.export.formats)
    src: Scene | Path
    if isinstance(scene, Scene):
        if out is None:
            raise InputError("a Scene object has no folder to export into; pass out=DIR (or pass the scene's "
                             "folder instead of the object)")
        src = scene
        require_rasters(scene)
        target = Path(_path(out, "out"))
    else:
        src = Path(_path(scene, "scene"))
        require_rasters(load_scene(src))  # so is the scene, with its real paths in the messages
        target = Path(_path(out, "out")) if out is not None else (src.parent if src.is_file() else src)
    if not overwrite:  # before any work: an existing export is replaced only on request
        done = [f for f in fmts if (target / f).is_dir() and any((target / f).iterdir())]
        if done:
            raise OutputExistsError(f"{target / done[0]} exists; pass --overwrite to replace the {done[0]} "
                                    "export, or choose another --out")
    if command is None:
        command = _call("export_scene", src if isinstance(src, Path) else _Repr(f"<Scene {src.name!r}>"),
                        formats=fmts, out=target, library=library)
    notes: list[str] = []
    # all-or-nothing: every format is written into a staging copy of the target, swapped in when all are done
    with output_folder(target, update=True, notes=notes, command=command) as stage:
        written = write_exports(src, fmts, out_dir=stage, overwrite=overwrite, config=cfg.export, library=lib)
    files = {f: [target / p.relative_to(stage) for p in ps] for f, ps in written.items()}
    return ExportResult(target, files, tuple(notes))


def evaluate_scenes(truth: Scene | PathLike, pred: Scene | PathLike) -> dict[str, Any]:
    """The metrics of ``pred`` against ``truth`` (DESIGN.md §5), as ``coastforge evaluate --json`` prints
    them: ``n_truth``, ``n_pred``, ``n_matched``, ``xy_rmse_m``, ``rotation_rmse_deg``,
    ``orientation_rmse_deg``, ``recall``, ``match_precision``, ``match_precision_category``,
    ``detection_precision``, ``per_category`` (the same per object category), ``terrain`` (``miou``, height
    RMSE on land and water) and ``piers`` (connectivity). Each scene is a ``Scene``, a scene folder, its
    scene.json, or a synthetic level's truth.json; both must cover the same ground (else ``InputError``)."""
    from .evaluate import evaluate_scenes as metrics
    from .scene import Scene, load_scene

    def scene_of(s: Any, what: str) -> Scene:
        return s if isinstance(s, Scene) else load_scene(_path(s, what))

    return metrics(scene_of(truth, "truth"), scene_of(pred, "pred"))


# ------------------------------------------------------------------ argument checks (before any work)


def _path(value: Any, what: str) -> str:
    if isinstance(value, (str, os.PathLike)):
        text = os.fspath(value)
        if isinstance(text, str) and text:
            return text
    raise InputError(f"{what} must be a path (a str or pathlib.Path), got {value!r}")


def _gsd(value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return float(value)  # its range is checked where the image is read, as for --gsd
    raise InputError(f"gsd {value!r} must be a positive number of metres per pixel (e.g. 0.2)")


def _size(value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        w, h = value
        if all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in (w, h)):
            return float(w), float(h)
    except (TypeError, ValueError):
        pass
    raise InputError(f"size_m {value!r} must be the image's (width, height) on the ground, in metres")


def _flag(value: Any, what: str) -> bool:
    if isinstance(value, bool):
        return value
    raise InputError(f"{what} must be True or False, got {value!r}")


def _names(value: Any, what: str) -> tuple[str, ...]:
    """A comma-separated string or an iterable of strings, as a tuple of stripped non-empty names."""
    items = value.split(",") if isinstance(value, str) else value
    try:
        items = tuple(items)
    except TypeError:
        items = (None,)
    if not all(isinstance(i, str) for i in items):
        raise InputError(f"{what} must be a list of names or one comma-separated string, got {value!r}")
    return tuple(i.strip() for i in items if i.strip())


def _generate_formats(value: Any) -> tuple[str, ...]:
    from .export import FORMATS

    fmts = _names(value, "export")
    bad = [f for f in fmts if f not in FORMATS]
    if bad:
        raise InputError(f"--export {','.join(bad)} is not a known format; valid formats: {', '.join(FORMATS)}")
    return fmts


def _dems(value: Any) -> tuple[str, ...]:
    if isinstance(value, (str, os.PathLike)):
        value = (value,)
    try:
        items = tuple(value)
    except TypeError:
        items = (None,)
    return tuple(_path(d, "dem") for d in items)


class _Repr(str):
    """Text shown as is in ``_call`` (not quoted)."""

    def __repr__(self) -> str:
        return str(self)


def _call(name: str, first: Any, **kw: Any) -> str:
    """``coastforge.NAME(FIRST, key=value, ...)`` with the arguments given: a call's provenance."""
    def text(v: Any) -> str:
        return repr(os.fspath(v)) if isinstance(v, os.PathLike) else repr(v)

    args = [text(first)] + [f"{k}={text(v)}" for k, v in kw.items()
                            if v is not None and not (isinstance(v, (tuple, list)) and not v)]
    return f"coastforge.{name}({', '.join(args)})"
