"""The generated scene rendered from above, and the GLB of the 3D preview."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..scene import Scene
from .inputs import ReportAssets

TOP_MAX_PX = 768  # the generated scene rendered from above (shown at half the page width; costs per pixel)


def top_gsd(gsd_m: float, extent_m) -> float:
    """The metres per pixel of the report's render from above. It is shown beside the input at half the page
    width (~550 px; ``TOP_MAX_PX`` leaves room to enlarge it), and the procedural terrain costs per pixel."""
    return max(float(gsd_m), max(float(v) for v in extent_m) / TOP_MAX_PX)


def render_top(scene: Scene, assets: ReportAssets, terrain=None) -> np.ndarray | None:
    try:
        from ..render import render_scene
    except ImportError:
        return None
    gsd = top_gsd(scene.gsd_m, scene.extent_m)
    cache: dict = {}

    def mesh_for(aid):
        if aid not in cache:
            cache[aid] = assets.mesh(aid)
        return cache[aid]

    try:
        return render_scene(scene, mesh_for, gsd, seed=scene.seed, terrain=terrain)
    except Exception:  # noqa: BLE001 - no top render (e.g. a missing mesh) rather than no report
        return None


PREVIEW_MAX_BYTES = 4_500_000  # an exported GLB bigger than this is replaced by a lighter preview build
PREVIEW_VERTICES = 30_000
PREVIEW_TEXTURE_PX = 1024


def glb_bytes(scene: Scene, scene_dir: Path, assets: ReportAssets,
               cleaned: np.ndarray | None = None) -> tuple[bytes | None, str]:
    """The GLB shown in the 3D view: the exported one when small enough, else one built with a lighter
    terrain (fewer vertices, smaller texture) so that the page stays light and loads fast."""
    d = scene_dir / "gltf"
    files = sorted(d.glob("*.glb")) if d.is_dir() else []
    if files and files[0].stat().st_size <= PREVIEW_MAX_BYTES:
        return files[0].read_bytes(), str(files[0].relative_to(scene_dir))
    why = (f"a lighter preview of {files[0].relative_to(scene_dir)} ({files[0].stat().st_size / 1e6:.1f} MB)"
           if files else "built for the report (no gltf export in the folder)")
    try:
        from ..config import ExportConfig
        from ..export import DefaultResolver, run_exporter

        cfg = ExportConfig(gltf_max_vertices=PREVIEW_VERTICES, texture_max_px=PREVIEW_TEXTURE_PX)
        resolver = DefaultResolver(library=assets.lib, scene_dir=scene_dir, texture=cleaned)
        built = run_exporter("gltf", scene, resolver, cfg)
        for name, data in built.items():
            if name.endswith(".glb"):
                return data, why
    except Exception:  # noqa: BLE001 - no 3D preview rather than no report
        pass
    return None, ""
