"""Detection benchmark: ``python -m coastforge.bench.detection [--data DIR] [--synth] [--backend NAME]``.

Prints, per image: recall, detection precision (Hungarian one-to-one on centre distance, a match when
the centres are within half the labelled length), orientation RMSE (mod 180°), heading accuracy when
the truth has a heading, RMS relative length and width errors (Lrel, Wrel) and the centre RMSE in
metres of the matched boxes, pier structures found, and the time. ``--set detect.refine=false`` gives
the backend's boxes before refinement (``coastforge.detection.refine``). Real data: the DOTA marina crop
(ships + harbor structures), the DOTA vehicles crop and the sen2ships ports from ``../shared/data``;
synthetic: ``coastforge.synth`` levels at both resolutions. An image the backend cannot run on (the learned
detector on the 7-9 m/px sen2ships ports) gets a row "n/a (reason)" and the others are still measured.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..config import DetectConfig
from ..frames import wrap_deg, wrap_half_deg, yaw_from_direction_px
from ..types import Detection, GeoImage, Grid

DOTA_CLASSES = {1: "ship", 7: "harbor", 9: "large vehicle", 10: "small vehicle"}


@dataclass
class Truth:
    category: str  # boat | vehicle | pier
    cx: float
    cy: float
    length: float
    width: float
    yaw: float  # axis or heading (degrees)
    heading_known: bool = False
    corners: np.ndarray | None = None


@dataclass
class Score:
    name: str
    n_truth: int = 0
    n_pred: int = 0
    matched: int = 0
    orient_err: list = field(default_factory=list)
    heading_ok: int = 0
    heading_n: int = 0
    size_err: list = field(default_factory=list)  # (length, width) relative errors of matched boxes
    centre_err: list = field(default_factory=list)  # centre distance of matched boxes (pixels)
    gsd_m: float = float("nan")
    extra: dict = field(default_factory=dict)
    na: str | None = None  # why this row could not be measured (e.g. the backend refuses the image's GSD)

    @property
    def recall(self):
        return self.matched / self.n_truth if self.n_truth else float("nan")

    @property
    def precision(self):
        return self.matched / self.n_pred if self.n_pred else float("nan")

    @property
    def orient_rmse(self):
        return float(np.sqrt(np.mean(np.square(self.orient_err)))) if self.orient_err else float("nan")

    @property
    def size_rmse(self):
        """RMS relative error of (length, width) over matched boxes."""
        if not self.size_err:
            return float("nan"), float("nan")
        a = np.asarray(self.size_err)
        return tuple(float(v) for v in np.sqrt(np.mean(np.square(a), 0)))

    @property
    def centre_rmse_m(self):
        return float(np.sqrt(np.mean(np.square(self.centre_err))) * self.gsd_m) if self.centre_err else float("nan")

    @property
    def heading_acc(self):
        return self.heading_ok / self.heading_n if self.heading_n else float("nan")


def truth_from_corners(cat: str, corners: np.ndarray) -> Truth:
    """A labelled quadrilateral → centre, long side as length, axis yaw."""
    c = np.asarray(corners, float).reshape(4, 2)
    e1, e2 = c[1] - c[0], c[2] - c[1]
    l1, l2 = np.hypot(*e1), np.hypot(*e2)
    e = e1 if l1 >= l2 else e2
    yaw = float(wrap_half_deg(yaw_from_direction_px(e[0], e[1])))
    return Truth(cat, float(c[:, 0].mean()), float(c[:, 1].mean()), float(max(l1, l2)), float(min(l1, l2)), yaw,
                 corners=c)


def read_dota_yolo(path: Path, width: int, height: int) -> list[tuple[str, Truth]]:
    out = []
    for line in path.read_text().splitlines():
        v = line.split()
        if len(v) != 9:
            continue
        cid = int(v[0])
        c = np.array(v[1:], float).reshape(4, 2) * [width, height]
        out.append((DOTA_CLASSES.get(cid, str(cid)), truth_from_corners(DOTA_CLASSES.get(cid, str(cid)), c)))
    return out


def read_dota_px(path: Path) -> list[Truth]:
    out = []
    for line in path.read_text().splitlines():
        v = line.split()
        if len(v) < 9 or line.startswith(("imagesource", "gsd")):
            continue
        out.append(truth_from_corners("boat", np.array(v[:8], float)))
    return out


def match(truth: list[Truth], preds: list[Detection], score: Score) -> list[tuple[int, int]]:
    """Hungarian one-to-one on centre distance, gate = half the truth length."""
    from scipy.optimize import linear_sum_assignment

    score.n_truth += len(truth)
    score.n_pred += len(preds)
    if not truth or not preds:
        return []
    t = np.array([[g.cx, g.cy] for g in truth])
    p = np.array([[d.cx_px, d.cy_px] for d in preds])
    dist = np.hypot(t[:, None, 0] - p[None, :, 0], t[:, None, 1] - p[None, :, 1])
    gate = np.array([g.length / 2.0 for g in truth])[:, None]
    cost = np.where(dist <= gate, dist, 1e6)
    ri, ci = linear_sum_assignment(cost)
    pairs = [(int(i), int(j)) for i, j in zip(ri, ci) if cost[i, j] < 1e6]
    score.matched += len(pairs)
    for i, j in pairs:
        g, d = truth[i], preds[j]
        score.orient_err.append(float(wrap_half_deg(d.yaw_deg - g.yaw)))
        score.centre_err.append(float(dist[i, j]))
        if g.width > 0:
            score.size_err.append((d.length_px / g.length - 1.0, d.width_px / g.width - 1.0))
        if g.heading_known:
            score.heading_n += 1
            score.heading_ok += int(abs(wrap_deg(d.yaw_deg - g.yaw)) < 90.0)
    return pairs


def piers_found(structures: list[Truth], preds: list[Detection], min_cover: float = 0.3) -> int:
    """A labelled pier structure counts as found when walkway/finger boxes centred inside it cover at
    least ``min_cover`` of its long side."""
    from shapely.geometry import Point, Polygon

    found = 0
    for s in structures:
        poly = Polygon(s.corners)
        inside = [d for d in preds if d.category in ("pier_walkway", "pier_finger")
                  and poly.contains(Point(d.cx_px, d.cy_px))]
        walk = sum(d.length_px for d in inside if d.category == "pier_walkway")
        if walk >= min_cover * s.length or (inside and sum(d.length_px for d in inside) >= s.length):
            found += 1
    return found


def timed_detect(image: GeoImage, backend: str, config: DetectConfig,
                 **opts) -> tuple[list[Detection], float]:
    """Detections and the detector's time. ``segment_config`` in ``opts``: segment first (not timed) and
    detect with the class map, as generate does."""
    from ..detection import detect

    seg = opts.pop("segment_config", None)
    class_map = None
    if seg is not None:
        from ..segmentation import segment

        class_map = segment(image, seg, seed=0)
    t0 = time.perf_counter()
    dets = detect(image, config, class_map=class_map, backend=backend, **opts)
    return dets, time.perf_counter() - t0


def _try_run(name: str, image: GeoImage, backend: str, config: DetectConfig,
             **opts) -> tuple[list[Detection], float] | Score:
    """``timed_detect``, or a "n/a" row naming why the backend cannot run on this image (e.g. the learned
    detector on 8 m/px satellite images): the other images are still measured."""
    from ..errors import InputError

    try:
        return timed_detect(image, backend, config, **opts)
    except InputError as exc:
        return Score(name, gsd_m=image.grid.gsd_m, na=str(exc).split(";")[0])


def bench_real(data: Path, backend: str, config: DetectConfig, overlay_dir: Path | None, **opts) -> list[Score]:
    """Scores on the real images found under ``data``; an image the backend cannot run on (the learned
    detector on 8 m/px satellite ports) gives a "n/a (reason)" row and the others are still measured."""
    from ..detection import write_overlay
    from ..io import read_image

    def marina(img: GeoImage, dets: list[Detection], dt: float, folder: Path) -> Score:
        lab = read_dota_yolo(folder / "labels_yolo_obb.txt", img.grid.width_px, img.grid.height_px)
        ships = [t for c, t in lab if c == "ship"]
        harbors = [t for c, t in lab if c == "harbor"]
        s = Score("marina_p0861 boats", gsd_m=img.grid.gsd_m)
        boats = [d for d in dets if d.category == "boat"]
        pairs = match(ships, boats, s)
        # the right edge (x > 96 %) holds a column of boats that DOTA labelled only partly
        matched = {j for _i, j in pairs}
        strip = sum(1 for j, d in enumerate(boats) if j not in matched and d.cx_px > 0.96 * img.grid.width_px)
        s.extra = {"unmatched_in_partly_labelled_right_strip": strip,
                   "precision_outside_strip": round(s.matched / max(1, s.n_pred - strip), 3),
                   "piers_found": f"{piers_found(harbors, dets)}/{len(harbors)}",
                   "pier_boxes": sum(d.category.startswith("pier") for d in dets),
                   "cars_found(unlabelled)": sum(d.category == "vehicle" for d in dets),
                   "seconds": round(dt, 2)}
        return s

    def vehicles(img: GeoImage, dets: list[Detection], dt: float, folder: Path) -> Score:
        lab = read_dota_yolo(folder / "labels_yolo_obb.txt", img.grid.width_px, img.grid.height_px)
        cars = [t for c, t in lab if c in ("small vehicle", "large vehicle")]
        s = Score("vehicles_p1053 vehicles", gsd_m=img.grid.gsd_m)
        match(cars, [d for d in dets if d.category == "vehicle"], s)
        s.extra = {"boats_reported": sum(d.category == "boat" for d in dets), "seconds": round(dt, 2)}
        return s

    def ships(truth_path: Path, name: str):
        def score(img: GeoImage, dets: list[Detection], dt: float, _folder: Path) -> Score:
            s = Score(name, gsd_m=img.grid.gsd_m)
            match(read_dota_px(truth_path), [d for d in dets if d.category == "boat"], s)
            s.extra = {"seconds": round(dt, 2)}
            return s
        return score

    # (name, image path, GSD, scoring, overlay file)
    jobs = []
    folder = data / "aerial" / "marina_p0861"
    if folder.is_dir():
        jobs.append(("marina_p0861 boats", folder / "image.jpg", 0.2, marina, "marina_p0861.png"))
    folder = data / "aerial" / "vehicles_p1053"
    if folder.is_dir():
        jobs.append(("vehicles_p1053 vehicles", folder / "image.jpg", 0.125, vehicles, "vehicles_p1053.png"))
    s2 = data / "sen2ships"
    man = s2 / "MANIFEST.json"
    if man.is_file():
        for entry in json.loads(man.read_text()):
            name = f"sen2ships {entry['city']}"
            jobs.append((name, s2 / entry["image"], float(entry["ground_gsd_m"]),
                         ships(s2 / entry["obb_dota"], name), f"sen2ships_{entry['city']}.png"))
    scores = []
    for name, path, gsd, score, overlay in jobs:
        img = read_image(path, gsd_m=gsd)
        got = _try_run(name, img, backend, config, **opts)
        if isinstance(got, Score):
            scores.append(got)
            continue
        dets, dt = got
        scores.append(score(img, dets, dt, path.parent))
        if overlay_dir:
            write_overlay(overlay_dir / overlay, img.rgb, dets)
    return scores


def synth_truth(scene_path: Path, image_path: Path, gsd: float) -> tuple[GeoImage, list[Truth], list[Truth]]:
    """Objects of a synthetic truth scene → pixel truths (boats+vehicles with heading, piers)."""
    from ..fsio import read_png

    rgb = read_png(image_path)[..., :3]
    grid = Grid(rgb.shape[1], rgb.shape[0], gsd)
    doc = json.loads(scene_path.read_text())
    objs, piers = [], []
    for o in doc["objects"]:
        col, row = grid.to_pixel(o["x_m"], o["y_m"])
        t = Truth(o["category"], float(col), float(row), o["length_m"] / gsd, o.get("width_m", 0) / gsd,
                  float(o["yaw_deg"]), heading_known=o["category"] in ("boat", "vehicle"))
        (piers if o["category"] == "pier" else objs).append(t)
    return GeoImage(rgb=np.ascontiguousarray(rgb), grid=grid, path=str(image_path)), objs, piers


def bench_synth(presets: list[str], seeds: list[int], backend: str, config: DetectConfig, work: Path,
                **opts) -> list[Score]:
    from ..synth import synth_to_dir

    by_gsd: dict = {}
    for preset in presets:
        for seed in seeds:
            out = work / f"{preset}_{seed}"
            if not (out / "inputs.json").is_file():
                synth_to_dir(preset, seed, out, overwrite=True)
            inputs = json.loads((out / "inputs.json").read_text())
            truth_path = out / "truth.json"
            for im in inputs.get("images", []):
                gsd = float(im["gsd_m"])
                img, objs, _piers = synth_truth(truth_path, out / im["path"], gsd)
                dets, dt = timed_detect(img, backend, config, **opts)
                s = by_gsd.setdefault(gsd, Score(f"synthetic {gsd:g} m/px (all)", gsd_m=gsd))
                for cat in ("boat", "vehicle", "buoy"):
                    t_c, d_c = [t for t in objs if t.category == cat], [d for d in dets if d.category == cat]
                    match(t_c, d_c, s)
                    match(t_c, d_c, by_gsd.setdefault((gsd, cat), Score(f"synthetic {gsd:g} m/px {cat}", gsd_m=gsd)))
                s.extra["seconds"] = round(s.extra.get("seconds", 0.0) + dt, 2)
    return list(by_gsd.values())


def bench_timing(backend: str, config: DetectConfig, size: int = 2048, repeats: int = 2) -> float:
    """Seconds for one ``size``² image: a real marina crop tiled up, else a synthetic pattern."""
    from ..rng import stage_rng

    rng = stage_rng(0, "bench", "detect-timing")
    rgb = np.zeros((size, size, 3), np.uint8)
    rgb[:] = (45, 62, 44)
    rgb = np.clip(rgb + rng.normal(0, 2, rgb.shape), 0, 255).astype(np.uint8)
    import cv2

    for _ in range(300):  # boats as bright ellipses on water
        c = tuple(int(v) for v in rng.integers(50, size - 50, 2))
        cv2.ellipse(rgb, c, (int(rng.integers(20, 50)), int(rng.integers(8, 15))), float(rng.uniform(0, 180)),
                    0, 360, (230, 230, 225), -1)
    img = GeoImage(rgb=rgb, grid=Grid(size, size, 0.2))
    best = 1e9
    for _ in range(repeats):
        _, dt = timed_detect(img, backend, config)
        best = min(best, dt)
    return best


def _fmt(v) -> str:
    return "   -  " if v != v else f"{v:6.3f}"


def print_scores(scores: list[Score]) -> None:
    print(f"{'set':34s} {'truth':>5s} {'pred':>5s} {'recall':>6s} {'prec':>6s} {'orRMSE':>6s} {'head':>6s} "
          f"{'Lrel':>6s} {'Wrel':>6s} {'ctr_m':>6s}  extra")
    for s in scores:
        if s.na is not None:
            print(f"{s.name:34s} n/a ({s.na})")
            continue
        lr, wr = s.size_rmse
        print(f"{s.name:34s} {s.n_truth:5d} {s.n_pred:5d} {_fmt(s.recall)} {_fmt(s.precision)} "
              f"{_fmt(s.orient_rmse)} {_fmt(s.heading_acc)} {_fmt(lr)} {_fmt(wr)} {_fmt(s.centre_rmse_m)}  {s.extra}")


def main(argv: list[str] | None = None) -> None:
    from ..config import load_config

    root = Path(__file__).resolve().parents[3]
    ap = argparse.ArgumentParser(prog="python -m coastforge.bench.detection", description=__doc__)
    ap.add_argument("--data", type=Path, default=root.parent / "shared" / "data")
    ap.add_argument("--backend", default=None,
                    help="detector backend (default: the preset's, as generate uses; issue figures for the "
                         "2048² speed target use --backend classical)")
    ap.add_argument("--weights", default=None)
    ap.add_argument("--overlays", type=Path, default=None, help="write overlay PNGs into this folder")
    ap.add_argument("--synth-presets",
                    default="simple_pier_a,simple_pier_b,pier_parking,marina,lake_harbor,beach,rocky_shore")
    ap.add_argument("--synth-seeds", default="0")
    ap.add_argument("--synth-dir", type=Path, default=Path("/tmp/coastforge-bench-detect"))
    ap.add_argument("--no-synth", action="store_true")
    ap.add_argument("--no-timing", action="store_true")
    ap.add_argument("--set", dest="sets", action="append", default=[])
    ap.add_argument("--segment", action="store_true",
                    help="segment each image first (untimed) and detect with its class map, as generate does")
    a = ap.parse_args(argv)
    full = load_config(sets=a.sets)
    cfg = full.detect
    a.backend = a.backend or cfg.backend
    print(f"backend: {a.backend}" + (f", with the {full.segment.backend} class map" if a.segment else ""))
    opts: dict = {"weights": a.weights} if a.weights else {}
    if a.segment:
        opts["segment_config"] = full.segment
    if a.overlays:
        a.overlays.mkdir(parents=True, exist_ok=True)
    scores: list[Score] = []
    if a.data.is_dir():
        scores += bench_real(a.data, a.backend, cfg, a.overlays, **opts)
    else:
        print(f"real data folder {a.data} not found: skipping real images")
    if not a.no_synth:
        try:
            scores += bench_synth(a.synth_presets.split(","), [int(s) for s in a.synth_seeds.split(",")],
                                  a.backend, cfg, a.synth_dir, **opts)
        except (ImportError, AttributeError) as exc:
            print(f"synthetic benchmark unavailable here: {exc}")
    print_scores(scores)
    if not a.no_timing:
        print(f"timing 2048x2048 ({a.backend}, best of 2): {bench_timing(a.backend, cfg):.2f} s")


if __name__ == "__main__":
    main()
