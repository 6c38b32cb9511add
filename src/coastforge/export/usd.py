"""USD stage for Isaac Sim / OceanSim: z-up, metres (metersPerUnit = 1), the scene frame unchanged.

``<scene>.usdc``: /World/Terrain (mesh with vertex colours and a UsdPreviewSurface reading
``textures/terrain.png`` through the ``st`` primvar; one GeomSubset per terrain class, labelled),
/World/Water (a plane at z = 0, translucent), /World/Objects/<id> (instanceable references to
``assets/<asset>.usda`` with translate / rotateZ (= yaw) / scale, labelled) and /World/Vegetation (a
PointInstancer whose prototypes reference the same asset files). Each asset file binds a UsdPreviewSurface
per face colour (GeomSubsets of family ``materialBind``).

Semantic labels come from the scene's label table (``labels.instances_table``) in both forms Isaac Sim reads:
``UsdSemantics.LabelsAPI`` (``SemanticsLabelsAPI:class``, ``token[] semantics:labels:class``; Isaac Sim 4.5+,
OpenUSD's usdSemantics) and the legacy Isaac ``SemanticsAPI:Semantics`` (``semantic:Semantics:params:
semanticType = "class"``, ``semanticData = <label>``), written as plain attributes since usd-core does not
register that schema; NVIDIA's SimReady rule SL.002 accepts the legacy label beside an equal LabelsAPI one.
Sources are listed in ``labels.py``.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..classes import TERRAIN_CLASSES
from ..registry import require
from . import safe_name, scene_texture, unique_names
from .labels import TERRAIN_LABELS, instances_table, vegetation_label
from .terrain_mesh import face_colors, png_bytes, sample_class, terrain_image, terrain_mesh

WATER_RGB = (0.0, 0.35, 0.63)
WATER_OPACITY = 0.55  # translucent: a camera above sees the seabed through it
TERRAIN_TEXTURE = "textures/terrain.png"  # beside the stage, referenced relatively
INSTANCE_TAXONOMY = "coastforge_instance"  # a second LabelsAPI taxonomy: the object's instance id


def _modules():
    require("pxr", "usd", "the USD exporter")
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    return Gf, Sdf, Usd, UsdGeom, Vt


def set_semantics(prim, label: str, instance_id: int | None = None) -> None:
    """The class label in both of Isaac Sim's forms (see the module docstring), and the instance id as a
    second LabelsAPI taxonomy when given."""
    from pxr import Sdf, UsdSemantics

    UsdSemantics.LabelsAPI.Apply(prim, "class").CreateLabelsAttr().Set([label])
    if instance_id is not None:
        UsdSemantics.LabelsAPI.Apply(prim, INSTANCE_TAXONOMY).CreateLabelsAttr().Set([str(int(instance_id))])
    # Isaac Sim's legacy Semantics schema: not registered in usd-core, so its applied name and attributes are
    # authored as they appear in stages Isaac Sim writes
    prim.AddAppliedSchema("SemanticsAPI:Semantics")
    prim.CreateAttribute("semantic:Semantics:params:semanticType", Sdf.ValueTypeNames.String).Set("class")
    prim.CreateAttribute("semantic:Semantics:params:semanticData", Sdf.ValueTypeNames.String).Set(label)


def preview_material(stage, path: str, rgb, opacity: float = 1.0, roughness: float = 0.8, texture: str | None = None):
    """A UsdPreviewSurface material; ``texture`` (an asset path) feeds diffuseColor through a UsdUVTexture
    reading the ``st`` primvar (UsdPrimvarReader_float2), as the UsdPreviewSurface spec asks."""
    from pxr import Gf, Sdf, UsdShade

    mat = UsdShade.Material.Define(stage, path)
    surf = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    surf.CreateIdAttr("UsdPreviewSurface")
    surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
    surf.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    if opacity < 1.0:
        surf.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(opacity))
    if texture is None:
        surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*map(float, rgb)))
    else:
        reader = UsdShade.Shader.Define(stage, f"{path}/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        tex = UsdShade.Shader.Define(stage, f"{path}/Texture")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(texture))
        tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
        tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("clamp")
        tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("clamp")
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
        tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    surf.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    return mat


def bind(prim, material) -> None:
    from pxr import UsdShade

    UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)


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
    fc = face_colors(mesh)[:, :3]
    cols = fc.astype(np.float32) / 255.0
    pv = UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.uniform)
    pv.Set(Vt.Vec3fArray.FromNumpy(cols))
    # renderers that ignore displayColor (Isaac Sim's RTX) see the same colours as UsdPreviewSurface materials:
    # one per distinct face colour, bound through GeomSubsets of the materialBind family
    UsdGeom.Scope.Define(stage, "/Asset/Looks")
    keys, inverse = np.unique(fc, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    for k, rgb in enumerate(keys):
        mat = preview_material(stage, f"/Asset/Looks/c_{rgb[0]:02x}{rgb[1]:02x}{rgb[2]:02x}", rgb / 255.0)
        if len(keys) == 1:
            bind(m.GetPrim(), mat)
            break
        sub = UsdGeom.Subset.CreateGeomSubset(
            m, f"part_{rgb[0]:02x}{rgb[1]:02x}{rgb[2]:02x}", UsdGeom.Tokens.face,
            Vt.IntArray.FromNumpy(np.flatnonzero(inverse == k).astype(np.int32)), "materialBind",
            UsdGeom.Tokens.partition)
        bind(sub.GetPrim(), mat)
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
    UsdGeom.Scope.Define(stage, "/World/Looks")
    bind(t.GetPrim(), preview_material(stage, "/World/Looks/Terrain", (0.5, 0.5, 0.5), roughness=1.0,
                                       texture=f"./{TERRAIN_TEXTURE}"))
    # one GeomSubset per terrain class (a partition of the faces, by the class under each face's centre),
    # labelled with the class's label from the scene's label table
    centres = tm.vertices[tm.faces].mean(axis=1)
    face_cls = sample_class(scene, centres[:, 0], centres[:, 1])
    for c in TERRAIN_CLASSES:
        idx = np.flatnonzero(face_cls == c.id).astype(np.int32)
        if len(idx):
            sub = UsdGeom.Subset.CreateGeomSubset(t, c.name, UsdGeom.Tokens.face, Vt.IntArray.FromNumpy(idx),
                                                  "terrainClass", UsdGeom.Tokens.partition)
            sub.GetPrim().SetCustomDataByKey("coastforge:class_id", c.id)
            set_semantics(sub.GetPrim(), TERRAIN_LABELS[c.name])

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
    bind(w.GetPrim(), preview_material(stage, "/World/Looks/Water", WATER_RGB, opacity=WATER_OPACITY, roughness=0.1))
    set_semantics(w.GetPrim(), TERRAIN_LABELS["water"])

    # objects: instanceable references, one asset file each
    UsdGeom.Scope.Define(stage, "/World/Objects")
    prim_names = unique_names([o.id for o in scene.objects])
    for o, r in zip(scene.objects, instances_table(scene)["objects"]):
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
        prim.SetCustomDataByKey("coastforge:instance_id", r["instance_id"])
        prim.SetCustomDataByKey("coastforge:label", r["holoocean"])
        set_semantics(prim, r["holoocean"], r["instance_id"])

    veg = scene.vegetation
    if veg is not None and len(veg):
        pi = UsdGeom.PointInstancer.Define(stage, "/World/Vegetation")
        ids = list(dict.fromkeys(str(a) for a in veg.asset_id))
        UsdGeom.Scope.Define(stage, "/World/Vegetation/Prototypes")
        names = unique_names(ids)
        targets = []
        kind = {str(a): str(c) for a, c in zip(veg.asset_id, veg.category)}  # asset -> its table category
        for aid in ids:
            p = UsdGeom.Xform.Define(stage, f"/World/Vegetation/Prototypes/{_prim_name(names[aid])}")
            p.GetPrim().GetReferences().AddReference(asset_files[aid])
            set_semantics(p.GetPrim(), vegetation_label(kind[aid], aid)[0])  # its instances share the label
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
    files[TERRAIN_TEXTURE] = png_bytes(terrain_image(scene, scene_texture(assets), config.texture_max_px))
    main = f"{safe_name(scene.name)}.usdc"
    with tempfile.TemporaryDirectory(prefix="coastforge-usd-") as tmp:
        for rel, data in files.items():
            (Path(tmp) / rel).parent.mkdir(parents=True, exist_ok=True)
            (Path(tmp) / rel).write_bytes(data)
        scene_layer(scene, assets, config, asset_files, str(Path(tmp) / main))
        files[main] = (Path(tmp) / main).read_bytes()
    return files
