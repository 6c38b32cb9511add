"""What the report reads besides the scene: the input image, detections.json, the terrain stage's
cross-sections, the matching decisions of each object and the scene's assets."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..scene import Scene, SceneObject


def read_rgb(path: Path) -> np.ndarray | None:
    import cv2

    a = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return None if a is None else a[:, :, ::-1].copy()


def input_image(scene: Scene, scene_dir: Path) -> tuple[np.ndarray | None, str]:
    """The input image (from provenance, else image.png beside the scene) and where it came from."""
    src = (scene.provenance.get("input") or {}).get("image")
    cands = []
    if src:
        p = Path(src)
        cands += [p] if p.is_absolute() else [p, scene_dir / p]
    for im in scene.provenance.get("images") or []:  # a synth truth folder: its rendered images
        if isinstance(im, dict) and im.get("path"):
            cands.append(scene_dir / str(im["path"]))
    cands.append(scene_dir / "image.png")
    for c in cands:
        if c.is_file():
            a = read_rgb(c)
            if a is not None:
                return a, str(c)
    return None, ""


def read_detections(scene_dir: Path) -> list[dict]:
    p = scene_dir / "detections.json"
    if not p.is_file():
        return []
    try:
        return list(json.loads(p.read_text()).get("detections", []))
    except (ValueError, AttributeError):
        return []


def match_objects_to_decisions(objects: list[SceneObject], matches: list[dict]) -> dict[str, dict]:
    """Object id → its entry of ``provenance["matches"]``.

    An explicit link wins (``attrs["match"]``: the decision's detection ``index``); otherwise objects made
    from detections are paired with the decisions in order (generate places them in decision order), and
    an object whose asset disagrees takes the first unused decision with its asset and the closest yaw."""
    by_det = {m.get("index"): m for m in matches if isinstance(m, dict)}
    out: dict[str, dict] = {}
    used: set[int] = set()
    rest = []
    for o in objects:
        k = o.attrs.get("match")
        m = by_det.get(k) if isinstance(k, int) else None
        if m is not None and m.get("asset_id") == o.asset_id:
            out[o.id] = m
            used.add(id(m))
        elif o.source == "detection":
            rest.append(o)
    free = [m for m in matches if isinstance(m, dict) and id(m) not in used]
    j = 0
    for o in rest:
        if j < len(free) and free[j].get("asset_id") == o.asset_id and id(free[j]) not in used:
            m = free[j]
            j += 1
        else:
            same = [m for m in free if id(m) not in used and m.get("asset_id") == o.asset_id]
            if not same:
                continue
            m = min(same, key=lambda m: abs(((float(m.get("yaw_deg", 0)) - o.yaw_deg + 180) % 360) - 180))
        out[o.id] = m
        used.add(id(m))
    return out


def library_config(provenance: dict):
    """The scene's ``config.library`` (the defaults when it has none or one this version cannot read)."""
    from ..config import Config, LibraryConfig, apply_settings
    from ..errors import ConfigError

    given = (provenance.get("config") or {}).get("library") or {}
    try:
        return apply_settings(Config(), {"library": given}).library
    except ConfigError:
        return LibraryConfig()


class ReportAssets:
    """Meshes and top views of the scene's assets: its library when it can be loaded, else the starter kit."""

    def __init__(self, scene: Scene, library=None):
        self.lib = library
        self._views: dict = {}
        if library is not None:  # the caller's (generate's), already loaded
            return
        lib_path = scene.provenance.get("library")
        try:
            from ..assets import library as lib_mod

            if lib_path and lib_path not in ("starter-kit", "kit") and Path(lib_path).is_dir():
                self.lib = lib_mod.Library.load(lib_path)
            else:  # the starter kit as the run built it (its config.library)
                self.lib = lib_mod.default_library(library_config(scene.provenance))
        except Exception:  # noqa: BLE001 - the report still renders without asset pictures
            self.lib = None
        self._views: dict = {}

    def mesh(self, asset_id: str):
        if self.lib is not None:
            try:
                return self.lib.mesh(asset_id)
            except Exception:  # noqa: BLE001 - fall back to the kit below
                pass
        from ..assets.kit import load_kit_mesh

        return load_kit_mesh(asset_id)

    def view(self, asset_id: str, background: str) -> np.ndarray | None:
        key = (asset_id, background)
        if key not in self._views:
            v = None
            if self.lib is not None:
                try:
                    from ..matching import asset_top_view

                    v = asset_top_view(self.lib, asset_id, background)[0]
                except Exception:  # noqa: BLE001 - an asset without a view only loses its thumbnail
                    v = None
            self._views[key] = v
        return self._views[key]


def read_cross_sections(scene_dir: Path) -> list[dict]:
    p = scene_dir / "terrain_outputs" / "cross_section.json"
    if not p.is_file():
        return []
    try:
        secs = json.loads(p.read_text()).get("sections", [])
        return [s for s in secs
                if len(s.get("distance_m", [])) >= 2 and len(s["distance_m"]) == len(s["height_m"])]
    except (ValueError, AttributeError, KeyError, TypeError):
        return []
