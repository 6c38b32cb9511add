"""``coastforge library build|query|info``: asset libraries (render, embed, FAISS index)."""

from __future__ import annotations

import json

import click

from .options import overwrite_option, pass_config, staged


@click.group()
def library() -> None:
    """Build and query asset libraries (3D models or Unreal thumbnails → views → embeddings → FAISS)."""


@library.command("build")
@click.argument("src", required=False, type=click.Path())
@click.option("--out", "out", required=True, type=click.Path(file_okay=False), help="Library folder to write.")
@click.option("--embedder", default=None, help="Embedder backend (default, dinov3); see `coastforge backends`.")
@click.option("--weights", type=click.Path(), default=None, help="Local weights folder for weights-based embedders.")
@click.option("--strict", is_flag=True, help="Stop at the first bad asset instead of reporting and skipping it.")
@click.option("--from-thumbnails", "thumbs", type=click.Path(file_okay=False), default=None,
              help="Build from a folder captured by the Unreal script (thumbnails.json + PNGs).")
@click.option("--workers", type=int, default=None, help="Render processes (default: one per core).")
@click.option("--json", "as_json", is_flag=True, help="Print the build report as JSON.")
@overwrite_option
@pass_config
def build(src, out, embedder, weights, strict, thumbs, workers, as_json, overwrite, config) -> None:
    """Build (or update) a library from SRC: a folder of models (GLB/glTF/OBJ/PLY/STL) or a JSON/TOML
    manifest with an `assets` list (id, category, mesh, optional length_m, up_axis, forward_axis, ue_path,
    tags). Only assets whose model or settings changed are re-rendered."""
    from ..assets.library import build_library

    from ..assets.library import Library
    from ..errors import InputError

    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers} must be at least 1 (render processes; leave it out for one per core)")
    say = (lambda m: None) if as_json else (lambda m: click.echo(m, err=True))
    with staged(out, update=True) as stage:  # all-or-nothing: the library changes only once the build is done
        built = build_library(src, stage, embedder=embedder or config.library.embedder, weights=weights,
                              strict=strict, config=config.library, from_thumbnails=thumbs, overwrite=overwrite,
                              workers=workers, progress=say, shown_as=out)
    r = built.build_report
    lib = Library.load(out, weights=weights)
    if as_json:
        click.echo(json.dumps({
            "library": str(lib.root), "assets": [a.id for a in lib.assets], "rendered": list(r.rendered),
            "reused": list(r.reused), "embedded": list(r.embedded),
            "skipped": [{"id": s.id, "error": s.error} for s in r.skipped],
            "notes": {k: list(v) for k, v in r.notes.items()}, "rows": r.rows, "seconds": round(r.seconds, 3),
        }, indent=2))
        return
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    t = Table(title=f"asset library {escape(str(lib.root))}")
    for col in ("id", "category", "L x W x H (m)", "view m/px", "status", "guesses"):
        t.add_column(col)
    for a in lib.assets:
        status = "rendered" if a.id in r.rendered else "reused"
        t.add_row(escape(a.id), a.category, " x ".join(f"{v:.2f}" for v in a.dims_m), f"{a.view_gsd_m:g}", status,
                  escape("; ".join(r.notes.get(a.id, ()))))
    con = Console()
    con.print(t)
    for s in r.skipped:
        con.print(f"[yellow]skipped[/yellow] {escape(s.id)}: {escape(s.error)}")
    con.print(f"{len(lib.assets)} assets, {r.rows} index rows, embedder {escape(lib.embedder_name)}, "
              f"{len(r.rendered)} rendered, {len(r.reused)} reused, {len(r.skipped)} skipped, {r.seconds:.1f} s")


@library.command("query")
@click.argument("lib_path", metavar="LIB", type=click.Path(exists=True))
@click.argument("image", type=click.Path(exists=True, dir_okay=False))
@click.option("--gsd", type=float, required=True, metavar="M", help="Metres per pixel of IMAGE.")
@click.option("--k", type=int, default=5, show_default=True, help="How many assets to list.")
@click.option("--category", default=None, help="Only assets of this category.")
@click.option("--embedder", default=None, help="Refuse to run unless the library was built with this embedder.")
@click.option("--weights", type=click.Path(), default=None, help="Weights folder (overrides the recorded one).")
@click.option("--json", "as_json", is_flag=True, help='Print {"results": [{"asset_id", "category", "score"}]}.')
def query(lib_path, image, gsd, k, category, embedder, weights, as_json) -> None:
    """Nearest assets of IMAGE: a crop of one object (centred, any rotation) at --gsd metres per pixel."""
    from ..assets.library import query_image

    results = query_image(lib_path, image, gsd, k=k, category=category, embedder=embedder, weights=weights)
    if as_json:
        click.echo(json.dumps({"results": results}, indent=2))
        return
    for i, r in enumerate(results, 1):
        click.echo(f"{i}. {r['asset_id']}  ({r['category']})  score {r['score']:.4f}")


@library.command("info")
@click.argument("lib_path", metavar="LIB", required=False, type=click.Path(exists=True))
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
def info(lib_path, as_json) -> None:
    """Describe a library (the starter-kit library when LIB is not given)."""
    from ..assets.library import library_info

    doc = library_info(lib_path)
    if as_json:
        click.echo(json.dumps(doc, indent=2))
        return
    click.echo(f"{doc['root']}: {len(doc['assets'])} assets, embedder {doc['embedder']}, {doc['rows']} rows")
    for a in doc["assets"]:
        click.echo(f"  {a['id']:<24} {a['category']:<8} {' x '.join(f'{v:.2f}' for v in a['dims_m'])} m")
