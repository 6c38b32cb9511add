"""The installed kit: its manifest (``kit.json``) and its meshes, loaded as scene-frame trimeshes."""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ...errors import LibraryError
from .encoding import read_glb

KIT_FORMAT = "coastforge.kit/1"
MANIFEST_NAME = "kit.json"
KIT_CATEGORIES = ("boat", "vehicle", "pier", "buoy", "tree", "bush", "rock", "grass", "seaweed")
FLOATING_CATEGORIES = ("boat", "buoy")


@dataclass(frozen=True)
class KitAsset:
    """One entry of a kit manifest; ``mesh_path`` is absolute."""

    id: str
    category: str
    mesh_path: Path
    dims_m: tuple[float, float, float]
    draft_m: float
    floating: bool
    tags: tuple[str, ...]

    @property
    def length_m(self) -> float:
        return self.dims_m[0]


def kit_dir() -> Path:
    """The installed ``coastforge/data/kit`` folder."""
    return Path(str(resources.files("coastforge").joinpath("data", "kit")))


def read_manifest(manifest_path: str | Path) -> tuple[KitAsset, ...]:
    """Parse a ``coastforge.kit/1`` manifest; errors name the bad field and value."""
    path = Path(manifest_path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise LibraryError(
            f"kit manifest {path} not found; regenerate it with "
            f"`python -m coastforge.assets.kit --out {path.parent} --overwrite`"
        ) from None
    except (OSError, ValueError) as exc:
        raise LibraryError(f"kit manifest {path} is not readable JSON ({exc}); regenerate it") from None
    if not isinstance(doc, dict) or doc.get("format") != KIT_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise LibraryError(f"{path}: format is {got!r}, expected {KIT_FORMAT!r}")
    assets = []
    for i, a in enumerate(doc.get("assets") or []):
        where = f"{path}: assets[{i}]"
        try:
            dims = tuple(float(v) for v in a["dims_m"])
            if len(dims) != 3 or min(dims) <= 0:
                raise ValueError(f"dims_m {a['dims_m']!r} must be three positive numbers")
            if a["category"] not in KIT_CATEGORIES:
                raise ValueError(f"category {a['category']!r} is not one of {', '.join(KIT_CATEGORIES)}")
            assets.append(
                KitAsset(
                    id=str(a["id"]), category=str(a["category"]),
                    mesh_path=(path.parent / a["mesh"]).resolve(), dims_m=dims,
                    draft_m=float(a.get("draft_m", 0.0)), floating=bool(a.get("floating", False)),
                    tags=tuple(str(t) for t in a.get("tags", ())),
                )
            )
        except KeyError as exc:
            raise LibraryError(f"{where} misses the field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            label = a.get("id", "?") if isinstance(a, dict) else repr(a)
            raise LibraryError(f"{where} ({label}): {exc}") from None
    if not assets:
        raise LibraryError(f"{path} lists no assets")
    return tuple(assets)


@functools.lru_cache(maxsize=1)
def kit_assets() -> tuple[KitAsset, ...]:
    """Every asset of the installed kit, in manifest order (cached)."""
    return read_manifest(kit_dir() / MANIFEST_NAME)


def kit_asset(asset_id: str) -> KitAsset:
    """The installed kit's asset ``asset_id``; an unknown id raises ``LibraryError`` listing the ids."""
    for a in kit_assets():
        if a.id == asset_id:
            return a
    raise LibraryError(
        f"unknown kit asset {asset_id!r}; the kit has: {', '.join(a.id for a in kit_assets())}"
    )


def load_kit_mesh(asset_id: str):
    """One concatenated ``trimesh.Trimesh`` of a kit asset in the scene frame (z up, metres, forward +x),
    with per-face sRGB colours in ``mesh.visual.face_colors``. Loaded once; each call returns a copy,
    so callers may transform it freely."""
    return _load_cached(asset_id).copy()


@functools.cache
def _load_cached(asset_id: str):
    return load_glb_mesh(kit_asset(asset_id).mesh_path)


def load_glb_mesh(path: str | Path):
    """Read a GLB written by ``encoding.glb_bytes`` into one scene-frame Trimesh with face colours."""
    import trimesh

    vertices, faces, colours = read_glb(path)
    return trimesh.Trimesh(vertices=vertices, faces=faces, face_colors=colours, process=False)
