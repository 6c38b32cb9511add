"""The Quaternius CC0 models of ``../shared/data/models`` split into a training and a held-aside asset library,
for the detector's training renders and its held-aside check (README, "Real photographs").

    python -m coastforge.train.qlib --out QLIB_SRC
    coastforge library build QLIB_SRC/train.json --out QLIB_TRAIN
    coastforge library build QLIB_SRC/held.json --out QLIB_HELD

writes ``QLIB_SRC/`` with copies of the models (a manifest may only point inside its own folder), the starter
kit's pier and buoy models (both libraries need them to lay out a level) and the two manifests. The real sizes
are the ones ``../shared/data/README.md`` gives (boat ~5 m, lifeboat ~7 m, cars 4-5 m); the cruise ship
(250 m) has no role in a level and is left out. Nothing here is committed or shipped: the models stay in
``../shared/data``.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from .. import realdata
from ..assets.kit.manifest import MANIFEST_NAME, kit_dir
from ..errors import InputError

# file stem -> (asset id, category, length in metres)
TRAIN = {"Ship_pack__Boat": ("q_boat", "boat", 5.0),
         "Basic_Car_Pack__BasicCar": ("q_basic_car", "vehicle", 4.5),
         "Basic_Car_Pack__RaceCar": ("q_race_car", "vehicle", 4.4),
         "Basic_Car_Pack__SimpleCarShort": ("q_simple_car_short", "vehicle", 3.9)}
HELD = {"Ship_pack__Lifeboat": ("q_lifeboat", "boat", 7.0),
        "Basic_Car_Pack__CopCar": ("q_cop_car", "vehicle", 4.8),
        "Basic_Car_Pack__SimpleCarHigh": ("q_simple_car_high", "vehicle", 4.6),
        "Basic_Car_Pack__Taxi": ("q_taxi", "vehicle", 4.6)}
KIT_KEEP = ("pier_walkway", "pier_finger", "buoy", "buoy_channel")


def write_sources(out: str | Path) -> tuple[Path, Path]:
    """Copy the models and write ``train.json`` and ``held.json`` into ``out``; returns both manifests."""
    out = Path(out)
    qdir = realdata.SHARED / "models" / "quaternius"
    if not qdir.is_dir():
        raise InputError(f"{qdir} not found: the Quaternius models come from ../shared/data beside the project")
    kit_root = kit_dir()
    # the raw entries, not assets.kit.read_manifest's: a library manifest takes their axes and sizes as they are
    kit = {a["id"]: a for a in json.loads((kit_root / MANIFEST_NAME).read_text())["assets"]}
    out.mkdir(parents=True, exist_ok=True)
    kit_entries = []
    for aid in KIT_KEEP:
        e = dict(kit[aid])
        shutil.copyfile(kit_root / e["mesh"], out / e["mesh"])
        e.pop("dims_m", None)  # measured again from the mesh by the build
        kit_entries.append(e)
    paths = []
    for name, split in (("train", TRAIN), ("held", HELD)):
        entries = list(kit_entries)
        for stem, (aid, cat, length) in split.items():
            shutil.copyfile(qdir / f"{stem}.glb", out / f"{stem}.glb")
            entries.append({"id": aid, "category": cat, "mesh": f"{stem}.glb", "length_m": length})
        p = out / f"{name}.json"
        p.write_text(json.dumps({"assets": entries}, indent=1))
        paths.append(p)
    return paths[0], paths[1]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the model copies and the two manifests")
    a = ap.parse_args(argv)
    train, held = write_sources(a.out)
    print(f"wrote {train} and {held}")


if __name__ == "__main__":
    main()
