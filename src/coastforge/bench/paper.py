"""The paper-style benchmark: synthesize every level at two resolutions, generate, evaluate, tabulate.

``coastforge benchmark`` prints, per level and resolution, the paper's columns (objects, m/px, XY RMSE,
rotation RMSE, orientation RMSE, match precision, recall) plus detection precision, terrain and timing,
with the averages per resolution — as Markdown and JSON.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

PAPER = {
    "high": {"xy_rmse_m": 0.340, "rotation_rmse_deg": 135.9, "orientation_rmse_deg": 1.58, "match_precision": 0.991,
             "recall": 0.978},
    "low": {"xy_rmse_m": 0.448, "rotation_rmse_deg": 134.9, "orientation_rmse_deg": 1.89, "match_precision": 0.855,
            "recall": 0.965},
}
COLUMNS = ("n_truth", "gsd_m", "xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "match_precision",
           "match_precision_category", "recall", "detection_precision", "miou", "piers_connected", "pier_deck_recall",
           "pier_deck_precision", "generate_s")


def check_benchmark(presets=None, gsds=(0.1, 0.2), library: str | None = None) -> tuple[list[str], tuple]:
    """The benchmark's levels and GSDs, checked before anything runs or is written (a bad level name or
    library would otherwise stop it after the first levels)."""
    from ..assets.library import Library
    from ..synth import PRESETS, check_preset, parse_gsds

    presets = list(presets or PRESETS)
    for p in presets:
        check_preset(p)
    gsds = parse_gsds(gsds)
    if library is not None:
        Library.load(library)
    return presets, gsds


def run_benchmark(out: str | Path, presets=None, seed: int = 0, gsds=(0.1, 0.2), library: str | None = None,
                  config=None, overwrite: bool = False, log=print) -> dict:
    from ..config import Config
    from ..evaluate import evaluate_scenes
    from ..fsio import atomic_write_text, prepare_output_dir
    from ..pipeline import GenerateRequest, run_generate
    from ..scene import load_scene
    from ..synth import synth_to_dir

    config = config or Config()
    presets, gsds = check_benchmark(presets, gsds, library)
    out = prepare_output_dir(out, overwrite)
    rows = []
    for p in presets:
        sdir = out / p / "truth"
        t0 = time.perf_counter()
        res = synth_to_dir(p, seed, sdir, gsds=gsds, library=library, overwrite=True)
        synth_s = time.perf_counter() - t0
        truth = load_scene(res.truth_path)
        inputs = json.loads((sdir / "inputs.json").read_text())["images"]
        for i, img in enumerate(inputs):
            gdir = out / p / f"gen_{img['gsd_m']:.2f}m"
            t0 = time.perf_counter()
            r = run_generate(GenerateRequest(image=str(sdir / img["path"]), out=str(gdir), gsd_m=img["gsd_m"],
                                             library=library, overwrite=True, report=False),
                             replace(config, seed=seed))
            gen_s = time.perf_counter() - t0
            m = evaluate_scenes(truth, load_scene(r.scene_path))
            row = {"level": p, "resolution": "high" if i == 0 else "low", "gsd_m": img["gsd_m"],
                   **{k: m[k] for k in ("n_truth", "n_pred", "n_matched", "xy_rmse_m", "rotation_rmse_deg",
                                        "orientation_rmse_deg", "match_precision", "match_precision_category",
                                        "recall", "detection_precision")},
                   "miou": m["terrain"].get("miou"), "height_rmse_land_m": m["terrain"].get("height_rmse_land_m"),
                   "height_rmse_water_m": m["terrain"].get("height_rmse_water_m"),
                   "piers_connected": m["piers"].get("all_connected"),
                   "pier_deck_recall": m["pier_deck"]["recall"], "pier_deck_precision": m["pier_deck"]["precision"],
                   "generate_s": round(gen_s, 2),
                   "synth_s": round(synth_s, 2), "timings_s": r.timings_s, "per_category": m["per_category"]}
            rows.append(row)
            log(f"{p:14s} {img['gsd_m']:.2f} m/px  recall {_f(row['recall'])}  xy {_f(row['xy_rmse_m'])} m  "
                f"rot {_f(row['rotation_rmse_deg'])}°  ori {_f(row['orientation_rmse_deg'])}°  "
                f"match {_f(row['match_precision'])}  det.prec {_f(row['detection_precision'])}  {gen_s:.1f}s")
    averages = {}
    for res_name in ("high", "low"):
        sel = [r for r in rows if r["resolution"] == res_name]
        if not sel:
            continue
        avg = {}
        for k in ("xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "match_precision",
                  "match_precision_category", "recall", "detection_precision", "miou", "pier_deck_recall",
                  "pier_deck_precision", "generate_s"):
            vals = [r[k] for r in sel if r[k] is not None]
            avg[k] = float(np.mean(vals)) if vals else None
        avg["piers_connected"] = all(r["piers_connected"] in (True, None) for r in sel)
        avg["n_truth"] = int(sum(r["n_truth"] for r in sel))
        averages[res_name] = avg
    result = {"seed": seed, "gsds": list(gsds), "rows": rows, "averages": averages, "paper": PAPER}
    atomic_write_text(out / "benchmark.json", json.dumps(result, indent=2))
    atomic_write_text(out / "benchmark.md", to_markdown(result))
    return result


def _f(v, nd=3):
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "NO"
    if isinstance(v, (int, np.integer)):
        return str(v)
    return f"{v:.{nd}f}"


def to_markdown(result: dict) -> str:
    head = ("| level | res | objects | m/px | XY RMSE (m) | rotation RMSE (°) | orientation RMSE (°) | match precision "
            "| category precision | recall | detection precision | mIoU | piers connected | pier deck recall "
            "| pier deck precision | generate (s) |")
    lines = [head, "|" + "---|" * 16]
    for r in result["rows"]:
        lines.append(f"| {r['level']} | {r['resolution']} | {r['n_truth']} | {r['gsd_m']:.2f} | {_f(r['xy_rmse_m'])} | "
                     f"{_f(r['rotation_rmse_deg'], 1)} | {_f(r['orientation_rmse_deg'], 2)} | "
                     f"{_f(r['match_precision'])} | {_f(r['match_precision_category'])} | {_f(r['recall'])} | "
                     f"{_f(r['detection_precision'])} | {_f(r['miou'])} | {_f(r['piers_connected'])} | "
                     f"{_f(r.get('pier_deck_recall'))} | {_f(r.get('pier_deck_precision'))} | "
                     f"{_f(r['generate_s'], 1)} |")
    for name, a in result["averages"].items():
        lines.append(f"| **average** | {name} | {a['n_truth']} | | {_f(a['xy_rmse_m'])} | {_f(a['rotation_rmse_deg'], 1)} | "
                     f"{_f(a['orientation_rmse_deg'], 2)} | {_f(a['match_precision'])} | "
                     f"{_f(a['match_precision_category'])} | {_f(a['recall'])} | {_f(a['detection_precision'])} | "
                     f"{_f(a['miou'])} | {_f(a['piers_connected'])} | {_f(a.get('pier_deck_recall'))} | "
                     f"{_f(a.get('pier_deck_precision'))} | {_f(a['generate_s'], 1)} |")
    for name, p in result["paper"].items():
        lines.append(f"| *paper* | {name} | | | {p['xy_rmse_m']:.3f} | {p['rotation_rmse_deg']:.1f} | "
                     f"{p['orientation_rmse_deg']:.2f} | {p['match_precision']:.3f} | | {p['recall']:.3f} | | | | | | |")
    return "\n".join(lines) + "\n"
