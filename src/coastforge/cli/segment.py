"""``coastforge segment`` (terrain classes and their rasters) and ``coastforge clean`` (inpaint boats and cars)."""

from __future__ import annotations

import click

from .options import overwrite_option, pass_config, size_options, staged


@click.command()
@click.argument("image", type=click.Path(dir_okay=False))
@size_options
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output folder: classes.png, classes_preview.png, weights/, biome.png, biome.json.")
@click.option("--backend", default=None,
              help="learned (default), classical, labels, onnx or gemini; see `coastforge backends`.")
@click.option("--labels", type=click.Path(dir_okay=False), default=None,
              help="labels backend: your class raster (PNG or GeoTIFF).")
@click.option("--mapping", type=click.Path(dir_okay=False), default=None,
              help="labels/onnx backends: JSON or TOML mapping from your values/colours (or model classes) to ours.")
@click.option("--weights", type=click.Path(dir_okay=False), default=None, help="onnx backend: the .onnx model.")
@overwrite_option
@pass_config
def segment(image, gsd, size_m, out_dir, backend, labels, mapping, weights, overwrite, config):
    """Segment IMAGE into the eight terrain classes and write the class rasters to --out."""
    from ..segmentation import segment_file

    name = backend or config.segment.backend
    options = {}
    if name == "labels":
        options = {"labels": labels, "mapping": mapping}
    elif name == "onnx":
        options = {"weights": weights, "mapping": mapping}
    elif labels or weights:
        raise click.UsageError("--labels goes with --backend labels, --weights with --backend onnx")
    with staged(out_dir, overwrite=overwrite, inputs=(image, labels, mapping, weights)) as stage:  # all-or-nothing
        res = segment_file(image, stage, gsd_m=gsd, size_m=tuple(size_m) if size_m else None, config=config,
                           backend=name, overwrite=True, **options)
    fr = res["class_fractions"]
    click.echo(f"wrote {out_dir}: " + ", ".join(f"{k} {v:.1%}" for k, v in fr.items() if v > 0))


@click.command()
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--detections", required=True, type=click.Path(dir_okay=False),
              help="JSON from `coastforge detect` (oriented boxes); boats, vehicles and buoys are removed.")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False), help="The cleaned PNG.")
@click.option("--classes", "classes_path", type=click.Path(dir_okay=False), default=None,
              help="Optional classes.png from `coastforge segment`: large holes are filled from their own class.")
@size_options
@overwrite_option
@pass_config
def clean(image, detections, out_path, classes_path, gsd, size_m, overwrite, config):
    """Remove boats and vehicles from IMAGE by inpainting; write the cleaned image to --out."""
    from ..segmentation.clean import clean_file

    path = clean_file(image, detections, out_path, gsd_m=gsd, size_m=tuple(size_m) if size_m else None,
                      config=config, overwrite=overwrite, classes_path=classes_path)
    click.echo(f"wrote {path}")
