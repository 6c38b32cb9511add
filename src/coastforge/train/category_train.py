"""Train the category head (``coastforge.assets.category_net``) on ``category_data`` crops and export it.

    python -m coastforge.train.category_data --out /tmp/catdata
    python -m coastforge.train.category_train --data /tmp/catdata --out /tmp/cathead     # ~22 min, 2 cores

writes ``OUT/category.onnx`` and ``OUT/category.json`` (copy both to ``coastforge/data/models/`` to ship
them). Seeded (torch and numpy, seed 0); batches are drawn with equal weight per category; crops are
turned by 90° steps and mirrored (a top view has no up), their colours, brightness and gamma jittered and
their side in metres by ±10 % (a detection's box is not exactly 1.5 x the object).
"""

from __future__ import annotations

import argparse
import glob
import json
import time
from pathlib import Path

import numpy as np

from ..assets.category_net import CATEGORIES, FORMAT, INPUT_PX, net_batch, net_scalars


def build_net(width: int = 24):
    import torch.nn as nn
    import torch

    def blk(i, o, stride):
        return nn.Sequential(nn.Conv2d(i, o, 3, stride, 1, bias=False), nn.BatchNorm2d(o), nn.ReLU())

    class Net(nn.Module):
        def __init__(self, w):
            super().__init__()
            self.f = nn.Sequential(blk(3, w, 1), blk(w, w, 1), blk(w, 2 * w, 2), blk(2 * w, 2 * w, 1),
                                   blk(2 * w, 4 * w, 2), blk(4 * w, 4 * w, 1), blk(4 * w, 4 * w, 2))
            self.s = nn.Sequential(nn.Linear(2, 32), nn.ReLU())
            self.h = nn.Sequential(nn.Linear(8 * w + 32, 128), nn.ReLU(), nn.Linear(128, len(CATEGORIES)))

        def forward(self, x, scalars):
            f = self.f(x)
            return self.h(torch.cat([f.mean((2, 3)), f.amax((2, 3)), self.s(scalars)], 1))

    return Net(width)


def load_data(folder: Path):
    files = sorted(glob.glob(str(folder / "*.npz")))
    if not files:
        raise SystemExit(f"no .npz crops in {folder}; run python -m coastforge.train.category_data first")
    parts = [np.load(f) for f in files]
    cat = {k: np.concatenate([p[k] for p in parts]) for k in ("x", "g", "m", "y")}
    return cat["x"], net_scalars(cat["m"], cat["g"]), cat["y"]


def augment(xb: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    x = xb.astype(np.float32) / 255.0
    n = len(x)
    k = rng.integers(4, size=n)
    x = np.stack([np.rot90(xi, ki) for xi, ki in zip(x, k)])
    flip = rng.random(n) < 0.5
    x[flip] = x[flip, :, ::-1]
    gain = np.exp(rng.normal(0, 0.12, (n, 1, 1, 3))) * np.exp(rng.normal(0, 0.15, (n, 1, 1, 1)))
    gamma = np.exp(rng.normal(0, 0.15, (n, 1, 1, 1)))
    x = np.clip(x * gain, 0, 1) ** gamma
    x = x + rng.normal(0, 0.01, x.shape) * (rng.random((n, 1, 1, 1)) < 0.5)
    return net_batch(np.clip(x * 255.0, 0, 255))


def train(data: Path, steps: int = 3000, batch: int = 128, lr: float = 2e-3, threads: int = 2):
    import torch
    import torch.nn.functional as F

    torch.manual_seed(0)
    torch.set_num_threads(threads)
    rng = np.random.default_rng(0)
    x, sc, y = load_data(data)
    net = build_net()
    opt = torch.optim.AdamW(net.parameters(), lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, lr, total_steps=steps)
    w = 1.0 / np.maximum(np.bincount(y, minlength=len(CATEGORIES)), 1)
    p = w[y] / w[y].sum()
    t0 = time.time()
    for it in range(steps):
        idx = rng.choice(len(y), batch, p=p)
        s = sc[idx] + np.stack([rng.normal(0, 0.1, batch), np.zeros(batch)], 1).astype(np.float32)
        out = net(torch.from_numpy(augment(x[idx], rng)), torch.from_numpy(s))
        loss = F.cross_entropy(out, torch.from_numpy(y[idx]).long(), label_smoothing=0.05)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if it % 500 == 0:
            print(f"step {it} loss {loss.item():.3f} {time.time() - t0:.0f} s", flush=True)
    net.eval()
    info = {"steps": steps, "batch": batch, "lr": lr, "threads": threads, "crops": int(len(y)),
            "per_category": dict(zip(CATEGORIES, np.bincount(y, minlength=len(CATEGORIES)).tolist())),
            "seconds": round(time.time() - t0, 1), "params": int(sum(q.numel() for q in net.parameters()))}
    return net, info


def export(net, out: Path, info: dict) -> Path:
    import torch

    from ..fsio import atomic_path, atomic_write_text

    out.mkdir(parents=True, exist_ok=True)
    path = out / "category.onnx"
    net.eval()
    with atomic_path(path) as tmp:
        torch.onnx.export(net, (torch.zeros(1, 3, INPUT_PX, INPUT_PX), torch.zeros(1, 2)), str(tmp),
                          dynamo=False, opset_version=17, input_names=["image", "scalars"],
                          output_names=["logits"], dynamic_axes={"image": {0: "n"}, "scalars": {0: "n"},
                                                                 "logits": {0: "n"}})
    meta = {"format": FORMAT, "categories": list(CATEGORIES), "input_px": INPUT_PX,
            "scalars": ["log(side_m / 10)", "log(gsd_m / 0.15)"], "training": info}
    atomic_write_text(path.with_suffix(".json"), json.dumps(meta, indent=1) + "\n")
    return path


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--threads", type=int, default=2)
    a = p.parse_args(argv)
    net, info = train(Path(a.data), steps=a.steps, threads=a.threads)
    print("wrote", export(net, Path(a.out), info))


if __name__ == "__main__":
    main()
