"""What the training-data commands share: seed lists that keep validation seeds out, and the resumable
render loop (one synthetic level per seed, presets cycling, log-uniform render GSD, an ``index.json``
rewritten after every level so a run cut short still leaves usable data).

Used by ``coastforge.train.detector_data`` and ``coastforge.train.seg_data``; each supplies only what it
writes per level.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from collections.abc import Callable
from typing import Any
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
              generate: Callable[..., Path], mix_option: bool = False, looks_option: bool = False) -> None:
    """The shared command line: ``--out DIR --seeds A:B [--minutes M]`` (and ``--mix NAME`` if asked)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--out", required=True, help="output folder (resumable: written levels are skipped)")
    ap.add_argument("--seeds", default=default_seeds,
                    help="'A:B' (half-open) or a comma list; seeds below 100 are refused")
    ap.add_argument("--minutes", type=float, default=None, help="stop starting new levels after this long")
    if mix_option:
        from ..synth.layout import MIXES

        ap.add_argument("--mix", choices=tuple(MIXES), default="benchmark",
                        help="asset types as in the benchmark's levels, or with rare ones shown more often (training), "
                             "and boats tied alongside end to end and rafted (rafted), or with big vessels of 20-50 m "
                             "at anchor and alongside (big)")
    if looks_option:
        ap.add_argument("--library", default=None, help="render with this asset library's assets (default: the kit)")
        ap.add_argument("--looks", choices=("kit", "varied", "covers", "wakes"), default="kit",
                        help="'varied' repaints about half the boats (dark hulls among them), 'covers' puts "
                             "about half under canvas covers, 'wakes' repaints and draws foam wakes astern")
    a = ap.parse_args(argv)
    kw = {"mix": a.mix} if mix_option else {}
    if looks_option:
        kw.update(library=a.library, looks=a.looks)
    generate(a.out, parse_seeds(a.seeds), minutes=a.minutes, **kw)


def init_from_onnx(torch, net, onnx_path: Path, make_input: Callable[[int], Any], batches: int = 24) -> float:
    """Start ``net`` from its exported ONNX model (e.g. a shipped model, whose torch checkpoint is not
    kept); ``make_input(n)`` returns a batch of n training inputs as ``net`` takes them. The export
    folded each BatchNorm into its convolution; the folded weights are loaded and
    each BatchNorm is set to the statistics of its convolution's output on training crops, with scale and
    shift chosen so that the network computes exactly what the ONNX model does (checked: the largest
    output difference on a crop is returned). Training then goes on from the same function."""
    import onnx
    from onnx import numpy_helper
    from torch import nn

    model = onnx.load(str(onnx_path))
    inits = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    onnx_convs = [n for n in model.graph.node if n.op_type == "Conv"]
    order: list[nn.Conv2d] = []
    hooks = [m.register_forward_hook(lambda m, _i, _o: order.append(m))
             for m in net.modules() if isinstance(m, nn.Conv2d)]
    net.eval()
    with torch.no_grad():
        net(torch.zeros(1, 3, 64, 64))
    for h in hooks:
        h.remove()
    if len(order) != len(onnx_convs):
        raise InputError(f"{onnx_path} has {len(onnx_convs)} convolutions, this network {len(order)}: "
                         "not a detector of this architecture")
    bn_after: dict[nn.Conv2d, nn.BatchNorm2d] = {}
    for seq in net.modules():
        if isinstance(seq, nn.Sequential):
            mods = list(seq)
            for a, b in itertools.pairwise(mods):
                if isinstance(a, nn.Conv2d) and isinstance(b, nn.BatchNorm2d):
                    bn_after[a] = b
    folded_bias: dict[nn.Conv2d, torch.Tensor] = {}
    with torch.no_grad():
        for conv, node in zip(order, onnx_convs):
            w = torch.from_numpy(inits[node.input[1]].copy())
            b = (torch.from_numpy(inits[node.input[2]].copy()) if len(node.input) > 2
                 else torch.zeros(w.shape[0]))
            if tuple(w.shape) != tuple(conv.weight.shape):
                raise InputError(f"{onnx_path}: convolution {node.name} has weights {tuple(w.shape)}, "
                                 f"expected {tuple(conv.weight.shape)}")
            conv.weight.copy_(w)
            if conv in bn_after:  # identity BatchNorm that adds the folded bias: exact in eval mode
                bn = bn_after[conv]
                bn.weight.fill_(1.0)
                bn.bias.copy_(b)
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
                folded_bias[conv] = b
            else:
                conv.bias.copy_(b)
    # the statistics each BatchNorm will see in training: per-channel mean and variance of its input
    sums: dict[nn.Conv2d, list] = {c: [0.0, 0.0, 0] for c in bn_after}

    def record(m, _i, o):
        s = sums[m]
        s[0] = s[0] + o.sum((0, 2, 3))
        s[1] = s[1] + (o * o).sum((0, 2, 3))
        s[2] += o.numel() // o.shape[1]

    hooks = [c.register_forward_hook(record) for c in bn_after]
    with torch.no_grad():
        for _ in range(batches):
            net(make_input(16))
    for h in hooks:
        h.remove()
    with torch.no_grad():
        x = make_input(1)
        before = net(x)
        for conv, bn in bn_after.items():
            s0, s1, n = sums[conv]
            mu = s0 / n
            var = (s1 / n - mu * mu).clamp(min=1e-8)
            bn.running_mean.copy_(mu)
            bn.running_var.copy_(var)
            bn.weight.copy_(torch.sqrt(var + bn.eps))
            bn.bias.copy_(mu + folded_bias[conv])
        after = net(x)
    net.train()
    return float((after - before).abs().max())
