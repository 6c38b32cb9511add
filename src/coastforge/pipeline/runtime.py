"""What runs beside ``generate``'s main chain: the stage timer, the background thread pool with its named
jobs, and the one spawned side process for pure-Python work.

Jobs are named by ``Job``: a name that is not one of them is an error (a misspelt name must not wait for
nothing, or for everything).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from contextlib import contextmanager
from enum import Enum
from typing import TYPE_CHECKING, Any
from collections.abc import Callable, Iterable

if TYPE_CHECKING:
    from concurrent.futures import Future

# images at least this big (pixels) get a side process; below, its start-up costs more than it saves
SIDE_PROCESS_MIN_PX = 1_500_000


class Job(str, Enum):
    """The background jobs of a generate run (the value is the name in the provenance's ``background_s``)."""

    LIBRARY = "library"  # the asset library, loaded beside segmentation and detection
    SIDE_LIBRARY = "side_library"  # the side process loads it too, for its matching
    MATCH = "match"  # detections matched to assets
    CLEANED = "cleaned"  # cleaned.png, the inpainted image
    SEGMENTATION = "segmentation"  # the segmentation rasters
    TERRAIN_OUTPUTS = "terrain_outputs"  # hillshade, shore types, cross-sections
    REPORT_TERRAIN = "report_terrain"  # the terrain layer of the report's render from above
    REPORT_MESHES = "report_meshes"  # the meshes the report shows, loaded into the library's cache
    SCENE_RASTERS = "scene_rasters"  # the scene's height and class rasters
    PCG = "pcg"  # the vegetation masks

    @classmethod
    def of(cls, name: Job | str) -> Job:
        """``name`` as a ``Job``; an unknown name raises ``ValueError`` naming the known ones."""
        try:
            return cls(name)
        except ValueError:
            raise ValueError(f"unknown background job {name!r}; the jobs are "
                             f"{', '.join(j.value for j in cls)}") from None


class Timer:
    """Wall and CPU seconds per stage of the chain; ``progress(stage, fraction)`` is told as each stage starts
    (0) and ends (1)."""

    def __init__(self, progress: Callable[[str, float], None] | None = None):
        self.t: dict[str, float] = {}
        self.cpu: dict[str, float] = {}  # the calling thread's CPU time per stage (wall minus waiting for a core)
        self.progress = progress

    @contextmanager
    def stage(self, name: str):
        if self.progress:
            self.progress(name, 0.0)
        t0, c0 = time.perf_counter(), time.thread_time()
        yield
        self.t[name] = round(time.perf_counter() - t0, 3)
        self.cpu[name] = round(time.thread_time() - c0, 3)
        if self.progress:
            self.progress(name, 1.0)


class Background:
    """A small thread pool for work beside the main chain. NumPy, OpenCV and zlib release the GIL, so on
    two cores the side rasters are encoded while the next stage computes. ``result``/``wait`` re-raise a
    job's exception; leaving the block waits for every job (nothing is left writing behind the caller)."""

    def __init__(self, workers: int = 3, low_workers: int = 2):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="coastforge-bg")
        # output files nothing waits for until the end, in threads the OS runs only when a core is free of
        # the chain's work (and the side process's): they fill its idle moments instead of slowing it
        self._low = ThreadPoolExecutor(max_workers=low_workers, thread_name_prefix="coastforge-bg-low",
                                       initializer=lower_thread_priority)
        self._jobs: dict[Job, Future[Any]] = {}
        self._t: dict[str, dict] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for pool in (self._pool, self._low):
            pool.shutdown(wait=True, cancel_futures=exc[0] is not None)
        return False

    def submit(self, job: Job | str, fn, *args, low: bool = False, **kw) -> None:
        """Run ``fn(*args, **kw)`` as ``job``; ``low``: at a lower CPU priority (Linux)."""
        job = Job.of(job)

        def timed():
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return fn(*args, **kw)
            finally:  # wall and this thread's CPU time: their gap is time spent waiting for a core
                self._t[job.value] = {"wall": round(time.perf_counter() - t0, 3),
                                      "cpu": round(time.thread_time() - c0, 3)}

        self._jobs[job] = (self._low if low else self._pool).submit(timed)

    def result(self, job: Job | str):
        """The job's result, once it is done; a job that was never submitted raises ``KeyError``."""
        job = Job.of(job)
        if job not in self._jobs:
            raise KeyError(f"background job {job.value!r} was not submitted")
        return self._jobs[job].result()

    def wait(self, skip: Iterable[Job] = ()) -> None:
        """Wait for every job but those in ``skip``."""
        skipped = {Job.of(j) for j in skip}
        for job, f in list(self._jobs.items()):
            if job not in skipped:
                f.result()

    def timings(self) -> dict[str, dict]:
        return dict(sorted(self._t.items()))


def lower_thread_priority(nice: int = 10) -> None:
    """Give the calling thread a nice value ``nice`` above the process's (Linux schedules threads on their
    own; elsewhere ``setpriority`` would take the id for a process's, so nothing is done). Relative, so
    that under ``nice -n 10`` the low jobs still yield to the chain."""
    if sys.platform.startswith("linux") and hasattr(os, "setpriority"):
        try:
            own = os.getpriority(os.PRIO_PROCESS, 0)
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), min(19, own + nice))
        except OSError:
            pass


class SideProcess:
    """One spawned worker process for pure-Python-heavy side work. In a thread that work would hold the
    GIL against the main chain; in a process it runs on the other core. ``start`` gives None (run it in a
    thread instead) for small images, in a daemonic process (which may not have children) or where
    processes cannot start."""

    def __init__(self, pool):
        self._pool = pool
        self._futures: list = []

    @classmethod
    def start(cls, n_px: int, warm_up: Callable[[], None] | None = None) -> SideProcess | None:
        """A side process for an image of ``n_px`` pixels, or None; ``warm_up`` (a module-level function)
        runs in it first (its imports, while the main process starts on the chain)."""
        import multiprocessing

        if n_px < SIDE_PROCESS_MIN_PX or multiprocessing.current_process().daemon or (os.cpu_count() or 1) < 2:
            return None
        try:
            from concurrent.futures import ProcessPoolExecutor

            pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
            if warm_up is not None:
                pool.submit(warm_up)
        except (OSError, RuntimeError, ValueError):
            return None
        return cls(pool)

    def run(self, fn, *args):
        """``fn(*args)`` in the side process, waiting for its result (call it from a background thread); here
        if the side process died (killed for memory, say): the work is redone rather than lost."""
        from concurrent.futures.process import BrokenProcessPool

        try:
            return self.submit(fn, *args).result()
        except BrokenProcessPool:
            return fn(*args)

    def submit(self, fn, *args):
        """A future of ``fn(*args)`` in the side process (jobs run one at a time, in the order submitted)."""
        fut = self._pool.submit(fn, *args)
        self._futures.append(fut)
        return fut

    def close(self) -> None:
        """Stop the side process. With every job done it is terminated rather than left to tear its
        interpreter down (its imports and caches: time the user would wait for nothing)."""
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        idle = all(f.done() for f in self._futures)
        self._pool.shutdown(wait=not idle, cancel_futures=True)
        if idle:
            for p in procs:
                p.terminate()
