"""Train the learned segmenter on coastforge's own synthetic renders and real labelled photos, and export
it to ONNX.

    python -m coastforge.train.seg_data --out /tmp/segdata --seeds 2000:2240      # ~12 min, rendering
    python -m coastforge.train.seg_train --data /tmp/segdata --out /tmp/segnet --steps 2400 \
        --real dubai,ships,cars --init SYNTHETIC_ONLY.onnx

The shipped model (its card ``segmenter.json`` has the exact command, 12.9 min on one core):

    python -m coastforge.train.seg_data --out DATA --seeds 2000:2240
    git show 9c27fa8:src/coastforge/data/models/segmenter.onnx > segmenter_shipped.onnx
    python -m coastforge.train.seg_train --data DATA --out OUT --steps 2000 --lr 0.002 --real dubai:0.5 \
        --init segmenter_shipped.onnx

(``ships`` and ``cars`` as weak labels were tried and not shipped: the network then took packed car parks
for rafted boats, i.e. water. ``streets``, the Munich crops as "no water anywhere", was tried too: it did not
lower the false water on the Dubai validation tiles and cost the DOTA marina its 0.60 mIoU. ``--looks wide``,
dark/grey land classes and cast shadows against the dark lawns and shadows taken for water there, was tried
from the shipped model too: Dubai training tiles improved, the validation tiles did not; see docs/benchmarks.md.)

``--hold tile_4`` leaves Dubai training tiles out: a recipe is judged on tiles it never saw (an inner check)
while the validation tiles stay unseen. ``--work-gsd`` sets the working resolution (a coarser one widens the
context a crop spans; docs/benchmarks.md has the 1.2 m/px trial).

``shipsself`` (``--real``) labels the ships_aerial training photos with a teacher's sure calls (``--teacher``,
default ``--init``): self-training on real harbour water; tried with ``--false-water`` and not shipped.

``--real`` mixes in the training splits of real sets in ``../shared/data`` (never the validation groups
of ``coastforge.realdata``): ``dubai`` (land-cover masks), ``ships`` and ``cars`` (boxes as weak labels:
a moored or anchored boat is water in our class map, a car stands on pavement; all other pixels of those
photos are unlabelled). Real labels are coarser than our eight classes (road, vegetation, unpaved land,
building), so they are learned as *sets*: a vegetation pixel must be grass or trees, a road or roof
pavement (asphalt or sidewalk), unpaved land sand or dirt; the loss is the negative log of the
probability summed over the set (for an exact label, plain cross-entropy).
The card (``segmenter.json``) lists every data set the model saw, with licence and attribution.

writes ``OUT/segmenter.onnx`` and ``OUT/segmenter.json`` (copy both to ``coastforge/data/models/`` to
ship them). One CPU thread (``torch.set_num_threads(1)``), seeded through ``coastforge.rng``; the real
marina photo (DOTA: evaluation only) and the Dubai validation tiles are only *evaluated* at checkpoints
(printed), never trained on.

Appearance randomisation is heavy on purpose, since real photos do not look like our renders: global
brightness/contrast/gamma/saturation/channel gains, per-class recolouring (water blue, green, olive or
brown; grass and trees dry or lush; pavement warm or cold), haze, blur, sensor noise, JPEG, and a random
scale around the working GSD (so a wrong ``--gsd`` of ±30 % still works; the real tiles, whose GSD is
only known to be about 0.5-1 m/px, get a wider range).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from ..classes import CLASS_NAMES, N_CLASSES, WATER
from ..errors import InputError
from ..rng import stage_rng, stage_seed
from .detector_data import resample_to_gsd

WORK_GSD_M = 0.3  # the network's working resolution (metres per pixel)
FORMAT = "coastforge.learned_segmenter/1"
IGNORE = 255
# label codes of the training rasters: 0-7 our classes; 8-10 sets of them (coarse real labels)
SET_PAVED, SET_VEGETATION, SET_BARE, REAL_WATER, SET_LAND = 8, 9, 10, 11, 12
N_CODES = 13  # REAL_WATER: water of a real photo (weighted as a set, not by the renders' water share)
# input side multiple and the tile overlap inference needs (> half the useful receptive field) per network
ARCH_MULTIPLE = {"unet4": 16, "unet5": 32}
ARCH_OVERLAP_PX = {"unet4": 48, "unet5": 96}
LOOKS = ("base", "wide")  # appearance randomisation recipes (augment)
DUBAI_NOMINAL_GSD_M = 0.6  # ../shared/data/README.md: "about 0.5-1 m/px"; DESIGN.md §5 uses 0.6


def label_sets() -> np.ndarray:
    """(N_CODES, 8) bool: which of our classes each training label code allows."""
    from ..classes import CLASS_IDS

    t = np.zeros((N_CODES, N_CLASSES), bool)
    t[np.arange(N_CLASSES), np.arange(N_CLASSES)] = True
    for code, names in ((SET_PAVED, ("asphalt", "sidewalk")), (SET_VEGETATION, ("grass", "trees")),
                        (SET_BARE, ("sand", "dirt")), (REAL_WATER, ("water",)),
                        (SET_LAND, tuple(n for n in CLASS_NAMES if n != "water"))):
        for n in names:
            t[code, CLASS_IDS[n]] = True
    return t


# data sets a model may have seen, for its card (licences from ../shared/data/README.md)
DATASETS = {
    "synthetic": {"name": "coastforge synthetic levels (coastforge.train.seg_data)", "licence": "Apache-2.0 (this project)",
                  "attribution": "rendered by coastforge from its own starter kit"},
    "dubai": {"name": "Semantic segmentation of aerial imagery (Dubai), training tiles "
                      "(../shared/data/real/landcover_dubai minus the validation tiles)",
              "licence": "CC0 1.0 as reported by the publisher (not verified)",
              "attribution": "Humans in the Loop / MBRSC; via github.com/Kaarti22/satellite-imagery (4943c528)"},
    "ships": {"name": "Ship Detection from Aerial Images (Kaggle andrewmvd), training groups: boat boxes as weak "
                      "water labels (moored and anchored boats are water in the class map), the rest unlabelled",
              "licence": "CC0 1.0 as reported (not verified); the imagery's own terms may also apply",
              "attribution": "andrewmvd; via github.com/urielFamien95/RESNET_101 (66af054f)"},
    "cars": {"name": "KIT AIS vehicle data (Munich crops), training crops: vehicle boxes as weak pavement labels "
                     "(parked and driving cars stand on pavement), the rest unlabelled",
             "licence": "CC BY 3.0", "attribution": "KIT IPF; via github.com/jekhor/aerial-cars-dataset (d2ed927f)"},
    "shipsself": {"name": "Ship Detection from Aerial Images (Kaggle andrewmvd), training groups: self-training "
                          "labels, water where the teacher segmenter (the model trained from) is >= 0.9 sure of "
                          "water or a boat box lies, land where it is >= 0.9 sure of land, the rest unlabelled",
                  "licence": "CC0 1.0 as reported (not verified); the imagery's own terms may also apply",
                  "attribution": "andrewmvd; via github.com/urielFamien95/RESNET_101 (66af054f)"},
    "streets": {"name": "KIT AIS vehicle data (Munich crops), training crops: every pixel land (two inland street "
                        "scenes with no water: tree canopy, shadows and dark cars as negatives for water), "
                        "vehicle boxes pavement",
                "licence": "CC BY 3.0", "attribution": "KIT IPF; via github.com/jekhor/aerial-cars-dataset (d2ed927f)"},
}
REAL_SETS = ("dubai", "ships", "cars", "streets", "shipsself")
# share of each batch from each real set when it is used (the rest: renders)
REAL_SHARES = {"dubai": 0.3, "ships": 0.1, "cars": 0.1, "streets": 0.1, "shipsself": 0.15}
# scale jitter of each pool (its GSD is known to this factor at best): renders, Dubai (nominal GSD), weak sets
SCALE_RANGE = {"synthetic": (0.75, 1.33), "dubai": (0.5, 1.6), "ships": (0.6, 1.5), "cars": (0.8, 1.25),
               "streets": (0.8, 1.25), "shipsself": (0.6, 1.5)}


def _paint_boxes(lab: np.ndarray, boxes: np.ndarray, code: int) -> np.ndarray:
    """``lab`` with every axis-aligned box (x0, y0, x1, y1 in its pixels, ends included) set to ``code``."""
    for x0, y0, x1, y1 in boxes:
        lab[int(round(y0)):int(round(y1)) + 1, int(round(x0)):int(round(x1)) + 1] = code
    return lab


def load_boxes_as_labels(which: str, work_gsd_m: float = WORK_GSD_M) -> list[tuple[np.ndarray, np.ndarray]]:
    """Weak labels from the training split of a real box set at ``work_gsd_m``: ``ships`` boat boxes are
    REAL_WATER, ``cars`` vehicle boxes SET_PAVED, every other pixel IGNORE; ``streets`` is ``cars`` with
    every other pixel SET_LAND (the Munich crops are inland streets: no pixel of them is water)."""
    from .. import realdata

    if which == "ships":
        items = [(it, realdata.ships_gsd(it.boxes)) for it in realdata.ships_items() if len(it.boxes)]
        code = REAL_WATER
    else:
        items = [(it, realdata.MUNICH_GSD_M) for it in realdata.munich_items()]
        code = SET_PAVED
    background = SET_LAND if which == "streets" else IGNORE
    out = []
    for it, gsd in items:
        if it.val:
            continue
        rgb, s = resample_to_gsd(realdata.read_rgb(it.path), gsd, work_gsd_m)
        lab = np.full(rgb.shape[:2], background, np.uint8)
        out.append((rgb, _paint_boxes(lab, it.boxes * s, code)))
    if not out:
        raise InputError(f"no {which} training images under {realdata.SHARED}; --real {which} needs ../shared/data")
    return out


SELF_SURE = 0.9  # the teacher's probability of water (or of land) that makes a self-training label


def load_ships_self(teacher: str | Path, work_gsd_m: float = WORK_GSD_M) -> list[tuple[np.ndarray, np.ndarray]]:
    """Self-training labels on the ``ships_aerial`` training images (harbours, marinas, anchorages: water of
    every colour): REAL_WATER where the ``teacher`` segmenter (an exported segmenter.onnx) is at least SELF_SURE
    sure of water or a labelled boat lies (moored boats are water in our class map), SET_LAND where it is that
    sure of land, IGNORE between. They keep the dark marina water the teacher knows while other losses (such
    as ``--false-water``) push the network away from dark land."""
    from .. import realdata
    from ..segmentation.learned import LearnedSegmenter

    teacher = Path(teacher)
    if not teacher.is_file():
        raise InputError(f"--real shipsself needs a teacher model: {teacher} does not exist (give --teacher or --init)")
    seg = LearnedSegmenter(weights=teacher)
    t_gsd = float(seg.meta["work_gsd_m"])
    out = []
    for it in realdata.ships_items():
        if it.val or not len(it.boxes):
            continue
        gsd = realdata.ships_gsd(it.boxes)
        rgb, s = resample_to_gsd(realdata.read_rgb(it.path), gsd, work_gsd_m)
        small, _ = resample_to_gsd(rgb, work_gsd_m, t_gsd)
        pw = cv2.resize(seg.proba_small(small)[..., WATER], rgb.shape[1::-1], interpolation=cv2.INTER_LINEAR)
        lab = np.full(rgb.shape[:2], IGNORE, np.uint8)
        lab[pw >= SELF_SURE] = REAL_WATER
        lab[pw <= 1.0 - SELF_SURE] = SET_LAND
        out.append((rgb, _paint_boxes(lab, it.boxes * s, REAL_WATER)))
    if not out:
        raise InputError(f"no ships_aerial training images under {realdata.SHARED}; --real shipsself needs ../shared/data")
    return out


def load_dubai(work_gsd_m: float = WORK_GSD_M, val: bool = False,
               hold: tuple[str, ...] = ()) -> list[tuple[np.ndarray, np.ndarray]]:
    """Dubai training (or validation) tiles at ``work_gsd_m`` (from the nominal 0.6 m/px) with label codes:
    water REAL_WATER, road and roofs SET_PAVED, vegetation SET_VEGETATION, unpaved land SET_BARE, unlabeled IGNORE.
    ``hold``: training tiles left out (an inner check on unseen tiles that keeps the validation tiles unseen)."""
    from .. import realdata

    lut = np.full(256, IGNORE, np.uint8)
    lut[0], lut[1], lut[2], lut[3] = REAL_WATER, SET_PAVED, SET_VEGETATION, SET_BARE
    lut[realdata.BUILDING] = SET_PAVED  # roofs count as paved for now (never water or vegetation)
    items = realdata.dubai_items()
    tiles = {n.split("/")[0] for n, _i, _m, v in items if not v}
    if set(hold) - tiles:
        raise InputError(f"--hold {','.join(sorted(set(hold) - tiles))}: not a Dubai training tile; "
                         f"the training tiles are {', '.join(sorted(tiles)) or 'none (../shared/data absent)'}")
    out = []
    for name, img, mask, is_val in items:
        if is_val != val or name.split("/")[0] in hold:
            continue
        rgb, _s = resample_to_gsd(realdata.read_rgb(img), DUBAI_NOMINAL_GSD_M, work_gsd_m)
        codes = lut[realdata.dubai_coarse(realdata.read_rgb(mask))]
        out.append((rgb, cv2.resize(codes, rgb.shape[1::-1], interpolation=cv2.INTER_NEAREST)))
    if not out:
        raise InputError(f"no Dubai tiles under {realdata.SHARED / 'real' / 'landcover_dubai'}; "
                         "--real dubai needs ../shared/data beside the project")
    return out


def load_levels(data_dir: Path, work_gsd_m: float = WORK_GSD_M) -> list[tuple[np.ndarray, np.ndarray]]:
    """All (rgb, ids) pairs of a ``seg_data`` folder, resampled to ``work_gsd_m``."""
    from ..fsio import read_png

    idx_path = data_dir / "index.json"
    if not idx_path.is_file():
        raise InputError(f"{idx_path} not found; write training data first with python -m coastforge.train.seg_data")
    index = json.loads(idx_path.read_text(encoding="utf-8"))
    s = float(index.get("gsd_m", 0.2)) / work_gsd_m
    out = []
    for it in index["items"]:
        rgb = read_png(data_dir / it["image"])[..., :3]
        ids = read_png(data_dir / it["classes"])
        h, w = ids.shape
        nw, nh = int(round(w * s)), int(round(h * s))
        out.append((cv2.resize(rgb, (nw, nh), interpolation=cv2.INTER_AREA),
                    cv2.resize(ids, (nw, nh), interpolation=cv2.INTER_NEAREST)))
    if not out:
        raise InputError(f"{idx_path} lists no levels")
    return out


def _recolour_classes(img: np.ndarray, ids: np.ndarray, rng: np.random.Generator, wide: bool = False) -> np.ndarray:
    """Per-class colour gains: the same class looks different from photo to photo. ``wide``: land classes
    too may turn dark, grey or of another hue (dark wet lawns, grey scrub, dusty trees), so a dark
    smooth patch alone never says water and the network has to look at texture and context."""
    waters = (WATER, REAL_WATER) if wide else (WATER,)
    for c in np.unique(ids):
        m = ids == c
        if c in waters:
            g = rng.uniform(0.55, 1.45, 3)  # blue, green, olive, brown, grey water
        elif wide and rng.random() < 0.5:
            g = rng.normal(1.0, 0.08, 3) * math.exp(rng.uniform(math.log(0.4), math.log(1.25)))
        else:
            g = rng.normal(1.0, 0.12, 3)
        v = img[m] * g.astype(np.float32) + rng.normal(0, 8)
        if wide and c not in waters and rng.random() < 0.3:  # desaturate this class only
            grey = v.mean(1, keepdims=True)
            v = grey + (v - grey) * rng.uniform(0.0, 0.6)
        img[m] = v
    return img


def _shadows(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Cast shadows: a few dark, slightly blue rotated rectangles (a building's or a tree row's) over
    whatever lies below; labels unchanged, since a shadowed lawn is still a lawn."""
    h, w = img.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    for _ in range(int(rng.integers(1, 5))):
        size = (float(rng.uniform(0.05, 0.4) * w), float(rng.uniform(0.05, 0.25) * h))
        box = cv2.boxPoints(((float(rng.uniform(0, w)), float(rng.uniform(0, h))), size, float(rng.uniform(0, 180))))
        cv2.fillConvexPoly(mask, box.astype(np.int32), 1)
    f = rng.uniform(0.3, 0.7)
    tint = np.array([f * 0.92, f * 0.97, f * 1.1], np.float32)  # skylight: shadows are bluer than sunlit ground
    sel = mask.astype(bool)
    img[sel] = img[sel] * tint
    return img


def augment(rgb: np.ndarray, ids: np.ndarray, rng: np.random.Generator, looks: str = "base") -> np.ndarray:
    """Appearance randomisation of one crop (uint8 → float32 0..255, labels unchanged). ``looks="wide"``
    adds dark/grey/other-hue land classes, cast shadows and the odd greyscale crop (see ``LOOKS``)."""
    wide = looks == "wide"
    img = rgb.astype(np.float32)
    if rng.random() < (0.8 if wide else 0.6):
        img = _recolour_classes(img, ids, rng, wide)
    if wide and rng.random() < 0.3:
        img = _shadows(img, rng)
    img = img * rng.uniform(0.75, 1.25, 3).astype(np.float32)  # white balance
    grey = img.mean(2, keepdims=True)
    sat = 0.0 if wide and rng.random() < 0.08 else rng.uniform(0.4, 1.5)  # wide: the odd greyscale crop
    img = grey + (img - grey) * sat  # saturation
    mean = img.mean()
    img = mean + (img - mean) * rng.uniform(0.6, 1.4) + rng.uniform(-35, 35)  # contrast, brightness
    img = 255.0 * (np.clip(img, 0, 255) / 255.0) ** rng.uniform(0.7, 1.5)  # gamma
    if rng.random() < 0.25:  # haze: a veil of one bluish-grey colour
        a = rng.uniform(0.1, 0.45)
        img = img * (1 - a) + a * rng.uniform(150, 235, 3).astype(np.float32)
    if rng.random() < 0.15:  # hue turn: water and vegetation of colours nobody rendered
        hsv = cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_RGB2HSV)
        hsv[..., 0] = (hsv[..., 0].astype(np.int16) + int(rng.integers(-15, 16))) % 180
        img = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB).astype(np.float32)
    if rng.random() < 0.3:
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.4, 1.3))
    if rng.random() < 0.5:
        img = img + rng.normal(0, rng.uniform(1, 7), img.shape).astype(np.float32)
    img = np.clip(img, 0, 255)
    if rng.random() < 0.3:
        _ok, buf = cv2.imencode(".jpg", img.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(35, 90))])
        img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED).astype(np.float32)
    return img


def class_centres(levels, rng: np.random.Generator, per_level: int = 300) -> list[np.ndarray]:
    """Per label code present: (level index, row, col) of up to ``per_level`` random pixels of each level."""
    out: list[list[np.ndarray]] = [[] for _ in range(N_CODES)]
    for i, (_, ids) in enumerate(levels):
        for c in range(N_CODES):
            rr, cc = np.nonzero(ids == c)
            if len(rr):
                k = rng.choice(len(rr), min(per_level, len(rr)), replace=False)
                out[c].append(np.stack([np.full(len(k), i), rr[k], cc[k]], 1))
    return [np.concatenate(o) for o in out if o]


def sample_batch(levels, batch: int, crop: int, rng: np.random.Generator,
                 centres: list[np.ndarray] | None = None,
                 pools: list[tuple[list, list | None, tuple[float, float], float]] | None = None,
                 looks: str = "base") -> tuple[np.ndarray, np.ndarray]:
    """A batch of augmented crops: (N, 3, crop, crop) float32 in [-0.5, 0.5], (N, crop, crop) int64 label
    codes. ``pools``: more sources (levels, centres, scale range, share of the batch); the renders
    ``levels`` take the rest."""
    xs = np.empty((batch, 3, crop, crop), np.float32)
    ys = np.empty((batch, crop, crop), np.int64)
    pools = list(pools or [])
    rest = max(0.0, 1.0 - sum(p[3] for p in pools))
    allp = [(levels, centres, SCALE_RANGE["synthetic"], rest)] + pools
    w = np.array([p[3] for p in allp], np.float64)
    for b in range(batch):
        lv, ce, (slo, shi), _ = allp[int(rng.choice(len(allp), p=w / w.sum()))]
        xs[b], ys[b] = _one_crop(lv, crop, rng, ce, slo, shi, looks)
    return xs, ys


def _one_crop(levels, crop: int, rng: np.random.Generator, centres, slo: float, shi: float,
              looks: str = "base"):
    """One augmented crop (3, crop, crop) float32 and its label codes (crop, crop)."""
    s = math.exp(rng.uniform(math.log(slo), math.log(shi)))  # GSD error / scale jitter
    side = int(round(crop / s))
    if centres is not None and rng.random() < 0.75:
        # class-balanced: centre the crop on a pixel of a uniformly drawn class (water fills most
        # levels; dirt, rocks and sand are rare)
        pts = centres[int(rng.integers(len(centres)))]
        li_, r, c = pts[int(rng.integers(len(pts)))]
        rgb, ids = levels[li_]
        r0, c0 = r - side // 2 + int(rng.integers(-side // 4, side // 4 + 1)), c - side // 2
    else:
        rgb, ids = levels[int(rng.integers(len(levels)))]
        r0 = c0 = None
    h, w = ids.shape
    if h < side or w < side:
        pad = max(side - h, side - w, 0)
        rgb = cv2.copyMakeBorder(rgb, 0, pad, 0, pad, cv2.BORDER_REFLECT)
        ids = cv2.copyMakeBorder(ids, 0, pad, 0, pad, cv2.BORDER_REFLECT)
        h, w = ids.shape
    if r0 is None:
        r0, c0 = int(rng.integers(h - side + 1)), int(rng.integers(w - side + 1))
    r0, c0 = int(np.clip(r0, 0, h - side)), int(np.clip(c0, 0, w - side))
    ci = rgb[r0:r0 + side, c0:c0 + side]
    li = ids[r0:r0 + side, c0:c0 + side]
    if side != crop:
        ci = cv2.resize(ci, (crop, crop), interpolation=cv2.INTER_AREA if side > crop else cv2.INTER_LINEAR)
        li = cv2.resize(li, (crop, crop), interpolation=cv2.INTER_NEAREST)
    k = int(rng.integers(4))
    ci, li = np.rot90(ci, k), np.rot90(li, k)
    if rng.random() < 0.5:
        ci, li = ci[:, ::-1], li[:, ::-1]
    ci, li = np.ascontiguousarray(ci), np.ascontiguousarray(li)
    img = augment(ci, li, rng, looks)
    return img.transpose(2, 0, 1) / 255.0 - 0.5, li


def class_weights(levels) -> np.ndarray:
    """Inverse square-root frequency weights (clipped), so rare classes (dirt, rocks, sand) count."""
    counts = np.zeros(N_CLASSES, np.float64)
    for _, ids in levels:
        counts += np.bincount(ids.ravel(), minlength=N_CLASSES)[:N_CLASSES]
    freq = counts / counts.sum()
    present = freq > 0
    w = np.ones(N_CLASSES)
    w[present] = np.sqrt(np.median(freq[present]) / freq[present])
    return np.clip(w, 0.3, 4.0).astype(np.float32)


# loss weight of each real label set (doubling vegetation's did not keep lawns from water: see the card)
SET_WEIGHTS = {SET_PAVED: 1.0, SET_VEGETATION: 1.0, SET_BARE: 1.0, REAL_WATER: 1.0, SET_LAND: 1.0}


def code_weights(levels) -> np.ndarray:
    """Loss weight per label code: our classes by ``class_weights`` of the renders, the sets of real
    labels by ``SET_WEIGHTS``."""
    sets = [SET_WEIGHTS[c] for c in range(N_CLASSES, N_CODES)]
    return np.r_[class_weights(levels), np.asarray(sets, np.float32)].astype(np.float32)


def set_loss(torch, logits, y, sets, weights, false_water: float = 1.0):
    """Negative log of the probability summed over each pixel's allowed classes (plain cross-entropy for
    an exact label), weighted by label code; IGNORE pixels are left out. ``false_water`` > 1 weighs the
    pixels the network currently calls water (argmax) where water is not allowed that much more: online
    hard negatives for the confusion that costs most on real photos (lawns, shadows, dark ground as water)."""
    valid = y != IGNORE
    yc = torch.where(valid, y, torch.zeros_like(y))
    allowed = sets[yc].permute(0, 3, 1, 2)  # (N, 8, H, W)
    nll = torch.logsumexp(logits, 1) - torch.logsumexp(logits.masked_fill(~allowed, -1e4), 1)
    w = weights[yc] * valid
    if false_water != 1.0:
        wrong = (logits.detach().argmax(1) == WATER) & ~allowed[:, WATER]
        w = w * torch.where(wrong, torch.full_like(w, false_water), torch.ones_like(w))
    return (nll * w).sum() / w.sum().clamp(min=1e-6)


def export_onnx(net, path: Path) -> Path:
    """Export in eval mode with dynamic H, W (multiples of 16); input RGB 0..1, output logits."""
    import torch

    from ..fsio import atomic_path

    class Wrap(torch.nn.Module):
        def __init__(self, m):
            super().__init__()
            self.m = m

        def forward(self, x):
            return self.m(x - 0.5)

    net.eval()
    with atomic_path(path) as tmp, torch.no_grad():
        torch.onnx.export(Wrap(net), (torch.zeros(1, 3, 128, 128),), str(tmp), dynamo=False, opset_version=17,
                          input_names=["image"], output_names=["logits"],
                          dynamic_axes={"image": {2: "h", 3: "w"}, "logits": {2: "h", 3: "w"}})
    net.train()
    return path


def _eval_marina(onnx_path: Path, meta: dict) -> str:
    """mIoU of the exported model on the real marina (evaluation only), or '' without the shared data."""
    from ..bench.segmentation import MARINA_TRUTH, SHARED, class_ious, rasterize_polygons

    img_path = SHARED / "aerial" / "marina_p0861" / "image.jpg"
    if not img_path.exists() or not MARINA_TRUTH.exists():
        return ""
    from ..config import SegmentConfig
    from ..io import read_image
    from ..segmentation.learned import LearnedSegmenter

    spec = json.loads(MARINA_TRUTH.read_text(encoding="utf-8"))
    image = read_image(img_path, gsd_m=float(spec["gsd_m"]))
    seg = LearnedSegmenter(SegmentConfig(learned_water="net", learned_flips=1), weights=onnx_path, meta=meta)  # raw net
    res = class_ious(seg.segment(image, 0).ids, rasterize_polygons(spec))
    return f"marina mIoU {res['miou']:.3f} water {res['iou']['water']:.3f} | " + " ".join(
        f"{n}={res['iou'][n]:.2f}" for n in res["present"])


def train(data_dir: str | Path, out_dir: str | Path, *, steps: int = 2400, batch: int = 12, crop: int = 128,
          lr: float = 3e-3, width: int = 16, seed: int = 1, eval_every: int = 400,
          real: tuple[str, ...] = (), init: str | Path | None = None, arch: str = "unet4",
          looks: str = "base", false_water: float = 1.0, work_gsd_m: float = WORK_GSD_M,
          hold: tuple[str, ...] = (), teacher: str | Path | None = None) -> Path:
    from ..fsio import atomic_write_text
    from ..registry import require

    torch = require("torch", "train", "training the learned segmenter")
    from .seg_model import build_segmenter

    torch.set_num_threads(1)
    torch.manual_seed(stage_seed(seed, "train", "seg", "torch"))
    rng = stage_rng(seed, "train", "seg", "batches")
    data_dir, out = Path(data_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    levels = load_levels(data_dir, work_gsd_m)
    seeds = [int(it["seed"]) for it in json.loads((data_dir / "index.json").read_text())["items"]]
    weights = code_weights(levels)
    centres = class_centres(levels, stage_rng(seed, "train", "seg", "centres"))
    shares = parse_real(tuple(real))
    pools, counts = [], {}
    teacher = teacher or init
    if "shipsself" in shares and teacher is None:
        raise InputError("--real shipsself learns from a teacher model's sure calls: give --teacher or --init")
    for name, share in shares.items():
        lv = (load_dubai(work_gsd_m, hold=hold) if name == "dubai"
              else load_ships_self(str(teacher), work_gsd_m) if name == "shipsself"
              else load_boxes_as_labels(name, work_gsd_m))
        counts[name] = len(lv)
        pools.append((lv, class_centres(lv, stage_rng(seed, "train", "seg", f"{name}-centres")), SCALE_RANGE[name],
                      share))
    print(f"{len(levels)} levels" + "".join(f" + {n} {k} images" for k, n in counts.items())
          + f" loaded in {time.time() - t0:.0f} s; class weights "
          + " ".join(f"{n}={w:.2f}" for n, w in zip(CLASS_NAMES, weights)), flush=True)
    net = build_segmenter(N_CLASSES, width, arch)
    if init is not None:
        from .common import init_from_onnx

        init = Path(init)
        if not init.is_file():
            raise InputError(f"--init {init} does not exist; give a segmenter.onnx written by this command")

        def make_input(n: int):
            x, _ = sample_batch(levels, n, crop, rng, centres, pools, looks)
            return torch.from_numpy(x)

        diff = init_from_onnx(torch, net, init, make_input, batches=12)
        print(f"started from {init} (largest output difference to the ONNX model {diff:.2e})", flush=True)
    n_params = sum(p.numel() for p in net.parameters())
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=lr, total_steps=steps, pct_start=0.1)
    sets_t = torch.from_numpy(label_sets())
    weights_t = torch.from_numpy(weights)
    onnx_path, meta_path = out / "segmenter.onnx", out / "segmenter.json"
    cmd = (f"python -m coastforge.train.seg_data --out DATA --seeds {min(seeds)}:{max(seeds) + 1}"
           f" && python -m coastforge.train.seg_train --data DATA --out OUT --steps {steps} "
           f"--batch {batch} --crop {crop} --width {width} --seed {seed} --lr {lr}"
           + (f" --arch {arch}" if arch != "unet4" else "") + (f" --looks {looks}" if looks != "base" else "")
           + (f" --false-water {false_water:g}" if false_water != 1.0 else "")
           + (f" --work-gsd {work_gsd_m:g}" if work_gsd_m != WORK_GSD_M else "")
           + (f" --hold {','.join(hold)}" if hold else ""))
    if real:
        cmd += " --real " + ",".join(f"{k}:{v:g}" for k, v in shares.items())
    if init is not None:
        cmd += f" --init {init.name}"
    if teacher is not None and "shipsself" in shares:
        cmd += f" --teacher {Path(teacher).name}"
    datasets = [DATASETS["synthetic"]] + [{**DATASETS[k], "images": n, "batch_share": shares[k]}
                                          for k, n in counts.items()]
    # real photos at ~0.4-1.2 m/px (Dubai with its scale jitter, the ship photos) widen the range of GSDs the
    # network may be trusted with; renders alone cover ~0.04-0.6 m/px
    gsd_range = [0.04, 1.2] if real else [0.04, 0.6]
    meta = {"format": FORMAT, "classes": list(CLASS_NAMES), "work_gsd_m": work_gsd_m,
            "multiple": ARCH_MULTIPLE[arch], "overlap_px": ARCH_OVERLAP_PX[arch], "arch": arch,
            "gsd_range_m": gsd_range,
            "input": "RGB 0..1, NCHW", "output": "logits (1, 8, H, W)",
            "datasets": datasets,
            "training": {"seed": seed, "steps": steps, "batch": batch, "crop_px": crop, "lr": lr, "width": width,
                         "threads": 1, "levels": len(levels), "params": n_params, "looks": looks,
                         "false_water": false_water, "held_out_tiles": list(hold),
                         "data_seeds": [min(seeds), max(seeds)], "command": cmd,
                         "init": str(init.name) if init is not None else None}}
    t_train = time.time()
    run = 0.0
    for step in range(1, steps + 1):
        x, y = sample_batch(levels, batch, crop, rng, centres, pools, looks)
        logits = net(torch.from_numpy(x))
        loss = set_loss(torch, logits, torch.from_numpy(y), sets_t, weights_t, false_water)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        run = 0.98 * run + 0.02 * loss.item() if step > 1 else loss.item()
        if step % 50 == 0:
            print(f"step {step}/{steps} loss {run:.3f} {time.time() - t_train:.0f} s", flush=True)
        if step % eval_every == 0 or step == steps:
            export_onnx(net, onnx_path)
            meta["training"]["minutes"] = round((time.time() - t_train) / 60, 1)
            atomic_write_text(meta_path, json.dumps(meta, indent=1) + "\n")
            print(f"checkpoint {step}: {_eval_marina(onnx_path, meta)}", flush=True)
    print(f"done: {onnx_path} ({onnx_path.stat().st_size / 1e6:.2f} MB, {n_params} parameters), "
          f"{(time.time() - t_train) / 60:.1f} min", flush=True)
    return onnx_path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="folder written by python -m coastforge.train.seg_data")
    ap.add_argument("--out", required=True)
    ap.add_argument("--steps", type=int, default=2400)
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--crop", type=int, default=128)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--width", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--eval-every", type=int, default=400)
    ap.add_argument("--real", default="",
                    help=f"comma list of real sets to mix in (training splits, ../shared/data): {', '.join(REAL_SETS)}; "
                         "NAME:SHARE sets the share of each batch (default " +
                         ", ".join(f"{k} {v}" for k, v in REAL_SHARES.items()) + ")")
    ap.add_argument("--init", default=None, help="start from this exported segmenter.onnx")
    ap.add_argument("--arch", default="unet4", choices=sorted(ARCH_MULTIPLE),
                    help="unet4: 4 stages (1/16); unet5: a 1/32 stage too (wider context)")
    ap.add_argument("--looks", default="base", choices=LOOKS,
                    help="appearance randomisation: base, or wide (land classes dark/grey/other hues, cast shadows)")
    ap.add_argument("--false-water", type=float, default=1.0,
                    help="loss weight of the pixels currently called water where water is not allowed (1: plain)")
    ap.add_argument("--work-gsd", type=float, default=WORK_GSD_M,
                    help=f"the network's working resolution in m/px (default {WORK_GSD_M}; coarser: wider context)")
    ap.add_argument("--teacher", default=None,
                    help="the segmenter.onnx whose sure calls label --real shipsself (default: --init)")
    ap.add_argument("--hold", default="",
                    help="comma list of Dubai training tiles to leave out (e.g. tile_4): an inner check on tiles "
                         "the model never saw, so that the validation tiles stay unseen")
    a = ap.parse_args(argv)
    if not 0.05 <= a.work_gsd <= 5.0:
        raise InputError(f"--work-gsd {a.work_gsd:g}: give the working resolution in metres per pixel (0.05-5)")
    if a.crop % ARCH_MULTIPLE[a.arch]:
        raise InputError(f"--crop {a.crop} must be a multiple of {ARCH_MULTIPLE[a.arch]} for --arch {a.arch}")
    train(a.data, a.out, steps=a.steps, batch=a.batch, crop=a.crop, lr=a.lr, width=a.width, seed=a.seed,
          eval_every=a.eval_every, real=tuple(r for r in a.real.split(",") if r), init=a.init, arch=a.arch, looks=a.looks,
          false_water=a.false_water, work_gsd_m=a.work_gsd, hold=tuple(t for t in a.hold.split(",") if t),
          teacher=a.teacher)


def parse_real(items: tuple[str, ...]) -> dict[str, float]:
    """("dubai:0.5", "ships") -> {"dubai": 0.5, "ships": REAL_SHARES["ships"]}."""
    out = {}
    for it in items:
        name, _, share = it.partition(":")
        if name not in REAL_SETS:
            raise InputError(f"--real {name!r}: the real sets are {', '.join(REAL_SETS)}")
        try:
            out[name] = float(share) if share else REAL_SHARES[name]
        except ValueError:
            raise InputError(f"--real {it!r}: the share after ':' must be a number") from None
    if sum(out.values()) > 1.0:
        raise InputError(f"--real shares add up to {sum(out.values()):g}; they must leave room for the renders (<= 1)")
    return out


if __name__ == "__main__":
    main()
