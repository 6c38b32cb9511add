"""Train the pier-deck network (``coastforge.detection.pier_net``) on ``pier_data`` levels and export it.

    python -m coastforge.train.pier_data --out DATA --seeds 6000:6600
    python -m coastforge.train.pier_train --data DATA --out OUT --minutes 30      # 2 cores

writes ``OUT/piers.onnx`` and its card ``OUT/piers.json`` (copy both to ``coastforge/data/models/`` to ship them).
The network is the segmenter's small U-Net with one output (deck logit) at 0.2 m/px. Crops of 160 px, most of
them centred on a deck; turned by 90° steps and mirrored, rescaled by 0.8-1.25, and their colours jittered,
with the decks repainted half the time (any lightness, any tint: timber darker than the water, grey concrete,
white plastic) so that the network learns a deck's shape and texture rather than the renders' paint. The last
tenth of the levels (by seed) is held out: its deck IoU / precision / recall are in the card. Seeded (``--seed``);
the learning rate follows a cosine over the time budget, so a run is reproducible only in its step count.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from ..detection.pier_net import DEFAULT_MAX_GSD_M, FORMAT
from ..errors import InputError
from ..rng import stage_rng, stage_seed

CROP = 160
WORK_GSD_M = 0.2
COARSE_GSD_M = (0.3, 1.2)  # the GSDs ``augment(coarse=...)`` imitates


def load_levels(dirs: list[Path]) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(seed, rgb, deck mask) of every level in the ``pier_data`` folders."""
    from ..fsio import read_png

    out = []
    for d in dirs:
        try:
            items = json.loads((d / "index.json").read_text(encoding="utf-8"))["items"]
        except (OSError, json.JSONDecodeError, KeyError) as exc:
            raise InputError(f"{d} is not a pier_data folder ({exc}); write one with "
                             "python -m coastforge.train.pier_data --out DIR") from None
        for it in items:
            rgb = read_png(d / it["image"])[..., :3]
            out.append((int(it["seed"]), np.ascontiguousarray(rgb), read_png(d / it["piers"]).astype(np.uint8)))
    out.sort(key=lambda t: t[0])
    return out


def _repaint_decks(img: np.ndarray, mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The deck pixels given another mean lightness and tint, their texture (lightness detail) kept."""
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2LAB).astype(np.float32)
    m = mask > 0
    if not m.any():
        return img
    L = lab[..., 0]
    L[m] = np.clip(L[m] - L[m].mean() + rng.uniform(40, 240), 0, 255)
    lab[..., 1][m] = np.clip(128 + rng.normal(0, 14) + 0.3 * (lab[..., 1][m] - lab[..., 1][m].mean()), 0, 255)
    lab[..., 2][m] = np.clip(128 + rng.normal(6, 18) + 0.3 * (lab[..., 2][m] - lab[..., 2][m].mean()), 0, 255)
    return cv2.cvtColor(lab.astype(np.uint8), cv2.COLOR_LAB2RGB)


def coarsen(rgb: np.ndarray, factor: float) -> np.ndarray:
    """``rgb`` as an image ``factor`` times coarser looks once the network's input resampling has brought it
    back to the working GSD (area-averaged down, bilinear up: ``PierNet.probability``'s path)."""
    h, w = rgb.shape[:2]
    small = cv2.resize(rgb, (max(2, round(w / factor)), max(2, round(h / factor))), interpolation=cv2.INTER_AREA)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def augment(rgb: np.ndarray, mask: np.ndarray, rng: np.random.Generator,
            coarse: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A randomised look of one crop; with probability ``coarse`` it is also made as coarse as an image of
    0.3-1.2 m/px (the renders are 0.08-0.35 m/px; real marina photos go to 1 m/px)."""
    if coarse and rng.random() < coarse:
        rgb = coarsen(rgb, math.exp(rng.uniform(math.log(COARSE_GSD_M[0] / WORK_GSD_M),
                                                math.log(COARSE_GSD_M[1] / WORK_GSD_M))))
    if rng.random() < 0.5:
        rgb = _repaint_decks(rgb, cv2.dilate(mask, np.ones((3, 3), np.uint8)) if rng.random() < 0.3 else mask, rng)
    x = rgb.astype(np.float32) / 255.0
    x = x * rng.normal(1.0, 0.08, 3).astype(np.float32)  # white balance
    x = (x - x.mean()) * rng.uniform(0.7, 1.3) + x.mean() + rng.uniform(-0.12, 0.12)
    x = np.clip(x, 0, 1) ** rng.uniform(0.75, 1.35)
    if rng.random() < 0.3:
        x = cv2.GaussianBlur(x, (0, 0), rng.uniform(0.4, 1.2))
    x = x + rng.normal(0, rng.uniform(0, 0.03), x.shape).astype(np.float32)
    k = int(rng.integers(4))
    x, mask = np.rot90(x, k), np.rot90(mask, k)
    if rng.random() < 0.5:
        x, mask = x[:, ::-1], mask[:, ::-1]
    return np.clip(x, 0, 1), mask


def sample(levels, rng: np.random.Generator, deck_share: float = 0.6,
           coarse: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """One augmented crop (3, CROP, CROP) float32 in 0..1 and its mask (CROP, CROP) float32."""
    _seed, rgb, mask = levels[int(rng.integers(len(levels)))]
    s = float(math.exp(rng.uniform(math.log(0.8), math.log(1.25))))
    side = min(int(round(CROP * s)), min(rgb.shape[:2]))
    h, w = mask.shape
    if rng.random() < deck_share and mask.any():
        ys, xs = np.nonzero(mask)
        j = int(rng.integers(len(ys)))
        cy, cx = ys[j] + int(rng.integers(-side // 3, side // 3 + 1)), xs[j] + int(rng.integers(-side // 3, side // 3 + 1))
    else:
        cy, cx = int(rng.integers(h)), int(rng.integers(w))
    r0 = int(np.clip(cy - side // 2, 0, h - side))
    c0 = int(np.clip(cx - side // 2, 0, w - side))
    im, m = rgb[r0:r0 + side, c0:c0 + side], mask[r0:r0 + side, c0:c0 + side]
    if side != CROP:
        im = cv2.resize(im, (CROP, CROP), interpolation=cv2.INTER_AREA if side > CROP else cv2.INTER_LINEAR)
        m = cv2.resize(m, (CROP, CROP), interpolation=cv2.INTER_NEAREST)
    x, m = augment(im, m, rng, coarse)
    return np.ascontiguousarray(x.transpose(2, 0, 1)), np.ascontiguousarray(m, dtype=np.float32)


def evaluate(onnx_path: Path, levels, gsd_m: float = WORK_GSD_M) -> dict:
    """Deck IoU, precision and recall (probability >= 0.5) over held-out levels, pooled; with ``gsd_m``
    coarser than the working GSD, the levels are first made that coarse (``coarsen``)."""
    from ..detection.pier_net import PierNet

    net = PierNet(onnx_path)
    tp = fp = fn = 0
    for _seed, rgb, mask in levels:
        if gsd_m > WORK_GSD_M:
            rgb = coarsen(rgb, gsd_m / WORK_GSD_M)
        pred = net.probability_small(rgb) >= 0.5
        t = mask > 0
        tp += int((pred & t).sum())
        fp += int((pred & ~t).sum())
        fn += int((~pred & t).sum())
    return {"levels": len(levels), "iou": round(tp / max(1, tp + fp + fn), 3),
            "precision": round(tp / max(1, tp + fp), 3), "recall": round(tp / max(1, tp + fn), 3)}


def train(data: list[Path], out_dir: Path, minutes: float = 30.0, batch: int = 12, lr: float = 3e-3,
          width: int = 12, seed: int = 1, threads: int = 2, coarse: float = 0.0) -> Path:
    from ..fsio import atomic_write_text
    from ..registry import require

    torch = require("torch", "train", "training the pier-deck network")
    from .seg_model import build_segmenter
    from .seg_train import export_onnx  # input RGB 0..1, output the deck logit (1, 1, H, W)

    torch.set_num_threads(threads)
    torch.manual_seed(stage_seed(seed, "train", "piers", "torch"))
    rng = stage_rng(seed, "train", "piers", "batches")
    out_dir.mkdir(parents=True, exist_ok=True)
    levels = load_levels(data)
    n_held = max(1, len(levels) // 10)
    train_lv, held = levels[:-n_held], levels[-n_held:]
    print(f"{len(train_lv)} training levels, {len(held)} held out", flush=True)
    net = build_segmenter(1, width, "unet4")
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    pos = torch.tensor(2.0)
    onnx_path, card_path = out_dir / "piers.onnx", out_dir / "piers.json"
    seeds = [s for s, _, _ in levels]
    card: dict = {
        "format": FORMAT, "work_gsd_m": WORK_GSD_M, "multiple": 16, "input": "RGB 0..1, NCHW",
        "max_gsd_m": COARSE_GSD_M[1] if coarse else DEFAULT_MAX_GSD_M,
        "output": "deck logit (1, 1, H, W)",
        "datasets": [{"name": "coastforge synthetic levels (coastforge.train.pier_data), every preset",
                      "licence": "Apache-2.0 (this project)", "levels": len(levels), "seeds": [min(seeds), max(seeds)]}],
        "training": {"seed": seed, "batch": batch, "crop_px": CROP, "lr": lr, "width": width, "threads": threads,
                     "minutes": minutes, "coarse": coarse, "held_out_levels": [s for s, _, _ in held],
                     "command": f"python -m coastforge.train.pier_data --out DATA --seeds {min(seeds)}:{max(seeds) + 1} "
                                f"&& python -m coastforge.train.pier_train --data DATA --out OUT --minutes {minutes:g} "
                                f"--seed {seed}" + (f" --coarse {coarse:g}" if coarse else "")},
        "limits": "trained on renders only: no real photograph with labelled pier decks was available"}
    t0 = time.time()
    step, run = 0, 0.0
    budget = minutes * 60.0
    last_eval = t0
    while True:
        frac = (time.time() - t0) / budget
        if frac >= 1.0:
            break
        for g in opt.param_groups:
            g["lr"] = lr * (min(1.0, frac / 0.05) if frac < 0.05 else 0.5 * (1 + math.cos(math.pi * frac)))
        xs, ys = zip(*(sample(train_lv, rng, coarse=coarse) for _ in range(batch)))
        x, y = torch.from_numpy(np.stack(xs)), torch.from_numpy(np.stack(ys))[:, None]
        logits = net(x - 0.5)
        loss = torch.nn.functional.binary_cross_entropy_with_logits(logits, y, pos_weight=pos)
        opt.zero_grad()
        loss.backward()
        opt.step()
        step += 1
        run = 0.98 * run + 0.02 * loss.item() if step > 1 else loss.item()
        if step % 50 == 0:
            print(f"step {step} loss {run:.4f} {time.time() - t0:.0f} s", flush=True)
        if time.time() - last_eval > 600:
            export_onnx(net, onnx_path)
            print(f"checkpoint {step}: held-out {evaluate(onnx_path, held)}", flush=True)
            last_eval = time.time()
    export_onnx(net, onnx_path)
    card["training"]["steps"] = step
    card["training"]["params"] = int(sum(p.numel() for p in net.parameters()))
    card["held_out"] = evaluate(onnx_path, held)
    if coarse:
        card["held_out_coarse"] = {f"{g:g} m/px": evaluate(onnx_path, held, g) for g in (0.5, 1.0)}
    atomic_write_text(card_path, json.dumps(card, indent=1) + "\n")
    print(f"done: {onnx_path}, {step} steps, held-out {card['held_out']}", flush=True)
    return onnx_path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, nargs="+", help="folders written by python -m coastforge.train.pier_data")
    ap.add_argument("--out", required=True)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--width", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--coarse", type=float, default=0.0,
                    help="share of crops made as coarse as 0.3-1.2 m/px images (default 0)")
    a = ap.parse_args(argv)
    train([Path(d) for d in a.data], Path(a.out), a.minutes, a.batch, a.lr, a.width, a.seed, a.threads,
          a.coarse)


if __name__ == "__main__":
    main()
