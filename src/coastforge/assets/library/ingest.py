"""One asset made library-ready (in a worker process): its model normalised and saved, its views
rendered and embedded."""

from __future__ import annotations

import math
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from ...config import LibraryConfig
from ...errors import CoastforgeError
from ...fsio import atomic_write_bytes, read_png, write_png
from ..meshes import footprint_mask, load_mesh, normalise_mesh
from .manifest import AssetSpec
from .paints import PAINTS, is_paintable, repaint
from .store import Z_UP_TO_GLTF, make_embedder
from .views import (choose_view_gsd, read_query_views, render_query_views, scale_variants, view_conditions,
                    view_lightings, write_query_views)


FLOATING = ("boat", "buoy")


def estimate_draft(category: str, dims_m: Sequence[float]) -> float:
    """Typical draft when the manifest does not give one: small craft ~0.3 m, ships grow with length."""
    L, _W, H = dims_m
    if category == "boat":
        return round(float(min(0.35 * H, 0.04 * L + 0.12)), 3)
    if category == "buoy":
        return round(float(0.4 * H), 3)
    return 0.0


def ingest_mesh(spec: AssetSpec, out: str, cfg: dict, want_vectors: dict | None) -> dict:
    """Load, normalise, save the mesh, render and save the views; embed when ``want_vectors`` is given.
    Returns a plain dict (picklable); errors come back as {'error': message}."""
    try:
        from ...render import render_mesh_view

        config = LibraryConfig(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in cfg.items()})
        raw = load_mesh(spec.mesh, spec.id)
        mesh, norm = normalise_mesh(raw, spec.category, asset_id=spec.id, length_m=spec.length_m,
                                    height_m=spec.height_m, up_axis=spec.up_axis, forward_axis=spec.forward_axis,
                                    unit=spec.unit, suffix=spec.mesh.suffix, keep_z=spec.origin == "keep",
                                    source=spec.mesh)
        floating = spec.floating if spec.floating is not None else spec.category in FLOATING
        draft = spec.draft_m if spec.draft_m is not None else (estimate_draft(spec.category, norm.dims_m)
                                                               if floating else 0.0)
        if floating and draft > 0 and spec.origin != "keep":
            mesh.apply_translation([0.0, 0.0, -draft])  # z = 0 at the waterline
        root = Path(out)
        mesh_rel = f"meshes/{spec.id}.glb"
        # glTF is y-up: store (x, y, z) as (x, z, -y), so Unreal's and other glTF importers see it upright
        gltf_mesh = mesh.copy()
        gltf_mesh.apply_transform(Z_UP_TO_GLTF)
        atomic_write_bytes(root / mesh_rel, gltf_mesh.export(file_type="glb"))
        gsd = choose_view_gsd(norm.dims_m, config)
        lightings = view_lightings()
        views, images = [], []
        for k, bg in view_conditions(config):
            img = render_mesh_view(mesh, gsd, int(config.view_size_px), lightings[k], bg, yaw_deg=0.0, seed=k)
            rel = f"views/{spec.id}/l{k}_{bg}.png"
            write_png(root / rel, img)
            views.append({"file": rel, "lighting": k, "background": bg})
            images.append(img)
        # the footprint, aligned with the views: the matcher's templates need it, and rasterising it from the
        # mesh at match time would load trimesh and every mesh into a generate run
        sil_rel = f"views/{spec.id}/silhouette.png"
        write_png(root / sil_rel, footprint_mask(mesh, int(config.view_size_px), gsd) * np.uint8(255))
        paint_views = []
        if config.paint_variants and is_paintable(spec.category, norm.dims_m):
            bg = "ground" if spec.category == "vehicle" else "water"
            for k, rgb in enumerate(PAINTS):
                img = render_mesh_view(repaint(mesh, rgb), gsd, int(config.view_size_px), lightings[1], bg,
                                       yaw_deg=0.0, seed=10 + k)
                rel = f"views/{spec.id}/paint{k}_{bg}.png"
                write_png(root / rel, img)
                paint_views.append({"file": rel, "lighting": 1, "background": bg, "paint": list(rgb)})
                images.append(img)
        qv = render_query_views(mesh, spec.id, norm.dims_m, gsd, config, spec.category)
        query_images, query_views = [q[0] for q in qv], [q[1] for q in qv]
        qfile = f"views/{spec.id}/query_views.npz" if qv else None
        if qfile:
            write_query_views(root / qfile, query_images)
        rec = {
            "id": spec.id, "category": spec.category, "dims_m": [round(v, 5) for v in norm.dims_m],
            "draft_m": float(draft), "floating": bool(floating), "ue_path": spec.ue_path, "mesh": mesh_rel, "mesh_up": "y",
            "source_mesh": str(spec.mesh), "views": views, "paint_views": paint_views,
            "query_views": query_views, "query_views_file": qfile, "silhouette": sil_rel,
            "view_gsd_m": gsd,
            "tags": list(spec.tags),
            "normalisation": {"up_axis": norm.up_axis, "forward_axis": norm.forward_axis, "unit": norm.unit,
                              "scale": norm.scale},
            "notes": ([f"category guessed from the {spec.guessed}"] if spec.guessed else []) + list(norm.notes),
        }
        result = {"record": rec}
        if want_vectors is not None:
            emb = make_embedder(want_vectors["name"], want_vectors.get("weights"))
            result["vectors"] = embed_views(emb, images, gsd, norm.dims_m[0], config, query_images,
                                             [q["gsd_m"] for q in query_views])
        else:
            result["images"] = images
            result["query_images"] = query_images
        return result
    except CoastforgeError as exc:
        return {"error": str(exc)}
    except OSError as exc:
        return os_failure(spec, exc)
    except Exception as exc:  # noqa: BLE001 - a broken model must not take the other assets down
        return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}


_OUTPUT_ERRNOS = (28, 122, 30)  # ENOSPC, EDQUOT, EROFS: the library folder, not the asset, is the problem


def os_failure(spec, exc: OSError) -> dict:
    """An asset job's OS error: a full or read-only disk stops the build (every asset would fail the same
    way, and "no asset could be built" would hide why); others only skip the asset."""
    if exc.errno in _OUTPUT_ERRNOS:
        return {"oserror": (exc.errno, exc.strerror, None if exc.filename is None else str(exc.filename))}
    return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}


def embed_views(emb, images: list, gsd: float, length_m: float, config: LibraryConfig,
                 query_images: Sequence = (), query_gsds: Sequence[float] = ()) -> np.ndarray:
    """Rows of one asset: each standard view at its scale variants, then the query-like views as they are.
    Downsampled copies as coarse as the query-like views are left out: those views stand for that scale."""
    crops, gsds = [], []
    coarse = min(query_gsds) * 0.99 if len(query_gsds) else math.inf
    for img in images:
        for im, g in scale_variants(img, gsd, length_m, config.embed_scales):
            if g > gsd * 1.0001 and g >= coarse:
                continue
            crops.append(im)
            gsds.append(g)
    crops.extend(query_images)
    gsds.extend(float(g) for g in query_gsds)
    return np.asarray(emb.embed(crops, gsds), np.float32)


def stored_images(out: Path, rec: dict) -> tuple[list, list, list[float]]:
    """(standard + paint views, query-like views, their GSDs) of a built asset, read back from disk."""
    def rgb(v):
        img = read_png(out / v["file"])
        return img[:, :, :3] if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2)

    qv = rec.get("query_views", [])
    qimgs = read_query_views(out / rec["query_views_file"], len(qv)) if qv else []
    return [rgb(v) for v in rec["views"] + rec.get("paint_views", [])], qimgs, [float(v["gsd_m"]) for v in qv]
