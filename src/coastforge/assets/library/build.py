"""``build_library``: a library folder from a manifest, a folder of models or Unreal thumbnails; only
the assets whose model or settings changed are rendered again, only what the embedder has not seen is
embedded."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

import numpy as np

from ... import __version__
from ...config import LibraryConfig
from ...errors import InputError, LibraryError, OutputExistsError
from ...fsio import atomic_write_text
from ..index import VectorIndex
from ..meshes import file_hash
from .ingest import embed_views, ingest_mesh, stored_images
from .manifest import AssetSpec, SkippedAsset, read_manifest, scan_folder
from .store import FORMAT, INDEX_FILE, LIBRARY_JSON, Library, make_embedder, record_files, sha
from .thumbnails import ingest_thumbnail, read_thumbnails
from .views import view_conditions, view_settings


@dataclass(frozen=True)
class BuildReport:
    rendered: tuple[str, ...]  # assets (re-)rendered in this build
    reused: tuple[str, ...]  # assets whose views were unchanged
    embedded: tuple[str, ...]  # assets (re-)embedded
    skipped: tuple[SkippedAsset, ...]
    notes: dict  # asset id -> normalisation notes (guesses)
    seconds: float
    rows: int


def _intact(path: Path) -> bool:
    """A stored view or model copy that is complete: a PNG whose chunks pass their CRCs, a GLB as long as its
    header says. (An interrupted copy or a damaged disk leaves files that exist but cannot be read.)"""
    from ...export import glb
    from ...io import image_damage

    if path.suffix.lower() == ".png":
        return image_damage(path) is None
    if path.suffix.lower() == ".glb":
        try:
            with open(path, "rb") as fh:
                head = fh.read(12)
            return len(head) == 12 and head[:4] == glb.MAGIC and int.from_bytes(head[8:12], "little") == \
                path.stat().st_size
        except OSError:
            return False
    return path.is_file()


def _previous(out: Path) -> tuple[dict | None, VectorIndex | None, str]:
    """The library already in ``out`` (for incremental rebuilds), or (None, None, why) if absent/unusable."""
    try:
        lib = Library.load(out, check_files=False)  # a missing view is rendered again, not a reason to stop
    except LibraryError as exc:
        return None, None, str(exc)
    return lib.doc, lib.index, ""


def config_dict(config: LibraryConfig) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(config).items()}


def build_library(src: str | Path | None, out: str | Path, embedder: str = "default", weights: str | Path | None = None,
                  strict: bool = False, config: LibraryConfig = LibraryConfig(), *, from_thumbnails: str | Path | None
                  = None, overwrite: bool = False, workers: int | None = None,
                  progress: Callable[[str], None] | None = None, keep_origin: bool = False,
                  shown_as: str | Path | None = None) -> Library:
    """Build (or incrementally rebuild) a library in ``out`` from a models folder, a manifest, or (with
    ``from_thumbnails``) a folder captured by the Unreal script. Returns the loaded library with
    ``build_report`` set. One bad asset is reported and skipped unless ``strict``. ``shown_as``: the folder
    messages name (``out`` is a staging copy of it)."""
    t0 = time.perf_counter()
    say = progress or (lambda _m: None)
    out = Path(out)
    shown = Path(shown_as) if shown_as is not None else out
    if from_thumbnails is not None:
        specs, skipped = read_thumbnails(Path(from_thumbnails))
    else:
        if src is None:
            raise InputError("give a models folder or a manifest (SRC), or --from-thumbnails DIR")
        src = Path(src)
        if src.is_dir():
            if (src / "thumbnails.json").is_file():
                raise InputError(f"{src} holds a thumbnails.json from Unreal: use --from-thumbnails {src}")
            specs, skipped = scan_folder(src)
        elif src.is_file():
            if src.suffix.lower() not in (".json", ".toml"):
                raise InputError(f"SRC {src} is neither a folder of models nor a .json/.toml manifest")
            specs, skipped = read_manifest(src, lenient=keep_origin)
        else:
            raise InputError(f"SRC {src} does not exist; give a folder of models or a manifest file")
    if keep_origin:  # models authored in the scene frame (the starter kit): keep their waterline / ground
        specs = [dataclasses.replace(s, origin="keep") for s in specs]
    if strict and skipped:
        raise LibraryError(f"{len(skipped)} asset(s) are invalid (--strict): " + "; ".join(s.error for s in skipped))
    if not specs:
        raise LibraryError("no usable assets: " + "; ".join(s.error for s in skipped))
    emb = make_embedder(embedder, str(weights) if weights is not None else None)
    view_conditions(config)
    # output folder
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {shown} exists and is not a folder")
    prev_doc, prev_index = (None, None)
    if out.is_dir() and any(out.iterdir()):
        prev_doc, prev_index, why = _previous(out)
        if prev_doc is None and not overwrite:
            if (out / LIBRARY_JSON).is_file():
                raise OutputExistsError(f"{shown} holds a library that cannot be read ("
                                        f"{why.replace(str(out), str(shown))}); pass --overwrite to build it "
                                        "again from scratch, or choose another --out")
            raise OutputExistsError(f"{shown} is not empty and holds no valid library; pass --overwrite or "
                                    "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    vset = view_settings(config)
    emb_info = {"name": emb.name, "settings": emb.settings, "dim": int(emb.dim),
                "weights": str(Path(weights).resolve()) if weights is not None else None}
    emb_hash = sha(emb.name, emb.settings, list(config.embed_scales))
    prev_assets = {a["id"]: a for a in (prev_doc or {}).get("assets", [])}
    dropped = sorted(set(prev_assets) - {s.id for s in specs})
    if dropped and not overwrite:  # an update may add and refresh assets; removing some needs --overwrite
        raise OutputExistsError(f"{shown} holds {len(dropped)} asset(s) that SRC no longer has "
                                f"({', '.join(dropped[:5])}{', ...' if len(dropped) > 5 else ''}); pass "
                                "--overwrite to remove them from the library, or choose another --out")
    prev_vectors = prev_index.vectors() if prev_index is not None else None
    # which assets need work
    records: dict[str, dict] = {}
    vectors: dict[str, np.ndarray] = {}
    todo: list[tuple[AssetSpec, str]] = []
    rendered, reused, embedded = [], [], []
    for s in specs:
        try:
            content = _content_hash(s, vset)
        except OSError as exc:
            skipped.append(SkippedAsset(s.id, f"asset {s.id!r}: cannot read {s.mesh}: {exc}"))
            continue
        old = prev_assets.get(s.id)
        if old is not None and old.get("hashes", {}).get("content") == content and all(
                _intact(out / f) for f in record_files(old)):  # a missing or damaged file: render it again
            rec = {k: v for k, v in old.items() if k not in ("index_rows", "hashes")}
            records[s.id] = rec
            reused.append(s.id)
            if old["hashes"].get("embedding") == emb_hash and prev_vectors is not None:
                a0, n = old["index_rows"]
                vectors[s.id] = prev_vectors[a0:a0 + n]
            records[s.id]["_content"] = content
        else:
            todo.append((s, content))
    # render (and, for the weight-free default, embed) in worker processes
    in_worker = emb.name == "default"
    if config.workers and workers is None:
        workers = int(config.workers)
    cfg = config_dict(config)
    results = _run_jobs([(s, str(out), cfg, {"name": emb.name} if in_worker else None) for s, _c in todo],
                        workers, say)
    for res in results:
        if "oserror" in res:
            raise OSError(*res["oserror"])
    for (s, content), res in zip(todo, results):
        if "error" in res:
            skipped.append(SkippedAsset(s.id, res["error"]))
            continue
        rec = res["record"]
        rec["_content"] = content
        records[s.id] = rec
        rendered.append(s.id)
        if "vectors" in res:
            vectors[s.id] = res["vectors"]
        else:
            vectors[s.id] = embed_views(emb, res["images"], rec["view_gsd_m"], rec["dims_m"][0], config,
                                         res.get("query_images", ()), [q["gsd_m"] for q in rec.get("query_views", [])])
        embedded.append(s.id)
    if strict and skipped:
        raise LibraryError(f"{len(skipped)} asset(s) failed (--strict): " + "; ".join(x.error for x in skipped))
    # reused assets whose embedding is stale: embed their stored views
    for aid, rec in records.items():
        if aid not in vectors:
            imgs, qimgs, qgsds = stored_images(out, rec)
            vectors[aid] = embed_views(emb, imgs, rec["view_gsd_m"], rec["dims_m"][0], config, qimgs, qgsds)
            embedded.append(aid)
    if not records:
        raise LibraryError("no asset could be built: " + "; ".join(x.error for x in skipped))
    lib = _write_library(out, [s.id for s in specs if s.id in records], records, vectors, emb_info, emb_hash, vset,
                         config, skipped, weights)
    _prune(out, set(records))
    notes = {aid: tuple(records[aid].get("notes", ())) for aid in records}
    lib.build_report = BuildReport(tuple(rendered), tuple(reused), tuple(embedded), tuple(skipped), notes,
                                   time.perf_counter() - t0, lib.index.rows)
    lib.embedder = emb
    say(f"library {shown}: {len(records)} assets ({len(rendered)} rendered, {len(reused)} reused), "
        f"{len(skipped)} skipped, {lib.index.rows} index rows")
    return lib


def _write_library(out: Path, order: list[str], records: dict, vectors: dict, emb_info: dict, emb_hash: str,
                   vset: dict, config: LibraryConfig, skipped: list, weights) -> Library:
    rows, row_asset, assets_json = [], [], []
    start = 0
    for i, aid in enumerate(order):
        rec = dict(records[aid])
        content = rec.pop("_content")
        v = np.asarray(vectors[aid], np.float32)
        if v.ndim != 2 or v.shape[1] != emb_info["dim"] or not len(v):
            raise LibraryError(f"asset {aid!r}: embedder returned {v.shape} vectors, expected (n, {emb_info['dim']})")
        rec["index_rows"] = [start, int(len(v))]
        rec["hashes"] = {"content": content, "embedding": emb_hash}
        start += len(v)
        rows.append(v)
        row_asset.extend([i] * len(v))
        assets_json.append(rec)
    index = VectorIndex(np.vstack(rows), row_asset)
    digest = index.save(out / INDEX_FILE)
    doc = {
        "format": FORMAT, "generator": f"coastforge {__version__}",
        "embedder": emb_info, "views": vset, "config": config_dict(config),
        "index": {"file": INDEX_FILE, "kind": "faiss.IndexFlatIP", "rows": index.rows, "dim": index.dim,
                  "sha256": digest},
        "assets": assets_json,
        "skipped": [{"id": s.id, "error": s.error} for s in skipped],
    }
    atomic_write_text(out / LIBRARY_JSON, json.dumps(doc, indent=1))
    return Library.load(out, weights=weights)


def _prune(out: Path, keep: set[str]) -> None:
    """Remove views and meshes of assets no longer in the library (only inside our own sub-folders)."""
    views = out / "views"
    if views.is_dir():
        for d in views.iterdir():
            if d.is_dir() and d.name not in keep:
                shutil.rmtree(d, ignore_errors=True)
    meshes = out / "meshes"
    if meshes.is_dir():
        for f in meshes.glob("*.glb"):
            if f.stem not in keep:
                f.unlink(missing_ok=True)


def _start_method() -> str:
    """``fork`` when it is safe, else ``spawn`` (which needs the caller's script to guard its entry point).

    Forking while another thread holds a lock leaves the child waiting forever on that lock; spawned workers
    start clean. Two such cases: generate builds the starter kit in a background thread while the main thread
    imports scipy, and after our first embree ray cast its TBB pool has native threads of its own (a test that
    rendered views in-process, then built the kit with a forked pool, hung in the child's first ray cast).
    BLAS and OpenCV pools, which every numpy / cv2 process has, fork safely.
    """
    import threading

    ro = sys.modules.get("coastforge.render.objects")
    return "fork" if threading.active_count() == 1 and not getattr(ro, "EMBREE_USED", False) else "spawn"


def ingest_asset(spec: AssetSpec, out: str, cfg: dict, want_vectors: dict | None) -> dict:
    """One asset's job (``ingest.ingest_mesh`` or ``thumbnails.ingest_thumbnail``), by name for a worker."""
    ingest = ingest_thumbnail if spec.thumb is not None else ingest_mesh
    return ingest(spec, out, cfg, want_vectors)


def _run_jobs(jobs: list[tuple], workers: int | None, say) -> list[dict]:
    """Run ``ingest_asset`` over jobs in worker processes when there is more than one core."""
    if not jobs:
        return []
    n = workers if workers is not None else min(os.cpu_count() or 1, 4)
    if n <= 1 or len(jobs) == 1 or sys.platform == "win32":
        return [ingest_asset(*j) for j in jobs]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ctx = multiprocessing.get_context(_start_method())
    with ProcessPoolExecutor(max_workers=min(n, len(jobs)), mp_context=ctx) as pool:
        futs = [pool.submit(ingest_asset, *j) for j in jobs]
        out = []
        for i, f in enumerate(futs):
            out.append(f.result())
            if (i + 1) % 20 == 0:
                say(f"  {i + 1}/{len(jobs)} assets rendered")
        return out


def _content_hash(s: AssetSpec, vset: dict) -> str:
    fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(s).items()
              if k not in ("mesh", "guessed", "thumb")}
    if s.thumb is not None:
        pngs = [hashlib.sha256(Path(v["file"]).read_bytes()).hexdigest() for v in s.thumb["views"]]
        return sha("thumb", fields, {k: v for k, v in s.thumb.items() if k != "views"},
                    [(v["lighting"], v["background"]) for v in s.thumb["views"]], pngs)
    return sha(s.mesh.name, file_hash(s.mesh) if s.mesh.is_file() else "missing", fields, vset)
