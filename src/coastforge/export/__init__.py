"""Exporters: each target is a pure function ``(scene, assets, config) -> {relative path: bytes}``.

``export_scene`` is the one writer: it resolves the assets, runs the exporters, refuses to replace
existing export files without ``overwrite`` (checked for every format before anything is written)
and writes each file atomically under ``DIR/<format>/``, and the scene's label table ``DIR/instances.json``
(``labels.instances_table``) that every format's labels come from.

Assets reach the exporters through an ``AssetResolver`` (meshes in the scene frame: metres, z up,
forward +x, face colours). The default one reads the asset library when given, then the starter kit.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable
from collections.abc import Callable, Iterable

import numpy as np

from ..errors import InputError, LibraryError, OutputExistsError
from .labels import instances_json

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from ..config import ExportConfig
    from ..scene import Scene

FORMATS: dict[str, str] = {
    "ue5": "Unreal Engine 5.3 level bundle (heightmap, weight maps, placements, build_level.py)",
    "holoocean": "HoloOcean scenario JSON and config.json world entry",
    "gltf": "binary glTF (GLB), y-up",
    "usd": "USD stage (z-up, metres) with per-asset USD files",
    "sdf": "Gazebo / Project DAVE SDF world with heightmap and OBJ meshes",
    "ue5_tiles": "Unreal Engine 5 World-Partition landscape: heightmap and weight-map tiles named _x<i>_y<j>",
}

INSTANCES_FILE = "instances.json"  # the scene's label table (DESIGN.md §3), beside scene.json
# texture files looked for in a scene folder, best first (the cleaned image has boats removed)
TEXTURE_NAMES = ("cleaned.png", "cleaned.jpg", "image.png", "image.jpg", "input.png", "input.jpg")


@runtime_checkable
class AssetResolver(Protocol):
    """What exporters may ask about an asset id."""

    def mesh(self, asset_id: str) -> trimesh.Trimesh: ...  # scene frame, metres, face colours

    def mesh_path(self, asset_id: str) -> Path | None: ...  # a GLB on disk, if any

    def ue_path(self, asset_id: str) -> str | None: ...  # an Unreal asset path (/Game/...), if any

    def category(self, asset_id: str) -> str | None: ...


class DefaultResolver:
    """Library first (if given), then the starter kit; meshes are cached per asset id.

    ``texture()`` returns the scene's cleaned (or original) image when ``scene_dir`` holds one, so the
    exporters can texture the terrain with it; otherwise they use the class colours."""

    def __init__(self, library: Any = None, scene_dir: str | Path | None = None,
                 mesh_lookup: Callable[[str], trimesh.Trimesh | None] | None = None,
                 texture: np.ndarray | None = None):
        self.library = library
        self.scene_dir = Path(scene_dir) if scene_dir is not None else None
        self.mesh_lookup = mesh_lookup
        self._meshes: dict[str, Any] = {}
        # ``texture``: the terrain image when the caller already holds it (not read from scene_dir)
        self._texture: np.ndarray | bool | None = False if texture is None else texture

    # -- sources
    def _library_asset(self, asset_id: str):
        if self.library is None:
            return None
        try:
            return self.library.asset(asset_id)
        except (KeyError, LibraryError):
            return None

    @staticmethod
    def _kit_asset(asset_id: str):
        try:
            from ..assets import kit
        except ImportError:
            return None
        try:
            return kit.kit_asset(asset_id)
        except (KeyError, LibraryError, InputError, FileNotFoundError):
            return None

    def mesh(self, asset_id: str):
        if asset_id in self._meshes:
            return self._meshes[asset_id]
        m = None
        if self.mesh_lookup is not None:
            m = self.mesh_lookup(asset_id)
        if m is None and self._library_asset(asset_id) is not None:
            m = self.library.mesh(asset_id)
        if m is None and self._kit_asset(asset_id) is not None:
            from ..assets import kit

            m = kit.load_kit_mesh(asset_id)
        if m is None:
            raise LibraryError(
                f"asset {asset_id!r} is in neither the asset library nor the starter kit; pass the library that "
                "holds it (--library DIR) or re-run matching with an available library"
            )
        self._meshes[asset_id] = m
        return m

    def mesh_path(self, asset_id: str) -> Path | None:
        a = self._library_asset(asset_id) or self._kit_asset(asset_id)
        p = getattr(a, "mesh_path", None) if a is not None else None
        return Path(p) if p else None

    def ue_path(self, asset_id: str) -> str | None:
        a = self._library_asset(asset_id) or self._kit_asset(asset_id)
        p = getattr(a, "ue_path", None) if a is not None else None
        return str(p) if p else None

    def category(self, asset_id: str) -> str | None:
        a = self._library_asset(asset_id) or self._kit_asset(asset_id)
        c = getattr(a, "category", None) if a is not None else None
        return str(c) if c else None

    def texture(self) -> np.ndarray | None:
        """RGB (H, W, 3) uint8 of the scene's cleaned or original image, or None."""
        if self._texture is False:
            self._texture = None
            if self.scene_dir is not None:
                from ..fsio import read_png

                for name in TEXTURE_NAMES:
                    p = self.scene_dir / name
                    if p.is_file():
                        img = read_png(p)
                        if img.ndim == 3 and img.shape[2] >= 3:
                            self._texture = np.ascontiguousarray(img[:, :, :3]).astype(np.uint8)
                            break
        return self._texture  # type: ignore[return-value]


def scene_texture(assets: Any) -> np.ndarray | None:
    """The terrain image a resolver offers (``texture()``), if any."""
    fn = getattr(assets, "texture", None)
    return fn() if callable(fn) else None


def parse_formats(formats: str | Iterable[str]) -> list[str]:
    """``"ue5,gltf"`` or a list → validated, de-duplicated format names."""
    items = formats.split(",") if isinstance(formats, str) else list(formats)
    out: list[str] = []
    for f in items:
        f = str(f).strip().lower()
        if not f:
            continue
        if f not in FORMATS:
            raise InputError(f"unknown export format {f!r}; valid formats: {', '.join(FORMATS)}")
        if f not in out:
            out.append(f)
    if not out:
        raise InputError(f"no export format given; choose from {', '.join(FORMATS)} (e.g. --format ue5,gltf)")
    return out


def safe_name(text: str, maxlen: int = 64) -> str:
    """A file/asset-safe name (letters, digits, _ and -) derived from ``text``; never empty."""
    s = re.sub(r"[^A-Za-z0-9_-]+", "_", str(text)).strip("_")[:maxlen]
    return s or "unnamed"


def unique_names(ids: Iterable[str], maxlen: int = 64) -> dict[str, str]:
    """Map each id to a distinct safe name (suffixes on collisions, e.g. 'a b' and 'a_b')."""
    out: dict[str, str] = {}
    used: set[str] = set()
    for i in ids:
        if i in out:
            continue
        base = safe_name(i, maxlen)
        name, k = base, 1
        while name.lower() in used:
            k += 1
            name = f"{base}_{k}"
        used.add(name.lower())
        out[i] = name
    return out


def run_exporter(fmt: str, scene: Scene, assets: AssetResolver, config: ExportConfig) -> dict[str, bytes]:
    from .. import registry

    fn = registry.load("export", fmt)
    files = fn(scene, assets, config)
    for rel in files:
        p = Path(rel)
        if p.is_absolute() or ".." in p.parts:
            raise RuntimeError(f"exporter {fmt} produced a path outside its folder: {rel!r}")
    return files


def require_rasters(scene: Scene) -> None:
    """Every exporter needs the terrain: refuse a scene without its height or class raster."""
    if scene.height is None or scene.classes is None:
        raise InputError(f"scene {scene.name!r} has no height or class raster; run `coastforge terrain` first")


def export_scene(scene_dir_or_scene: str | Path | Scene, formats: str | Iterable[str] = ("ue5", "holoocean", "gltf"),
                 out_dir: str | Path | None = None, overwrite: bool = False,
                 mesh_lookup: Callable[[str], Any] | AssetResolver | None = None,
                 config: ExportConfig | None = None, library: Any = None) -> dict[str, list[Path]]:
    """Export a scene (folder or ``Scene``) to ``out_dir/<format>/``; returns the written files per format.

    ``mesh_lookup`` is either a full ``AssetResolver`` or a function ``asset_id -> trimesh`` (None: not
    found) tried before the library and the kit. Nothing is written if any format would replace an
    existing file without ``overwrite``."""
    from ..config import ExportConfig
    from ..fsio import atomic_write_bytes
    from ..scene import Scene, load_scene

    cfg = config or ExportConfig()
    fmts = parse_formats(formats)
    scene_dir: Path | None = None
    if isinstance(scene_dir_or_scene, Scene):
        scene = scene_dir_or_scene
        if out_dir is None:
            raise InputError("export_scene got a Scene object but no out_dir; pass out_dir (--out DIR)")
    else:
        scene_dir = Path(scene_dir_or_scene)
        scene = load_scene(scene_dir)
        if scene_dir.is_file():
            scene_dir = scene_dir.parent
    require_rasters(scene)
    out = Path(out_dir) if out_dir is not None else scene_dir
    assert out is not None
    if out.exists() and not out.is_dir():
        raise InputError(f"output {out} exists and is not a folder; choose a folder with --out")
    if isinstance(mesh_lookup, AssetResolver):
        assets: AssetResolver = mesh_lookup
    else:
        assets = DefaultResolver(library=library, scene_dir=scene_dir, mesh_lookup=mesh_lookup)

    produced = {fmt: run_exporter(fmt, scene, assets, cfg) for fmt in fmts}
    # the scene's label table beside the format folders (and beside scene.json when exporting in place):
    # every format above took its labels from the same table
    table = instances_json(scene)
    table_path = out / INSTANCES_FILE
    if not overwrite:
        clashes = [out / fmt / rel for fmt, files in produced.items() for rel in files if (out / fmt / rel).exists()]
        if table_path.exists() and table_path.read_bytes() != table:  # the same table is not a clash
            clashes.append(table_path)
        if clashes:
            more = f" and {len(clashes) - 1} more" if len(clashes) > 1 else ""
            raise OutputExistsError(f"{clashes[0]}{more} exist(s); pass --overwrite to replace the export, "
                                    "or choose another --out")
    written: dict[str, list[Path]] = {}
    for fmt, files in produced.items():
        if overwrite and (out / fmt).is_dir():  # the format's folder is replaced whole: no stale file survives
            import shutil

            shutil.rmtree(out / fmt)
        written[fmt] = [atomic_write_bytes(out / fmt / rel, data) for rel, data in sorted(files.items())]
    atomic_write_bytes(table_path, table)
    return written


def export_summary(written: dict[str, list[Path]]) -> list[str]:
    """One line per format: how many files and the folder that holds them, as plain strings."""
    import os

    lines = []
    for fmt, paths in written.items():
        folder = os.path.commonpath([str(p.parent) for p in paths]) if paths else "-"
        lines.append(f"{fmt}: {len(paths)} files under {folder}")
    return lines
