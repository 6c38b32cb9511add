"""The scene as binary glTF 2.0 (GLB, laid out by ``glb.GlbBuilder``): the terrain as a decimated textured
mesh, a water plane at z = 0, every object and vegetation instance as a node instancing one mesh per asset.

glTF is y-up, right-handed, metres: a scene point (x east, y north, z up) becomes (x, z, -y). That map is
a proper rotation (a -90° turn about +x), so triangle winding and handedness are kept; a scene yaw θ
about +z becomes a rotation θ about glTF +y.
"""

from __future__ import annotations

import math

import numpy as np

from . import scene_texture, unique_names
from .glb import GlbBuilder
from .labels import HOLOOCEAN_LABELS, instances_table, object_class, vegetation_label
from .terrain_mesh import flat_mesh_arrays, png_bytes, terrain_image, terrain_mesh

WATER_RGBA = (0.0, 0.35, 0.63, 0.55)


def to_gltf(p: np.ndarray) -> np.ndarray:
    """Scene-frame points or directions (..., 3) → glTF y-up (x, z, -y)."""
    p = np.asarray(p, np.float64)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def from_gltf(p: np.ndarray) -> np.ndarray:
    p = np.asarray(p, np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def yaw_quaternion(yaw_deg: float) -> list[float]:
    """glTF rotation [x, y, z, w] for a scene yaw (counter-clockwise about scene +z = glTF +y)."""
    h = math.radians(yaw_deg) / 2.0
    return [0.0, math.sin(h), 0.0, math.cos(h)]


def yaw_from_quaternion(q) -> float:
    _x, y, _z, w = q
    return math.degrees(2.0 * math.atan2(y, w))


def add_asset_mesh(b: GlbBuilder, name: str, mesh, material: int) -> int:
    pos, nrm, cols, faces = flat_mesh_arrays(mesh)
    return b.mesh(name, to_gltf(pos), to_gltf(nrm), faces, material, colors=cols)


def vertex_colour_material(b: GlbBuilder) -> int:
    return b.material({"name": "asset_vertex_colours", "pbrMetallicRoughness": {
        "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}})


def mesh_glb_bytes(mesh, name: str) -> bytes:
    """One asset mesh (scene frame) as a standalone y-up GLB, e.g. for Unreal's glTF importer."""
    b = GlbBuilder()
    m = add_asset_mesh(b, name, mesh, vertex_colour_material(b))
    b.node({"name": name, "mesh": m})
    return b.to_bytes()


def _node_trs(x: float, y: float, z: float, yaw_deg: float, scale) -> dict:
    sx, sy, sz = (float(s) for s in scale)
    return {"translation": [float(v) for v in to_gltf(np.array([x, y, z]))],
            "rotation": yaw_quaternion(yaw_deg), "scale": [sx, sz, sy]}  # local y/z swap with the axes


def build_glb(scene, assets, config) -> bytes:
    b = GlbBuilder()
    table = instances_table(scene)
    root = b.node({"name": f"coastforge:{scene.name}", "extras": {
        "coastforge": {"scene": scene.name, "extent_m": list(scene.extent_m), "water_level_m": 0.0,
                       "frame": "glTF y-up metres: (x, y, z)_gltf = (x_east, z_up, -y_north)",
                       "classes": table["classes"]}}})

    # terrain
    tm = terrain_mesh(scene, config.gltf_max_vertices - 4)  # the water plane uses 4 of the budget
    img = terrain_image(scene, scene_texture(assets), config.texture_max_px)
    tex = b.png_texture(png_bytes(img))
    tmat = b.material({"name": "terrain", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": tex}, "metallicFactor": 0.0, "roughnessFactor": 1.0}})
    tmesh = b.mesh("terrain", to_gltf(tm.vertices), to_gltf(tm.normals), tm.faces, tmat, uv=tm.uv)
    b.node({"name": "terrain", "mesh": tmesh, "extras": {"label": "Landscape", "label_id": HOLOOCEAN_LABELS["Landscape"],
                                                          "classes": "the class raster (scene terrain/classes.png)"}}, root)

    # water plane at z = 0 over the whole extent
    ew, eh = scene.extent_m
    wv = np.array([[-ew / 2, -eh / 2, 0.0], [ew / 2, -eh / 2, 0.0], [ew / 2, eh / 2, 0.0], [-ew / 2, eh / 2, 0.0]])
    wmat = b.material({"name": "water", "alphaMode": "BLEND", "doubleSided": True, "pbrMetallicRoughness": {
        "baseColorFactor": list(WATER_RGBA), "metallicFactor": 0.0, "roughnessFactor": 0.1}})
    wmesh = b.mesh("water", to_gltf(wv), to_gltf(np.tile([0.0, 0.0, 1.0], (4, 1))),
                   np.array([[0, 1, 2], [0, 2, 3]]), wmat)
    b.node({"name": "water", "mesh": wmesh, "extras": {"class": "water", "label": "WaterPlane",
                                                        "label_id": HOLOOCEAN_LABELS["WaterPlane"]}}, root)

    # one mesh per asset, many nodes
    veg = scene.vegetation
    veg_ids = [str(a) for a in veg.asset_id] if veg is not None else []
    asset_ids = list(dict.fromkeys([o.asset_id for o in scene.objects] + veg_ids))
    names = unique_names(asset_ids)
    mesh_of: dict[str, int] = {}
    if asset_ids:
        amat = vertex_colour_material(b)
        for aid in asset_ids:
            mesh_of[aid] = add_asset_mesh(b, names[aid], assets.mesh(aid), amat)

    # labels from the scene's label table (instances.json): the same ids and HoloOcean labels as every export
    objs = b.node({"name": "objects"}, root)
    for o, r in zip(scene.objects, table["objects"]):
        node = {"name": o.id, "mesh": mesh_of[o.asset_id],
                **_node_trs(o.x_m, o.y_m, o.z_m, o.yaw_deg, o.scale),
                "extras": {"id": o.id, "asset_id": o.asset_id, "category": o.category, "source": o.source,
                           "class": r["class"], "label": r["holoocean"], "label_id": r["holoocean_id"],
                           "instance_id": r["instance_id"], "floating": r["floating"]}}
        b.node(node, objs)
    if veg is not None and len(veg):
        vroot = b.node({"name": "vegetation"}, root)
        for i in range(len(veg)):
            s = float(veg.scale[i])
            cat, aid = str(veg.category[i]), str(veg.asset_id[i])
            label, label_id = vegetation_label(cat, aid)
            b.node({"name": f"veg_{i}", "mesh": mesh_of[aid],
                    **_node_trs(veg.x_m[i], veg.y_m[i], veg.z_m[i], veg.yaw_deg[i], (s, s, s)),
                    "extras": {"asset_id": aid, "category": cat, "class": object_class(cat, aid),
                               "label": label, "label_id": label_id, "instance_id": 0}}, vroot)
    return b.to_bytes()


def export_gltf(scene, assets, config) -> dict[str, bytes]:
    """``{"<scene>.glb": bytes}``: a single self-contained GLB."""
    from . import safe_name

    return {f"{safe_name(scene.name)}.glb": build_glb(scene, assets, config)}
