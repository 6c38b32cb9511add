"""``coastforge benchmark``: the paper's results table on coastforge's own synthetic levels."""

from __future__ import annotations

import json

import click

from .options import overwrite_option, pass_config


@click.command()
@click.option("--out", default="out/benchmark", show_default=True, type=click.Path(), help="Working folder.")
@click.option("--presets", default="", help="Comma-separated levels (default: all).")
@click.option("--gsd", "gsds", default="0.1,0.2", show_default=True, help="High and low resolution, m/px.")
@click.option("--library", type=click.Path(), default=None, help="Asset library (default: the starter kit).")
@click.option("--json", "as_json", is_flag=True, help="Print the JSON result instead of Markdown.")
@overwrite_option
@pass_config
def benchmark(out, presets, gsds, library, as_json, overwrite, config):
    """Synthesize the benchmark levels at both resolutions, run generate, evaluate, print the table."""
    from ..bench.paper import check_benchmark, run_benchmark, to_markdown
    from ..errors import InputError
    from .options import staged

    try:
        g = tuple(float(v) for v in gsds.split(","))
    except ValueError as exc:
        raise InputError(f"--gsd {gsds!r} must be comma-separated metres per pixel, e.g. 0.1,0.2") from exc
    names = [p.strip() for p in presets.split(",") if p.strip()] or None
    names, g = check_benchmark(names, g, library)  # every check before the first write
    # all-or-nothing like every output folder: a stopped benchmark leaves --out as it was
    with staged(out, overwrite=overwrite, inputs=(library,)) as stage:
        res = run_benchmark(stage, names, config.seed, g, library, config, True,
                            log=lambda s: click.echo(s, err=True))
    click.echo(json.dumps(res, indent=2) if as_json else to_markdown(res))
