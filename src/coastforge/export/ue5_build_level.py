"""Build a HoloOcean level in Unreal Engine 5.3 from ``level.json`` beside this script (written by coastforge).

Inside the Unreal Editor (Python Editor Script Plugin enabled), Output Log, "Python" mode:
    py "C:/path/to/ue5/build_level.py"
or headless:
    UnrealEditor-Cmd.exe Project.uproject -run=pythonscript -script="C:/path/to/ue5/build_level.py"
Preview every action without Unreal (plain Python 3):
    python build_level.py --dry-run
Options: --dry-run, --spec FILE (another level.json), --skip-landscape (after a manual landscape import).

Every scene value (names, paths, positions, sizes) is read from level.json; this file holds none, so a
name containing quotes or newlines is only ever data. Re-running replaces the actors a previous run made
(they carry the run tag from level.json) and re-uses meshes it imported.
"""

import json
import os
import sys

FORMAT = "coastforge.ue5/1"
HERE = os.path.dirname(os.path.abspath(__file__))
REQUIRED = ("level", "landscape", "weightmaps", "assets", "actors", "pcg", "run_tag", "content_path")


class BuildStopped(Exception):
    """A step cannot be done automatically; the message says what to do by hand."""


def load_spec(path):
    with open(path, encoding="utf-8") as fh:
        spec = json.load(fh)
    if not isinstance(spec, dict) or spec.get("format") != FORMAT:
        raise BuildStopped("%s is not a coastforge level file (format %r, expected %r)"
                           % (path, spec.get("format") if isinstance(spec, dict) else None, FORMAT))
    missing = [k for k in REQUIRED if k not in spec]
    if missing:
        raise BuildStopped("%s lacks the keys %s; re-export it with `coastforge export --format ue5`" % (path, missing))
    return spec


def manual_landscape_settings(spec):
    """The exact settings for Landscape mode → Manage → Import from File (UE 5.3)."""
    ls = spec["landscape"]
    lines = [
        "Manual landscape import (Landscape mode > Manage > Import from File, Unreal Engine 5.3):",
        "  Heightmap File:            %s" % os.path.join(spec["_dir"], ls["heightmap_png"]),
        "                             (or the raw file %s, 16-bit little-endian)" % ls["heightmap_r16"],
        "  Resolution:                %d x %d" % (ls["size"], ls["size"]),
        "  Section Size:              %d x %d quads" % (ls["quads_per_section"], ls["quads_per_section"]),
        "  Sections Per Component:    %d x %d" % (ls["sections_per_component"], ls["sections_per_component"]),
        "  Number of Components:      %d x %d" % (ls["components"], ls["components"]),
        "  Location (cm):             X=%.3f Y=%.3f Z=%.3f" % tuple(ls["location"]),
        "  Scale:                     X=%.6f Y=%.6f Z=%.6f" % tuple(ls["scale"]),
        "  Water level:               Z = 0 cm (heightmap value %d)" % ls["water_height_value"],
        "  Paint layers (weight-blended, 8-bit maps, same resolution):",
    ]
    for w in spec["weightmaps"]:
        lines.append("    %-12s %s" % (w["layer"], os.path.join(spec["_dir"], w["file"])))
    lines.append("Then re-run this script with --skip-landscape.")
    return "\n".join(lines)


class Builder:
    """Runs (or, with dry_run, only prints) every editor action of the build."""

    def __init__(self, spec, unreal=None, dry_run=False, skip_landscape=False, log=print):
        self.spec = spec
        self.ue = unreal
        self.dry = dry_run
        self.skip_landscape = skip_landscape
        self.log = log
        self.world = None
        self.loaded = {}

    def act(self, text, fn=None):
        self.log(("[dry-run] " if self.dry else "") + text)
        if self.dry or fn is None:
            return None
        return fn()

    def path(self, rel):
        return os.path.join(self.spec["_dir"], rel)

    # ---------------------------------------------------------------- steps
    def run(self):
        spec = self.spec
        ue = self.ue
        self.log("coastforge: building level %r (%d actors) for Unreal Engine %s"
                 % (spec["level"]["name"], len(spec["actors"]), spec.get("unreal_version", "5.3")))
        les = None if self.dry else ue.get_editor_subsystem(ue.LevelEditorSubsystem)
        eas = None if self.dry else ue.get_editor_subsystem(ue.EditorActorSubsystem)
        self.open_level(les)
        if not self.dry:
            self.world = ue.get_editor_subsystem(ue.UnrealEditorSubsystem).get_editor_world()
        self.remove_previous(eas)
        self.check_water(eas)
        if self.skip_landscape:
            self.log("landscape: skipped (--skip-landscape)")
            # a landscape imported by hand is checked all the same: manual imports go wrong most often
            lands = [] if self.dry else [a for a in eas.get_all_level_actors() if isinstance(a, ue.LandscapeProxy)]
            if self.dry or lands:
                self.verify_heights(lands[0] if lands else None)
        else:
            self.landscape(eas)
        self.spawn_actors(eas)
        self.pcg(eas)
        self.act("save the level %s" % spec["level"]["asset_path"], lambda: les.save_current_level())
        self.log("coastforge: done")

    def open_level(self, les):
        lv = self.spec["level"]
        # the Asset Registry (EditorAssetSubsystem) also knows levels; EditorAssetLibrary excludes them
        if not self.dry and self.ue.get_editor_subsystem(self.ue.EditorAssetSubsystem).does_asset_exist(
                lv["asset_path"]):
            ok = self.act("load the existing level %s (re-run)" % lv["asset_path"], lambda: les.load_level(lv["asset_path"]))
        else:
            ok = self.act("create the level %s from the template %s" % (lv["asset_path"], lv["template"]),
                          lambda: les.new_level_from_template(lv["asset_path"], lv["template"]))
        if not self.dry and not ok:
            raise BuildStopped(
                "could not create %s from the template level %s. Make the template first: a HoloOcean base level "
                "holding a landscape of %d x %d vertices (see README.md), then set it with "
                "`coastforge export --set export.template_level=/Game/...`"
                % (lv["asset_path"], lv["template"], self.spec["landscape"]["size"], self.spec["landscape"]["size"]))

    @staticmethod
    def _tags(actor):
        return [str(t) for t in (actor.get_editor_property("tags") or [])]

    def remove_previous(self, eas):
        tag = self.spec["run_tag"]
        if self.dry:
            self.act("destroy every actor tagged %r from a previous run" % tag)
            return
        for actor in list(eas.get_all_level_actors()):
            if tag in self._tags(actor):
                self.act("destroy %s (made by a previous run)" % actor.get_actor_label(),
                         lambda a=actor: eas.destroy_actor(a))

    def check_water(self, eas):
        if self.dry:
            self.act("check the template's HoloOcean actors: WaterSurface plane at Z = 0, WaterPPV, Sunny, Cloudy")
            return
        planes = [a for a in eas.get_all_level_actors() if "WaterSurface" in self._tags(a)]
        if not planes:
            self.log("WARNING: no actor tagged WaterSurface: HoloOcean needs a Movable water plane at Z = 0 "
                     "(custom-depth stencil 9); add it to the template level")
        for p in planes:
            z = p.get_actor_location().z
            if abs(z) > 0.5:
                self.log("WARNING: the WaterSurface plane is at Z = %.1f cm; coastforge's heights assume 0" % z)
            # HoloOcean's tides move the plane: its docs ask for a Movable plane (create-env, "Water Plane")
            root = p.get_editor_property("root_component")
            if root is not None and root.get_editor_property("mobility") != self.ue.ComponentMobility.MOVABLE:
                self.log("WARNING: the WaterSurface plane %s is not Movable; HoloOcean's tides need it Movable"
                         % p.get_actor_label())
        tags = {}
        for a in eas.get_all_level_actors():
            for t in set(self._tags(a)):
                tags[t] = tags.get(t, 0) + 1
        for tag, what in (("WaterPPV", "the underwater post-process volumes"),
                          ("Sunny", "the sunny cloud of BP_Weather_Manager"),
                          ("Cloudy", "the cloudy cloud of BP_Weather_Manager")):
            if tag not in tags:
                self.log("WARNING: no actor tagged %s (%s); HoloOcean levels expect it in the template" % (tag, what))
        if tags.get("WaterPPV") == 1:
            self.log("WARNING: one post-process volume tagged WaterPPV; HoloOcean's levels have two (water colour, "
                     "and water fog with MM_Fog_Water), both tagged WaterPPV")

    def _render_target(self, ue, size):
        return ue.RenderingLibrary.create_render_target2d(
            self.world, size, size, ue.TextureRenderTargetFormat.RTF_RGBA8, ue.LinearColor(0.0, 0.0, 0.0, 1.0), False)

    def _draw_file_to_target(self, ue, filename, target, size):
        """Load an 8-bit PNG as a transient texture and copy it 1:1 (no sRGB, no filtering) into target."""
        tex = ue.RenderingLibrary.import_file_as_texture2d(self.world, filename)
        if tex is None:
            raise BuildStopped("Unreal could not read %s" % filename)
        tex.set_editor_property("srgb", False)
        tex.set_editor_property("filter", ue.TextureFilter.TF_NEAREST)
        canvas, _size, ctx = ue.RenderingLibrary.begin_draw_canvas_to_render_target(self.world, target)
        canvas.draw_texture(tex, ue.Vector2D(0.0, 0.0), ue.Vector2D(float(size), float(size)), ue.Vector2D(0.0, 0.0),
                            ue.Vector2D(1.0, 1.0), ue.LinearColor(1.0, 1.0, 1.0, 1.0), ue.BlendMode.BLEND_OPAQUE)
        ue.RenderingLibrary.end_draw_canvas_to_render_target(self.world, ctx)

    def landscape(self, eas):
        ls = self.spec["landscape"]
        ue = self.ue
        n = ls["size"]
        if self.dry:
            lands = [None]
        else:
            lands = [a for a in eas.get_all_level_actors() if isinstance(a, ue.LandscapeProxy)]
        if not lands:
            raise BuildStopped("the level has no landscape; the template must hold one of %d x %d vertices.\n%s"
                               % (n, n, manual_landscape_settings(self.spec)))
        land = lands[0]
        loc, sc = ls["location"], ls["scale"]
        self.act("landscape: location (%.2f, %.2f, %.2f) cm, scale (%.6f, %.6f, %.6f)" % (tuple(loc) + tuple(sc)),
                 lambda: (land.set_actor_location(ue.Vector(*loc), False, False),
                          land.set_actor_scale3d(ue.Vector(*sc))))

        def push_heights():
            rt = self._render_target(ue, n)
            self._draw_file_to_target(ue, self.path(ls["heightmap_rg8"]), rt, n)
            return land.landscape_import_heightmap_from_render_target(rt, True)

        ok = self.act("landscape: import %d x %d heights from %s through an RGBA8 render target (R = high byte, "
                      "G = low byte)" % (n, n, ls["heightmap_rg8"]), push_heights)
        if not self.dry and not ok:
            raise BuildStopped("Unreal refused the render-target height import.\n" + manual_landscape_settings(self.spec))
        self.verify_heights(land)
        for w in self.spec["weightmaps"]:
            def push_weights(w=w):
                rt = self._render_target(ue, n)
                self._draw_file_to_target(ue, self.path(w["file"]), rt, n)
                return land.landscape_import_weightmap_from_render_target(rt, w["layer"])

            ok = self.act("landscape: paint layer %r from %s" % (w["layer"], w["file"]), push_weights)
            if not self.dry and not ok:
                raise BuildStopped("Unreal refused the weight map of layer %r (does the landscape material have a "
                                   "paint layer of that name with a layer info?).\n%s"
                                   % (w["layer"], manual_landscape_settings(self.spec)))

    def verify_heights(self, land):
        """Read the landscape's heights back (exported into an RGBA8 render target, R = high byte, G = low byte,
        the mirror of the import) at the sample vertices of level.json, print the largest error and stop when it
        exceeds the tolerance: a landscape that silently differs from the heightmap is worse than none."""
        ls = self.spec["landscape"]
        chk = ls.get("height_check")
        if not chk:
            return
        pts = chk["points"]
        if self.dry:
            self.act("landscape: read the heights back at %d vertices and compare them with the heightmap "
                     "(stop beyond %.2f cm)" % (len(pts), chk["tolerance_cm"]))
            return
        ue = self.ue
        n = ls["size"]
        rt = self._render_target(ue, n)
        if not land.landscape_export_heightmap_to_render_target(rt, True, True):
            raise BuildStopped("Unreal could not export the landscape heights to a render target to check them; "
                               "check the landscape by hand against %s" % ls["heightmap_png"])
        step = ls["height_step_cm"]
        worst = (-1.0, None, None, None)
        for c, r, want in pts:
            px = ue.RenderingLibrary.read_render_target_raw_pixel(self.world, rt, c, r)  # normalised to 0..1
            got = int(round(px.r * 255.0)) * 256 + int(round(px.g * 255.0))
            err = abs(got - want) * step
            if err > worst[0]:
                worst = (err, (c, r), got, want)
        err, (c, r), got, want = worst
        self.log("landscape: height check at %d vertices: max error %.3f cm (tolerance %.3f cm)"
                 % (len(pts), err, chk["tolerance_cm"]))
        if err > chk["tolerance_cm"]:
            raise BuildStopped("the landscape's heights differ from the heightmap: max error %.2f cm at vertex "
                               "(column %d, row %d): Unreal holds %d, the heightmap %d. Import it by hand:\n%s"
                               % (err, c, r, got, want, manual_landscape_settings(self.spec)))

    def find_imported(self, dest, name):
        """The static mesh an earlier import left in ``dest``, or None. Interchange (UE 5.3's default for glTF)
        ignores ``AssetImportTask.destination_name`` and names assets after the source, so besides the
        expected path the folder's assets are matched by name (the bundle's GLB, its mesh and node all carry
        the import name)."""
        ue = self.ue
        lib = ue.EditorAssetLibrary
        if lib.does_asset_exist(dest + "/" + name):
            obj = lib.load_asset(dest + "/" + name)
            if isinstance(obj, ue.StaticMesh):
                return obj
        for path in lib.list_assets(dest, False, False) or []:
            if str(path).rsplit("/", 1)[-1].split(".", 1)[0] == name:
                obj = lib.load_asset(str(path))
                if isinstance(obj, ue.StaticMesh):
                    return obj
        return None

    def asset(self, entry):
        """The Unreal asset of one library asset: its ue_path, or its GLB imported (once) into the project."""
        key = entry["asset_id"]
        if key in self.loaded:
            return self.loaded[key]
        ue = self.ue
        if entry.get("ue_path"):
            obj = self.act("load asset %s" % entry["ue_path"],
                           lambda: ue.EditorAssetLibrary.load_asset(entry["ue_path"]))
        else:
            dest = entry["import_path"]
            target = dest + "/" + entry["import_name"]

            def do_import():
                found = self.find_imported(dest, entry["import_name"])
                if found is not None:
                    return found
                task = ue.AssetImportTask()
                task.set_editor_property("filename", self.path(entry["glb"]))
                task.set_editor_property("destination_path", dest)
                task.set_editor_property("destination_name", entry["import_name"])
                task.set_editor_property("automated", True)
                task.set_editor_property("replace_existing", True)
                task.set_editor_property("save", True)
                ue.AssetToolsHelpers.get_asset_tools().import_asset_tasks([task])
                # a glTF import also makes materials; keep the static mesh
                for p in task.get_editor_property("imported_object_paths") or []:
                    obj = ue.EditorAssetLibrary.load_asset(p)
                    if isinstance(obj, ue.StaticMesh):
                        return obj
                found = self.find_imported(dest, entry["import_name"])  # an importer that lists nothing
                if found is not None:
                    return found
                raise BuildStopped("importing %s produced no static mesh; import it by hand into %s"
                                   % (self.path(entry["glb"]), dest))

            obj = self.act("import %s as %s (AssetImportTask)" % (entry["glb"], target), do_import)
        self.loaded[key] = obj
        return obj

    def spawn_actors(self, eas):
        ue = self.ue
        entries = {a["asset_id"]: a for a in self.spec["assets"]}
        for a in self.spec["actors"]:
            asset = self.asset(entries[a["asset_id"]])
            x, y, z = a["location"]
            r = a["rotation"]

            def spawn(a=a, asset=asset, x=x, y=y, z=z, r=r):
                actor = eas.spawn_actor_from_object(asset, ue.Vector(x, y, z),
                                                    ue.Rotator(roll=r["roll"], pitch=r["pitch"], yaw=r["yaw"]))
                if actor is None:
                    raise BuildStopped("Unreal could not spawn %r from asset %r" % (a["label"], a["asset_id"]))
                actor.set_actor_scale3d(ue.Vector(*a["scale"]))
                actor.set_folder_path(a["folder"])
                actor.set_actor_label(a["label"])
                # the HoloOcean label first (ATagger::TagActor reads Tags[0]), then Float, then the run tag
                actor.set_editor_property("tags", list(a.get("tags") or [self.spec["run_tag"],
                                                                         "coastforge:" + a["category"]]))
                return actor

            self.act("spawn %r (%s) at (%.1f, %.1f, %.1f) cm, yaw %.2f, scale %s, folder %s, tags %s"
                     % (a["label"], a["asset_id"], x, y, z, r["yaw"], a["scale"], a["folder"], a.get("tags")), spawn)
        if self.spec.get("vegetation_left_to_pcg"):
            self.log("vegetation: %d instances left to the PCG masks (more than max_vegetation_actors)"
                     % self.spec["vegetation_left_to_pcg"])

    def pcg(self, eas):
        pcg = self.spec["pcg"]
        ue = self.ue
        if not pcg.get("graph"):
            self.log("PCG: no graph given (export.pcg_graph); the biome masks are in %s for your own graph"
                     % ", ".join(m["file"] for m in pcg["masks"]))
            return
        vol = pcg["volume"]

        def make_volume():
            graph = ue.EditorAssetLibrary.load_asset(pcg["graph"])
            if graph is None:
                raise BuildStopped("PCG graph %s not found" % pcg["graph"])
            actor = eas.spawn_actor_from_class(ue.PCGVolume, ue.Vector(*vol["location"]), ue.Rotator(0.0, 0.0, 0.0))
            actor.set_actor_scale3d(ue.Vector(*vol["scale"]))
            actor.set_folder_path(pcg["folder"])
            actor.set_actor_label(pcg["label"])
            actor.set_editor_property("tags", [self.spec["run_tag"], "coastforge:pcg"])
            comp = actor.get_component_by_class(ue.PCGComponent)
            comp.set_graph(graph)
            comp.generate(True)
            return actor

        self.act("PCG: volume over the level with graph %s, generate" % pcg["graph"], make_volume)
        for m in pcg["masks"]:
            def import_mask(m=m):
                task = ue.AssetImportTask()
                task.set_editor_property("filename", self.path(m["file"]))
                task.set_editor_property("destination_path", pcg["mask_path"])
                task.set_editor_property("automated", True)
                task.set_editor_property("replace_existing", True)
                task.set_editor_property("save", True)
                ue.AssetToolsHelpers.get_asset_tools().import_asset_tasks([task])

            self.act("PCG: import biome mask %s into %s" % (m["file"], pcg["mask_path"]), import_mask)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    dry = "--dry-run" in argv
    skip = "--skip-landscape" in argv
    spec_path = os.path.join(HERE, "level.json")
    if "--spec" in argv:
        i = argv.index("--spec")
        if i + 1 >= len(argv):
            print("--spec needs a file")
            return 2
        spec_path = argv[i + 1]
    try:
        spec = load_spec(spec_path)
        spec["_dir"] = os.path.dirname(os.path.abspath(spec_path))
        unreal = None
        if not dry:
            try:
                import unreal  # only inside the Unreal Editor
            except ImportError:
                print("This script runs inside the Unreal Editor (Python Editor Script Plugin). "
                      "Use --dry-run to preview it here.")
                return 2
        Builder(spec, unreal, dry_run=dry, skip_landscape=skip).run()
    except BuildStopped as exc:
        print("coastforge: STOPPED: %s" % exc)
        return 1
    return 0


if __name__ == "__main__":
    rc = main()
    if rc and "unreal" not in sys.modules:  # never sys.exit inside the editor: it would close it
        sys.exit(rc)
