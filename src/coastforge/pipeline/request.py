"""What ``generate`` is asked for (``GenerateRequest``) and what it made (``GenerateResult``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from collections.abc import Callable

from ..scene import Scene, load_scene

Progress = Callable[[str, float], None]  # (stage name, fraction done)


@dataclass(frozen=True)
class GenerateRequest:
    image: str
    out: str
    gsd_m: float | None = None
    size_m: tuple[float, float] | None = None
    library: str | None = None
    exports: tuple[str, ...] = ()
    dems: tuple[str, ...] = ()
    overwrite: bool = False
    report: bool = True
    command: str = ""
    # a spawned side process for GIL-heavy side work on big images; off by default because a spawned
    # child re-imports the caller's __main__ (a script without a main guard would run twice): the CLI,
    # whose entry point is guarded, turns it on
    side_process: bool = False


@dataclass(frozen=True)
class GenerateResult:
    """What ``generate`` made: the paths of the scene, its exports and report, with the run's figures."""

    scene_path: Path
    out_dir: Path
    timings_s: dict[str, float]  # wall seconds per stage, and "total"
    n_objects: dict[str, int]  # per category, vegetation included
    exports: dict[str, list[Path]] = field(default_factory=dict)  # the written files per format
    report_path: Path | None = None
    warnings: list = field(default_factory=list)  # selfcheck.SceneWarning: the scene looks implausible
    notes: tuple[str, ...] = ()  # what the output folder's recovery did (an earlier run's leftovers removed)

    @cached_property
    def scene(self) -> Scene:
        """The generated scene, read from ``scene_path`` on first use (the command only prints paths)."""
        return load_scene(self.scene_path)
