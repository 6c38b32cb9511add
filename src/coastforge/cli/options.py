"""Options shared by several subcommands."""

from __future__ import annotations

import functools

import click


def size_options(f):
    """--gsd M / --size-m W H: the ground size of a plain image."""
    f = click.option("--size-m", nargs=2, type=float, default=None, metavar="W H",
                     help="Width and height of the image on the ground, in metres.")(f)
    f = click.option("--gsd", type=float, default=None, metavar="M",
                     help="Metres per pixel (ground sample distance).")(f)
    return f


def config_options(f):
    """--preset, --config, --set key=value, --seed: the one typed config and the root seed."""
    f = click.option("--seed", type=int, default=None, help="Root seed for everything random (default 0).")(f)
    f = click.option("--set", "sets", multiple=True, metavar="KEY=VALUE",
                     help="Override a config value, e.g. --set terrain.max_depth_m=12 (repeatable).")(f)
    f = click.option("--config", "config_path", type=click.Path(dir_okay=False), default=None,
                     help="A TOML config file (sections as in the presets).")(f)
    f = click.option("--preset", default="default", show_default=True, help="Named config preset.")(f)
    return f


def overwrite_option(f):
    return click.option("--overwrite", is_flag=True,
                        help="Replace existing outputs (a whole output folder, if an earlier run made it).")(f)


def build_config(preset, config_path, sets, seed):
    from ..config import load_config

    return load_config(preset, config_path, list(sets), seed)


def pass_config(f):
    """Decorator: turn the config options into one ``config`` keyword argument."""

    @config_options
    @functools.wraps(f)
    def wrapper(*args, preset, config_path, sets, seed, **kw):
        return f(*args, config=build_config(preset, config_path, sets, seed), **kw)

    return wrapper


def staged(out, *, overwrite: bool = False, update: bool = False, inputs=()):
    """``fsio.output_folder`` for a command: all-or-nothing writes into ``out``, one writer at a time; what
    recovery did (an earlier run's leftovers) is printed."""
    import contextlib
    import shlex
    import sys

    from ..fsio import output_folder

    @contextlib.contextmanager
    def run():
        notes: list[str] = []
        with output_folder(out, overwrite=overwrite, update=update, notes=notes, inputs=inputs,
                           command=shlex.join(["coastforge", *sys.argv[1:]])) as stage:
            for n in notes:
                click.echo(f"note: {n}", err=True)
            yield stage

    return run()
