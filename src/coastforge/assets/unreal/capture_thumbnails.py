"""Unreal Editor (5.3) Python: top-down thumbnails of static meshes for a coastforge asset library.

Run in the editor's Python console (Output Log → Python), with a level open:

    py "<path>/capture_thumbnails.py" --out C:/thumbs                 # the assets selected in the Content Browser
    py "<path>/capture_thumbnails.py" --out C:/thumbs --folder /Game/Boats --category boat

For every static mesh it places the mesh at the origin far from the level's content, then captures it
from straight above with an orthographic SceneCapture2D under the same 3 lightings x 2 backgrounds
as coastforge's own library views (water-like dark, ground-like light), writes
``<out>/<name>/l<k>_<background>.png`` and finally ``<out>/thumbnails.json`` (format
``coastforge.thumbnails/1``: asset paths, bounds in cm, metres per pixel, views). Then, outside Unreal:

    coastforge library build --from-thumbnails C:/thumbs --out my_library

Image orientation matches coastforge's views: image right = +X (the mesh's forward), image up = -Y in
Unreal (= +y in coastforge's right-handed scene frame). Everything the script spawns is deleted again.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import unreal

FORMAT = "coastforge.thumbnails/1"
SIZE_PX = 256
# The same three lightings as coastforge.render.standard_view_lightings(): (azimuth CCW from +x in the
# right-handed scene frame, elevation, sun intensity in lux, fill intensity).
LIGHTINGS = ((200.0, 35.0, 6.0, 1.2), (135.0, 70.0, 8.0, 1.3), (30.0, 50.0, 5.0, 2.0))
BACKGROUNDS = {"water": (0.03, 0.13, 0.22), "ground": (0.50, 0.48, 0.43)}  # linear RGB
STAGE_Z_CM = -100000.0  # far below the level, so its own actors do not show up in the capture
STANDARD_GSD_M = (0.0125, 0.025, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2, 6.4)


def _args(argv):
    ap = argparse.ArgumentParser(prog="capture_thumbnails.py")
    ap.add_argument("--out", required=True, help="Output folder for PNGs and thumbnails.json")
    ap.add_argument("--folder", default=None, help="Content folder to capture (default: the selected assets)")
    ap.add_argument("--category", default=None, help="Category for every captured asset (else guessed later)")
    ap.add_argument("--size", type=int, default=SIZE_PX, help="Thumbnail size in pixels")
    return ap.parse_args(argv)


def _static_meshes(folder):
    if folder:
        paths = unreal.EditorAssetLibrary.list_assets(folder, recursive=True, include_folder=False)
        assets = [unreal.EditorAssetLibrary.load_asset(p) for p in paths]
    else:
        assets = list(unreal.EditorUtilityLibrary.get_selected_assets())
    return [a for a in assets if isinstance(a, unreal.StaticMesh)]


def _gsd_for(extent_cm, size_px):
    """Finest standard metres-per-pixel at which the footprint (and a shadow margin) fits the image."""
    ex, ey, ez = extent_cm
    reach_m = math.hypot(2 * ex, 2 * ey) / 100.0 + 0.6 * min(2 * ez, 4 * max(ex, ey)) / 100.0
    for g in STANDARD_GSD_M:
        if reach_m / g <= 0.9 * size_px:
            return g
    return STANDARD_GSD_M[-1]


def _sun_rotation(azimuth_deg, elevation_deg):
    # The light shines along its forward (+X) axis: pitch down by the elevation, and point away from the
    # sun's azimuth. Unreal's yaw is clockwise seen from above (left-handed), hence the minus sign.
    return unreal.Rotator(roll=0.0, pitch=-elevation_deg, yaw=-(azimuth_deg + 180.0))


def main(argv=None):
    args = _args(sys.argv[1:] if argv is None else argv)
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    meshes = _static_meshes(args.folder)
    if not meshes:
        unreal.log_error("capture_thumbnails: no static meshes (select some in the Content Browser or pass --folder)")
        return 1
    actors = unreal.get_editor_subsystem(unreal.EditorActorSubsystem)
    world = unreal.get_editor_subsystem(unreal.UnrealEditorSubsystem).get_editor_world()
    spawned = []

    def spawn(cls, loc, rot=None):
        a = actors.spawn_actor_from_class(cls, loc, rot or unreal.Rotator(0.0, 0.0, 0.0))
        spawned.append(a)
        return a

    origin = unreal.Vector(0.0, 0.0, STAGE_Z_CM)
    # background plane with the engine's BasicShapeMaterial (it has a "Color" vector parameter)
    plane_mesh = unreal.EditorAssetLibrary.load_asset("/Engine/BasicShapes/Plane.Plane")
    base_mat = unreal.EditorAssetLibrary.load_asset("/Engine/BasicShapes/BasicShapeMaterial.BasicShapeMaterial")
    plane = spawn(unreal.StaticMeshActor, origin)
    plane_comp = plane.static_mesh_component
    plane_comp.set_static_mesh(plane_mesh)
    plane.set_actor_scale3d(unreal.Vector(2000.0, 2000.0, 1.0))
    bg_mid = plane_comp.create_dynamic_material_instance(0, base_mat)
    sun = spawn(unreal.DirectionalLight, origin)
    fill = spawn(unreal.DirectionalLight, origin, unreal.Rotator(roll=0.0, pitch=-90.0, yaw=0.0))
    cap = spawn(unreal.SceneCapture2D, origin)
    comp = cap.capture_component2d
    comp.set_editor_property("projection_type", unreal.CameraProjectionMode.ORTHOGRAPHIC)
    comp.set_editor_property("capture_source", unreal.SceneCaptureSource.SCS_FINAL_COLOR_LDR)
    comp.set_editor_property("capture_every_frame", False)
    comp.set_editor_property("capture_on_movement", False)
    rt = unreal.RenderingLibrary.create_render_target2d(world, args.size, args.size,
                                                        unreal.TextureRenderTargetFormat.RTF_RGBA8)
    comp.set_editor_property("texture_target", rt)
    holder = spawn(unreal.StaticMeshActor, origin)
    entries = []
    try:
        for mesh in meshes:
            name = mesh.get_name()
            path = mesh.get_path_name()
            bounds = mesh.get_bounds()
            c, e = bounds.origin, bounds.box_extent
            gsd = _gsd_for((e.x, e.y, e.z), args.size)
            holder.static_mesh_component.set_static_mesh(mesh)
            # footprint centre over the origin, lowest point on the background plane
            holder.set_actor_location(unreal.Vector(-c.x, -c.y, STAGE_Z_CM - (c.z - e.z) + 1.0), False, False)
            top = STAGE_Z_CM + 2 * e.z + 500.0
            # looking straight down; yaw -90 puts +X at image right and -Y (scene +y) at image up
            cap.set_actor_location(unreal.Vector(0.0, 0.0, top), False, False)
            cap.set_actor_rotation(unreal.Rotator(roll=0.0, pitch=-90.0, yaw=-90.0), False)
            comp.set_editor_property("ortho_width", gsd * 100.0 * args.size)
            folder = os.path.join(out, name)
            os.makedirs(folder, exist_ok=True)
            views = []
            for bg, colour in BACKGROUNDS.items():
                bg_mid.set_vector_parameter_value("Color", unreal.LinearColor(colour[0], colour[1], colour[2], 1.0))
                for k, (az, el, lux, fill_lux) in enumerate(LIGHTINGS):
                    sun.set_actor_rotation(_sun_rotation(az, el), False)
                    sun.light_component.set_intensity(lux)
                    fill.light_component.set_intensity(fill_lux)
                    comp.capture_scene()
                    fname = f"l{k}_{bg}"
                    unreal.RenderingLibrary.export_render_target(world, rt, folder, fname)
                    # export_render_target writes <fname>.png for 8-bit targets; normalise the extension
                    if not os.path.isfile(os.path.join(folder, fname + ".png")) and os.path.isfile(
                            os.path.join(folder, fname)):
                        os.replace(os.path.join(folder, fname), os.path.join(folder, fname + ".png"))
                    views.append({"file": f"{name}/{fname}.png", "lighting": k, "background": bg})
            entries.append({
                "name": name, "asset_path": path, "category": args.category, "tags": [],
                "bounds_cm": {"origin": [c.x, c.y, c.z], "box_extent": [e.x, e.y, e.z]},
                "gsd_m": gsd, "views": views,
            })
            unreal.log(f"capture_thumbnails: {path} ({2 * e.x / 100:.2f} x {2 * e.y / 100:.2f} x "
                       f"{2 * e.z / 100:.2f} m) at {gsd} m/px")
    finally:
        for a in spawned:
            actors.destroy_actor(a)
    doc = {"format": FORMAT, "generator": "coastforge capture_thumbnails.py (Unreal Editor)", "size_px": args.size,
           "lightings": len(LIGHTINGS), "backgrounds": list(BACKGROUNDS), "assets": entries}
    tmp = os.path.join(out, "thumbnails.json.tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1)
    os.replace(tmp, os.path.join(out, "thumbnails.json"))
    unreal.log(f"capture_thumbnails: {len(entries)} assets written to {out}; now run: "
               f"coastforge library build --from-thumbnails {out} --out <library>")
    return 0


if __name__ == "__main__":
    main()
