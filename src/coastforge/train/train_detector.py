"""Train the learned detector on synthetic renders and export it to ONNX.

``python -m coastforge.train.train_detector --out DIR --seed N --minutes M [--data DIR]``

Without ``--data`` the training levels are rendered first (``detector_data.generate``, seeds from 100;
seeds below 100 are validation). Writes ``DIR/detector.onnx`` (refreshed at checkpoints, so a run cut
short still leaves a model) and ``DIR/detector.json`` (settings, parameter count, loss curve). The
learning rate follows a cosine over the time budget, so ``--steps`` fixes the step count for an exact
re-run. ``--init`` continues from a ``detector.pt`` or from an exported ``detector.onnx`` (such as the
shipped model, whose checkpoint is not kept: ``init_from_onnx`` rebuilds the BatchNorms the export folded).
torch is a training-time extra (``pip install coastforge[train]``).

The shipped model (``coastforge/data/models/detector.json`` records its lineage and lists its data sets)
was fine-tuned from the synthetic-only model before it on renders and the training split of the real box
sets (``coastforge.realdata``; the validation groups are never written):

    python -m coastforge.train.detector_data --out S --seeds 1000:1400 --mix training
    python -m coastforge.train.detector_real --out SHIPS --sets ships_aerial
    python -m coastforge.train.detector_real --out CARS --sets cars_munich
    python -m coastforge.train.detector_data --out T --seeds 5000:5021
    git show 9c27fa8:src/coastforge/data/models/detector.onnx > previous.onnx
    python -m coastforge.train.train_detector --out R --seed 5 --minutes 35 --lr 8e-4 --threads 1 \
        --batch 12 --crop 224 --data S --data SHIPS --data CARS --share 0.45 --share 0.35 --share 0.2 \
        --init previous.onnx
    python -m coastforge.train.eval_detector --weights R/detector.onnx --tune T --write-meta

(35 minutes on one core, 11,529 steps; the time budget fixes the step count, so ``--steps 11529`` re-runs
it exactly. Real boxes are axis-aligned: they teach centres and looks, not sizes along the hull nor
headings, which still come from the renders. The detection thresholds are tuned for F1 on levels
5000-5020, never on the benchmark's seeds 0-4 or the real photos.)
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..rng import stage_rng
from .detector_data import CLASSES, WORK_GSD_M
from .detector_model import N_CLASSES, build_model, export_wrapper

STRIDE = 4


# ------------------------------------------------------------------------------------------ samples

def affine_boxes(boxes: np.ndarray, M: np.ndarray, scale: float, angle_deg: float) -> np.ndarray:
    """Boxes (N, 6: cls, cx, cy, length, width, yaw) under ``M = cv2.getRotationMatrix2D(.., angle, scale)``
    (+ translation): centres mapped, sizes scaled, yaw turned by ``angle`` (CCW on screen = CCW yaw)."""
    out = boxes.copy()
    if len(out):
        pts = np.c_[out[:, 1:3], np.ones(len(out))] @ M.T
        out[:, 1:3] = pts
        out[:, 3:5] *= scale
        out[:, 5] = (out[:, 5] + angle_deg + 180.0) % 360.0 - 180.0
    return out


OBJECT_RECOLOUR_P = 0.5  # share of rendered crops whose objects are recoloured one by one
# an object longer than this share of the crop is never "cut" by it (a 224 px crop cannot hold 70 % of a
# 300 px ship; the inference edge rule, ``detection.drop_cut_by_frame``, sees the whole image)
CUT_MAX_LENGTH = 0.5


def shares_inside(boxes: np.ndarray, region: np.ndarray) -> np.ndarray:
    """The share of each box's area (``boxes`` N, >= 6: class, cx, cy, length, width, yaw, ...) inside the
    convex ``region`` (its corners, float32); 1 for a box without area."""
    from ..frames import box_corners_px

    out = np.ones(len(boxes))
    for k, (_, cx, cy, L, W, yaw) in enumerate(boxes[:, :6]):
        if L * W > 0:
            inside, _ = cv2.intersectConvexConvex(box_corners_px(cx, cy, L, W, yaw).astype(np.float32), region)
            out[k] = inside / (L * W)
    return out


def drop_cut_boxes(boxes: np.ndarray, size: int, min_inside: float) -> np.ndarray:
    """``boxes`` (N, >= 6: class, cx, cy, length, width, yaw, ...) without those lying less than ``min_inside``
    of their area inside the ``size`` x ``size`` crop: what the crop cuts is no object to find, as the real
    sets label it (DOTA's crops and ships_aerial leave an object under 70 % inside to the next picture). The
    network sees the crop's edge as the picture's edge, so it learns to leave such objects, where before it
    learned to find any whose centre was inside."""
    if min_inside <= 0 or not len(boxes):
        return boxes
    square = np.array([[0, 0], [size, 0], [size, size], [0, size]], np.float32)
    keep = (shares_inside(boxes, square) >= min_inside) | (boxes[:, 3] > CUT_MAX_LENGTH * size)
    return boxes[keep]


# a flat margin along one side of a crop (``blank_margin``): its width as a share of the crop, and the least
# share of an object's box that must stay visible for it to remain an object to find
BLANK_WIDTH = (0.08, 0.3)
BLANK_MIN_VISIBLE = 0.3
# the flat margin the card of a network trained with blank margins asks ``detect`` to add at the picture's
# edges: within the strips it saw (18-67 px of a 224 px crop), and enough to hold the centre of a 10 m boat
# (50 px at 0.2 m/px) the frame cuts at its middle
EDGE_MARGIN_PX = 48


def blank_margin(img: np.ndarray, boxes: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``img`` with a strip along one side painted one flat colour, as the detector pads a picture's edges
    (``detect`` with a card's ``edge_margin_px``), and the boxes it leaves: an object still at least
    ``BLANK_MIN_VISIBLE`` visible keeps its whole box, its centre perhaps under the strip; one hidden more
    is no object. So the network learns to draw a boat the frame cuts whole, past the edge, and the edge
    rule (``detection.drop_cut_by_frame``) can judge how much of it the picture holds; before, it only
    saw cut objects end where the picture ended."""
    size = img.shape[0]
    width = int(round(rng.uniform(*BLANK_WIDTH) * size))
    side = int(rng.integers(4))
    out = img.copy()
    fill = rng.uniform(20, 200, 3).astype(np.uint8)
    visible = np.array([[0, 0], [size, 0], [size, size], [0, size]], np.float32)
    if side == 0:
        out[:, :width] = fill
        visible[[0, 3], 0] = width
    elif side == 1:
        out[:, size - width:] = fill
        visible[[1, 2], 0] = size - width
    elif side == 2:
        out[:width] = fill
        visible[[0, 1], 1] = width
    else:
        out[size - width:] = fill
        visible[[2, 3], 1] = size - width
    if not len(boxes):
        return out, boxes
    return out, boxes[shares_inside(boxes, visible) >= BLANK_MIN_VISIBLE]


def recolour_objects(img: np.ndarray, boxes: np.ndarray, rng: np.random.Generator, shrink: float = 0.85) -> np.ndarray:
    """Each oriented (rendered) object of the crop gets, with probability 0.6, its own hue turn, saturation
    and brightness inside its box (shrunk so that little of the water around it changes): hulls and car
    bodies of colours no model in the renders has, independent of the background (a global hue turn moves
    water and hulls together). Axis-aligned real boxes hold too much background and are left alone."""
    todo = [b for b in boxes if len(b) > 6 and b[6] > 0.5 and rng.random() < 0.6]
    if not todo:
        return img
    hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)
    h, s, v = (hsv[..., i].astype(np.int16) for i in range(3))
    for b in todo:
        _c, cx, cy, L, W, yaw = (float(x) for x in b[:6])
        poly = cv2.boxPoints(((cx, cy), (max(L * shrink, 1.0), max(W * shrink, 1.0)), -yaw)).astype(np.int32)
        m = np.zeros(img.shape[:2], np.uint8)
        cv2.fillConvexPoly(m, poly, 1)
        m = m.astype(bool)
        if not m.any():
            continue
        h[m] = (h[m] + int(rng.integers(0, 180))) % 180
        s[m] = np.clip(s[m] * rng.uniform(0.6, 2.0) + rng.uniform(0, 60), 0, 255).astype(np.int16)
        v[m] = np.clip(v[m] * rng.uniform(0.45, 1.15), 0, 255).astype(np.int16)
    out = np.stack([h, s, v], 2).astype(np.uint8)
    return cv2.cvtColor(out, cv2.COLOR_HSV2RGB)


COARSE_SOURCE_FACTORS = (1.5, 5.0)  # ``coarse_source``: how many times coarser the simulated source image is


def coarse_source(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``img`` as if it came from an image 1.5-5 times coarser (0.3-1 m/px for a 0.2 m/px crop), brought to
    the working GSD as the detector brings one: averaged down, sometimes JPEG-compressed at that size, and
    interpolated back up. The renders are made at 0.08-0.3 m/px, so without this the network never sees the
    soft, blocky boats of a 1 m/px photo."""
    h, w = img.shape[:2]
    k = float(rng.uniform(*COARSE_SOURCE_FACTORS))
    small = cv2.resize(img, (max(2, int(round(w / k))), max(2, int(round(h / k)))), interpolation=cv2.INTER_AREA)
    if rng.random() < 0.5:
        ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(40, 90))])
        if ok:
            small = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def photometric(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Colour, hue, blur, noise and JPEG randomisation (uint8 RGB in, uint8 out)."""
    x = img.astype(np.float32)
    if rng.random() < 0.3:  # hue shift: unseen water and hull colours
        hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)
        hsv[..., 0] = (hsv[..., 0].astype(np.int16) + int(rng.integers(-25, 26))) % 180
        x = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB).astype(np.float32)
    x = x * rng.uniform(0.8, 1.2, 3)[None, None, :].astype(np.float32)
    m = x.mean()
    x = (x - m) * rng.uniform(0.65, 1.35) + m + rng.uniform(-35, 35)
    if rng.random() < 0.15:
        g = x.mean(2, keepdims=True)
        x = g + (x - g) * rng.uniform(0.0, 0.6)
    if rng.random() < 0.3:
        x = 255.0 * (np.clip(x, 0, 255) / 255.0) ** rng.uniform(0.7, 1.4)
    if rng.random() < 0.4:
        x = cv2.GaussianBlur(x, (0, 0), float(rng.uniform(0.4, 1.3)))
    if rng.random() < 0.5:
        x = x + rng.standard_normal(x.shape).astype(np.float32) * float(rng.uniform(1, 7))
    out = np.clip(x, 0, 255).astype(np.uint8)
    if rng.random() < 0.4:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(35, 92))])
        if ok:
            out = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return out


# ``weather``: the stronger photometric changes real photographs bring and ``photometric`` stays short of
WEATHER_HAZE_ALPHA = (0.1, 0.45)  # share of a bright airlight blended in (haze, thin cloud, glare)
WEATHER_GAMMA = (0.5, 2.0)  # under- and over-exposure
WEATHER_NOISE = (6.0, 14.0)  # sensor noise sigma, grey levels


def weather(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One of haze, hard exposure, heavy noise or a grey picture (uint8 RGB in, uint8 out): the changes that,
    applied to the DOTA marina and the real training photos, cost the network the most recall while
    ``photometric`` stays short of them (haze at 0.3, gamma 1.6, noise sigma 8, greyscale)."""
    x = img.astype(np.float32)
    kind = int(rng.integers(4))
    if kind == 0:
        a = float(rng.uniform(*WEATHER_HAZE_ALPHA))
        light = rng.uniform(170, 235) + rng.uniform(-10, 10, 3)
        x = x * (1 - a) + light[None, None, :].astype(np.float32) * a
    elif kind == 1:
        x = 255.0 * (x / 255.0) ** float(np.exp(rng.uniform(*np.log(WEATHER_GAMMA))))
    elif kind == 2:
        x = x + rng.standard_normal(x.shape).astype(np.float32) * float(rng.uniform(*WEATHER_NOISE))
    else:
        x = np.repeat(x @ np.array([0.299, 0.587, 0.114], np.float32), 3).reshape(x.shape)
    return np.clip(x, 0, 255).astype(np.uint8)


def make_targets(boxes: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """CenterNet targets at stride 4: heat (C, h, w), regression (8, h, w), offset mask, angle mask and size
    mask (h, w).

    Centres are oriented Gaussians (elongated along the hull, so boats moored side by side keep
    separate peaks); regression is supervised on the cells near each centre (the nearest object wins).
    A box with a 7th column of 0 is an axis-aligned real label: its centre teaches the heatmap (a round
    Gaussian as wide as the box's short side) and the offset, but neither its size nor its axis."""
    n = size // STRIDE
    heat = np.zeros((N_CLASSES, n, n), np.float32)
    reg = np.zeros((8, n, n), np.float32)
    wmask = np.zeros((n, n), np.float32)
    amask = np.zeros((n, n), np.float32)
    smask = np.zeros((n, n), np.float32)
    owner = np.zeros((n, n), np.float32)
    jj, ii = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    for row in boxes:
        c, cx, cy, L, W, yaw = row[:6]
        oriented = len(row) < 7 or row[6] > 0.5
        u, v = cx / STRIDE, cy / STRIDE
        if not (0 <= u < n and 0 <= v < n):
            continue
        t = math.radians(yaw)
        f = np.array([math.cos(t), -math.sin(t)])  # front in (col, row)
        sl, sw = max(0.6, L / STRIDE / 6.0), max(0.6, W / STRIDE / 6.0)
        if not oriented:
            sl = sw
        du, dv = jj - u, ii - v
        along = du * f[0] + dv * f[1]
        across = -du * f[1] + dv * f[0]
        g = np.exp(-(along ** 2 / (2 * sl * sl) + across ** 2 / (2 * sw * sw)))
        pj, pi = int(u), int(v)
        g[pi, pj] = 1.0
        ci = int(c)
        np.maximum(heat[ci], g, out=heat[ci])
        sel = ((g > 0.6) & (g > owner))
        sel[pi, pj] = True
        owner[sel] = g[sel]
        reg[0][sel] = u - (jj[sel] - 0.5)
        reg[1][sel] = v - (ii[sel] - 0.5)
        reg[2][sel] = math.log(max(L, 1.0) / STRIDE)
        reg[3][sel] = math.log(max(W, 1.0) / STRIDE)
        reg[4][sel], reg[5][sel] = math.cos(2 * t), math.sin(2 * t)
        reg[6][sel], reg[7][sel] = math.cos(t), math.sin(t)
        wmask[sel] = 1.0
        smask[sel] = 1.0 if oriented else 0.0
        amask[sel] = 0.0 if CLASSES[ci] == "buoy" or not oriented else 1.0
    return heat, reg, wmask, amask, smask


class Sampler:
    """Random augmented crops from the generated levels (re-reads the index as more levels appear)."""

    def __init__(self, data_dirs: Path | list[Path], crop: int, rng: np.random.Generator,
                 shares: list[float] | None = None, min_inside: float = 0.0, coarse_p: float = 0.0,
                 blank_p: float = 0.0, weather_p: float = 0.0):
        """``data_dirs``: one folder of ``detector_data`` (or ``detector_real``) levels or several (their
        levels in that order); ``shares``: the share of crops drawn from each folder (default: by its
        number of images); ``min_inside``: objects the crop cuts below this share are background
        (``drop_cut_boxes``; 0 keeps every object whose centre is inside); ``coarse_p``: the share of crops
        seen as from a coarser image (``coarse_source``); ``blank_p``: the share with a flat margin along one
        side (``blank_margin``); ``weather_p``: the share with haze, hard exposure, heavy noise or no colour
        (``weather``)."""
        self.min_inside = float(min_inside)
        self.weather_p = float(weather_p)
        self.blank_p = float(blank_p)
        self.coarse_p = float(coarse_p)
        self.dirs = [Path(d) for d in (data_dirs if isinstance(data_dirs, (list, tuple)) else [data_dirs])]
        if shares is not None and (len(shares) != len(self.dirs) or min(shares) < 0 or sum(shares) <= 0):
            raise InputError(f"--share needs one non-negative share per --data folder, got {shares}")
        self.shares = shares
        self.crop, self.rng = crop, rng
        self.images: dict[str, np.ndarray] = {}
        self.items: list[dict] = []
        self.refresh()

    def refresh(self) -> None:
        for d in self.dirs:
            idx = d / "index.json"
            if not idx.is_file():
                raise InputError(f"no training index {idx}; generate data with "
                                 "coastforge.train.detector_data")
            for it in json.loads(idx.read_text())["items"]:
                path = str(d / it["image"])
                if path not in self.images:
                    bgr = cv2.imread(path, cv2.IMREAD_COLOR)
                    if bgr is None:
                        continue
                    self.images[path] = np.ascontiguousarray(bgr[:, :, ::-1])
                    self.items.append({**it, "image": path, "dir": str(d)})
        if not self.items:
            where = ", ".join(map(str, self.dirs))
            raise InputError(f"the training indexes in {where} list no readable images")

    def _pick(self) -> dict:
        rng = self.rng
        if self.shares is None:
            return self.items[int(rng.integers(len(self.items)))]
        p = np.asarray(self.shares, np.float64)
        d = str(self.dirs[int(rng.choice(len(p), p=p / p.sum()))])
        pool = [it for it in self.items if it["dir"] == d] or self.items
        return pool[int(rng.integers(len(pool)))]

    def sample(self) -> tuple[np.ndarray, np.ndarray]:
        """An augmented crop and its boxes (N, 7: class, cx, cy, length, width, yaw, oriented 0/1)."""
        return self.sample_item()[:2]

    def sample_item(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As ``sample``, plus which classes the crop's image has labels for (bool per class)."""
        rng, C = self.rng, self.crop
        it = self._pick()
        img = self.images[it["image"]]
        boxes = np.asarray(it["boxes"], np.float64).reshape(-1, 6)
        boxes = np.c_[boxes, np.full(len(boxes), 0.0 if it.get("aligned") else 1.0)]
        labelled = np.zeros(N_CLASSES, bool)
        labelled[list(it.get("labelled", range(N_CLASSES)))] = True
        h, w = img.shape[:2]
        if len(boxes) and rng.random() < 0.75:  # most crops around an object (they are sparse)
            b = boxes[int(rng.integers(len(boxes)))]
            cx, cy = b[1] + rng.uniform(-0.4, 0.4) * C, b[2] + rng.uniform(-0.4, 0.4) * C
        else:
            cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        angle = float(rng.uniform(-180, 180))
        scale = float(math.exp(rng.uniform(math.log(0.8), math.log(1.25))))
        M = cv2.getRotationMatrix2D((float(cx), float(cy)), angle, scale)
        M[:, 2] += np.array([C / 2 - cx, C / 2 - cy])
        fill = tuple(float(v) for v in rng.uniform(20, 200, 3))
        crop = cv2.warpAffine(img, M, (C, C), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=fill)
        bx = affine_boxes(boxes, M, scale, angle)
        if rng.random() < 0.5:  # mirror: yaw → 180 - yaw
            crop = np.ascontiguousarray(crop[:, ::-1])
            if len(bx):
                bx[:, 1] = C - bx[:, 1]
                bx[:, 5] = (180.0 - bx[:, 5] + 180.0) % 360.0 - 180.0
        if len(bx) and rng.random() < OBJECT_RECOLOUR_P:
            crop = recolour_objects(crop, bx, rng)
        # rendered crops only (real photos have their own GSD, up to 1.2 m/px); no draw when off, so that
        # earlier runs re-run alike
        if self.coarse_p > 0 and "seed" in it and rng.random() < self.coarse_p:
            crop = coarse_source(crop, rng)
        crop, bx = photometric(crop, rng), drop_cut_boxes(bx, C, self.min_inside)
        if self.weather_p > 0 and rng.random() < self.weather_p:  # no draw when off: earlier runs re-run alike
            crop = weather(crop, rng)
        if self.blank_p > 0 and rng.random() < self.blank_p:  # after the photometry: the margin stays flat
            crop, bx = blank_margin(crop, bx, rng)
        return crop, bx, labelled


# ------------------------------------------------------------------------------------------ training

def label_mask(boxes: np.ndarray, labelled: np.ndarray, size: int, grow: float = 1.5) -> np.ndarray:
    """(C, h, w) float mask of where each class's heatmap is supervised at stride 4: everywhere for the
    classes the image has labels for; for the others only on and around the labelled objects (boxes grown
    by ``grow``), so that a labelled boat also teaches "this is no vehicle" while the unlabelled cars of
    the same photo are not taught as background."""
    n = size // STRIDE
    m = np.zeros((N_CLASSES, n, n), np.float32)
    m[labelled] = 1.0
    if labelled.all() or not len(boxes):
        return m
    near = np.zeros((n, n), np.uint8)
    for row in boxes:
        cx, cy, L, W = row[1] / STRIDE, row[2] / STRIDE, row[3] * grow / STRIDE, row[4] * grow / STRIDE
        rect = ((float(cx), float(cy)), (float(max(L, 1.0)), float(max(W, 1.0))), -float(row[5]))
        cv2.fillPoly(near, [np.round(cv2.boxPoints(rect)).astype(np.int32)], 1)
    m[~labelled] = near
    return m


def losses(torch, out, heat, reg, wmask, amask, smask=None, labelled=None):
    """CenterNet focal loss on the heatmaps (only where each class is labelled: ``labelled`` (N, C) bool,
    or (N, C, h, w) float from ``label_mask``) + L1 on offsets, log sizes (where ``smask``), axis and
    heading."""
    p = torch.sigmoid(out[:, :N_CLASSES]).clamp(1e-4, 1 - 1e-4)
    if labelled is None:
        lab = torch.ones_like(heat[:, :, :1, :1])
    elif labelled.dim() == 2:
        lab = labelled.float()[:, :, None, None]
    else:
        lab = labelled.float()
    pos = (heat >= 0.999).float() * lab
    npos = pos.sum().clamp(min=1.0)
    lpos = -(torch.log(p) * (1 - p) ** 2 * pos).sum()
    lneg = -(torch.log(1 - p) * p ** 2 * (1 - heat) ** 4 * (1 - pos) * lab).sum()
    l_heat = (lpos + lneg) / npos
    r = out[:, N_CLASSES:]
    wm, am = wmask[:, None], amask[:, None]
    sm = wm if smask is None else smask[:, None]
    nw, na, ns = wm.sum().clamp(min=1.0), am.sum().clamp(min=1.0), sm.sum().clamp(min=1.0)
    l_off = (torch.abs(r[:, 0:2] - reg[:, 0:2]) * wm).sum() / nw
    l_size = (torch.abs(r[:, 2:4] - reg[:, 2:4]) * sm).sum() / ns
    l_axis = (torch.abs(r[:, 4:6] - reg[:, 4:6]) * am).sum() / na
    l_head = (torch.abs(r[:, 6:8] - reg[:, 6:8]) * am).sum() / na
    total = l_heat + l_off + l_size + 2.0 * l_axis + l_head
    return total, {"heat": l_heat, "off": l_off, "size": l_size, "axis": l_axis, "head": l_head}


def export_onnx(net, path: Path) -> Path:
    """Export (dynamic H, W) atomically; the graph ends with the 3x3 peak search."""
    import torch

    from ..fsio import atomic_path

    net.eval()
    wrap = export_wrapper(net)
    with atomic_path(path) as tmp:
        torch.onnx.export(wrap, (torch.zeros(1, 3, 128, 128),), str(tmp), dynamo=False, opset_version=17,
                          input_names=["image"], output_names=["heat", "peaks", "reg"],
                          dynamic_axes={"image": {2: "h", 3: "w"}, "heat": {2: "hh", 3: "ww"},
                                        "peaks": {2: "hh", 3: "ww"}, "reg": {2: "hh", 3: "ww"}})
    net.train()
    return path


def init_from_onnx(torch, net, onnx_path: Path, sampler: Sampler, batches: int = 24) -> float:
    """Start ``net`` from an exported ``detector.onnx`` (e.g. the shipped model, whose torch checkpoint is
    not kept): ``common.init_from_onnx`` on batches of training crops. Returns the largest output
    difference to the ONNX model on a crop (checked: the network computes what the model does)."""
    from .common import init_from_onnx as init

    def crops(n: int):
        x = np.stack([sampler.sample()[0] for _ in range(n)])
        return torch.from_numpy(x).permute(0, 3, 1, 2).float() / 255.0

    return init(torch, net, onnx_path, crops, batches)


def train(out_dir: str | Path, seed: int, minutes: float, data_dir: str | Path | list | None = None,
          steps: int | None = None, batch: int = 16, crop: int = 160, lr: float = 2e-3, width: int = 16,
          threads: int = 1, data_minutes: float = 10.0, init: str | Path | None = None,
          shares: list[float] | None = None, min_inside: float = 0.0, coarse_p: float = 0.0,
          blank_p: float = 0.0, weather_p: float = 0.0) -> dict:
    from ..registry import require

    torch = require("torch", "train", "training the learned detector")
    torch.set_num_threads(threads)
    torch.manual_seed(seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if data_dir is None:
        from .detector_data import generate

        data_dir = out / "data"
        generate(data_dir, list(range(100 + seed * 1000, 100 + seed * 1000 + 1000)), minutes=data_minutes)
    sampler = Sampler(data_dir, crop, stage_rng(seed, "train", "detector", "samples"), shares, min_inside, coarse_p,
                      blank_p, weather_p)
    net = build_model(width)
    previous = None
    if init is not None:  # continue an earlier run (its settings are kept in the record)
        init = Path(init)
        if not init.is_file():
            raise InputError(f"--init {init} does not exist; give a detector.pt or detector.onnx written "
                             "by this command")
        if init.suffix.lower() == ".onnx":
            diff = init_from_onnx(torch, net, init, sampler)
            print(f"started from {init} (largest output difference to the ONNX model {diff:.2e})", flush=True)
        else:
            net.load_state_dict(torch.load(init, map_location="cpu"))
        side = init.with_suffix(".json")
        previous = json.loads(side.read_text()).get("training") if side.is_file() else None
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    budget = minutes * 60.0
    t0 = time.time()
    curve, step, ema = [], 0, None
    onnx_path = out / "detector.onnx"
    while True:
        el = time.time() - t0
        frac = step / steps if steps else el / budget
        if frac >= 1.0:
            break
        for g in opt.param_groups:  # short warm-up, then a cosine to 2 % of lr
            g["lr"] = lr * min(1.0, (step + 1) / 100) * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * frac)))
        xs, ts, labs = [], [], []
        for _ in range(batch):
            im, bx, lab = sampler.sample_item()
            xs.append(im)
            ts.append(make_targets(bx, crop))
            labs.append(label_mask(bx, lab, crop))
        x = torch.from_numpy(np.stack(xs)).permute(0, 3, 1, 2).float() / 255.0
        heat, reg, wm, am, sm = (torch.from_numpy(np.stack([t[k] for t in ts])) for k in range(5))
        total, parts = losses(torch, net(x), heat, reg, wm, am, sm, torch.from_numpy(np.stack(labs)))
        opt.zero_grad()
        total.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 5.0)
        opt.step()
        step += 1
        v = float(total.detach())
        ema = v if ema is None else 0.98 * ema + 0.02 * v
        if step % 50 == 0:
            row = {"step": step, "s": round(time.time() - t0), "loss": round(ema, 4),
                   **{k: round(float(p), 4) for k, p in parts.items()}, "images": len(sampler.items)}
            curve.append(row)
            print(json.dumps(row), flush=True)
        if step % 200 == 0:
            sampler.refresh()
        if step % 500 == 0:
            export_onnx(net, onnx_path)
            torch.save(net.state_dict(), out / "detector.pt")
    export_onnx(net, onnx_path)
    torch.save(net.state_dict(), out / "detector.pt")
    synth = [it for it in sampler.items if "seed" in it]
    datasets = []
    for d in sampler.dirs:
        head = json.loads((d / "index.json").read_text())
        if head.get("datasets"):  # real sets (coastforge.train.detector_real) name themselves in their index
            datasets += head["datasets"]
            continue
        n = len(head.get("items", []))
        lib, looks = head.get("library", "kit"), head.get("looks", "kit")
        if lib == "kit" and looks == "kit":
            datasets.append({"name": "coastforge synthetic levels (coastforge.train.detector_data)",
                             "licence": "Apache-2.0 (this project)", "images": n})
        else:  # renders of another library's models: those keep their own licence (add it to the card)
            datasets.append({"name": f"coastforge synthetic levels (coastforge.train.detector_data --library {lib} "
                                     f"--looks {looks})",
                             "licence": "Apache-2.0 (this project) for the renders; the library's models keep "
                                        "their own licences", "images": n})
    meta = {
        "format": "coastforge.learned_detector/1",
        "datasets": datasets,
        "classes": list(CLASSES), "work_gsd_m": WORK_GSD_M, "stride": STRIDE,
        "edge_margin_px": EDGE_MARGIN_PX if blank_p > 0 else 0,
        "outputs": {"heat": "sigmoid centre heatmaps", "peaks": "heat at 3x3 local maxima, else 0",
                    "reg": "offset(2) log(len/4) log(wid/4) cos2t sin2t cos t sin t"},
        "training": {"seed": seed, "minutes": minutes, "steps": step, "batch": batch, "crop_px": crop,
                     "lr": lr, "width": width, "threads": threads, "min_inside": min_inside, "coarse_p": coarse_p,
                     "blank_p": blank_p, "weather_p": weather_p,
                     "data": ", ".join(map(str, sampler.dirs)),
                     "levels": len(synth), "real_images": len(sampler.items) - len(synth), "shares": shares,
                     "presets": sorted({it["preset"] for it in synth}),
                     "seeds": [min(it["seed"] for it in synth), max(it["seed"] for it in synth)] if synth else None,
                     "params": int(sum(p.numel() for p in net.parameters())),
                     "seconds": round(time.time() - t0, 1),
                     "init": str(init) if init is not None else None, "previous": previous},
        "curve": curve,
    }
    from ..fsio import atomic_write_text

    atomic_write_text(out / "detector.json", json.dumps(meta, indent=1) + "\n")
    return meta


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--minutes", type=float, default=25.0)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--data", action="append", default=None,
                    help="levels from coastforge.train.detector_data (else rendered); repeatable")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--crop", type=int, default=160)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--share", type=float, action="append", default=None,
                    help="share of crops from each --data folder, in their order (default: by image count)")
    ap.add_argument("--init", default=None,
                    help="start from this detector.pt or exported detector.onnx (continue a run)")
    ap.add_argument("--min-inside", type=float, default=0.0,
                    help="objects the crop cuts below this share of their area are background (0: none; "
                         "tried at 0.7, not shipped: docs/benchmarks.md)")
    ap.add_argument("--coarse-p", type=float, default=0.0,
                    help="share of rendered crops seen as from a 1.5-5 times coarser image (default 0; tried at "
                         "0.3, not shipped: docs/benchmarks.md)")
    ap.add_argument("--blank-p", type=float, default=0.0,
                    help="share of crops with a flat margin along one side, objects under it kept whole (for a "
                         "card's edge_margin_px; default 0)")
    ap.add_argument("--weather-p", type=float, default=0.0,
                    help="share of crops with haze, hard exposure, heavy noise or no colour (default 0; tried at "
                         "0.25, not shipped: docs/benchmarks.md)")
    a = ap.parse_args(argv)
    if not 0.0 <= a.weather_p <= 1.0:
        raise SystemExit(f"--weather-p must lie in [0, 1], got {a.weather_p}")
    if not 0.0 <= a.blank_p <= 1.0:
        raise SystemExit(f"--blank-p must lie in [0, 1], got {a.blank_p}")
    if not 0.0 <= a.coarse_p <= 1.0:
        raise SystemExit(f"--coarse-p must lie in [0, 1], got {a.coarse_p}")
    if not 0.0 <= a.min_inside < 1.0:
        raise SystemExit(f"--min-inside must lie in [0, 1), got {a.min_inside}")
    train(a.out, a.seed, a.minutes, a.data, a.steps, a.batch, a.crop, lr=a.lr, threads=a.threads, init=a.init,
          shares=a.share, min_inside=a.min_inside, coarse_p=a.coarse_p,
          blank_p=a.blank_p, weather_p=a.weather_p)


if __name__ == "__main__":
    main()
