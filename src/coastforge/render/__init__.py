"""Fast orthographic top-down renderer: a believable aerial photograph of a scene.

Modules: ``topdown`` (lighting, the terrain layer, compositing, whole scenes and single-mesh views),
``terrain`` (procedural terrain and water shading), ``objects`` (meshes ray-cast into sprites,
instancing, shadows).
"""

from .objects import ray_backend
from .topdown import (F32, MAX_PIXELS, Lighting, MeshInstance, TerrainLayer, kit_mesh_lookup, random_lighting,
                      render_mesh_view, render_scene, render_scene_file, render_terrain_layer, render_topdown,
                      scene_terrain_layer, standard_view_lightings)

__all__ = ["F32", "MAX_PIXELS", "Lighting", "MeshInstance", "TerrainLayer", "kit_mesh_lookup", "random_lighting",
           "ray_backend", "render_mesh_view", "render_scene", "render_scene_file", "render_terrain_layer",
           "render_topdown", "scene_terrain_layer", "standard_view_lightings"]
