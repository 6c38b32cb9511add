"""Unreal Engine 5.3 / HoloOcean level bundle (DESIGN.md §6).

The bundle holds the landscape heightmap (16-bit PNG, raw ``.r16`` and an RGBA8 copy split into high/low
bytes for the render-target import), one 8-bit weight map per terrain class, PCG biome masks, GLB meshes
for assets without an Unreal path, ``level.json`` (every scene value, in Unreal units) and
``build_level.py``, the editor script that reads it.

Landscape maths (DESIGN.md §6): N vertices per side from the valid sizes; the actor's location is the
(0, 0) vertex corner (the scene's north-west corner, since rows run along +Y_ue = south);
ScaleX/Y = extent·100/(N−1) cm per quad; the water level sits at the raw value 32768 with LocationZ = 0;
ScaleZ ≥ max|z|·100/256 and H = round(32768 + z·100·128/ScaleZ).
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np

from .. import __version__, frames
from ..classes import CLASS_NAMES, GRASS, ROCKS, SAND, TREES, WATER
from ..errors import InputError
from . import safe_name, unique_names
from .gltf import mesh_glb_bytes
from .labels import FLOAT_TAG, instances_table, vegetation_label
from .terrain_mesh import class_weight_maps_u8, png_bytes, resample_height

LANDSCAPE_SIZES = (127, 253, 505, 1009, 2017, 4033, 8129)
WATER_VALUE = 32768
LAYER_NAMES = tuple(n.capitalize() for n in CLASS_NAMES)  # Water, Asphalt, ... paint layer names
SEAWEED_DEPTH_M = (0.5, 6.0)  # shallow water band where the seaweed mask is on


def landscape_size(max_px: int, cap: int = 8129) -> int:
    """The smallest valid landscape size that keeps ``max_px`` samples per side (capped at ``cap``)."""
    valid = [s for s in LANDSCAPE_SIZES if s <= cap]
    if not valid:
        raise InputError(f"export.ue_max_size = {cap} is below the smallest landscape size 127; use one of "
                         f"{', '.join(map(str, LANDSCAPE_SIZES))}")
    for s in valid:
        if s >= max_px:
            return s
    return valid[-1]


def landscape_layout(n: int) -> tuple[int, int, int]:
    """(quads per section, sections per component side, components per side) for a valid size: Epic's
    recommended 63-quad 2x2 sections first, at most 32 x 32 (= 1024) components."""
    for q, s in ((63, 2), (127, 2), (31, 2), (255, 2), (63, 1), (127, 1), (31, 1), (15, 1), (7, 1)):
        if (n - 1) % (q * s) == 0 and (n - 1) // (q * s) <= 32:
            return q, s, (n - 1) // (q * s)
    raise InputError(f"landscape size {n} is not components x sections x quads + 1; use one of {LANDSCAPE_SIZES}")


def scale_z_for(max_abs_z_m: float) -> float:
    """ScaleZ (cm) with 2 % headroom over max|z|·100/256; at least 1 cm so flat scenes still encode."""
    return max(1.0, max_abs_z_m * 100.0 / 256.0 * 1.02)


def encode_heights(z_m: np.ndarray, scale_z: float) -> np.ndarray:
    """H = round(32768 + z·100·128/ScaleZ), clipped to 16 bits (in z's float precision)."""
    z = np.asarray(z_m)
    z = z if z.dtype in (np.float32, np.float64) else z.astype(np.float64)
    h = z * z.dtype.type(100.0 * 128.0 / scale_z)
    h += z.dtype.type(WATER_VALUE)
    np.round(h, out=h)
    return np.clip(h, 0, 65535).astype(np.uint16)


def decode_heights(h: np.ndarray, scale_z: float, location_z_cm: float = 0.0) -> np.ndarray:
    """Raw values → metres, exactly as Unreal places them: Z_cm = (H − 32768)/128·ScaleZ + LocationZ."""
    return ((np.asarray(h, np.float64) - WATER_VALUE) / 128.0 * scale_z + location_z_cm) / 100.0


def object_folder(row: dict, length_m: float, big_float_length_m: float) -> str:
    """World Outliner folder of an object (its row of the label table): floating boats and buoys under
    float/big_float or float/small_float (DESIGN.md §6), everything else in a folder named by its HoloOcean
    label (Car, Pier, Bus, ...). Folders only keep the Outliner tidy: the Tagger reads the first actor tag."""
    if row["floating"]:
        return "float/big_float" if length_m >= big_float_length_m else "float/small_float"
    return row["holoocean"]


def actor_tags(label: str, floating: bool, run_tag: str, category: str, instance_id: int) -> list[str]:
    """Actor tags in HoloOcean's order: the label FIRST (``ATagger::TagActor`` reads ``Tags[0]``), then
    ``Float`` for props the tide moves, then coastforge's own (the run tag lets a re-run replace them)."""
    return ([label] + ([FLOAT_TAG] if floating else [])
            + [run_tag, f"coastforge:{category}", f"coastforge:instance={instance_id}"])


def height_check(h16: np.ndarray, step_cm: float, per_side: int = 9) -> dict:
    """Vertices build_level.py reads back after the landscape import (a per_side² grid plus the lowest and
    highest vertex) with their raw values, and the largest error (cm) it accepts before it stops."""
    n = h16.shape[0]
    idx = np.unique(np.linspace(0, n - 1, per_side).round().astype(int))
    pts = [(int(c), int(r)) for r in idx for c in idx]
    for f in (np.argmin, np.argmax):
        r, c = np.unravel_index(int(f(h16)), h16.shape)
        pts.append((int(c), int(r)))
    pts = list(dict.fromkeys(pts))
    return {"points": [[c, r, int(h16[r, c])] for c, r in pts],  # [column, row, raw 16-bit value]
            "tolerance_cm": max(1.0, 2.0 * step_cm)}


def _rotation(yaw_deg: float) -> dict:
    return {"roll": 0.0, "pitch": 0.0, "yaw": float(frames.yaw_to_unreal(yaw_deg))}


def _location_cm(x, y, z) -> list[float]:
    return [float(v) for v in frames.scene_to_unreal(x, y, z)]


def build_bundle(scene, assets, config) -> tuple[dict, dict[str, bytes]]:
    """(level.json dict, {relative path: bytes} of the data files)."""
    files: dict[str, bytes] = {}
    h_px, w_px = scene.height.shape
    n = landscape_size(max(h_px, w_px), config.ue_max_size)
    q, spc, comps = landscape_layout(n)
    ew, eh = scene.extent_m
    # float32: 1e-5 m is far below a height step, and halves the memory of 8129² landscapes
    z = resample_height(scene, n, n, dtype=np.float32)  # row 0 = north edge = the landscape's first row (smallest Y_ue)
    scale_z = scale_z_for(float(np.abs(z).max()))
    h16 = encode_heights(z, scale_z)
    files["heightmap/terrain_height.png"] = png_bytes(h16)
    files["heightmap/terrain_height.r16"] = h16.astype("<u2").tobytes()
    rg8 = np.zeros((n, n, 4), np.uint8)
    rg8[..., 0] = h16 >> 8
    rg8[..., 1] = h16 & 0xFF
    rg8[..., 3] = 255
    files["heightmap/terrain_height_rg8.png"] = png_bytes(rg8)

    w8, w = class_weight_maps_u8(scene, n, n, keep=(WATER, TREES, GRASS, ROCKS, SAND))
    weightmaps = []
    for k, layer in enumerate(LAYER_NAMES):
        rel = f"weightmaps/{layer}.png"
        files[rel] = png_bytes(w8[k])
        weightmaps.append({"layer": layer, "class_id": k, "file": rel})

    band = (z <= -SEAWEED_DEPTH_M[0]) & (z >= -SEAWEED_DEPTH_M[1])  # water depth within the band
    seaweed = np.where(band, w[WATER], 0).astype(np.uint8)
    masks = {"trees": w[TREES], "grass": w[GRASS], "rocks": w[ROCKS], "sand": w[SAND], "seaweed": seaweed}
    mask_entries = []
    for biome, m in masks.items():
        rel = f"pcg/{biome}_mask.png"
        files[rel] = png_bytes(m)
        mask_entries.append({"biome": biome, "file": rel})

    level_name = safe_name(scene.name)
    content = config.content_path.rstrip("/")
    if not content.startswith("/Game"):
        raise InputError(f"export.content_path = {config.content_path!r} must be a project path under /Game")

    # assets: an Unreal path when the library has one, else a GLB in the bundle imported by the script
    rows = instances_table(scene)["objects"]  # one row per object, in scene order
    veg = scene.vegetation
    n_veg = len(veg) if veg is not None else 0
    veg_spawned = n_veg if n_veg <= config.max_vegetation_actors else 0
    asset_label: dict[str, str] = {}  # the label of the first object using each asset
    for o, r in zip(scene.objects, rows):
        asset_label.setdefault(o.asset_id, r["holoocean"])
    for i in range(veg_spawned):
        asset_label.setdefault(str(veg.asset_id[i]), vegetation_label(str(veg.category[i]), str(veg.asset_id[i]))[0])
    names = unique_names(asset_label)
    asset_entries = []
    for aid, nm in names.items():
        ue_path = assets.ue_path(aid)
        # imported meshes go to <level>/<Label>/Meshes: the Tagger's fallback for an actor without tags is the
        # static mesh's grandparent Content folder (GetLabelByPath), so that folder carries the label too
        entry = {"asset_id": aid, "ue_path": ue_path, "glb": None, "import_name": f"SM_{nm}",
                 "import_path": f"{content}/{level_name}/{asset_label[aid]}/Meshes"}
        if not ue_path:
            # the file, its mesh and node all carry the import name: Interchange ignores destination_name and
            # names the asset after the source, so every importer arrives at the same asset path
            rel = f"meshes/SM_{nm}.glb"
            files[rel] = mesh_glb_bytes(assets.mesh(aid), f"SM_{nm}")
            entry["glb"] = rel
        asset_entries.append(entry)

    run_tag = f"coastforge:{level_name}"
    actors = []
    for o, r in zip(scene.objects, rows):
        actors.append({"id": o.id, "label": o.id, "asset_id": o.asset_id, "category": o.category,
                       "location": _location_cm(o.x_m, o.y_m, o.z_m), "rotation": _rotation(o.yaw_deg),
                       "scale": [float(s) for s in o.scale], "semantic_label": r["holoocean"],
                       "instance_id": r["instance_id"], "floating": r["floating"],
                       "folder": object_folder(r, o.length_m, config.big_float_length_m),
                       "tags": actor_tags(r["holoocean"], r["floating"], run_tag, o.category, r["instance_id"])})
    for i in range(veg_spawned):
        cat = str(veg.category[i])
        s = float(veg.scale[i])
        label = vegetation_label(cat, str(veg.asset_id[i]))[0]  # Tree, Bush, Grass, Rock or Seaweed
        actors.append({"id": f"veg_{i}", "label": f"veg_{cat}_{i}", "asset_id": str(veg.asset_id[i]),
                       "category": cat, "location": _location_cm(veg.x_m[i], veg.y_m[i], veg.z_m[i]),
                       "rotation": _rotation(float(veg.yaw_deg[i])), "scale": [s, s, s], "semantic_label": label,
                       "instance_id": 0, "floating": False, "folder": label,
                       "tags": actor_tags(label, False, run_tag, cat, 0)})

    zmin, zmax = float(z.min()), float(z.max())
    spec = {
        "format": "coastforge.ue5/1", "generator": f"coastforge {__version__}", "unreal_version": "5.3",
        "scene": scene.name, "content_path": content, "run_tag": run_tag,
        "labels": {"instances": "../instances.json", "first_tag": "HoloOcean Tagger label (ATagger::TagActor)",
                   "float_tag": FLOAT_TAG},
        "level": {"name": level_name, "asset_path": f"{content}/Maps/{level_name}", "template": config.template_level},
        "landscape": {
            "size": n, "quads_per_section": q, "sections_per_component": spc, "components": comps,
            "location": [-ew / 2.0 * 100.0, -eh / 2.0 * 100.0, 0.0],
            "scale": [ew * 100.0 / (n - 1), eh * 100.0 / (n - 1), scale_z],
            "water_height_value": WATER_VALUE, "height_step_cm": scale_z / 128.0,
            "z_range_m": [zmin, zmax], "source_px": [w_px, h_px],
            "heightmap_png": "heightmap/terrain_height.png", "heightmap_r16": "heightmap/terrain_height.r16",
            "heightmap_rg8": "heightmap/terrain_height_rg8.png",
            "height_check": height_check(h16, scale_z / 128.0),
            "rows_along": "+Y_ue (row 0 = north edge)", "columns_along": "+X_ue (east)",
        },
        "weightmaps": weightmaps,
        "pcg": {"graph": config.pcg_graph or None, "masks": mask_entries, "mask_path": f"{content}/{level_name}/PCG",
                "folder": "PCG", "label": f"PCG_{level_name}",
                # a PCGVolume's default brush is a 200 cm cube: scale it to the level and 200 m tall
                "volume": {"location": [0.0, 0.0, (zmin + zmax) / 2.0 * 100.0],
                           "scale": [ew * 100.0 / 200.0, eh * 100.0 / 200.0,
                                     max(1.0, (zmax - zmin + 20.0) * 100.0 / 200.0)]}},
        "assets": asset_entries,
        "actors": actors,
        "vegetation_left_to_pcg": n_veg - veg_spawned,
    }
    return spec, files


def build_level_script() -> bytes:
    """The editor script shipped as package data (identical for every scene)."""
    return resources.files("coastforge.export").joinpath("ue5_build_level.py").read_bytes()


def readme(spec: dict) -> str:
    ls = spec["landscape"]
    n = ls["size"]
    sx, sy, sz = ls["scale"]
    lx, ly, lz = ls["location"]
    lines = [
        f"# {spec['scene']} — Unreal Engine 5.3 / HoloOcean level bundle",
        "",
        f"Written by {spec['generator']}. Target: **Unreal Engine 5.3** (HoloOcean 2.x), Python Editor Script "
        "Plugin and PCG plugin enabled.",
        "",
        "## Files",
        "- `level.json` — every scene value in Unreal units (cm, left-handed: X = 100·x, Y = −100·y, Z = 100·z, "
        "yaw_ue = −yaw). `build_level.py` reads it; the script itself holds no scene data.",
        "- `heightmap/terrain_height.png` (16-bit grayscale) and `terrain_height.r16` (raw little-endian): "
        f"{n} x {n} vertices. `terrain_height_rg8.png` holds the same values split into bytes (R = high, G = low) "
        "for the render-target import.",
        "- `weightmaps/<Layer>.png` — one 8-bit weight map per terrain class, same resolution; the 8 maps sum "
        "to 255 at every vertex.",
        "- `pcg/<biome>_mask.png` — biome masks (trees, grass, rocks, sand, seaweed) for PCG graphs.",
        "- `meshes/*.glb` — assets without an Unreal path (y-up glTF, metres; the glTF importer converts).",
        "",
        "## Landscape settings",
        f"- Size {n} x {n} vertices = {ls['components']} x {ls['components']} components of "
        f"{ls['sections_per_component']} x {ls['sections_per_component']} sections of {ls['quads_per_section']} quads.",
        f"- Location X={lx:.3f} Y={ly:.3f} Z={lz:.3f} cm (the north-west corner; rows run south along +Y).",
        f"- Scale X={sx:.6f} Y={sy:.6f} Z={sz:.6f}. Water level Z = 0 cm is the value 32768; one height step is "
        f"{ls['height_step_cm']:.4f} cm.",
        "",
        *([f"- The scene raster ({ls['source_px'][0]} x {ls['source_px'][1]} px) is larger than the "
           f"{n} x {n} landscape (export.ue_max_size), so it was downsampled; a tiled landscape keeps "
           "every sample.", ""] if max(ls["source_px"]) > n else []),
        "## Steps",
        "1. Make the template level once (name it as `export.template_level`, default "
        f"`{spec['level']['template']}`): a HoloOcean base level with a landscape of exactly {n} x {n} vertices "
        "(settings above) whose material has the paint layers "
        + ", ".join(w["layer"] for w in spec["weightmaps"])
        + " (each with a layer info), a Movable water plane at Z = 0 tagged `WaterSurface` (custom-depth stencil 9), "
        "two post-process volumes over the water tagged `WaterPPV` (water colour, and water fog with `MM_Fog_Water`), "
        "standard lighting, `BP_Weather_Manager` with two volumetric clouds tagged `Sunny` and `Cloudy`, and a "
        "`FlashlightManager`. Do not enable the UE Water plugin (incompatible).",
        "2. Preview: `python build_level.py --dry-run` prints every action.",
        "3. In the editor (Output Log, Python): `py \"<this folder>/build_level.py\"`. It creates "
        f"`{spec['level']['asset_path']}` from the template, pushes heights and paint layers through render "
        "targets, imports the GLBs (AssetImportTask), spawns every object in its World Outliner folder, sets up "
        "the PCG volume (when `export.pcg_graph` is set) and saves the level.",
        "4. If the render-target import is refused, the script stops and prints the exact manual import settings "
        "(Landscape mode → Manage → Import from File); import by hand, then run it again with `--skip-landscape`.",
        "5. Re-running is safe: actors tagged `" + spec["run_tag"] + "` are destroyed and spawned again; imported "
        "meshes are re-used.",
        "",
        "## Assumptions",
        "- Semantic labels: every actor's FIRST tag is its HoloOcean label (Boat, Car, Bus, SemiTruck, Pier, Buoy, "
        "Tree, Bush, Grass, Rock, Seaweed), which HoloOcean's `ATagger::TagActor` reads before anything else; the "
        "same labels and instance ids are in `../instances.json`, the scene's label table. Imported meshes sit in "
        "`<level>/<Label>/Meshes`, the Content folder the Tagger falls back to for an actor without tags.",
        "- Floating boats and buoys carry the tag `Float` (HoloOcean's tide moves them) and sit in the Outliner "
        "folders `float/big_float` (length ≥ big_float_length_m) or `float/small_float`; HoloOcean also wants "
        "\"customized collision\" checked on their static meshes (Static Mesh editor, Collision) for the tide. "
        "Other objects sit in a folder named by their label; vegetation in Tree, Bush, Grass, Rock and Seaweed.",
        "- After the landscape import the script exports the heights back through a render target, compares "
        "them with the heightmap at sample vertices, prints the maximum error and stops on a mismatch.",
        "- The render-target import uses an RGBA8 target: Unreal rebuilds each height as R·256 + G; the PNG is "
        "loaded as a transient texture with sRGB off and nearest filtering so bytes are copied unchanged.",
        "- Assets with an Unreal path are spawned as they are; their pivot is the centre of the footprint at the "
        "lowest point and +X is the bow/front (coastforge's asset convention).",
        f"- {spec['vegetation_left_to_pcg']} vegetation instances were left to the PCG masks "
        "(over export.max_vegetation_actors)." if spec["vegetation_left_to_pcg"] else
        "- Every vegetation instance is spawned as an actor.",
        "",
    ]
    return "\n".join(lines)


def export_ue5(scene, assets, config) -> dict[str, bytes]:
    spec, files = build_bundle(scene, assets, config)
    files["level.json"] = (json.dumps(spec, indent=2, ensure_ascii=False, allow_nan=False) + "\n").encode("utf-8")
    files["build_level.py"] = build_level_script()
    files["README.md"] = readme(spec).encode("utf-8")
    return files


__all__ = ["LANDSCAPE_SIZES", "decode_heights", "encode_heights", "export_ue5", "landscape_size", "scale_z_for"]
