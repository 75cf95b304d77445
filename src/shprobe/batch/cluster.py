"""Where a batch's probes are computed: in-process, or on Dask (a local cluster shprobe
starts, or the user's), in tasks of a few probes each, with workers warmed and their heap
kept for image buffers."""

from __future__ import annotations

import logging
import os
import secrets
from collections.abc import Iterator
from typing import Any

from .rows import BatchOptions, empty_row, probe_row

__all__ = ["LOCAL_CLUSTER_CONFIG", "MAX_CHUNK", "TASKS_PER_WORKER", "WORKER_MMAP_THRESHOLD",
           "WORKER_TRIM_THRESHOLD", "chunk_size"]


def _warm() -> None:
    """Compile / load the numba kernels a row uses, so the first probe pays no start-up."""
    import numpy as np

    from ..lighting import auto_window, min_irradiance
    from ..lighting.projection import _project_kernel
    from ..probes.codecs import rgbe_half_step, rgbe_row_sums, rgbe_rows
    from ..probes.presets import get_preset

    rgbe_half_step(np.ones((2, 2, 3), np.float32))
    rgbe_rows(np.zeros(0, np.uint8), 0, np.empty((0, 8, 3), np.float32))
    rgbe_row_sums(np.zeros(0, np.uint8), 0, np.empty((0, 1, 3)), np.ones((1, 8), np.float32))
    _project_kernel(np.array([[0.0, 0.0, 1.0]]), np.ones((1, 3)), np.ones(1), 2)
    c = get_preset("grace")
    min_irradiance(c)
    auto_window(c)
    import pyarrow  # noqa: F401  (the driver reads rows as Arrow; warm the import too)


#: glibc ``mallopt`` parameters (malloc.h) and the values a batch worker runs with.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Blocks up to this size come from the heap and are reused, not mapped and unmapped per probe
#: (glibc's ceiling for the mmap threshold on 64-bit).
WORKER_MMAP_THRESHOLD = 32 << 20
#: Free memory at the top of the heap kept for the next probe instead of being returned.
WORKER_TRIM_THRESHOLD = 64 << 20


def _keep_heap() -> bool:
    """Let a worker reuse its freed image buffers (glibc only; False where it cannot).

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which also freezes
    glibc's mmap threshold at 128 KiB: every block of decoded rows, every image buffer of the
    decoder, is a fresh ``mmap`` that the kernel zero-fills page by page and unmaps when
    freed — 31 000 page faults and ~50 ms of a 2048×1024 EXR probe's 190 ms
    (bench/bench_batch.py). With the thresholds above, buffers up to 32 MiB are reused from
    the heap (no faults) and at most 64 MiB of free heap is kept; larger buffers are still
    mapped and returned at once, so memory stays bounded."""
    import ctypes
    import ctypes.util
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # musl and others: no mallopt
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, WORKER_MMAP_THRESHOLD)
                and mallopt(_M_TRIM_THRESHOLD, WORKER_TRIM_THRESHOLD))


class _WarmPlugin:
    """Dask worker plugin: warm numba in every worker, including ones started later; with
    ``keep_heap`` (only in the cluster shprobe starts itself, `_local_cluster`) also let
    the heap keep freed image buffers (`_keep_heap`). A user's cluster keeps its heap."""

    name = "shprobe-warm"
    idempotent = True  # registered once per cluster, not again by every batch

    def __init__(self, keep_heap: bool = False) -> None:
        self.keep_heap = keep_heap
        if keep_heap:
            self.name = "shprobe-warm-heap"

    def setup(self, worker: Any) -> None:
        if self.keep_heap:
            _keep_heap()
        _warm()


def _task(jobs: list[tuple[str, str]], options: BatchOptions, done: frozenset[str]
          ) -> list[dict]:
    return [probe_row(path, layout, options, done) for path, layout in jobs]


#: Probes per Dask task: at most this many, and few enough that every worker gets
#: ``TASKS_PER_WORKER`` tasks or more (the last tasks of a batch keep all workers busy).
MAX_CHUNK = 8
TASKS_PER_WORKER = 4


def chunk_size(n: int, workers: int) -> int:
    """Probes per task for ``n`` probes on ``workers`` worker threads: one task costs the
    scheduler, the client and the worker 7–10 ms of CPU on the 2-core box (a tenth of a 2k
    probe's work), so large batches send ``MAX_CHUNK`` probes a task; small ones keep
    ``TASKS_PER_WORKER`` tasks per worker so that none idles long at the end (tasks go
    largest files first: the last ones are the cheapest)."""
    return max(1, min(MAX_CHUNK, n // max(1, TASKS_PER_WORKER * workers)))


def _by_size(jobs: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """Largest files first (a batch ends on small probes, not on one big one)."""
    def size(job: tuple[str, str]) -> int:
        try:
            return os.stat(job[0]).st_size
        except OSError:
            return 0

    return sorted(jobs, key=size, reverse=True)


#: Dask settings of the local cluster ``shprobe batch`` starts. It has no dashboard, so no use
#: for the workers' statistical profiler (a stack sample every 10 ms) or for system metrics
#: every 0.5 s; the event-loop tick (a blocked-loop diagnostic, every 20 ms in each process)
#: runs every second; work stealing and the memory monitor look every second and 0.5 s.
#: Together they halve what an idle 2-worker cluster costs (0.074 → 0.032 CPU-s per second on
#: the 2-core box, bench/bench_batch.py) — CPU the probes then have.
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.scheduler.work-stealing-interval": "1s",
    "distributed.worker.memory.monitor-interval": "500ms",
}


def _local_cluster(workers: int | None):
    import dask
    from distributed import LocalCluster

    n = int(workers) if workers else (os.cpu_count() or 1)
    with dask.config.set(LOCAL_CLUSTER_CONFIG):
        cluster = LocalCluster(n_workers=max(1, n), threads_per_worker=1, processes=True,
                               dashboard_address=None, host="127.0.0.1",
                               silence_logs=logging.ERROR)
    cluster._shprobe_keep_heap = True  # shprobe's own workers: see _WarmPlugin
    return cluster


def _run_inline(jobs, options, done) -> Iterator[dict[str, Any]]:
    _warm()
    for path, layout in jobs:
        yield probe_row(path, layout, options, done)


def _run_dask(jobs, options, done, client, chunk: int | None = None
              ) -> Iterator[dict[str, Any]]:
    """Rows from tasks of `chunk_size` probes, largest files first. A task that fails
    (its worker died too often) is split into one task per probe, so only the probe that
    kills workers becomes an error row."""
    from distributed import as_completed

    try:
        own = getattr(getattr(client, "cluster", None), "_shprobe_keep_heap", False)
        client.register_plugin(_plugin(keep_heap=own is True))
    except Exception:  # an old scheduler without plugins: workers warm on their first task
        pass
    # scattered as one object: scatter() of a set scatters its elements, and a task given a
    # frozenset of futures would see no hash in it (a resume on Dask recomputed everything)
    done_f = client.scatter([done], broadcast=True)[0] if done else done
    try:
        threads = sum(client.nthreads().values())
    except Exception:
        threads = os.cpu_count() or 1
    jobs = _by_size(list(jobs))
    k = max(1, int(chunk)) if chunk is not None else chunk_size(len(jobs), threads)
    jobs_of = {}

    def submit(part: list[tuple[str, str]]):
        f = client.submit(_task, part, options, done_f, pure=False,
                          key=f"shprobe-probes-{len(jobs_of)}-{secrets.token_hex(4)}")
        jobs_of[f] = part
        return f

    pending = as_completed([submit(jobs[i:i + k]) for i in range(0, len(jobs), k)])
    try:
        for f in pending:
            part = jobs_of.pop(f)
            try:
                rows = f.result()
            except Exception as e:  # the task itself never raises: a worker died too often
                rows = [empty_row(part[0][0]) | {
                    "failure": f"{part[0][0]}: worker failed: {type(e).__name__}: "
                             + " ".join(str(e).split())[:300]}]
                if len(part) > 1:  # find the probe that does it: one task each
                    rows = []
                    for job in part:
                        pending.add(submit([job]))
            f.release()
            yield from rows
    finally:
        if jobs_of:
            client.cancel(list(jobs_of), force=True)


def _plugin(keep_heap: bool = False):
    from distributed.diagnostics.plugin import WorkerPlugin

    class WarmPlugin(_WarmPlugin, WorkerPlugin):
        pass

    return WarmPlugin(keep_heap)
