"""``python -m coastforge.demo --out DIR`` (``make demo``): run ``generate`` on the bundled harbor example.

The example (``coastforge/data/examples/harbor``) is an aerial image coastforge rendered itself, with its
ground truth, so the report also shows how close the generated scene came.
"""

from __future__ import annotations

import argparse
import sys
import time
from importlib import resources
from pathlib import Path

EXPORTS_CORE = ("ue5", "holoocean", "gltf", "sdf")


def example_dir() -> Path:
    return Path(str(resources.files("coastforge.data").joinpath("examples/harbor")))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m coastforge.demo", description=__doc__)
    ap.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    from .config import load_config
    from .errors import CoastforgeError
    from .evaluate import evaluate_scenes
    from .pipeline import GenerateRequest, run_generate
    from .registry import get_spec, is_available
    from .report import build_report
    from .scene import load_scene

    ex = example_dir()
    out = Path(args.out)
    # re-running the demo replaces its own previous output, but never a folder it did not make
    mine = (out / "scene.json").is_file() and (out / ".coastforge-demo").is_file()
    exports = EXPORTS_CORE + (("usd",) if is_available(get_spec("export", "usd")) else ())
    t0 = time.perf_counter()
    try:
        r = run_generate(GenerateRequest(image=str(ex / "image.jpg"), out=str(out), gsd_m=0.2, exports=exports,
                                         overwrite=mine, report=False, command="make demo"),
                         load_config(seed=args.seed))
        (out / ".coastforge-demo").write_text("made by make demo; re-running it replaces this folder's outputs\n")
        report = build_report(out, truth=str(ex / "truth.json"))
        m = evaluate_scenes(load_scene(ex / "truth.json"), load_scene(out))
    except CoastforgeError as exc:
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    counts = ", ".join(f"{v} {k}" for k, v in r.n_objects.items())
    print(f"coastforge demo: generated a harbor scene from one aerial image in {time.perf_counter() - t0:.1f} s")
    print(f"  input image : {ex / 'image.jpg'} (0.2 m/px)")
    print(f"  scene       : {r.scene_path}  ({counts})")
    for fmt, paths in r.exports.items():
        print(f"  export {fmt:<9}: {out / fmt}  ({len(paths)} files)")
    print(f"  report      : {report}   <- open this in a browser")
    for w in r.warnings:  # the self-check (none on this example)
        print(f"  warning     : {w}")

    def f(v):
        return "-" if v is None else f"{v:.2f}"

    print(f"  against the truth: recall {f(m['recall'])}, detection precision {f(m['detection_precision'])}, "
          f"XY RMSE {f(m['xy_rmse_m'])} m, terrain mIoU {f(m['terrain'].get('miou'))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
