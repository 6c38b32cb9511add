"""Binary glTF 2.0 (GLB): the container, written and read here only.

``GlbBuilder`` collects a document and its binary buffer (4-byte aligned views, accessors with min/max)
and ``to_bytes`` lays out the header and the JSON and BIN chunks; ``read_glb`` splits a file back into
its document and buffer, and ``accessor_array`` reads one accessor. What goes in the document is the
caller's: the scene export (``export.gltf``) and the starter kit's meshes (``assets.kit``).
"""

from __future__ import annotations

import json
import struct

import numpy as np

from .. import __version__

MAGIC = b"glTF"
VERSION = 2
JSON_CHUNK = b"JSON"
BIN_CHUNK = b"BIN\x00"

# accessor component types
UBYTE, USHORT, UINT, FLOAT = 5121, 5123, 5125, 5126
COMPONENT_DTYPES = {UBYTE: np.uint8, USHORT: np.uint16, UINT: np.uint32, FLOAT: np.float32}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
# buffer view targets
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
TRIANGLES = 4  # primitive mode


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
        a = np.ascontiguousarray(arr, dtype=COMPONENT_DTYPES[ctype])
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

    def primitive(self, pos_gl: np.ndarray, nrm_gl: np.ndarray, faces: np.ndarray, material: int,
                  colors: np.ndarray | None = None, uv: np.ndarray | None = None, index_type: int = UINT) -> dict:
        """One triangle primitive (its accessors added): positions and normals in glTF axes, optional vertex
        colours (RGBA bytes) and UVs, indices of ``index_type`` (UINT, or USHORT for small meshes)."""
        attrs = {"POSITION": self.accessor(pos_gl, FLOAT, "VEC3", ARRAY_BUFFER, minmax=True),
                 "NORMAL": self.accessor(nrm_gl, FLOAT, "VEC3", ARRAY_BUFFER)}
        if uv is not None:
            attrs["TEXCOORD_0"] = self.accessor(uv, FLOAT, "VEC2", ARRAY_BUFFER)
        if colors is not None:
            attrs["COLOR_0"] = self.accessor(colors, UBYTE, "VEC4", ARRAY_BUFFER, normalized=True)
        idx = self.accessor(np.asarray(faces).reshape(-1), index_type, "SCALAR", ELEMENT_ARRAY_BUFFER)
        return {"attributes": attrs, "indices": idx, "material": material, "mode": TRIANGLES}

    def add_mesh(self, name: str, primitives: list[dict]) -> int:
        self.doc["meshes"].append({"name": name, "primitives": primitives})
        return len(self.doc["meshes"]) - 1

    def mesh(self, name: str, pos_gl: np.ndarray, nrm_gl: np.ndarray, faces: np.ndarray, material: int,
             colors: np.ndarray | None = None, uv: np.ndarray | None = None) -> int:
        """A mesh of one primitive."""
        return self.add_mesh(name, [self.primitive(pos_gl, nrm_gl, faces, material, colors, uv)])

    def node(self, node: dict, parent: int | None = None) -> int:
        self.doc["nodes"].append(node)
        i = len(self.doc["nodes"]) - 1
        if parent is None:
            self.doc["scenes"][0]["nodes"].append(i)
        else:
            self.doc["nodes"][parent].setdefault("children", []).append(i)
        return i

    def to_bytes(self, sort_keys: bool = False) -> bytes:
        """The GLB file; ``sort_keys`` orders the document's keys (bytes that do not depend on the order
        things were added in)."""
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["buffers"] = [{"byteLength": len(self.bin)}]
        for k in ("materials", "images", "samplers", "textures", "meshes", "accessors", "bufferViews"):
            if k in self.doc and not self.doc[k]:
                del self.doc[k]
        js = json.dumps(self.doc, separators=(",", ":"), ensure_ascii=False, allow_nan=False,
                        sort_keys=sort_keys).encode("utf-8")
        js += b" " * (-len(js) % 4)
        total = 12 + 8 + len(js) + 8 + len(self.bin)
        return (struct.pack("<4sII", MAGIC, VERSION, total) + struct.pack("<I4s", len(js), JSON_CHUNK) + js
                + struct.pack("<I4s", len(self.bin), BIN_CHUNK) + bytes(self.bin))


def read_glb(data: bytes) -> tuple[dict, bytes]:
    """GLB bytes → (JSON document, binary chunk); ``ValueError`` for anything else."""
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    if magic != MAGIC or version != VERSION or total != len(data):
        raise ValueError("not a GLB 2.0 file")
    jlen, _jtype = struct.unpack_from("<I4s", data, 12)
    doc = json.loads(data[20:20 + jlen].decode("utf-8"))
    off = 20 + jlen
    binary = b""
    if off < len(data):
        blen, _btype = struct.unpack_from("<I4s", data, off)
        binary = data[off + 8: off + 8 + blen]
    return doc, binary


def accessor_array(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` of a read GLB as an array: (count,) for scalars, else (count, components)."""
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    k = TYPE_SIZES[a["type"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    arr = np.frombuffer(binary, dtype=COMPONENT_DTYPES[a["componentType"]], count=a["count"] * k, offset=start)
    return arr.reshape(-1, k) if k > 1 else arr
