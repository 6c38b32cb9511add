"""Terrain benchmark: ``python -m coastforge.bench.terrain`` prints the shore-profile checks on synthetic
class maps, height RMSE against synthetic truth scenes (when ``coastforge.synth`` exists), the real
marina check and the 2048×2048 timing.

Also home of ``synthetic_class_map`` (used by the tests): simple coasts of one shore type, or mixed.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np

from ..classes import ASPHALT, DIRT, GRASS, ROCKS, SAND, SIDEWALK, TREES, WATER

KINDS = ("beach", "quay", "revetment", "bank", "mixed")


def synthetic_class_map(kind: str, size_px: int = 256, gsd_m: float = 0.25) -> np.ndarray:
    """A (size, size) uint8 class map: land on the left, water on the right (straight coast at 40 %),
    except ``mixed``: a wavy coast with beach, revetment, quay and bank stretches, a pier and an island."""
    n = size_px
    ids = np.full((n, n), WATER, np.uint8)
    cols = np.arange(n)[None, :].repeat(n, 0)
    rows = np.arange(n)[:, None].repeat(n, 1)
    x0 = int(0.4 * n)
    if kind == "beach":
        ids[cols < x0] = SAND
        ids[cols < x0 - int(25 / gsd_m)] = GRASS  # dunes/grass 25 m behind the waterline
    elif kind == "quay":
        ids[cols < x0] = ASPHALT
        ids[(cols < x0) & (cols >= x0 - int(4 / gsd_m))] = SIDEWALK  # promenade along the wall
    elif kind == "revetment":
        ids[cols < x0] = ROCKS
        ids[cols < x0 - int(5 / gsd_m)] = GRASS
    elif kind == "bank":
        ids[cols < x0] = GRASS
        ids[(cols < x0 - int(10 / gsd_m)) & (rows < n // 2)] = TREES
        ids[(cols < x0 - int(10 / gsd_m)) & (rows >= n // 2)] = DIRT
    elif kind == "mixed":
        coast = x0 + (0.06 * n * np.sin(rows / n * 2 * np.pi * 1.5)).astype(int)
        land = cols < coast
        seg = (rows * 4) // n  # four stretches along the coast
        band = cols >= coast - int(6 / gsd_m)
        ids[land] = GRASS
        ids[land & (rows > n // 3) & (cols < coast - int(20 / gsd_m))] = ASPHALT
        ids[land & band & (seg == 0)] = SAND
        ids[land & band & (seg == 1)] = ROCKS
        ids[land & band & (seg == 2)] = SIDEWALK
        ids[land & band & (seg == 3)] = TREES
        ids[land & (seg == 0) & (cols >= coast - int(30 / gsd_m))] = SAND  # a wide beach
        # a pier: 2 m wide walkway sticking 25 m out from the quay stretch
        pr = int(0.62 * n)
        half = max(1, int(1.0 / gsd_m))
        ids[pr - half:pr + half, :] = np.where(
            (cols[pr - half:pr + half] >= coast[pr - half:pr + half, None].min() - 2)
            & (cols[pr - half:pr + half] < coast.max() + int(25 / gsd_m)), SIDEWALK, ids[pr - half:pr + half])
        # a small rocky island offshore
        cy, cx, r = int(0.25 * n), int(0.8 * n), max(3, int(6 / gsd_m))
        ids[(rows - cy) ** 2 + (cols - cx) ** 2 < r * r] = ROCKS
    else:
        raise ValueError(f"unknown synthetic kind {kind!r}; one of {', '.join(KINDS)}")
    return ids


def max_interior_step(ids: np.ndarray, z: np.ndarray) -> tuple[float, int]:
    """The largest height difference between 4-neighbours that lie inside the same class region, one pixel
    away from its boundary (class boundaries, where quay walls legitimately are, are excluded)."""
    import cv2

    worst, worst_cls = 0.0, -1
    for c in np.unique(ids):
        m = (ids == c).astype(np.uint8)
        inner = cv2.erode(m, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE).astype(bool)
        for axis in (0, 1):
            a = inner & np.roll(inner, -1, axis)
            if axis == 0:
                a[-1, :] = False
            else:
                a[:, -1] = False
            if a.any():
                dz = np.abs(np.roll(z, -1, axis) - z)[a]
                v = float(dz.max())
                if v > worst:
                    worst, worst_cls = v, int(c)
    return worst, worst_cls


@dataclass(frozen=True)
class KindFigures:
    kind: str
    water_at_or_above: int
    land_at_or_below: int
    max_step_m: float  # largest neighbour step inside one class region
    dean_max_rel_err: float | None  # beach: worst relative deviation from Dean's curve (nearshore)
    berth_err_m: float | None  # quay: |first water pixel + berth depth|


def kind_figures(kind: str, size_px: int = 512, gsd_m: float = 0.25) -> KindFigures:
    from ..config import TerrainConfig
    from ..terrain import estimate_terrain
    from ..terrain.default import dean_depth
    from ..types import ClassMap, Grid

    cfg = TerrainConfig()
    ids = synthetic_class_map(kind, size_px, gsd_m)
    res = estimate_terrain(ClassMap(ids, Grid(size_px, size_px, gsd_m)), cfg, seed=0)
    z = res.height.z_m
    step, _cls = max_interior_step(ids, z)
    x0 = int(0.4 * size_px)
    dean_err = berth_err = None
    if kind == "beach":
        d = (np.arange(x0, size_px) - x0 + 0.5) * gsd_m
        dean = dean_depth(d, cfg.d50_mm)
        ok = dean < 0.5 * cfg.max_depth_m
        rel = np.abs(-z[:, x0:][:, ok] - dean[ok][None]) / dean[ok][None]
        dean_err = float(rel.max())
    if kind == "quay":
        berth_err = float(np.abs(z[:, x0] + cfg.berth_depth_m).max())
    d = res.diagnostics
    return KindFigures(kind, d.water_at_or_above, d.land_at_or_below, step, dean_err, berth_err)


def _truth_config(model: dict):
    """Our TerrainConfig with the synthetic truth's own terrain parameters (an 'oracle' upper bound)."""
    import dataclasses

    from ..config import TerrainConfig

    keys = {"max_depth_m": "max_depth_m", "depth_scale_m": "depth_scale_m", "berth_depth_m": "berth_depth_m",
            "quay_height_m": "quay_height_m", "d50_mm": "d50_mm", "beach_slope": "beach_slope",
            "berm_height_m": "beach_height_m", "revetment_slope": "revetment_slope",
            "revetment_top_m": "revetment_height_m", "revetment_toe_m": "revetment_toe_m",
            "bank_slope": "bank_slope", "bank_top_m": "bank_height_m", "land_rise_m": "land_rise_m",
            "land_rise_scale_m": "land_rise_scale_m"}
    vals = {ours: float(model[k]) for k, ours in keys.items() if k in model}
    return dataclasses.replace(TerrainConfig(), **vals)


def synth_rmse(preset: str, seed: int = 0) -> dict:
    """Height RMSE (land, water) against a synthetic truth scene, from its truth classes: with the default
    parameters, and with the truth's own terrain parameters (when the scene records them)."""
    from ..config import TerrainConfig
    from ..synth import synthesize
    from ..terrain import estimate_terrain
    from ..types import ClassMap

    scene = synthesize(preset, seed)
    water = scene.classes == WATER
    cm = ClassMap(scene.classes, scene.grid)

    def rmse(cfg):
        z = estimate_terrain(cm, cfg, seed=seed).height.z_m
        d = z - scene.height
        return (float(np.sqrt(np.mean(d[~water] ** 2))) if (~water).any() else float("nan"),
                float(np.sqrt(np.mean(d[water] ** 2))) if water.any() else float("nan"))

    out = {"shape": scene.classes.shape, "default": rmse(TerrainConfig())}
    model = scene.provenance.get("terrain_model")
    if isinstance(model, dict):
        out["truth_params"] = rmse(_truth_config(model))
    return out


def timing_2048(repeats: int = 3) -> tuple[tuple[float, float], tuple[float, float]]:
    """Best-of (wall s, CPU s) of the default model and of the whole ``estimate_terrain`` on 2048x2048."""
    from ..config import TerrainConfig
    from ..terrain import estimate_terrain
    from ..terrain.default import DefaultTerrain
    from ..types import ClassMap, Grid

    ids = synthetic_class_map("mixed", 2048, 0.2)
    cm = ClassMap(ids, Grid(2048, 2048, 0.2))
    cfg = TerrainConfig()
    model = DefaultTerrain(cfg)
    model.estimate(cm, None, 0)  # warm-up (imports, thread pools)

    def best(fn):
        runs = []
        for _ in range(repeats):
            t, c = time.perf_counter(), time.process_time()
            fn()
            runs.append((time.perf_counter() - t, time.process_time() - c))
        return min(runs)

    return best(lambda: model.estimate(cm, None, 0)), best(lambda: estimate_terrain(cm, cfg, seed=0))


def marina_figures(data_dir) -> dict | None:
    from pathlib import Path

    from ..classes import PAVED
    from ..config import Config, TerrainConfig
    from ..io import read_image
    from ..terrain import estimate_terrain

    path = Path(data_dir) / "aerial" / "marina_p0861" / "image.jpg"
    if not path.is_file():
        return None
    img = read_image(path, gsd_m=0.2)
    try:
        from ..segmentation import segment
    except ImportError:
        return {"note": "coastforge.segmentation.segment is not available"}
    cm = segment(img, Config().segment, seed=0)
    res = estimate_terrain(cm, TerrainConfig(), image=img, seed=0)
    ids, z = np.asarray(cm.ids), res.height.z_m
    step, cls = max_interior_step(ids, z)
    water = ids == WATER
    wall = water & (np.isin(np.roll(ids, 1, 1), PAVED) | np.isin(np.roll(ids, -1, 1), PAVED)
                    | np.isin(np.roll(ids, 1, 0), PAVED) | np.isin(np.roll(ids, -1, 0), PAVED))
    return {"water_fraction": float(water.mean()), "water_at_or_above": res.diagnostics.water_at_or_above,
            "land_at_or_below": res.diagnostics.land_at_or_below, "max_step_m": step, "step_class": cls,
            "shore_types": res.diagnostics.shore_types, "seconds": res.diagnostics.seconds,
            "median_depth_at_paved_walls_m": float(np.median(-z[wall])) if wall.any() else float("nan")}


def main(argv: list[str] | None = None) -> None:
    from pathlib import Path

    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.terrain",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--no-synth", action="store_true",
                    help="skip the synthetic truth scenes (coastforge.synth)")
    ap.add_argument("--no-timing", action="store_true", help="skip the 2048x2048 timing")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[3].parent / "shared" / "data"),
                    help="the shared real-data folder (for the marina check)")
    args = ap.parse_args(argv)

    print("== shore profiles on synthetic class maps (512x512, 0.25 m/px) ==")
    print(f"{'kind':10s} {'water>=0':>8s} {'land<=0':>8s} {'max step m':>10s} {'Dean err':>9s} "
          f"{'berth err m':>11s}")
    for kind in KINDS:
        f = kind_figures(kind)
        dean = f"{100 * f.dean_max_rel_err:.1f} %" if f.dean_max_rel_err is not None else "-"
        berth = f"{f.berth_err_m:.3f}" if f.berth_err_m is not None else "-"
        print(f"{kind:10s} {f.water_at_or_above:8d} {f.land_at_or_below:8d} {f.max_step_m:10.3f} {dean:>9s} "
              f"{berth:>11s}")

    if not args.no_synth:
        print("\n== height RMSE against synthetic truth (truth classes in, seed 0) ==")
        try:
            from ..synth import PRESETS
        except ImportError:
            print("coastforge.synth is not available")
            PRESETS = ()
        for p in PRESETS:
            try:
                r = synth_rmse(p)
            except Exception as exc:  # noqa: BLE001 - a broken preset should not hide the others' figures
                print(f"{p:14s} failed: {exc}")
                continue
            (rl, rw), shape = r["default"], r["shape"]
            line = f"{p:14s} {shape[1]}x{shape[0]}  default params: RMSE land {rl:5.2f} m  water {rw:5.2f} m"
            if "truth_params" in r:
                tl, tw = r["truth_params"]
                line += f"  | truth's params: land {tl:5.2f} m  water {tw:5.2f} m"
            print(line)

    m = marina_figures(args.data)
    print("\n== real marina (marina_p0861, 0.2 m/px, segmentation stage) ==")
    if m is None:
        print(f"not found under {args.data}")
    else:
        for k, v in m.items():
            print(f"{k}: {v:.3f}" if isinstance(v, float) else f"{k}: {v}")

    if not args.no_timing:
        (tm, cm), (ta, ca) = timing_2048()
        import os

        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(f"\n== 2048x2048 (mixed coast, 0.2 m/px), best of 3, load average {load:.1f} ==")
        print(f"default model: {tm:.2f} s wall ({cm:.2f} s CPU); estimate_terrain with shore analysis and "
              f"cross-sections: {ta:.2f} s wall ({ca:.2f} s CPU)")


if __name__ == "__main__":
    main()
