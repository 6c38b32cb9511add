"""A recording stand-in for Unreal Engine 5.3's ``unreal`` Python module (Unreal cannot run here).

Every attribute the script touches (module functions, classes, methods, enum values, editor property
names) is checked against ``ue53_api_names.API``; an undocumented name is recorded as a violation and
raises AttributeError, as the real module would for a name that does not exist. Calls are recorded with
their arguments, and a small world model (actors, assets, render targets, landscape data) lets the test
check what the script did: centimetres, left-handed Y, yaw sign, folders, tags, re-runs.
"""

from __future__ import annotations

import types
from typing import ClassVar

import numpy as np

from ue53_api_names import API, BASES


class Recorder:
    def __init__(self):
        self.calls: list[tuple[str, tuple, dict]] = []
        self.violations: list[str] = []
        self.world_actors: list = []
        self.assets: set[str] = set()
        self.templates: set[str] = set()
        self.saved = 0
        self.interchange = False  # import like Interchange: destination_name ignored, no imported_object_paths
        self.height_drift = 0  # raw steps added to the heights a landscape export returns

    def check(self, cls_name: str, member: str) -> str:
        """The documented key for cls_name.member (walking base classes), or a recorded violation."""
        c = cls_name
        while c:
            key = f"{c}.{member}"
            if key in API:
                return key
            c = BASES.get(c)
        self.violations.append(f"{cls_name}.{member}")
        raise AttributeError(f"'{cls_name}' has no documented UE 5.3 member '{member}'")

    def named(self, name: str) -> list[tuple[tuple, dict]]:
        return [(a, k) for n, a, k in self.calls if n == name]


REC: Recorder | None = None  # the active recorder (one module per test)


class EnumValue:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self):
        return self.name

    def __eq__(self, other):
        return isinstance(other, EnumValue) and other.name == self.name

    def __hash__(self):
        return hash(self.name)


class StubMeta(type):
    def __getattr__(cls, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        key = REC.check(cls.__name__, name)
        if hasattr(cls, f"_static_{name}"):
            fn = getattr(cls, f"_static_{name}")

            def call(*args, **kwargs):
                REC.calls.append((key, args, kwargs))
                return fn(*args, **kwargs)

            return call
        return EnumValue(key)


class StubObject(metaclass=StubMeta):
    _props_default: ClassVar[dict] = {}

    def __init__(self, *args, **kwargs):
        object.__setattr__(self, "_props", dict(self._props_default))

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        key = REC.check(type(self).__name__, name)
        impl = getattr(self, f"_do_{name}", None)
        if impl is None:
            raise AttributeError(f"the stand-in has no behaviour for documented {key}")

        def call(*args, **kwargs):
            REC.calls.append((key, (self,) + args, kwargs))
            return impl(*args, **kwargs)

        return call

    def set_editor_property(self, name, value):
        key = REC.check(type(self).__name__, f"editor_property:{name}")
        REC.calls.append((key + "=", (self, value), {}))
        self._props[name] = value

    def get_editor_property(self, name):
        REC.check(type(self).__name__, f"editor_property:{name}")
        return self._props.get(name)


# ---------------------------------------------------------------- value types (exact documented signatures)
class Vector(StubObject):
    def __init__(self, x=0.0, y=0.0, z=0.0):
        super().__init__()
        object.__setattr__(self, "x", float(x))
        object.__setattr__(self, "y", float(y))
        object.__setattr__(self, "z", float(z))

    def __repr__(self):
        return f"Vector({self.x}, {self.y}, {self.z})"


class Vector2D(StubObject):
    def __init__(self, x=0.0, y=0.0):
        super().__init__()
        object.__setattr__(self, "x", float(x))
        object.__setattr__(self, "y", float(y))


class Rotator(StubObject):
    def __init__(self, roll=0.0, pitch=0.0, yaw=0.0):
        super().__init__()
        object.__setattr__(self, "roll", float(roll))
        object.__setattr__(self, "pitch", float(pitch))
        object.__setattr__(self, "yaw", float(yaw))


class LinearColor(StubObject):
    def __init__(self, r=0.0, g=0.0, b=0.0, a=1.0):
        super().__init__()
        object.__setattr__(self, "rgba", (float(r), float(g), float(b), float(a)))
        for k, v in zip("rgba", self.rgba):
            object.__setattr__(self, k, v)


class TextureRenderTargetFormat(StubObject):
    pass


class TextureFilter(StubObject):
    pass


class BlendMode(StubObject):
    pass


class ComponentMobility(StubObject):
    pass


class SceneComponent(StubObject):
    _props_default: ClassVar[dict] = {"mobility": EnumValue("ComponentMobility.MOVABLE")}


# ---------------------------------------------------------------- objects
class Texture(StubObject):
    pass


class Texture2D(Texture):
    def __init__(self, data):
        super().__init__()
        object.__setattr__(self, "data", data)


class TextureRenderTarget2D(Texture):
    def __init__(self, w, h, fmt):
        super().__init__()
        object.__setattr__(self, "data", np.zeros((h, w, 4), np.uint8))
        object.__setattr__(self, "fmt", fmt)


class Canvas(StubObject):
    def __init__(self, target):
        super().__init__()
        object.__setattr__(self, "target", target)

    def _do_draw_texture(self, render_texture, screen_position, screen_size, coordinate_position,
                         coordinate_size=None, render_color=None, blend_mode=None, rotation=0.0, pivot_point=None):
        src = render_texture.data
        if src.ndim == 2:  # a gray PNG samples as (v, v, v, 255)
            src = np.stack([src, src, src, np.full_like(src, 255)], -1)
        elif src.shape[2] == 3:
            src = np.concatenate([src, np.full(src.shape[:2] + (1,), 255, src.dtype)], -1)
        t = self.target.data
        ok_1to1 = (screen_size.x, screen_size.y) == (t.shape[1], t.shape[0]) == (src.shape[1], src.shape[0])
        srgb_off = render_texture._props.get("srgb") is False
        nearest = render_texture._props.get("filter") == EnumValue("TextureFilter.TF_NEAREST")
        if ok_1to1 and srgb_off and nearest and blend_mode == EnumValue("BlendMode.BLEND_OPAQUE"):
            t[:] = src
        else:  # what Unreal would do wrong: sRGB decoding / filtering / blending garble the bytes
            t[:] = 0


class World(StubObject):
    pass


class Actor(StubObject):
    _props_default: ClassVar[dict] = {"tags": []}

    def __init__(self, location=None, rotation=None, asset=None, label="Actor"):
        super().__init__()
        for k, v in dict(location=location or Vector(), rotation=rotation or Rotator(), asset=asset,
                         scale=Vector(1, 1, 1), folder="", label=label, components=[]).items():
            object.__setattr__(self, k, v)

    def _do_set_actor_scale3d(self, new_scale3d):
        object.__setattr__(self, "scale", new_scale3d)

    def _do_set_actor_location(self, new_location, sweep, teleport):
        object.__setattr__(self, "location", new_location)
        return True

    def _do_get_actor_location(self):
        return self.location

    def _do_set_folder_path(self, new_folder_path):
        object.__setattr__(self, "folder", str(new_folder_path))

    def _do_set_actor_label(self, new_actor_label, mark_dirty=True):
        object.__setattr__(self, "label", str(new_actor_label))

    def _do_get_actor_label(self):
        return self.label

    def _do_get_component_by_class(self, component_class):
        for c in self.components:
            if isinstance(c, component_class):
                return c
        return None


class StaticMeshActor(Actor):
    pass


class LandscapeProxy(Actor):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        object.__setattr__(self, "heights", None)
        object.__setattr__(self, "weights", {})

    def _do_landscape_import_heightmap_from_render_target(self, render_target, import_height_from_rg_channel=False):
        d = render_target.data.astype(np.uint32)
        if render_target.fmt == EnumValue("TextureRenderTargetFormat.RTF_RGBA8"):
            object.__setattr__(self, "heights", (d[..., 0] << 8 | d[..., 1]).astype(np.uint16))
            return True
        return False

    def _do_landscape_export_heightmap_to_render_target(self, in_render_target, in_export_height_into_rg_channel=False,
                                                         in_export_landscape_proxies=True):
        # into an 8-bit target only as R = high byte, G = low byte (a single-channel height needs >= 16 bits)
        if (self.heights is None or not in_export_height_into_rg_channel
                or in_render_target.fmt != EnumValue("TextureRenderTargetFormat.RTF_RGBA8")):
            return False
        h = self.heights.astype(np.int64) + REC.height_drift  # a test can make Unreal disagree with the file
        d = in_render_target.data
        d[..., 0] = (h >> 8) & 0xFF
        d[..., 1] = h & 0xFF
        return True

    def _do_landscape_import_weightmap_from_render_target(self, render_target, layer_name):
        self.weights[str(layer_name)] = render_target.data[..., 0].copy()
        return True


class Landscape(LandscapeProxy):
    pass


class PCGComponent(StubObject):
    def __init__(self):
        super().__init__()
        object.__setattr__(self, "graph", None)
        object.__setattr__(self, "generated", False)

    def _do_set_graph(self, graph):
        object.__setattr__(self, "graph", graph)

    def _do_generate(self, force=False):
        object.__setattr__(self, "generated", True)


class PCGVolume(Actor):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.components.append(PCGComponent())


class Asset(StubObject):
    def __init__(self, path):
        super().__init__()
        object.__setattr__(self, "path", path)


class StaticMesh(Asset):
    pass


class Material(Asset):
    pass


class AssetImportTask(StubObject):
    _props_default: ClassVar[dict] = {"imported_object_paths": []}


class AssetTools(StubObject):
    def _do_import_asset_tasks(self, import_tasks):
        for t in import_tasks:
            p = t._props
            assert p.get("automated") is True, "an import without automated=True opens dialogs"
            stem = p["filename"].replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]
            # Interchange (UE 5.3's glTF importer) ignores destination_name: the asset is named after the source
            name = stem if REC.interchange else (p.get("destination_name") or stem)
            path = f"{p['destination_path']}/{name}"
            REC.assets.add(path)
            REC.assets.add(path + "_Material")
            # like the glTF importer: a material comes first, then the mesh (Interchange here: nothing listed)
            p["imported_object_paths"] = ([] if REC.interchange
                                          else [f"{path}_Material.{name}_Material", f"{path}.{name}"])


class AssetToolsHelpers(StubObject):
    @staticmethod
    def _static_get_asset_tools():
        return AssetTools()


class EditorAssetLibrary(StubObject):
    @staticmethod
    def _static_does_asset_exist(asset_path):
        return asset_path.split(".")[0] in REC.assets

    @staticmethod
    def _static_load_asset(asset_path):
        p = asset_path.split(".")[0]
        if p not in REC.assets:
            return None
        return Material(p) if p.endswith("_Material") else StaticMesh(p)

    @staticmethod
    def _static_list_assets(directory_path, recursive=True, include_folder=False):
        d = directory_path.rstrip("/") + "/"
        hits = [a for a in sorted(REC.assets) if a.startswith(d) and (recursive or "/" not in a[len(d):])]
        return [f"{a}.{a.rsplit('/', 1)[-1]}" for a in hits]  # object paths, as Unreal lists them


class EditorAssetSubsystem(StubObject):
    def _do_does_asset_exist(self, asset_path):
        return asset_path.split(".")[0] in REC.assets


class RenderingLibrary(StubObject):
    @staticmethod
    def _static_create_render_target2d(world_context_object, width=256, height=256, format=None,
                                       clear_color=None, auto_generate_mip_maps=False):
        assert isinstance(world_context_object, World)
        return TextureRenderTarget2D(int(width), int(height), format)

    @staticmethod
    def _static_import_file_as_texture2d(world_context_object, filename):
        import cv2

        a = cv2.imread(filename, cv2.IMREAD_UNCHANGED)
        if a is None:
            return None
        if a.ndim == 3:
            a = a[:, :, [2, 1, 0, 3]] if a.shape[2] == 4 else a[:, :, ::-1]
        return Texture2D(a)

    @staticmethod
    def _static_read_render_target_raw_pixel(world_context_object, texture_render_target, x, y, normalize=True):
        assert isinstance(world_context_object, World)
        v = texture_render_target.data[int(y), int(x)].astype(float)
        return LinearColor(*(v / 255.0 if normalize else v))

    @staticmethod
    def _static_begin_draw_canvas_to_render_target(world_context_object, texture_render_target):
        return Canvas(texture_render_target), Vector2D(texture_render_target.data.shape[1],
                                                       texture_render_target.data.shape[0]), object()

    @staticmethod
    def _static_end_draw_canvas_to_render_target(world_context_object, context):
        return None


class LevelEditorSubsystem(StubObject):
    def _do_new_level_from_template(self, asset_path, template_asset_path):
        if template_asset_path not in REC.templates:
            return False
        REC.assets.add(asset_path)
        return True

    def _do_load_level(self, asset_path):
        return asset_path in REC.assets

    def _do_save_current_level(self):
        REC.saved += 1
        return True


class EditorActorSubsystem(StubObject):
    def _do_get_all_level_actors(self):
        return list(REC.world_actors)

    def _do_destroy_actor(self, actor_to_destroy):
        REC.world_actors.remove(actor_to_destroy)
        return True

    def _do_spawn_actor_from_object(self, object_to_use, location, rotation=None, transient=False):
        assert isinstance(location, Vector) and isinstance(rotation, Rotator)
        a = StaticMeshActor(location, rotation, asset=object_to_use)
        REC.world_actors.append(a)
        return a

    def _do_spawn_actor_from_class(self, actor_class, location, rotation=None, transient=False):
        a = actor_class(location, rotation)
        REC.world_actors.append(a)
        return a


class UnrealEditorSubsystem(StubObject):
    def _do_get_editor_world(self):
        return World()


CLASSES = {c.__name__: c for c in (
    Vector, Vector2D, Rotator, LinearColor, TextureRenderTargetFormat, TextureFilter, BlendMode, ComponentMobility,
    SceneComponent, Texture, Texture2D,
    TextureRenderTarget2D, Canvas, Actor, StaticMeshActor, LandscapeProxy, Landscape, PCGComponent, PCGVolume,
    AssetImportTask, AssetTools, AssetToolsHelpers, EditorAssetLibrary, RenderingLibrary, LevelEditorSubsystem,
    EditorActorSubsystem, UnrealEditorSubsystem, EditorAssetSubsystem, StaticMesh)}


def make_unreal(templates=("/Game/HoloOcean/Maps/CoastforgeTemplate",), assets=(), landscape=True,
                water=True, interchange=False) -> tuple[types.ModuleType, Recorder]:
    """A fresh stand-in ``unreal`` module and its recorder, with a template level holding a landscape.
    ``interchange``: imports behave like UE 5.3's Interchange glTF importer (see AssetTools)."""
    global REC
    REC = Recorder()
    REC.templates.update(templates)
    REC.assets.update(assets)
    REC.interchange = interchange
    if landscape:
        REC.world_actors.append(Landscape(label="Landscape"))
    if water:  # the HoloOcean template actors DESIGN.md §6 and HoloOcean's create-env page list, by their tags
        for label, tag in (("WaterPlane", "WaterSurface"), ("PostProcessColour", "WaterPPV"),
                           ("PostProcessFog", "WaterPPV"), ("CloudSunny", "Sunny"), ("CloudCloudy", "Cloudy")):
            a = StaticMeshActor(Vector(0, 0, 0), Rotator(), label=label)
            a._props["tags"] = [tag]
            a._props["root_component"] = SceneComponent()  # Movable (SceneComponent's default here)
            REC.world_actors.append(a)
    mod = types.ModuleType("unreal")
    subsystems: dict = {}

    def get_editor_subsystem(cls):
        REC.calls.append(("get_editor_subsystem", (cls,), {}))
        if cls not in subsystems:
            subsystems[cls] = cls()
        return subsystems[cls]

    def module_getattr(name):
        if name in API and name in CLASSES:
            return CLASSES[name]
        if name == "get_editor_subsystem" and name in API:
            return get_editor_subsystem
        REC.violations.append(name)
        raise AttributeError(f"module 'unreal' has no documented UE 5.3 attribute {name!r}")

    mod.__getattr__ = module_getattr  # PEP 562
    return mod, REC
