"""Training samples for the learned detector: synthetic levels rendered at a random GSD, resampled to
the detector's working GSD, with their oriented boxes.

``python -m coastforge.train.detector_data --out DIR --seeds 100:400`` writes one PNG per level and an
``index.json`` listing, per image, the boxes ``[class_id, cx_px, cy_px, length_px, width_px, yaw_deg]``
(yaw = direction of the front, scene convention). Rendering goes through ``coastforge.synth.render``
(lighting, tints, clutter, blur, noise, JPEG), so the training images look like the benchmark's; the
benchmark's own seed (0) is refused so that validation never leaks into training. ``--mix training``
draws the rare asset types more often (``synth.layout.TRAINING_MIX``: buses and box trucks, hatchbacks,
dinghies, kayaks, rowboats, centre consoles); the default draws them as the benchmark's levels do.
``--library LIB`` renders the levels with another asset library's boats and cars (e.g. a training split of
the CC0 models in ../shared/data/models), ``--looks varied`` repaints about half the boats (dark hulls
among them), ``--looks covers`` puts about half of them under canvas covers, ``--looks wakes`` repaints as
``varied`` and draws a foam wake behind about half the boats with open water astern (boats under way, as
real photos of open water show them): looks the kit does not have.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .common import RESERVED_SEEDS, data_main, parse_seeds, render_levels  # noqa: F401 (re-exported)

WORK_GSD_M = 0.2  # the detector's working resolution (metres per pixel)
CLASSES: tuple[str, ...] = ("boat", "vehicle", "buoy")


def resample_to_gsd(rgb: np.ndarray, gsd_m: float, work_gsd_m: float = WORK_GSD_M) -> tuple[np.ndarray, float]:
    """Resample an image to ``work_gsd_m``; returns (image, scale = new px per old px)."""
    s = gsd_m / work_gsd_m
    if abs(s - 1.0) < 1e-3:
        return rgb, 1.0
    h, w = rgb.shape[:2]
    nw, nh = max(1, int(round(w * s))), max(1, int(round(h * s)))
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    return cv2.resize(rgb, (nw, nh), interpolation=interp), nw / w


# hull colours of real boats beyond the kit's white gel coat (sRGB): navy, black, dark green, varnished
# wood, grey, red, royal blue, cream; a detector trained on white hulls misses the dark ones on real photos
HULL_PAINTS = ((24, 34, 70), (20, 20, 24), (28, 58, 40), (110, 70, 38), (90, 92, 96), (150, 30, 30),
               (40, 70, 150), (220, 210, 180))


def _pick(rng: np.random.Generator, colours) -> list[int]:
    return list(colours[int(rng.integers(len(colours)))])


def _restyle_boats(level, rng: np.random.Generator, p_boat: float, key: str, attrs_of):
    """The level with about ``p_boat`` of its boats not yet holding ``key`` given ``attrs_of(rng, attrs)``."""
    import dataclasses

    objs = []
    for o in level.scene.objects:
        if o.category == "boat" and key not in o.attrs and rng.random() < p_boat:
            o = dataclasses.replace(o, attrs={**o.attrs, **attrs_of(rng, o.attrs)})
        objs.append(o)
    return dataclasses.replace(level, scene=dataclasses.replace(level.scene, objects=tuple(objs)))


def vary_looks(level, rng: np.random.Generator, p_boat: float = 0.5):
    """The level with the body colour of about ``p_boat`` of its boats drawn from ``HULL_PAINTS`` (half of
    those dark), for training only: the benchmark's levels keep the kit's looks."""
    return _restyle_boats(level, rng, p_boat, "paint", lambda r, _a: {"paint": _pick(r, HULL_PAINTS)})


# canvas covers of laid-up boats (sRGB): navy, royal blue, tan, grey, forest green, burgundy, teal, off-white
COVER_COLOURS = ((30, 40, 80), (40, 75, 140), (170, 150, 115), (110, 112, 115), (40, 70, 50), (100, 30, 40),
                 (30, 100, 110), (205, 200, 185))


def vary_covers(level, rng: np.random.Generator, p_boat: float = 0.5):
    """The level with about ``p_boat`` of its boats under a canvas cover (``assets.library.cover``: deck and
    cabin one colour from ``COVER_COLOURS``), a third of those also with a repainted hull; for training
    only."""
    def attrs_of(r: np.random.Generator, attrs: dict) -> dict:
        new = {"cover": _pick(r, COVER_COLOURS)}
        if "paint" not in attrs and r.random() < 1 / 3:
            new["paint"] = _pick(r, HULL_PAINTS)
        return new

    return _restyle_boats(level, rng, p_boat, "cover", attrs_of)


WAKE_P = 0.5  # share of the boats with open water astern that get a wake (``add_wakes``)


def add_wakes(rgb: np.ndarray, boxes: list[list[float]], water: np.ndarray, rng: np.random.Generator,
              p_boat: float = WAKE_P) -> np.ndarray:
    """``rgb`` with a foam wake behind about ``p_boat`` of the boats (``boxes`` in its pixels, class 0) whose
    wake would lie on ``water`` (bool, same shape) where it is inside the image: a turbulent white band from
    the stern, 3-20 hull lengths long, widening and fading with distance, and two faint arms diverging from
    it. Real photos of open water show boats under way at the head of such trails; the kit's renders have
    none. For training only."""
    h, w = water.shape
    out = rgb.astype(np.float32)
    for c, cx, cy, length, width, yaw in boxes:
        if int(c) != 0 or rng.random() >= p_boat:
            continue
        t = np.deg2rad(yaw)
        f = np.array([np.cos(t), -np.sin(t)])  # the front, in (col, row)
        n_len = float(rng.uniform(3.0, 20.0))
        trail = n_len * length
        stern = np.array([cx, cy]) - f * length / 2.0
        end = stern - f * trail  # may lie beyond the image: real wakes leave the picture too
        span = max(width, 2.0) * (1.0 + 0.6 * n_len)
        x0, x1 = int(max(0, min(stern[0], end[0]) - span)), int(min(w, max(stern[0], end[0]) + span + 1))
        y0, y1 = int(max(0, min(stern[1], end[1]) - span)), int(min(h, max(stern[1], end[1]) + span + 1))
        yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float32)
        dx, dy = xx - stern[0], yy - stern[1]
        back = -(dx * f[0] + dy * f[1])  # distance astern
        side = np.abs(-dx * f[1] + dy * f[0])
        on = (back >= 0) & (back <= trail)
        wet = water[y0:y1, x0:x1]
        if not on.any() or wet[on].mean() < 0.95:
            continue  # the trail would cross land, a pier or another boat: this boat is moored
        u = np.clip(back / trail, 0.0, 1.0)
        half = 0.5 * width * (0.8 + 2.5 * u)  # the turbulent band widens astern
        band = np.exp(-(side / np.maximum(half, 0.5)) ** 2) * (1.0 - u) ** 1.5
        arm_off = back * np.tan(np.deg2rad(rng.uniform(8.0, 19.0)))
        arms = np.exp(-((side - arm_off) / max(1.0, 0.4 * width)) ** 2) * (1.0 - u) ** 2 * 0.45
        grain = rng.uniform(0.55, 1.0, band.shape).astype(np.float32)
        a = np.clip((np.maximum(band, arms) * grain) * float(rng.uniform(0.5, 0.9)), 0.0, 1.0)
        a *= on & wet
        foam = np.array([rng.uniform(200, 240)] * 3, np.float32) + rng.uniform(-8, 8, 3).astype(np.float32)
        blk = out[y0:y1, x0:x1]
        out[y0:y1, x0:x1] = blk * (1.0 - a[..., None]) + foam * a[..., None]
    return np.clip(out, 0, 255).astype(np.uint8)


def level_sample(preset: str, seed: int, gsd_m: float, size_m: float | None,
                 work_gsd_m: float = WORK_GSD_M, mix: str = "benchmark", library: str | Path | None = None,
                 looks: str = "kit") -> tuple[np.ndarray, list[list[float]]]:
    """One synthetic level rendered at ``gsd_m`` and resampled to ``work_gsd_m``: (rgb, boxes).

    ``mix="training"`` draws the rare asset types more often (``synth.layout.TRAINING_MIX``), ``mix="rafted"``
    also ties boats alongside walkways end to end and rafts some two deep (``RAFTED_MIX``); ``library``
    fills the layout's roles with that library's assets (other looks than the kit's); ``looks="varied"``
    repaints about half the boats (``vary_looks``), ``looks="covers"`` covers about half (``vary_covers``),
    ``looks="wakes"`` repaints as ``varied`` and draws wakes (``add_wakes``)."""
    from .. import frames
    from ..rng import stage_rng
    from ..synth import synthesize_level
    from ..synth.layout import MIXES
    from ..synth.render import mesh_source, render_level

    level = synthesize_level(preset, seed, size_m=size_m, library=library,
                             mix=MIXES[mix])
    if looks in ("varied", "wakes"):
        level = vary_looks(level, stage_rng(seed, "train", "detector_data", "looks"))
    elif looks == "covers":
        level = vary_covers(level, stage_rng(seed, "train", "detector_data", "covers"))
    rgb = render_level(level, mesh_source(library), gsd_m, seed)
    sx, _sy = level.scene.extent_m
    work, _ = resample_to_gsd(rgb, sx / rgb.shape[1], work_gsd_m)
    h, w = work.shape[:2]
    g = sx / w
    boxes = []
    for o in level.scene.objects:
        if o.category not in CLASSES:
            continue
        col, row = frames.scene_to_pixel(o.x_m, o.y_m, w, h, g)
        length, width = o.length_m / g, o.width_m / g
        yaw = float(o.yaw_deg)
        if width > length:  # the long side is the length; the front then is ambiguous, keep the axis
            length, width, yaw = width, length, yaw + 90.0
        boxes.append([CLASSES.index(o.category), float(col), float(row), float(length), float(width),
                      float(frames.wrap_deg(yaw))])
    if looks == "wakes" and level.scene.classes is not None:
        from ..classes import WATER

        water = cv2.resize((level.scene.classes == WATER).astype(np.uint8), (w, h),
                           interpolation=cv2.INTER_NEAREST)
        for o in level.scene.objects:  # piers, moored boats and buoys are no open water either
            pts = [frames.scene_to_pixel(x, y, w, h, g) for x, y in o.footprint_m(grow_m=1.0)]
            cv2.fillPoly(water, [np.round(np.array(pts, np.float64)).astype(np.int32)], 0)
        water = water > 0
        work = add_wakes(work, boxes, water, stage_rng(seed, "train", "detector_data", "wakes"))
    return work, boxes


def generate(out_dir: str | Path, seeds: list[int], presets: list[str] | None = None,
             gsd_range: tuple[float, float] = (0.08, 0.3), minutes: float | None = None,
             mix: str = "benchmark", library: str | None = None, looks: str = "kit") -> Path:
    """Render one level per seed (preset cycling) into ``out_dir``; resumable (skips written images).

    The index is rewritten after every level so that a run cut short still leaves usable data."""
    from ..fsio import write_png

    def make_item(preset: str, seed: int, gsd: float, size: float, out: Path) -> tuple[dict, str]:
        rgb, boxes = level_sample(preset, seed, gsd, size, mix=mix, library=library, looks=looks)
        name = f"{preset}_{seed}.png"
        write_png(out / name, rgb)
        return ({"image": name, "preset": preset, "seed": seed, "render_gsd_m": round(gsd, 4),
                 "boxes": [[round(v, 3) for v in b] for b in boxes]}, f"boxes={len(boxes)}")

    # level sizes kept small (fast, many layouts); the big vessels' mix needs room for 20-50 m boats
    head = {"work_gsd_m": WORK_GSD_M, "mix": mix, "library": str(library) if library else "kit", "looks": looks}
    return render_levels(out_dir, seeds, make_item, stage="detector_data", index_head=head, presets=presets,
                         gsd_range=gsd_range, size_range_m=(120.0, 220.0) if mix == "big" else (70.0, 150.0),
                         minutes=minutes)


def main(argv: list[str] | None = None) -> None:
    data_main(argv, __doc__.splitlines()[0], "100:400", generate, mix_option=True, looks_option=True)


if __name__ == "__main__":
    main()
