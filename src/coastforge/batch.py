"""Batches of scenes on a ``dask.distributed`` cluster (a local one by default).

A batch is a list of items (image + size + output name). It is resumable — an item whose output folder
holds a finished ``scene.json`` and a ``.done`` marker with the same request is skipped — and failures are
isolated: one bad input is reported in ``batch_report.json`` and the rest finish.
"""

from __future__ import annotations

import hashlib
import json
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

from .config import Config
from .errors import CoastforgeError, InputError
from .fsio import atomic_write_text
from .registry import require


@dataclass(frozen=True)
class BatchItem:
    image: str
    name: str
    gsd_m: float | None = None
    size_m: tuple[float, float] | None = None
    seed: int | None = None


@dataclass(frozen=True)
class ItemResult:
    name: str
    status: str  # done | skipped | failed
    seconds: float
    error: str | None = None
    scene: str | None = None


def read_batch_list(path: str | Path) -> list[BatchItem]:
    """A batch list: JSON (``[{"image", "name"?, "gsd_m"?, "size_m"?, "seed"?}]`` or ``{"items": [...]}``), or a
    text file with one ``IMAGE [GSD]`` per line (``#`` comments). Relative image paths are relative to the list."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"batch list {p} does not exist; pass a JSON or text file listing the images")
    text = p.read_text(encoding="utf-8")
    raw: list[dict] = []
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"batch list {p} is not valid JSON: {exc}") from exc
        raw = data.get("items", []) if isinstance(data, dict) else data
        if not isinstance(raw, list):
            raise InputError(f"batch list {p}: expected a list of items or {{'items': [...]}}")
    else:
        for n, line in enumerate(text.splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            item: dict = {"image": parts[0]}
            if len(parts) > 1:
                try:
                    item["gsd_m"] = float(parts[1])
                except ValueError as exc:
                    raise InputError(f"{p}:{n}: GSD {parts[1]!r} is not a number") from exc
            raw.append(item)
    items, names = [], set()
    for i, r in enumerate(raw):
        if not isinstance(r, dict) or "image" not in r:
            raise InputError(f"batch list {p}: item {i} = {r!r} needs an 'image'")
        img = Path(r["image"])
        img = img if img.is_absolute() else (p.parent / img)
        name = str(r.get("name") or img.stem)
        if name in names:
            name = f"{name}_{i}"
        names.add(name)
        size = r.get("size_m")
        items.append(BatchItem(str(img), name, r.get("gsd_m"), tuple(size) if size else None, r.get("seed")))
    if not items:
        raise InputError(f"batch list {p} lists no images")
    return items


def _request_key(item: BatchItem, config: Config, exports: tuple[str, ...]) -> str:
    blob = json.dumps({"item": asdict(item), "config": config.to_dict(), "exports": list(exports)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def run_item(item: BatchItem, out_dir: str, config: Config, library: str | None, exports: tuple[str, ...]) -> ItemResult:
    """Generate one scene (runs on a worker). Never raises: failures come back as results."""
    from dataclasses import replace

    from .pipeline import GenerateRequest, run_generate

    t0 = time.perf_counter()
    out = Path(out_dir) / item.name
    key = _request_key(item, config, exports)
    marker = out / ".done"
    if marker.is_file() and marker.read_text().strip() == key and (out / "scene.json").is_file():
        return ItemResult(item.name, "skipped", 0.0, scene=str(out / "scene.json"))
    try:
        cfg = replace(config, seed=item.seed) if item.seed is not None else config
        r = run_generate(GenerateRequest(image=item.image, out=str(out), gsd_m=item.gsd_m, size_m=item.size_m,
                                         library=library, exports=exports, overwrite=True, report=False), cfg)
        atomic_write_text(marker, key + "\n")
        return ItemResult(item.name, "done", round(time.perf_counter() - t0, 3), scene=str(r.scene_path))
    except CoastforgeError as exc:
        return ItemResult(item.name, "failed", round(time.perf_counter() - t0, 3), error=str(exc))
    except Exception as exc:  # noqa: BLE001 - isolate failures: one broken input must not stop the batch
        return ItemResult(item.name, "failed", round(time.perf_counter() - t0, 3),
                          error=f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}")


def run_batch(items: list[BatchItem], out_dir: str | Path, config: Config, library: str | None = None,
              exports: tuple[str, ...] = (), scheduler: str | None = None, workers: int = 2,
              progress: Callable[[ItemResult, int, int], None] | None = None) -> dict:
    """Run every item on a Dask cluster; return (and write) the batch report."""
    distributed = require("distributed", "dask", "coastforge batch")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cluster = None
    if scheduler:
        client = distributed.Client(scheduler)
    else:
        # one thread per worker process: the stages use numpy/OpenCV threads of their own
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=40)
        client = distributed.Client(cluster)
    results: list[ItemResult] = []
    try:
        futures = [client.submit(run_item, it, str(out), config, library, exports, key=f"cf-{it.name}-{i}",
                                 pure=False) for i, it in enumerate(items)]
        for fut in distributed.as_completed(futures):
            try:
                r = fut.result()
            except Exception as exc:  # noqa: BLE001 - a worker that died still yields a report line
                r = ItemResult("?", "failed", 0.0, error=f"worker failure: {exc}")
            results.append(r)
            if progress:
                progress(r, len(results), len(items))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    order = {it.name: i for i, it in enumerate(items)}
    results.sort(key=lambda r: order.get(r.name, 1 << 30))
    report = {
        "n_items": len(items), "done": sum(r.status == "done" for r in results),
        "skipped": sum(r.status == "skipped" for r in results), "failed": sum(r.status == "failed" for r in results),
        "wall_s": round(time.perf_counter() - t0, 3), "workers": None if scheduler else workers,
        "scheduler": scheduler, "items": [asdict(r) for r in results],
    }
    atomic_write_text(out / "batch_report.json", json.dumps(report, indent=2))
    return report
