"""The kit's models as GLB files and back (laid out by ``export.glb``): glTF y-up, one primitive and
PBR material per colour, flat normals and a box-projected UV set, coordinates rounded so the bytes are
the same on every platform."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ...errors import LibraryError
from ...export import glb
from ...export.glb import UINT, USHORT, GlbBuilder
from .shapes import DECIMALS, Model

# glTF is y-up: scene (x, y, z) -> glTF (x, z, -y); a proper rotation, so face winding is kept.
SCENE_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
GLTF_TO_SCENE = SCENE_TO_GLTF.T


_FINISH = {"paint": (0.45, 0.0), "matte": (0.9, 0.0), "glass": (0.08, 0.0), "metal": (0.35, 0.8),
           "rubber": (0.85, 0.0), "plant": (0.85, 0.0)}


def _lin(c: int) -> float:
    s = c / 255.0
    return s / 12.92 if s <= 0.04045 else ((s + 0.055) / 1.055) ** 2.4


def _srgb(v: float) -> int:
    v = min(max(v, 0.0), 1.0)
    s = v * 12.92 if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(round(s * 255))


def _flat_primitive(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions, normals, UVs and indices with flat shading: vertices shared only where position and face
    normal agree (so boxes stay crisp in every viewer and engine). UVs are a box projection in metres
    along the normal's dominant axis, so engines that want a UV set (Unreal lightmaps, detail
    textures) get a sensible one."""
    v = np.round(v, DECIMALS)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ln = np.linalg.norm(n, axis=1)
    keep = ln > 1e-9
    tri, n = tri[keep], n[keep] / ln[keep][:, None]
    n = np.round(n, 5)
    n /= np.linalg.norm(n, axis=1)[:, None]
    n = np.round(n, 6)
    corners = np.concatenate([tri.reshape(-1, 3), np.repeat(n, 3, axis=0)], axis=1)
    uniq, inverse = np.unique(corners, axis=0, return_inverse=True)
    pos, nrm = uniq[:, :3].astype(np.float32), uniq[:, 3:].astype(np.float32)
    axis = np.argmax(np.abs(uniq[:, 3:]), axis=1)
    keep_axes = np.array([[2, 1], [0, 2], [0, 1]])[axis]  # drop the dominant axis
    uv = np.round(np.take_along_axis(uniq[:, :3], keep_axes, axis=1), DECIMALS).astype(np.float32)
    return pos, nrm, uv, inverse.reshape(-1).astype(np.uint32)


def glb_bytes(model: Model, name: str) -> bytes:
    """Encode a model as GLB (glTF y-up), one primitive + PBR material per colour; deterministic (the
    document's keys sorted)."""
    b = GlbBuilder(generator="coastforge.assets.kit")
    primitives = []
    for colour, v, f in model.by_colour():
        pos, nrm, uv, idx = _flat_primitive(v @ SCENE_TO_GLTF.T, f)
        if len(idx) == 0:
            continue
        (r, g, bl), finish = colour
        rough, metal = _FINISH[finish]
        material = {
            "name": f"{finish}_{r:02x}{g:02x}{bl:02x}",
            "pbrMetallicRoughness": {"baseColorFactor": [round(_lin(c), 6) for c in (r, g, bl)] + [1.0],
                                     "metallicFactor": metal, "roughnessFactor": rough},
        }
        index_type = UINT if len(pos) > 65535 else USHORT
        primitives.append(b.primitive(pos, nrm, idx, b.material(material), uv=uv, index_type=index_type))
    b.node({"name": name, "mesh": b.add_mesh(name, primitives)})
    return b.to_bytes(sort_keys=True)


def read_glb(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (scene frame), faces and per-face sRGB RGBA colours of a kit GLB."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LibraryError(f"cannot read kit mesh {path} ({exc}); regenerate the kit") from None
    try:
        doc, binary = glb.read_glb(data)
        vs, fs, cs, off = [], [], [], 0
        for node in doc["nodes"]:
            if "mesh" not in node:
                continue
            if any(k in node for k in ("matrix", "rotation", "translation", "scale")):
                raise ValueError("node transforms are not used by kit meshes")
            for prim in doc["meshes"][node["mesh"]]["primitives"]:
                pos = glb.accessor_array(doc, binary, prim["attributes"]["POSITION"]).astype(np.float64)
                idx = glb.accessor_array(doc, binary, prim["indices"]).astype(np.int64).reshape(-1, 3)
                mat = doc["materials"][prim["material"]]
                fac = mat.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])
                rgba = [_srgb(c) for c in fac[:3]] + [int(round(fac[3] * 255))]
                vs.append(pos @ GLTF_TO_SCENE.T)
                fs.append(idx + off)
                cs.append(np.tile(np.array(rgba, dtype=np.uint8), (len(idx), 1)))
                off += len(pos)
    except (ValueError, KeyError, IndexError, struct.error) as exc:
        raise LibraryError(f"kit mesh {path} is not a valid kit GLB ({exc}); regenerate the kit") from None
    if not vs:
        raise LibraryError(f"kit mesh {path} holds no mesh; regenerate the kit")
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(cs)
