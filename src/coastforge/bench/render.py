"""Benchmark of the top-down renderer: ``python -m coastforge.bench.render [--preview DIR]``.

Builds a synthetic harbour (quay, parking, park with trees, beach, rock revetment, a pier with fingers)
with ~100 objects and ~3000 vegetation instances from the starter kit (trimesh primitives if the kit
is not installed), renders it at 1024² and 2048² and prints wall times and the ray-casting backend.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ..classes import ASPHALT, DIRT, GRASS, ROCKS, SAND, SIDEWALK, TREES, WATER
from ..render import Lighting, MeshInstance, ray_backend, render_topdown
from ..rng import stage_rng


def _primitive_meshes() -> dict:
    import trimesh

    def box(size, z, rgb):
        m = trimesh.creation.box(size)
        m.apply_translation((0, 0, z))
        m.visual.face_colors = np.array([*rgb, 255], np.uint8)
        return m

    def blob(r, z, rgb):
        m = trimesh.creation.icosphere(1, radius=r)
        m.apply_translation((0, 0, z))
        m.visual.face_colors = np.array([*rgb, 255], np.uint8)
        return m

    return {
        "boat": [box((8, 2.6, 1.2), 0.3, (235, 235, 230)), box((6, 2.2, 1.0), 0.3, (40, 70, 130))],
        "vehicle": [box((4.5, 1.8, 1.5), 0.75, (170, 20, 20)), box((4.8, 1.9, 1.7), 0.85, (220, 220, 220))],
        "pier": [box((10, 2.5, 0.4), 0.8, (140, 115, 85))],
        "finger": [box((8, 1.0, 0.3), 0.7, (140, 115, 85))],
        "buoy": [blob(0.5, 0.2, (240, 90, 20))],
        "tree": [blob(2.5, 4.0, (40, 90, 35))],
        "bush": [blob(1.0, 0.8, (60, 100, 40))],
        "rock": [blob(0.8, 0.2, (120, 115, 105))],
        "grass": [blob(0.3, 0.1, (90, 130, 50))],
    }


def _kit_meshes() -> dict | None:
    try:
        from ..assets.kit import kit_assets, load_kit_mesh

        assets = kit_assets()
    except Exception:  # noqa: BLE001 - the benchmark falls back to primitives without a kit
        return None
    out: dict = {}
    for a in assets:
        cat = a.category
        if cat == "pier":
            cat = "finger" if "finger" in a.id else "pier"
        out.setdefault(cat, []).append(load_kit_mesh(a.id))
    need = ("boat", "vehicle", "pier", "finger", "buoy", "tree", "bush", "rock", "grass")
    return out if all(k in out for k in need) else None


def harbour_scene(
    seed: int = 0,
    extent_m: float = 204.8,
    grid_gsd_m: float = 0.2,
    n_objects: int = 100,
    n_vegetation: int = 3000,
    meshes: dict | None = None,
):
    """(classes, height, extent, instances, source) of a synthetic harbour for benchmarks and previews."""
    rng = stage_rng(seed, "bench", "render")
    src = "primitives"
    if meshes is None:
        meshes = _kit_meshes()
        src = "kit" if meshes is not None else "primitives"
        meshes = meshes or _primitive_meshes()
    n = round(extent_m / grid_gsd_m)
    g = extent_m / n
    yy, xx = np.mgrid[0:n, 0:n]
    x = (xx + 0.5) * g - extent_m / 2
    y = extent_m / 2 - (yy + 0.5) * g
    shore = 12.0 + 3.0 * np.sin(x / 23.0)
    cls = np.full((n, n), WATER, np.uint8)
    land = y > shore
    cls[land] = ASPHALT
    cls[land & (y < shore + 7)] = SIDEWALK
    park = land & (x < -30) & (y > shore + 25)
    cls[park] = GRASS
    cls[park & (np.hypot(x + 75, y - 75) < 28 + 6 * np.sin(3 * np.arctan2(y - 75, x + 75)))] = TREES
    cls[land & (x > 45) & (x < 70) & (y > shore + 30)] = DIRT
    beach = (x > 55 + 8 * np.sin(y / 9.0)) & (y > -30 + 0.1 * x + 6 * np.sin(x / 7.0))
    cls[beach & ~land] = SAND
    cls[beach & land & (y < shore + 20)] = SAND
    rev = (x < -60) & (y > shore - 5) & ~land
    cls[rev] = ROCKS
    height = np.zeros((n, n), np.float32)
    height[land] = 1.8 + 0.015 * (y[land] - shore[land])
    sb = cls == SAND
    beach_base = -30 + 0.1 * x + 6 * np.sin(x / 7.0)
    height[sb] = np.minimum(0.05 * (y[sb] - beach_base[sb]), 1.8)
    cls[sb & (height < 0.0)] = WATER  # the submerged part of the beach is water in the class map
    sb = cls == SAND
    height[sb] = np.maximum(height[sb], 0.05)
    height[rev] = 0.4 + 0.25 * (y[rev] - (shore[rev] - 5))
    # depth: shelving gently off the beach, a berth depth in front of the quay walls
    import cv2

    water = (cls == WATER).astype(np.uint8)
    d_beach = cv2.distanceTransform(np.where(sb, 0, 1).astype(np.uint8), cv2.DIST_L2, 5) * g
    d_land = cv2.distanceTransform(water, cv2.DIST_L2, 5) * g
    depth = np.minimum(np.minimum(0.1 + 0.07 * d_beach, 2.5 + 0.12 * d_land), 9.0)
    height[cls == WATER] = -depth[cls == WATER]

    def pick(cat, weights=None):
        lst = meshes[cat]
        if weights is not None and len(weights) == len(lst):
            return lst[int(rng.choice(len(lst), p=np.asarray(weights) / np.sum(weights)))]
        return lst[int(rng.integers(len(lst)))]

    def depth_at(bx, by):
        return -float(
            height[
                int(np.clip((extent_m / 2 - by) / g, 0, n - 1)),
                int(np.clip((bx + extent_m / 2) / g, 0, n - 1)),
            ]
        )

    def tint():
        return tuple(float(v) for v in rng.uniform(0.9, 1.1, 3))

    inst: list[MeshInstance] = []
    # a pier from the quay with fingers and boats moored on both sides
    px = 10.0
    for k in range(8):
        inst.append(MeshInstance(pick("pier"), px, shore[0, n // 2] - 3 - k * 5.0, 0.0, 90.0))
    for k in range(7):
        yk = shore[0, n // 2] - 8 - k * 5.5
        for side in (-1, 1):
            inst.append(MeshInstance(pick("finger"), px + side * 6.0, yk, 0.0, 0.0 if side > 0 else 180.0))
            if rng.random() < 0.8:
                inst.append(
                    MeshInstance(
                        pick("boat"),
                        px + side * 7.0,
                        yk - 2.6,
                        0.0,
                        float(rng.choice([0.0, 180.0]) + rng.normal(0, 3)),
                        tint=tint(),
                    )
                )
    while len(inst) < n_objects * 0.55:  # boats at anchor and along the quay
        bx, by = rng.uniform(-90, 90), rng.uniform(-95, -10)
        if (
            abs(bx - px) < 20
            or depth_at(bx, by) < 2.5
            or cls[int((extent_m / 2 - by) / g), int((bx + extent_m / 2) / g)] != WATER
        ):
            continue
        inst.append(MeshInstance(pick("boat"), bx, by, 0.0, float(rng.uniform(-180, 180)), tint=tint()))
    for k in range(4):
        inst.append(MeshInstance(pick("buoy"), -40 + 25 * k, -60.0, 0.0, 0.0))
    row_y = (shore[0, n // 2] + 16, shore[0, n // 2] + 23)
    cx = [-25.0, -25.0]
    k = 0
    while len(inst) < n_objects:
        j = k % 2
        k += 1
        m = pick("vehicle")
        wdt = float(m.bounds[1, 1] - m.bounds[0, 1])
        if rng.random() < 0.2:  # an empty bay
            cx[j] += 2.8
            continue
        cx[j] += max(2.8, wdt + 0.8)
        inst.append(
            MeshInstance(
                m,
                cx[j] - 0.5 * max(2.8, wdt + 0.8),
                row_y[j],
                1.8 + 0.015 * (row_y[j] - 13),
                float(rng.choice([90.0, -90.0])),
                tint=tint(),
            )
        )
    # vegetation on grass/trees/dirt, rocks on the revetment
    veg = 0
    tries = 0
    while veg < n_vegetation and tries < 20 * n_vegetation:
        tries += 1
        vx, vy = rng.uniform(-extent_m / 2, extent_m / 2, 2)
        c = cls[int((extent_m / 2 - vy) / g), int((vx + extent_m / 2) / g)]
        z = float(height[int((extent_m / 2 - vy) / g), int((vx + extent_m / 2) / g)])
        if c == TREES:
            cat = "tree" if rng.random() < 0.7 else "bush"
        elif c == GRASS:
            cat = "grass" if rng.random() < 0.75 else ("bush" if rng.random() < 0.7 else "tree")
        elif c == ROCKS:
            cat = "rock"
        elif c == DIRT and rng.random() < 0.3:
            cat = "grass"
        else:
            continue
        s = float(rng.uniform(0.7, 1.3))
        mesh = pick(cat, [3, 6, 1] if cat == "tree" else None)  # kit order: conifer, broadleaf, palm
        inst.append(
            MeshInstance(mesh, float(vx), float(vy), z, float(rng.uniform(-180, 180)), (s, s, s), tint())
        )
        veg += 1
    return cls, height, (extent_m, extent_m), inst, src


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m coastforge.bench.render", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--preview", default=None, help="Folder to write the rendered PNGs into.")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sizes", default="1024,2048", help="Comma-separated output sizes in pixels.")
    args = ap.parse_args(argv)
    t = time.perf_counter()
    cls, height, extent, inst, src = harbour_scene(args.seed)
    n_obj = sum(1 for i in inst if i.scale == (1.0, 1.0, 1.0))
    print(
        f"scene: {extent[0]:.1f} m square, {len(inst)} instances ({src} meshes; ~{n_obj} objects, "
        f"{len(inst) - n_obj} vegetation), built in {time.perf_counter() - t:.2f} s"
    )
    print(f"ray casting backend: {ray_backend()}")
    for size in (int(s) for s in args.sizes.split(",")):
        gsd = extent[0] / size
        t, c = time.perf_counter(), time.process_time()
        img = render_topdown(cls, height, extent, inst, gsd, Lighting(), seed=args.seed)
        dt, dc = time.perf_counter() - t, time.process_time() - c
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        print(
            f"{size}x{size} (gsd {gsd:.3f} m): {dt:.2f} s wall, {dc:.2f} s CPU (all threads), "
            f"peak RSS so far {peak:.0f} MB"
        )
        if args.preview:
            from pathlib import Path

            from ..fsio import write_png

            p = Path(args.preview) / f"render_{size}.png"
            write_png(p, img)
            print(f"  preview: {p}")


if __name__ == "__main__":
    main()
