"""What the training-data commands share: seed lists that keep validation seeds out, and the resumable
render loop (one synthetic level per seed, presets cycling, log-uniform render GSD, an ``index.json``
rewritten after every level so a run cut short still leaves usable data).

Used by ``coastforge.train.detector_data`` and ``coastforge.train.seg_data``; each supplies only what it
writes per level.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

from ..errors import InputError
from ..rng import stage_rng

RESERVED_SEEDS = range(0, 100)  # validation levels (benchmarks use seeds 0, 1, 2)


def parse_seeds(text: str) -> list[int]:
    """``"100:400"`` (half-open) or ``"100,101"`` → seeds; validation seeds (< 100) are refused."""
    try:
        if ":" in text:
            a, b = text.split(":")
            seeds = list(range(int(a), int(b)))
        else:
            seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise InputError(f"--seeds {text!r} must be 'A:B' or a comma list of integers") from None
    bad = [s for s in seeds if s in RESERVED_SEEDS]
    if bad or not seeds:
        raise InputError(f"--seeds {text!r}: seeds below 100 are reserved for validation (got {bad[:5]}); "
                         "use e.g. 100:400")
    return seeds


# make_item(preset, seed, gsd_m, size_m, out_dir) -> (index item, log text); raises ValueError to skip
MakeItem = Callable[[str, int, float, float, Path], tuple[dict, str]]


def render_levels(out_dir: str | Path, seeds: list[int], make_item: MakeItem, *, stage: str,
                  index_head: dict, presets: list[str] | None = None,
                  gsd_range: tuple[float, float] = (0.08, 0.3),
                  size_range_m: tuple[float, float] = (70.0, 150.0), minutes: float | None = None) -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (levels whose ``image`` is
    already in the index are skipped). ``stage`` names the random stream (``stage_rng(seed, "train",
    stage, preset)``) that draws each level's render GSD (log-uniform in ``gsd_range``: as many fine as
    coarse renders) and size (uniform in ``size_range_m``, even metres). ``index_head`` starts a new
    index (``items`` is added)."""
    from ..fsio import atomic_write_text
    from ..synth import PRESETS

    presets = list(presets or PRESETS)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    idx_path = out / "index.json"
    index = json.loads(idx_path.read_text()) if idx_path.is_file() else {**index_head, "items": []}
    done = {it["image"] for it in index["items"]}
    t0 = time.time()
    for i, seed in enumerate(seeds):
        if minutes is not None and time.time() - t0 > minutes * 60:
            break
        preset = presets[i % len(presets)]
        if f"{preset}_{seed}.png" in done:
            continue
        rng = stage_rng(seed, "train", stage, preset)
        gsd = float(math.exp(rng.uniform(math.log(gsd_range[0]), math.log(gsd_range[1]))))
        size = float(2 * round(rng.uniform(*size_range_m) / 2))
        try:
            item, note = make_item(preset, seed, gsd, size, out)
        except ValueError as exc:  # some presets cannot lay out every small size: skip that level
            print(f"{preset}_{seed}: skipped ({exc})", flush=True)
            continue
        index["items"].append(item)
        atomic_write_text(idx_path, json.dumps(index) + "\n")
        print(f"{preset}_{seed} gsd={gsd:.3f} {note} t={time.time() - t0:.0f}s", flush=True)
    return idx_path


def data_main(argv: list[str] | None, description: str, default_seeds: str,
              generate: Callable[..., Path], mix_option: bool = False) -> None:
    """The shared command line: ``--out DIR --seeds A:B [--minutes M]`` (and ``--mix NAME`` if asked)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--out", required=True, help="output folder (resumable: written levels are skipped)")
    ap.add_argument("--seeds", default=default_seeds,
                    help="'A:B' (half-open) or a comma list; seeds below 100 are refused")
    ap.add_argument("--minutes", type=float, default=None, help="stop starting new levels after this long")
    if mix_option:
        ap.add_argument("--mix", choices=("benchmark", "training"), default="benchmark",
                        help="asset types as in the benchmark's levels, or with rare ones shown more often")
    a = ap.parse_args(argv)
    kw = {"mix": a.mix} if mix_option else {}
    generate(a.out, parse_seeds(a.seeds), minutes=a.minutes, **kw)
