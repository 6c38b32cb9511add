"""``coastforge detect``: oriented boxes of boats, vehicles and piers, with heading, as JSON."""

from __future__ import annotations

import click

from .options import overwrite_option, pass_config, size_options


@click.command()
@click.argument("image", type=click.Path(dir_okay=False))
@size_options
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="Detections JSON to write.")
@click.option("--backend", default=None, help="Detector backend (classical, yolo, onnx; default from config).")
@click.option("--weights", default=None, type=click.Path(dir_okay=False), help="Local model file (yolo .pt, .onnx).")
@click.option("--overlay", default=None, type=click.Path(dir_okay=False), help="PNG with boxes and heading arrows.")
@click.option("--segment", "use_segment", is_flag=True,
              help="Segment the image first and detect with its terrain classes, as generate does (e.g. a boat "
                   "far from any water is not kept as a boat).")
@overwrite_option
@pass_config
def detect(image, gsd, size_m, out, backend, weights, overlay, use_segment, overwrite, config):
    """Detect boats, vehicles, buoys and pier walkways/fingers in IMAGE as oriented boxes."""
    from collections import Counter

    from ..detection import detect_file

    dets = detect_file(image, out, gsd_m=gsd, size_m=tuple(size_m) if size_m else None, backend=backend,
                       weights=weights, overlay=overlay, overwrite=overwrite, config=config,
                       segment=use_segment)
    counts = Counter(d.category for d in dets)
    summary = ", ".join(f"{n} {c}" for c, n in sorted(counts.items())) or "nothing"
    click.echo(f"{len(dets)} detections ({summary}) -> {out}")
