"""Gazebo / Project DAVE world (SDFormat 1.9): heightmap terrain, a water surface at z = 0, and one static
model per object with an OBJ mesh (written into the bundle) and its pose.

Gazebo's heightmap wants a square image of 2ⁿ+1 samples; ``<size>`` is the extent in metres (x, y) and
the height range (z), ``<pos>`` the centre with z at the lowest height. The 16-bit PNG spans the full
0..65535 range, so whether a reader normalises by the data or the type maximum, value v maps to
min_z + v/65535·(max_z − min_z). Row 0 of the image is the north edge (+y). Meshes are OBJ (with an MTL
of the face colours) in the scene frame: z up, metres, forward +x; relative URIs resolve against the
world file.
"""

from __future__ import annotations

import math
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from .. import __version__
from . import safe_name, scene_texture, unique_names
from .labels import HOLOOCEAN_LABELS, instances_table, vegetation_label
from .terrain_mesh import face_colors, png_bytes, resample_height, terrain_image

SDF_VERSION = "1.9"
COASTFORGE_NS = "https://coastforge.invalid/sdf"  # the namespace of coastforge's custom elements


def heightmap_size(max_px: int, cap: int) -> int:
    """Smallest 2ⁿ+1 ≥ max_px, at most ``cap`` (rounded down to a 2ⁿ+1 value)."""
    n = 2 ** max(1, math.ceil(math.log2(max(2, max_px - 1)))) + 1
    top = 2 ** max(1, int(math.floor(math.log2(max(2, cap - 1))))) + 1
    return min(n, top)


def obj_bytes(mesh, name: str) -> tuple[bytes, bytes]:
    """(OBJ, MTL) of a trimesh, one material per distinct face colour."""
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    cols = face_colors(mesh)
    keys = [tuple(int(c) for c in row[:3]) for row in cols]
    uniq = list(dict.fromkeys(keys))
    mtl = [f"# coastforge {__version__}"]
    for c in uniq:
        mtl += [f"newmtl c_{c[0]:02x}{c[1]:02x}{c[2]:02x}", "Ka 0 0 0",
                f"Kd {c[0] / 255:.4f} {c[1] / 255:.4f} {c[2] / 255:.4f}", "Ks 0.05 0.05 0.05", "d 1", "illum 2", ""]
    lines = [f"# coastforge {__version__}: {name} (metres, z up, forward +x)", f"mtllib {name}.mtl", f"o {name}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    keys_arr = np.array([uniq.index(k) for k in keys])
    for ci, c in enumerate(uniq):
        lines.append(f"usemtl c_{c[0]:02x}{c[1]:02x}{c[2]:02x}")
        for a, b, d in f[keys_arr == ci] + 1:
            lines.append(f"f {a} {b} {d}")
    return ("\n".join(lines) + "\n").encode(), ("\n".join(mtl) + "\n").encode()


def _pose(x, y, z, roll=0.0, pitch=0.0, yaw=0.0) -> str:
    return " ".join(f"{float(v):.6f}" for v in (x, y, z, roll, pitch, yaw))


def _mesh_geometry(uri: str, scale) -> str:
    return (f"<geometry><mesh><uri>{escape(uri)}</uri><scale>{' '.join(f'{float(s):.6f}' for s in scale)}</scale>"
            f"</mesh></geometry>")


def label_plugin(label_id: int) -> str:
    """Gazebo's Label system on a model: its visuals get ``label_id`` (0..255) in segmentation cameras.
    (Gazebo Fortress spells it filename="ignition-gazebo-label-system" name="ignition::gazebo::systems::Label";
    Garden and later read this name.)"""
    if not 0 <= int(label_id) <= 255:
        raise ValueError(f"Gazebo labels are 0..255, got {label_id}")
    return (f'<plugin filename="gz-sim-label-system" name="gz::sim::systems::Label"><label>{int(label_id)}</label>'
            "</plugin>")


def instance_element(row: dict) -> str:
    """coastforge's own SDFormat element (a namespaced custom element, which sdformat keeps and ignores):
    the object's row of the label table, so the world carries the instance id a segmentation label cannot."""
    return (f"<coastforge:instance id={quoteattr(str(row['id']))} instance_id=\"{int(row['instance_id'])}\" "
            f"class={quoteattr(row['class'])} label={quoteattr(row['holoocean'])}/>")


def _model(name: str, pose: str, uri: str, scale, label_id: int, collision: bool = True, extra: str = "") -> str:
    geom = _mesh_geometry(uri, scale)
    col = f"<collision name=\"collision\">{geom}</collision>" if collision else ""
    return (f"    <model name={quoteattr(name)}>\n      <static>true</static>\n      <pose>{pose}</pose>\n"
            f"      <link name=\"link\">\n        <visual name=\"visual\">{geom}</visual>\n        {col}\n"
            f"      </link>\n      {label_plugin(label_id)}{extra}\n    </model>\n")


def build_world(scene, assets, config) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    h_px, w_px = scene.height.shape
    n = heightmap_size(max(h_px, w_px), config.sdf_heightmap_max)
    z = resample_height(scene, n, n)
    zmin, zmax = float(z.min()), float(z.max())
    zr = max(zmax - zmin, 1e-3)
    h16 = np.clip(np.round((z - zmin) / zr * 65535.0), 0, 65535).astype(np.uint16)
    files["terrain/heightmap.png"] = png_bytes(h16)
    files["terrain/texture.png"] = png_bytes(terrain_image(scene, scene_texture(assets), config.texture_max_px))
    files["terrain/flat_normal.png"] = png_bytes(np.full((4, 4, 3), (128, 128, 255), np.uint8))
    ew, eh = scene.extent_m

    veg = scene.vegetation
    ids = list(dict.fromkeys([o.asset_id for o in scene.objects]
                             + ([str(a) for a in veg.asset_id] if veg is not None else [])))
    mesh_names = unique_names(ids)
    for aid in ids:
        obj, mtl = obj_bytes(assets.mesh(aid), mesh_names[aid])
        files[f"meshes/{mesh_names[aid]}.obj"] = obj
        files[f"meshes/{mesh_names[aid]}.mtl"] = mtl

    hm = (f"<heightmap><uri>terrain/heightmap.png</uri><size>{ew:.6f} {eh:.6f} {zr:.6f}</size>"
          f"<pos>0 0 {zmin:.6f}</pos>{{texture}}</heightmap>")
    tex = (f"<texture><diffuse>terrain/texture.png</diffuse><normal>terrain/flat_normal.png</normal>"
           f"<size>{max(ew, eh):.6f}</size></texture>")
    out = [
        '<?xml version="1.0" ?>',
        f"<!-- coastforge {__version__}: scene {escape(scene.name).replace('--', '- -')}; "
        "x east, y north, z up, metres; water surface at z = 0 -->",
        f'<sdf version="{SDF_VERSION}" xmlns:coastforge="{COASTFORGE_NS}">',
        f"  <world name={quoteattr(safe_name(scene.name))}>",
        "    <gravity>0 0 -9.8</gravity>",
        "    <light type=\"directional\" name=\"sun\"><cast_shadows>true</cast_shadows><pose>0 0 100 0 0 0</pose>"
        "<diffuse>0.9 0.9 0.9 1</diffuse><specular>0.2 0.2 0.2 1</specular><direction>-0.4 0.3 -0.9</direction>"
        "</light>",
        "    <model name=\"terrain\">\n      <static>true</static>\n      <link name=\"link\">",
        f"        <collision name=\"collision\"><geometry>{hm.format(texture='')}</geometry></collision>",
        f"        <visual name=\"visual\"><geometry>{hm.format(texture=tex)}</geometry></visual>",
        f"      </link>\n      {label_plugin(HOLOOCEAN_LABELS['Landscape'])}\n    </model>",
        "    <model name=\"water_surface\">\n      <static>true</static>\n      <pose>0 0 0 0 0 0</pose>"
        "\n      <link name=\"link\">",
        f"        <visual name=\"visual\"><geometry><plane><normal>0 0 1</normal><size>{ew:.6f} {eh:.6f}</size>"
        "</plane></geometry><material><ambient>0 0.3 0.55 0.5</ambient><diffuse>0 0.35 0.63 0.5</diffuse>"
        "</material><transparency>0.5</transparency></visual>",
        f"      </link>\n      {label_plugin(HOLOOCEAN_LABELS['WaterPlane'])}\n    </model>",
    ]
    body = []
    model_names = unique_names([o.id for o in scene.objects])
    # the label is the HoloOcean stencil value of the object's label (instances.json holoocean_id), so a
    # Gazebo semantic segmentation and HoloOcean's agree; Gazebo separates instances by model itself
    for o, r in zip(scene.objects, instances_table(scene)["objects"]):
        body.append(_model(model_names[o.id], _pose(o.x_m, o.y_m, o.z_m, yaw=math.radians(o.yaw_deg)),
                           f"meshes/{mesh_names[o.asset_id]}.obj", o.scale, r["holoocean_id"],
                           extra=instance_element(r)))
    if veg is not None:
        for i in range(len(veg)):
            s = float(veg.scale[i])
            body.append(_model(f"veg_{i}", _pose(veg.x_m[i], veg.y_m[i], veg.z_m[i], yaw=math.radians(veg.yaw_deg[i])),
                               f"meshes/{mesh_names[str(veg.asset_id[i])]}.obj", (s, s, s),
                               vegetation_label(str(veg.category[i]), str(veg.asset_id[i]))[1], collision=False))
    text = "\n".join(out) + "\n" + "".join(body) + "  </world>\n</sdf>\n"
    files[f"{safe_name(scene.name)}.world"] = text.encode("utf-8")
    return files


def export_sdf(scene, assets, config) -> dict[str, bytes]:
    files = build_world(scene, assets, config)
    files["README.md"] = (
        f"# {scene.name} — Gazebo / Project DAVE world\n\n"
        f"Written by coastforge {__version__} (SDFormat {SDF_VERSION}).\n\n"
        f"Run: `gz sim {safe_name(scene.name)}.world` from this folder (mesh and heightmap URIs are relative "
        "to the world file). The terrain is a 16-bit heightmap of 2^n+1 samples per side, row 0 = north; meshes "
        "are OBJ in metres, z up. Models keep the scene object ids as names (made file-safe).\n\n"
        "Semantic labels: every model has Gazebo's Label system (`gz-sim-label-system`, Garden or later; Fortress "
        "calls it `ignition-gazebo-label-system`) with the HoloOcean stencil value of its label, so a segmentation "
        "camera here and HoloOcean's semantic camera give the same numbers; `<coastforge:instance>` carries the "
        "object's instance id and class from `../instances.json`.\n"
    ).encode()
    return files
