"""Binary glTF 2.0 (GLB): the terrain as a decimated textured mesh, a water plane at z = 0, every object
and vegetation instance as a node instancing one mesh per asset.

glTF is y-up, right-handed, metres: a scene point (x east, y north, z up) becomes (x, z, -y). That map is
a proper rotation (a -90° turn about +x), so triangle winding and handedness are kept; a scene yaw θ
about +z becomes a rotation θ about glTF +y.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np

from .. import __version__
from . import scene_texture, unique_names
from .labels import HOLOOCEAN_LABELS, instances_table, object_class, vegetation_label
from .terrain_mesh import flat_mesh_arrays, png_bytes, terrain_image, terrain_mesh

FLOAT, UINT, UBYTE = 5126, 5125, 5121
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
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
    x, y, z, w = q
    return math.degrees(2.0 * math.atan2(y, w))


class GlbBuilder:
    """A small GLB writer: one binary buffer, 4-byte aligned views, accessors with min/max."""

    def __init__(self, generator: str = f"coastforge {__version__}"):
        self.doc: dict = {"asset": {"version": "2.0", "generator": generator}, "scene": 0, "scenes": [{"nodes": []}],
                          "nodes": [], "meshes": [], "accessors": [], "bufferViews": [], "buffers": []}
        self.bin = bytearray()

    def _list(self, key: str) -> list:
        return self.doc.setdefault(key, [])

    def view(self, data: bytes, target: int | None = None) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        bv = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            bv["target"] = target
        self.bin.extend(data)
        self.doc["bufferViews"].append(bv)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, arr: np.ndarray, ctype: int, atype: str, target: int, normalized: bool = False,
                 minmax: bool = False) -> int:
        dt = {FLOAT: np.float32, UINT: np.uint32, UBYTE: np.uint8}[ctype]
        a = np.ascontiguousarray(arr, dtype=dt)
        acc = {"bufferView": self.view(a.tobytes(), target), "componentType": ctype,
               "count": int(a.shape[0]), "type": atype}
        if normalized:
            acc["normalized"] = True
        if minmax:
            flat = a.reshape(a.shape[0], -1)
            acc["min"] = [float(v) if ctype == FLOAT else int(v) for v in flat.min(0)]
            acc["max"] = [float(v) if ctype == FLOAT else int(v) for v in flat.max(0)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, mat: dict) -> int:
        self._list("materials").append(mat)
        return len(self.doc["materials"]) - 1

    def png_texture(self, png: bytes) -> int:
        img = {"bufferView": self.view(png), "mimeType": "image/png"}
        self._list("images").append(img)
        self._list("samplers").append({"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071})
        self._list("textures").append({"sampler": len(self.doc["samplers"]) - 1, "source": len(self.doc["images"]) - 1})
        return len(self.doc["textures"]) - 1

    def mesh(self, name: str, pos_gl: np.ndarray, nrm_gl: np.ndarray, faces: np.ndarray, material: int,
             colors: np.ndarray | None = None, uv: np.ndarray | None = None) -> int:
        attrs = {"POSITION": self.accessor(pos_gl, FLOAT, "VEC3", ARRAY_BUFFER, minmax=True),
                 "NORMAL": self.accessor(nrm_gl, FLOAT, "VEC3", ARRAY_BUFFER)}
        if uv is not None:
            attrs["TEXCOORD_0"] = self.accessor(uv, FLOAT, "VEC2", ARRAY_BUFFER)
        if colors is not None:
            attrs["COLOR_0"] = self.accessor(colors, UBYTE, "VEC4", ARRAY_BUFFER, normalized=True)
        idx = self.accessor(np.asarray(faces).reshape(-1), UINT, "SCALAR", ELEMENT_ARRAY_BUFFER)
        self.doc["meshes"].append({"name": name, "primitives": [
            {"attributes": attrs, "indices": idx, "material": material, "mode": 4}]})
        return len(self.doc["meshes"]) - 1

    def node(self, node: dict, parent: int | None = None) -> int:
        self.doc["nodes"].append(node)
        i = len(self.doc["nodes"]) - 1
        if parent is None:
            self.doc["scenes"][0]["nodes"].append(i)
        else:
            self.doc["nodes"][parent].setdefault("children", []).append(i)
        return i

    def to_bytes(self) -> bytes:
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["buffers"] = [{"byteLength": len(self.bin)}]
        for k in ("materials", "images", "samplers", "textures", "meshes", "accessors", "bufferViews"):
            if k in self.doc and not self.doc[k]:
                del self.doc[k]
        js = json.dumps(self.doc, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
        js += b" " * (-len(js) % 4)
        total = 12 + 8 + len(js) + 8 + len(self.bin)
        return (struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js), 0x4E4F534A) + js
                + struct.pack("<II", len(self.bin), 0x004E4942) + bytes(self.bin))


def read_glb(data: bytes) -> tuple[dict, bytes]:
    """GLB bytes → (JSON document, binary chunk). Used by tests and round trips."""
    magic, version, total = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or version != 2 or total != len(data):
        raise ValueError("not a GLB 2.0 file")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + jlen].decode("utf-8"))
    off = 20 + jlen
    binary = b""
    if off < len(data):
        blen, _btype = struct.unpack_from("<II", data, off)
        binary = data[off + 8: off + 8 + blen]
    return doc, binary


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
    amat = vertex_colour_material(b) if asset_ids else None
    mesh_of: dict[str, int] = {}
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
