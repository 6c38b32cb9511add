"""Batches of scenes on a ``dask.distributed`` cluster (a local one by default).

A batch is a list of items (image + size + output name). It is resumable — an item whose output folder
holds a finished ``scene.json`` and a ``.done`` marker with the same request is skipped — and failures are
isolated: one bad input is reported in ``batch_report.json`` and the rest finish.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from collections.abc import Callable

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


def _bad_name(name: str) -> bool:
    """An item name must be one plain folder name inside --out (no separators, not '.' or '..')."""
    return (not name or name in (".", "..") or "/" in name or "\\" in name or os.sep in name
            or (os.altsep is not None and os.altsep in name) or "\0" in name)


def _positive(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0


def _check_item(p: Path, i: int, r) -> None:
    """One JSON item, checked before anything runs: each failure names the item, the field and its value."""
    where = f"batch list {p}: item {i}"
    if not isinstance(r, dict) or "image" not in r:
        raise InputError(f"{where} = {r!r} needs an 'image'")
    if not isinstance(r["image"], str) or not r["image"].strip():
        raise InputError(f"{where}: image = {r['image']!r} must be the path of an image (a string)")
    name = r.get("name")
    if name is not None and (not isinstance(name, str) or _bad_name(name)):
        raise InputError(f"{where}: name = {name!r} must be a plain folder name (no '/', not '.' or '..'): it "
                         "names the item's subfolder of --out")
    if r.get("gsd_m") is not None and not _positive(r["gsd_m"]):
        raise InputError(f"{where}: gsd_m = {r['gsd_m']!r} must be a positive number of metres per pixel")
    size = r.get("size_m")
    if size is not None and not (isinstance(size, (list, tuple)) and len(size) == 2 and all(map(_positive, size))):
        raise InputError(f"{where}: size_m = {size!r} must be [width, height] in metres, both positive")
    seed = r.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= 2**63 - 1):
        raise InputError(f"{where}: seed = {seed!r} must be an integer between 0 and {2**63 - 1}")


def _text_item(p: Path, n: int, line: str) -> dict:
    """One 'IMAGE [GSD]' line; an image path with spaces is taken whole, or quoted ("my image.png" 0.2)."""
    import shlex

    def exists(text: str) -> bool:
        return (Path(text) if Path(text).is_absolute() else p.parent / text).is_file()

    if exists(line):
        return {"image": line}
    head, _, tail = line.rpartition(" ")
    if head.strip() and exists(head.strip()) and not (tail.startswith(("'", '"'))):
        try:
            return {"image": head.strip(), "gsd_m": _gsd(p, n, tail)}
        except InputError:
            pass
    try:
        parts = shlex.split(line)
    except ValueError as exc:
        raise InputError(f"{p}:{n}: {exc}; write 'IMAGE [GSD]' per line") from None
    if len(parts) > 2:
        raise InputError(f"{p}:{n}: expected 'IMAGE [GSD]', got {len(parts)} words; quote an image path with "
                         'spaces ("my image.png" 0.2), or list the images in a JSON file')
    item: dict = {"image": parts[0]}
    if len(parts) > 1:
        item["gsd_m"] = _gsd(p, n, parts[1])
    return item


def _gsd(p: Path, n: int, text: str) -> float:
    try:
        g = float(text)
    except ValueError:
        raise InputError(f"{p}:{n}: GSD {text!r} is not a number; write 'IMAGE [GSD]' (quote an image path with "
                         'spaces: "my image.png" 0.2)') from None
    if not _positive(g):
        raise InputError(f"{p}:{n}: GSD {text!r} must be a positive number of metres per pixel")
    return g


def read_batch_list(path: str | Path) -> list[BatchItem]:
    """A batch list: JSON (``[{"image", "name"?, "gsd_m"?, "size_m"?, "seed"?}]`` or ``{"items": [...]}``), or a
    text file with one ``IMAGE [GSD]`` per line (``#`` comments). Relative image paths are relative to the list."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"batch list {p} is a folder; pass a JSON or text file listing the images")
    if not p.is_file():
        raise InputError(f"batch list {p} does not exist; pass a JSON or text file listing the images")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"batch list {p} is not a text file (an image?); pass a JSON list of items or a text "
                         "file with one 'IMAGE [GSD]' per line") from None
    raw: list = []
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"batch list {p} is not valid JSON: {exc}") from exc
        raw = data.get("items", []) if isinstance(data, dict) else data
        if not isinstance(raw, list):
            raise InputError(f"batch list {p}: expected a list of items or {{'items': [...]}}")
        for i, r in enumerate(raw):
            _check_item(p, i, r)
    else:
        for n, line in enumerate(text.splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if line:
                raw.append(_text_item(p, n, line))
    items, names = [], set()
    for i, r in enumerate(raw):
        img = Path(r["image"])
        img = img if img.is_absolute() else (p.parent / img)
        name = str(r.get("name") or img.stem)
        if _bad_name(name):
            raise InputError(f"batch list {p}: item {i} ({img}) gives no usable folder name ({name!r}); give it a "
                             "'name'")
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
    except OSError as exc:  # a full disk, a read-only folder: one line naming the path
        from .fsio import os_error_message

        return ItemResult(item.name, "failed", round(time.perf_counter() - t0, 3), error=os_error_message(exc))
    except Exception as exc:  # noqa: BLE001 - isolate failures: one broken input must not stop the batch
        return ItemResult(item.name, "failed", round(time.perf_counter() - t0, 3),
                          error=f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}")


def run_batch(items: list[BatchItem], out_dir: str | Path, config: Config, library: str | None = None,
              exports: tuple[str, ...] = (), scheduler: str | None = None, workers: int = 2,
              progress: Callable[[ItemResult, int, int], None] | None = None) -> dict:
    """Run every item on a Dask cluster; return (and write) the batch report. One batch at a time writes
    ``out_dir`` (a lock, as for every output folder); everything is checked before the first write."""
    from .export import parse_formats
    from .fsio import FolderLock, check_output_parent

    distributed = require("distributed", "dask", "coastforge batch")
    out = Path(out_dir)
    if not scheduler and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InputError(f"--workers {workers!r} must be at least 1 (worker processes of the local cluster)")
    if exports:
        parse_formats(exports)  # an unknown format stops the batch now, not once per item
    check_output_parent(out)
    for kind in ("scene.json", "library.json", "segmentation.json", "truth.json"):
        if (out / kind).is_file():
            raise InputError(f"--out {out} holds a {kind} (another command's output folder); a batch writes one "
                             "subfolder per item and its batch_report.json: choose another --out")
    import shlex
    import sys

    out.parent.mkdir(parents=True, exist_ok=True)
    with FolderLock(out, shlex.join(["coastforge", *sys.argv[1:]])):
        return _run_batch(items, out, config, library, exports, scheduler, workers, progress, distributed)


def _run_batch(items, out: Path, config, library, exports, scheduler, workers, progress, distributed) -> dict:
    t0 = time.perf_counter()
    cluster = None
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({exc}); check the address (e.g. "
                             "tcp://host:8786), or leave --scheduler out to run a local cluster") from None
    else:
        # one thread per worker process: the stages use numpy/OpenCV threads of their own
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None, silence_logs=40)
        client = distributed.Client(cluster)
    results: list[ItemResult] = []
    try:
        out.mkdir(exist_ok=True)  # once the cluster is up: a scheduler that cannot be reached leaves no folder
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
