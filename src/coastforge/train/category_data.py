"""Training crops for the category head (``coastforge.assets.category_net``), rendered from the starter kit.

    python -m coastforge.train.category_data --out /tmp/catdata          # ~3 min on 2 cores

writes ``rq_A_B.npz`` (every kit asset alone, as ``bench.library`` renders its queries: 12 per asset and
seed, random yaw, lighting, background, GSD 0.04-0.4 m), ``crowd_A_B.npz`` (cars and boats between
repainted copies of themselves, 4 per asset and seed) and ``synth_A_B.npz`` (the boats, vehicles and
buoys of synthetic levels, cut as the matcher cuts detections). Each holds the crops at the network's
size (``x``), their GSD (``g``), side in metres (``m``) and category index (``y``). Seeds below 100 are
refused: the retrieval benchmark uses seeds 0-9.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from ..assets.category_net import CATEGORIES, net_image
from .common import parse_seeds

CROWD_PER_ASSET = 4
SYNTH_PRESETS = ("marina", "pier_parking", "beach", "lake_harbor")


def _pack(out: Path, crops: list[tuple[np.ndarray, float, str]]) -> int:
    import io

    from ..fsio import atomic_write_bytes

    buf = io.BytesIO()
    np.savez_compressed(buf, x=np.array([net_image(c) for c, _g, _c in crops], np.uint8),
                        g=np.array([g for _c, g, _k in crops], np.float32),
                        m=np.array([c.shape[0] * g for c, g, _k in crops], np.float32),
                        y=np.array([CATEGORIES.index(k) for _c, _g, k in crops], np.int64))
    atomic_write_bytes(out, buf.getvalue())
    return len(crops)


def isolated(lib, seeds: list[int]) -> list:
    from ..bench.library import render_queries

    return [(img, gsd, cat) for s in seeds for img, gsd, _aid, cat in render_queries(lib, 12, s, (0.04, 0.4))]


def crowded(lib, seeds: list[int]) -> list:
    from ..assets.library import CROWD_MAX_LENGTH_M, crowd_mesh, random_lit_view
    from ..bench.library import MAX_QUERY_PX
    from ..rng import stage_rng

    out = []
    for seed in seeds:
        for a in lib.assets:
            if a.category not in ("vehicle", "boat") or a.dims_m[0] > CROWD_MAX_LENGTH_M:
                continue
            mesh = lib.mesh(a.id)
            rng = stage_rng(seed, "train-category-crowd", a.id)
            for _ in range(CROWD_PER_ASSET):
                gsd = float(math.exp(rng.uniform(math.log(0.05), math.log(0.3))))
                size = max(a.dims_m[:2])
                side = int(math.ceil(size * 1.5 / gsd)) + 4
                if side > MAX_QUERY_PX:
                    gsd, side = size * 1.5 / (MAX_QUERY_PX - 4), MAX_QUERY_PX
                # as library.crowded_view, with a coin for the background between the crowd and the view
                crowd, centre = crowd_mesh(mesh, a.category, a.dims_m, rng)
                bg = "ground" if a.category == "vehicle" else "water"
                if rng.random() < 0.25:  # now and then the other way round
                    bg = "water" if bg == "ground" else "ground"
                img, _ = random_lit_view(crowd, gsd, side, bg, rng, centre)
                out.append((img, gsd, a.category))
    return out


def synthetic(lib, seeds: list[int]) -> list:
    from ..bench.library import synth_levels, synth_queries

    out = []
    for s in seeds:
        levels, why = synth_levels(s, presets=SYNTH_PRESETS)
        if why:
            raise RuntimeError(why)
        out.extend((img, gsd, cat) for img, gsd, _aid, cat in synth_queries(lib, levels))
    return out


def main(argv: list[str] | None = None) -> None:
    from ..assets.library import default_library

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True)
    p.add_argument("--isolated-seeds", default="100:140")
    p.add_argument("--crowded-seeds", default="100:140")
    p.add_argument("--synth-seeds", default="100:145")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    lib = default_library()
    for name, fn, text in (("rq", isolated, a.isolated_seeds), ("crowd", crowded, a.crowded_seeds),
                           ("synth", synthetic, a.synth_seeds)):
        seeds = parse_seeds(text)
        n = _pack(out / f"{name}_{seeds[0]}_{seeds[-1] + 1}.npz", fn(lib, seeds))
        print(f"{name}: {n} crops (seeds {text})", flush=True)


if __name__ == "__main__":
    main()
