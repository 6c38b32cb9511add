"""``run_generate``: the inputs checked, the image's front end chosen, the chain run into a staging folder
that replaces ``--out`` only once complete."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..config import Config
from .chain import run_chain
from .request import GenerateRequest, GenerateResult, Progress
from .runtime import Timer
from .whole import WholeImage


def run_generate(req: GenerateRequest, config: Config, progress: Progress | None = None) -> GenerateResult:
    """Run the whole pipeline into ``req.out``, all-or-nothing: everything is written into a staging folder
    beside it and swapped into place only once the scene, its exports and its report are complete (a
    failed or killed run leaves ``req.out`` as it was). Inputs are checked before the first write."""
    from ..config import validate_config
    from ..fsio import output_folder
    from ..terrain.dem import DemSource
    from .tiled import TiledImage, needs_tiling

    validate_config(config)  # a Config built in code gets the checks load_config makes
    check_library_path(req.library)
    timer = Timer(progress)
    with timer.stage("read"):  # the image is read (a large one opened for windows) and checked before any write
        front = TiledImage.open(req, config) if needs_tiling(req.image) else WholeImage.read(req, config)
    check_dems(req, front)
    notes: list[str] = []
    inputs = (req.image, req.library, *(DemSource.parse(d).path for d in req.dems))
    with output_folder(req.out, overwrite=req.overwrite, command=req.command, notes=notes,
                       inputs=inputs) as stage:
        res = run_chain(front, replace(req, out=str(stage), overwrite=False), config, stage, timer)
    return _relocated(res, stage, Path(req.out), notes)


def check_dems(req: GenerateRequest, image) -> None:
    """Refuse, before any work, a --dem that does not exist or cannot be placed: generate fuses DEMs by the
    image's georeference, which a plain PNG/JPEG does not have. ``image``: the read image or the chain's
    front end (anything with the image's ``grid``), or None to read the georeference from the file."""
    if not req.dems:
        return
    from ..errors import InputError
    from ..terrain.dem import check_dem_files

    check_dem_files(req.dems)
    if image is not None:
        georef = image.grid.crs is not None and image.grid.transform is not None
    else:  # a tiled run reads the image later: its header says
        import rasterio

        with rasterio.open(req.image) as src:
            georef = src.crs is not None
    if not georef:
        raise InputError(f"--dem needs to know where the scene is on the map, but {req.image} has no georeference; "
                         "give generate a GeoTIFF, or generate without --dem and fuse the DEM afterwards with "
                         "`coastforge terrain OUT --overwrite --dem FILE --dem-crs CRS --dem-origin X Y`")


def check_library_path(path: str | None) -> None:
    """Refuse, before any work, a ``--library`` that does not exist or is not a library."""
    if path is None:
        return
    from ..errors import LibraryError

    p = Path(path)
    if not p.exists():
        raise LibraryError(f"--library {p} does not exist; build one with `coastforge library build SRC --out "
                           f"{p}`, or leave --library out to use the starter kit")
    if not (p / "library.json").is_file() and not (p.is_file() and p.name == "library.json"):
        raise LibraryError(f"--library {p} is not an asset library (no library.json in it); build one with "
                           "`coastforge library build`, or leave --library out to use the starter kit")


def _relocated(res: GenerateResult, stage: Path, out: Path, notes: list[str]) -> GenerateResult:
    """``res`` with its paths moved from the staging folder to the final one."""
    def mv(p):
        if isinstance(p, (str, Path)):
            try:
                return out / Path(p).relative_to(stage)
            except ValueError:
                return p
        if isinstance(p, list):
            return [mv(x) for x in p]
        return p

    return replace(res, scene_path=mv(res.scene_path), out_dir=out, notes=tuple(notes),
                   exports={k: mv(v) for k, v in res.exports.items()},
                   report_path=mv(res.report_path) if res.report_path else None)
