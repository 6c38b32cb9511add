"""Libraries from Unreal: thumbnails captured in the editor (``assets/unreal/capture_thumbnails.py``)
stand in for the models, which stay in the Unreal project."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from ...classes import ASSET_CATEGORIES
from ...config import LibraryConfig
from ...errors import CoastforgeError, LibraryError
from ...fsio import read_png, write_png
from .ingest import FLOATING, embed_views, estimate_draft, os_failure
from .manifest import AssetSpec, SkippedAsset, check_id, guess_category
from .store import make_embedder


THUMBNAILS_FORMAT = "coastforge.thumbnails/1"


def read_thumbnails(folder: Path) -> tuple[list[AssetSpec], list[SkippedAsset]]:
    """Parse ``thumbnails.json`` written by ``coastforge/assets/unreal/capture_thumbnails.py``."""
    jpath = folder / "thumbnails.json"
    if not jpath.is_file():
        from ..unreal import CAPTURE_SCRIPT

        raise LibraryError(f"{folder} has no thumbnails.json; capture it in Unreal with the script "
                           f"{CAPTURE_SCRIPT}")
    try:
        doc = json.loads(jpath.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise LibraryError(f"{jpath} is not readable JSON: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != THUMBNAILS_FORMAT or not isinstance(doc.get("assets"), list):
        raise LibraryError(f"{jpath}: expected format {THUMBNAILS_FORMAT!r} with an 'assets' list")
    specs, skipped, seen = [], [], set()
    base = os.path.normpath(os.path.abspath(folder))
    for i, a in enumerate(doc["assets"]):
        name = a.get("name") if isinstance(a, dict) else None
        try:
            if not isinstance(a, dict) or not isinstance(a.get("asset_path"), str):
                raise LibraryError(f"{jpath}: assets[{i}] needs an 'asset_path' string")
            raw = name or a["asset_path"].rsplit("/", 1)[-1].split(".")[0]
            aid = a.get("id") or re.sub(r"[^A-Za-z0-9_.\-]", "_", raw).strip("._-")
            check_id(aid, f"{jpath}: assets[{i}]")
            if aid in seen:
                raise LibraryError(f"asset {aid!r}: duplicate id in {jpath}; ids must be unique")
            seen.add(aid)
            cat = a.get("category")
            why = ""
            if cat is None:
                cat, why = guess_category(raw, a["asset_path"].split("/")[:-1], a.get("tags", ()))
                if cat is None:
                    raise LibraryError(f"asset {aid!r} ({a['asset_path']}): cannot guess its category ({why}); add "
                                       f"\"category\" to its entry in {jpath}")
            if cat not in ASSET_CATEGORIES:
                raise LibraryError(f"asset {aid!r}: unknown category {cat!r}; use one of {', '.join(ASSET_CATEGORIES)}")
            ext = [float(v) for v in a["bounds_cm"]["box_extent"]]
            if len(ext) != 3 or min(ext) <= 0:
                raise LibraryError(f"asset {aid!r}: bounds_cm.box_extent {ext} must be three positive numbers")
            gsd = float(a["gsd_m"])
            if not gsd > 0:
                raise LibraryError(f"asset {aid!r}: gsd_m {gsd} must be positive")
            views = []
            for v in a["views"]:
                full = os.path.normpath(os.path.join(base, v["file"]))
                if os.path.commonpath([base, full]) != base:
                    raise LibraryError(f"asset {aid!r}: view {v['file']!r} escapes {folder}")
                if not os.path.isfile(full):
                    raise LibraryError(f"asset {aid!r}: view {full} is missing; re-run the capture")
                if v["background"] not in ("water", "ground"):
                    raise LibraryError(f"asset {aid!r}: view background {v['background']!r} must be water or ground")
                views.append({"file": full, "lighting": int(v["lighting"]), "background": v["background"]})
            if not views:
                raise LibraryError(f"asset {aid!r} has no views in {jpath}")
            thumb = {"asset_path": a["asset_path"], "box_extent_cm": ext, "gsd_m": gsd, "views": views}
            specs.append(AssetSpec(id=aid, category=cat, mesh=Path(views[0]["file"]), ue_path=a["asset_path"],
                                   tags=tuple(a.get("tags", ())), guessed=why, thumb=thumb))
        except (KeyError, TypeError, ValueError) as exc:
            skipped.append(SkippedAsset(str(name or f"assets[{i}]"),
                                        f"{jpath}: assets[{i}] is malformed ({type(exc).__name__}: {exc})"))
        except LibraryError as exc:
            skipped.append(SkippedAsset(str(name or f"assets[{i}]"), str(exc)))
    return specs, skipped


def ingest_thumbnail(spec: AssetSpec, out: str, cfg: dict, want_vectors: dict | None) -> dict:
    """Thumbnail assets: copy the captured views, dimensions from the Unreal bounds (cm, X forward)."""
    try:
        config = LibraryConfig(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in cfg.items()})
        t = spec.thumb
        ex, ey, ez = t["box_extent_cm"]
        dims = (2 * ex / 100.0, 2 * ey / 100.0, 2 * ez / 100.0)
        notes = ([f"category guessed from the {spec.guessed}"] if spec.guessed else [])
        if dims[1] > dims[0] * 1.05:
            notes.append("the Unreal bounds are longer across Y than along X: forward (+X) may be the short axis")
        floating = spec.category in FLOATING
        draft = estimate_draft(spec.category, dims) if floating else 0.0
        root = Path(out)
        views, images = [], []
        for v in t["views"]:
            img = read_png(v["file"])
            if img.ndim == 3 and img.shape[2] == 4:
                img = img[:, :, :3]
            if img.ndim != 3:
                raise LibraryError(f"asset {spec.id!r}: view {v['file']} is not an RGB image")
            rel = f"views/{spec.id}/l{v['lighting']}_{v['background']}.png"
            write_png(root / rel, img)
            views.append({"file": rel, "lighting": v["lighting"], "background": v["background"]})
            images.append(img)
        rec = {
            "id": spec.id, "category": spec.category, "dims_m": [round(d, 5) for d in dims], "draft_m": draft,
            "floating": floating, "ue_path": spec.ue_path, "mesh": None, "source_mesh": None, "views": views,
            "view_gsd_m": float(t["gsd_m"]), "tags": list(spec.tags),
            "normalisation": {"up_axis": "+z", "forward_axis": "+x", "unit": "cm", "scale": 0.01}, "notes": notes,
        }
        result = {"record": rec}
        if want_vectors is not None:
            emb = make_embedder(want_vectors["name"], want_vectors.get("weights"))
            result["vectors"] = embed_views(emb, images, rec["view_gsd_m"], dims[0], config)
        else:
            result["images"] = images
        return result
    except CoastforgeError as exc:
        return {"error": str(exc)}
    except OSError as exc:
        return os_failure(spec, exc)
    except Exception as exc:  # noqa: BLE001 - one asset's broken thumbnail must not take the others down
        return {"error": f"asset {spec.id!r}: {type(exc).__name__}: {exc}"}
