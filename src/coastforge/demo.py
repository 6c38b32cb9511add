"""``python -m coastforge.demo --out DIR`` (``make demo``): synthesize a marina, render it, say where."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m coastforge.demo", description=__doc__)
    ap.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--gsd", default="0.2", help="metres per pixel of the images, comma-separated")
    ap.add_argument("--overwrite", action="store_true", help="replace the files in a non-empty --out folder")
    args = ap.parse_args(argv)
    from .errors import CoastforgeError
    from .synth import synth_to_dir

    t0 = time.perf_counter()
    try:
        # re-running the demo replaces its own previous output, but nothing else
        again = (Path(args.out) / "truth.json").is_file() and (Path(args.out) / "inputs.json").is_file()
        r = synth_to_dir("marina", args.seed, args.out, args.gsd, overwrite=args.overwrite or again)
    except CoastforgeError as exc:
        print(f"Error: {exc}", file=sys.stderr)
        return 2
    size = f"{r.extent_m[0]:.0f} x {r.extent_m[1]:.0f} m"
    print(f"coastforge demo: a synthetic marina ({r.n_objects} objects, {size}) "
          f"in {time.perf_counter() - t0:.1f} s")
    print(f"  truth scene: {r.truth_path}")
    for p, g in zip(r.image_paths, r.gsds):
        print(f"  aerial image ({g:g} m/px): {p}")
    print(f"  image list:  {r.inputs_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
