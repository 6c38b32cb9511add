"""``coastforge evaluate``: the paper's metrics of a generated scene against a truth scene."""

from __future__ import annotations

import json

import click


@click.command()
@click.option("--truth", "truth_path", required=True, type=click.Path(), help="Truth scene (truth.json or its folder).")
@click.option("--pred", "pred_path", required=True, type=click.Path(), help="Predicted scene (scene.json or its folder).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def evaluate(truth_path: str, pred_path: str, as_json: bool) -> None:
    """Compare PRED with TRUTH: XY/rotation/orientation RMSE, recall, precisions, terrain and pier checks."""
    from ..api import evaluate_scenes

    result = evaluate_scenes(truth_path, pred_path)
    if as_json:
        click.echo(json.dumps(result, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    def fmt(v):
        return "—" if v is None else (f"{v:.3f}" if isinstance(v, float) else str(v))

    t = Table(title="objects (boat, vehicle, buoy)")
    keys = ["n_truth", "n_pred", "n_matched", "xy_rmse_m", "rotation_rmse_deg", "orientation_rmse_deg", "recall",
            "match_precision", "match_precision_category", "detection_precision"]
    t.add_column("")
    t.add_column("all")
    cats = list(result["per_category"])
    for c in cats:
        t.add_column(c)
    for k in keys:
        t.add_row(k, fmt(result[k]), *(fmt(result["per_category"][c][k]) for c in cats))
    con = Console()
    con.print(t)
    terr = result["terrain"]
    if terr:
        con.print(f"terrain: mIoU {fmt(terr.get('miou'))}, height RMSE land {fmt(terr.get('height_rmse_land_m'))} m, "
                  f"water {fmt(terr.get('height_rmse_water_m'))} m")
    p = result["piers"]
    if p["n_segments"]:
        con.print(f"piers: {p['n_segments']} segments in {p['n_structures']} structures, all connected: "
                  f"{p['all_connected']}")
    d = result["pier_deck"]
    if d["truth_m2"] or d["pred_m2"]:
        con.print(f"pier deck: {d['truth_m2']:.0f} m² in the truth, {d['pred_m2']:.0f} m² built; recall "
                  f"{fmt(d['recall'])}, precision {fmt(d['precision'])}")
