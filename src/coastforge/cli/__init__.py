"""The ``coastforge`` command. Subcommands live one per module and are imported only when run,
so ``coastforge --help`` stays instant. A ``CoastforgeError`` is printed as a one-line error
(no traceback) with exit code 2."""

from __future__ import annotations

import importlib
import os
import sys

import click

from .. import __version__
from ..errors import CoastforgeError

# name -> (module, attribute, one-line help). Kept here so listing commands imports nothing.
COMMANDS: dict[str, tuple[str, str, str]] = {
    "generate": ("generate", "generate", "Run the whole pipeline: image in, scene (and exports) out."),
    "synth": ("synth", "synth", "Synthesize a ground-truth coastal level and render its aerial images."),
    "evaluate": ("evaluate", "evaluate", "Compare a generated scene against a truth scene (paper metrics)."),
    "benchmark": ("benchmark", "benchmark", "Run the synthetic benchmark and print the paper's table."),
    "segment": ("segment", "segment", "Segment an image into the eight terrain classes."),
    "clean": ("segment", "clean", "Remove boats and vehicles from an image by inpainting."),
    "terrain": ("terrain", "terrain", "Estimate a height map (land and bathymetry) for a scene."),
    "detect": ("detect", "detect", "Detect boats, vehicles and piers as oriented boxes with heading."),
    "library": ("library", "library", "Build and query asset libraries (render, embed, FAISS index)."),
    "export": ("export", "export", "Export a scene to ue5, holoocean, gltf, usd, sdf."),
    "report": ("report", "report", "Build the HTML report of a generated scene."),
    "render": ("render", "render", "Render a scene from above (orthographic)."),
    "batch": ("batch", "batch", "Generate many scenes on a Dask cluster."),
    "backends": ("backends", "backends", "List every stage's backends and whether each is usable here."),
}


class LazyGroup(click.Group):
    def list_commands(self, ctx):
        return [n for n, (mod, _a, _h) in COMMANDS.items() if importlib.util.find_spec(f"{__name__}.{mod}")]

    def get_command(self, ctx, name):
        if name not in COMMANDS:
            return None
        mod, attr, _h = COMMANDS[name]
        try:
            module = importlib.import_module(f"{__name__}.{mod}")
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{mod}":
                return None
            raise
        return getattr(module, attr)

    def format_commands(self, ctx, formatter):
        rows = [(n, COMMANDS[n][2]) for n in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except CoastforgeError as exc:
            _echo_error(str(exc), exc)
            ctx.exit(2)
        except KeyboardInterrupt as exc:
            notes = getattr(exc, "__notes__", None)
            click.echo("Interrupted; " + (notes[-1] if notes else "files already written are complete and kept."),
                       err=True)
            ctx.exit(130)
        except MemoryError as exc:
            _echo_error("out of memory; try a smaller image, a coarser --gsd, or a machine with more memory", exc)
            ctx.exit(2)
        except OSError as exc:  # no space, read-only, permission, not a folder, loops: name the path
            from ..fsio import os_error_message

            _echo_error(os_error_message(exc), exc)
            ctx.exit(2)
        except Exception as exc:  # a bug of ours: one line here, the traceback in a log file
            if os.environ.get("COASTFORGE_DEBUG"):
                raise
            log = _write_crash_log(exc)
            _echo_error(f"unexpected {type(exc).__name__}: {exc}", exc)
            click.echo(f"This is a coastforge bug; the traceback is in {log}. Please report it with that file.",
                       err=True)
            ctx.exit(3)


def _echo_error(message: str, exc: BaseException) -> None:
    """One line for the error, then any notes (e.g. where a failed run left its partial output)."""
    click.echo(f"Error: {message}", err=True)
    for note in getattr(exc, "__notes__", ()) or ():
        click.echo(f"  {note}", err=True)


def _write_crash_log(exc: BaseException) -> str:
    """Write the traceback of an unexpected error to a log file; returns its path."""
    import tempfile
    import time
    import traceback
    from pathlib import Path

    text = (f"coastforge {__version__}\ncommand: {' '.join(sys.argv)}\n\n"
            + "".join(traceback.format_exception(exc)))
    name = f"crash-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.log"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "coastforge" / "logs"
    for folder in (base, Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text, encoding="utf-8")
            return str(folder / name)
        except OSError:
            continue
    return "(no writable folder for the log; run again with COASTFORGE_DEBUG=1 to see it)"


import importlib.util  # noqa: E402  (used by LazyGroup.list_commands)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="coastforge")
def cli() -> None:
    """coastforge: one overhead image of a coastline in, a marine-robotics simulation environment out.

    Start with `coastforge generate IMAGE --gsd 0.2 --out DIR`; every command has --help.
    """


def _on_sigint(signum, frame) -> None:
    """Ctrl-C: raise KeyboardInterrupt as Python does, and remember it, so a library that swallows it (trimesh
    catches BaseException around its imports) cannot let the run go on to write its output."""
    from ..fsio import note_interrupt

    note_interrupt()
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> None:
    import signal
    import threading

    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    # GDAL's default handler prints raw lines such as "ERROR 1: PROJ: ... crs not found" before our message;
    # rasterio turns the errors that matter into exceptions, whose reason our messages quote
    os.environ.setdefault("CPL_LOG", os.devnull)
    cli.main(args=argv if argv is not None else sys.argv[1:], prog_name="coastforge")
