"""USD stage for Isaac Sim / OceanSim: z-up, metres (metersPerUnit = 1), the scene frame unchanged.

``<scene>.usdc``: /World/Terrain (mesh with vertex colours from the cleaned image or the class colours),
/World/Water (a plane at z = 0), /World/Objects/<id> (instanceable references to ``assets/<asset>.usda``
with translate / rotateZ (= yaw) / scale) and /World/Vegetation (a PointInstancer whose prototypes
reference the same asset files).
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..registry import require
from . import safe_name, scene_texture, unique_names
from .terrain_mesh import face_colors, terrain_image, terrain_mesh

WATER_RGB = (0.0, 0.35, 0.63)
WATER_OPACITY = 0.55


def _modules():
    require("pxr", "usd", "the USD exporter")
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    return Gf, Sdf, Usd, UsdGeom, Vt


def _stage_metadata(stage, UsdGeom, comment: str):
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.GetRootLayer().comment = comment


def asset_layer(mesh, name: str) -> str:
    """One asset as its own USD layer: /Asset (component) with a Mesh coloured per face."""
    Gf, Sdf, Usd, UsdGeom, Vt = _modules()
    stage = Usd.Stage.CreateInMemory(f"{name}.usda")
    _stage_metadata(stage, UsdGeom, f"coastforge {__version__} asset {name}: metres, z up, forward +x")
    root = UsdGeom.Xform.Define(stage, "/Asset")
    stage.SetDefaultPrim(root.GetPrim())
    Usd.ModelAPI(root.GetPrim()).SetKind("component")
    m = UsdGeom.Mesh.Define(stage, "/Asset/mesh")
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces, np.int64)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(v.astype(np.float32)))
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(f), 3, np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(f.reshape(-1).astype(np.int32)))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    m.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, v.min(0))), Gf.Vec3f(*map(float, v.max(0)))]))
    cols = face_colors(mesh)[:, :3].astype(np.float32) / 255.0
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.uniform)
    pv.Set(Vt.Vec3fArray.FromNumpy(cols))
    return stage.GetRootLayer().ExportToString()


def _yaw_quath(Gf, yaw_deg: float):
    h = math.radians(float(yaw_deg)) / 2.0
    return Gf.Quath(math.cos(h), Gf.Vec3h(0.0, 0.0, math.sin(h)))


def scene_layer(scene, assets, config, asset_files: dict[str, str], path: str):
    """Author the scene stage at ``path`` (a scratch folder holding the asset files, so the references
    resolve while authoring) and save it."""
    Gf, Sdf, Usd, UsdGeom, Vt = _modules()
    stage = Usd.Stage.CreateNew(path)
    _stage_metadata(stage, UsdGeom, f"coastforge {__version__} scene {scene.name}: x east, y north, z up, metres; "
                                    "water surface at z = 0")
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    world.GetPrim().SetCustomDataByKey("coastforge:scene", scene.name)

    # terrain with vertex colours sampled from the terrain image
    tm = terrain_mesh(scene, config.gltf_max_vertices)
    img = terrain_image(scene, scene_texture(assets), config.texture_max_px)
    ih, iw = img.shape[:2]
    cols = img[np.clip((tm.uv[:, 1] * (ih - 1)).round().astype(int), 0, ih - 1),
               np.clip((tm.uv[:, 0] * (iw - 1)).round().astype(int), 0, iw - 1)].astype(np.float32) / 255.0
    t = UsdGeom.Mesh.Define(stage, "/World/Terrain")
    t.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(tm.vertices.astype(np.float32)))
    t.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(tm.faces), 3, np.int32)))
    t.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(tm.faces.reshape(-1).astype(np.int32)))
    t.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(tm.normals.astype(np.float32)))
    t.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    t.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    t.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, tm.vertices.min(0))),
                                      Gf.Vec3f(*map(float, tm.vertices.max(0)))]))
    pv = UsdGeom.PrimvarsAPI(t)
    pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex).Set(
        Vt.Vec3fArray.FromNumpy(cols))
    pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex).Set(
        Vt.Vec2fArray.FromNumpy(np.stack([tm.uv[:, 0], 1.0 - tm.uv[:, 1]], 1).astype(np.float32)))

    # water plane at z = 0
    ew, eh = scene.extent_m
    w = UsdGeom.Mesh.Define(stage, "/World/Water")
    w.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(-ew / 2, -eh / 2, 0), Gf.Vec3f(ew / 2, -eh / 2, 0),
                                      Gf.Vec3f(ew / 2, eh / 2, 0), Gf.Vec3f(-ew / 2, eh / 2, 0)]))
    w.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    w.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    w.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    w.CreateDoubleSidedAttr(True)
    w.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(-ew / 2, -eh / 2, 0), Gf.Vec3f(ew / 2, eh / 2, 0)]))
    w.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*WATER_RGB)]))
    w.CreateDisplayOpacityAttr(Vt.FloatArray([WATER_OPACITY]))

    # objects: instanceable references, one asset file each
    UsdGeom.Scope.Define(stage, "/World/Objects")
    prim_names = unique_names([o.id for o in scene.objects])
    for o in scene.objects:
        x = UsdGeom.Xform.Define(stage, f"/World/Objects/{_prim_name(prim_names[o.id])}")
        x.AddTranslateOp().Set(Gf.Vec3d(o.x_m, o.y_m, o.z_m))
        x.AddRotateZOp().Set(float(o.yaw_deg))
        x.AddScaleOp().Set(Gf.Vec3f(*map(float, o.scale)))
        prim = x.GetPrim()
        prim.GetReferences().AddReference(asset_files[o.asset_id])
        prim.SetInstanceable(True)
        prim.SetCustomDataByKey("coastforge:id", o.id)
        prim.SetCustomDataByKey("coastforge:asset_id", o.asset_id)
        prim.SetCustomDataByKey("coastforge:category", o.category)

    veg = scene.vegetation
    if veg is not None and len(veg):
        pi = UsdGeom.PointInstancer.Define(stage, "/World/Vegetation")
        ids = list(dict.fromkeys(str(a) for a in veg.asset_id))
        UsdGeom.Scope.Define(stage, "/World/Vegetation/Prototypes")
        names = unique_names(ids)
        targets = []
        for aid in ids:
            p = UsdGeom.Xform.Define(stage, f"/World/Vegetation/Prototypes/{_prim_name(names[aid])}")
            p.GetPrim().GetReferences().AddReference(asset_files[aid])
            targets.append(p.GetPath())
        pi.CreatePrototypesRel().SetTargets(targets)
        index = {a: i for i, a in enumerate(ids)}
        pi.CreateProtoIndicesAttr(Vt.IntArray([index[str(a)] for a in veg.asset_id]))
        pos = np.stack([veg.x_m, veg.y_m, veg.z_m], 1).astype(np.float32)
        pi.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(pos))
        pi.CreateOrientationsAttr(Vt.QuathArray([_yaw_quath(Gf, y) for y in veg.yaw_deg]))
        sc = np.repeat(np.asarray(veg.scale, np.float32)[:, None], 3, 1)
        pi.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(sc))
    stage.GetRootLayer().Save()


def _prim_name(name: str) -> str:
    """A valid USD prim name (letters, digits, _; not starting with a digit)."""
    n = name.replace("-", "_")
    return n if not n[0].isdigit() else f"_{n}"


def export_usd(scene, assets, config) -> dict[str, bytes]:
    """Per-asset ``assets/<asset>.usda`` files and ``<scene>.usdc`` (binary: the terrain mesh is large)."""
    veg = scene.vegetation
    ids = list(dict.fromkeys([o.asset_id for o in scene.objects]
                             + ([str(a) for a in veg.asset_id] if veg is not None else [])))
    names = unique_names(ids)
    files: dict[str, bytes] = {}
    asset_files: dict[str, str] = {}
    for aid in ids:
        rel = f"assets/{names[aid]}.usda"
        files[rel] = asset_layer(assets.mesh(aid), names[aid]).encode("utf-8")
        asset_files[aid] = f"./{rel}"
    main = f"{safe_name(scene.name)}.usdc"
    with tempfile.TemporaryDirectory(prefix="coastforge-usd-") as tmp:
        for rel, data in files.items():
            (Path(tmp) / rel).parent.mkdir(parents=True, exist_ok=True)
            (Path(tmp) / rel).write_bytes(data)
        scene_layer(scene, assets, config, asset_files, str(Path(tmp) / main))
        files[main] = (Path(tmp) / main).read_bytes()
    return files
