"""The batch engine: probes → rows on Dask (a local cluster, an existing one, or in-process),
written to Parquet in atomically committed parts, resumable by content hash.

Output ``T.parquet``: while a batch runs, finished rows are written every ``flush_rows`` rows
(or ``flush_seconds``) as ``T.parquet.parts/part-*.parquet``, each written to a temporary
name and renamed (a part is whole or absent). When every probe is done the parts and any
previous ``T.parquet`` are merged into ``T.parquet`` (again temp + rename) and the parts
folder is removed. Re-running with the same output reads the table and any parts left by an
interrupted run, skips every file whose content hash already has a successful row (failed
rows are tried again) and computes the rest. Ctrl-C, or a crash, loses at most the rows not
yet flushed; a worker that dies has its probes recomputed by Dask on another worker. One
batch writes an output at a time (`shprobe.batch.lock.output_lock`, ``T.parquet.lock``).
"""

from __future__ import annotations

import json
import logging
import os
import secrets
import shutil
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ShprobeError
from ..files import atomic_output, check_output_path
from ..limits import check_disk
from .inputs import expand_inputs
from .lock import interruptible, output_lock
from .rows import COLUMNS, RENAMED, SCHEMA_VERSION, BatchOptions, empty_row, probe_row, schema
from .settings import BatchSettings, Engine

__all__ = ["BatchSettings", "Engine", "parts_dir", "read_table", "run_batch"]

#: Progress callback: (done, total) after each probe.
Progress = Callable[[int, int], None]


def parts_dir(output: str | os.PathLike[str]) -> Path:
    """Folder of the parts of ``output`` while a batch runs: ``<output>.parts``.

    Parameters
    ----------
    output
        The batch table's path.

    Returns
    -------
    Path
        ``<output>.parts``.
    """
    p = Path(output)
    return p.with_name(p.name + ".parts")


def table_meta(table: Any) -> dict[str, Any]:
    """The ``shprobe`` JSON metadata of a batch table ({} if absent)."""
    raw = (table.schema.metadata or {}).get(b"shprobe")
    return json.loads(raw) if raw else {}


def _upgrade(t: Any, path: Any):
    """A table (or part) of any schema version with today's column names (`RENAMED`);
    one made by a newer shprobe is refused."""
    version = table_meta(t).get("schema_version", 1)
    if not isinstance(version, int) or version > SCHEMA_VERSION:
        raise ShprobeError(f"is a batch table of schema version {version}; this shprobe reads "
                           f"versions up to {SCHEMA_VERSION} (upgrade shprobe)", path)
    names = [RENAMED.get(n, n) if version < 2 else n for n in t.column_names]
    if names == t.column_names:
        return t
    return t.rename_columns(names).replace_schema_metadata(t.schema.metadata)


def read_table(path: str | os.PathLike[str]):
    """A batch table (pyarrow.Table) with its metadata, columns named as today (a table of an
    older schema version has its renamed columns renamed); one line for a file that is not
    one.

    Parameters
    ----------
    path
        A batch table (``.parquet``).

    Returns
    -------
    pyarrow.Table
        The table with its metadata.
    """
    import pyarrow.parquet as pq

    if os.path.exists(path) and not os.path.isfile(path):
        raise ShprobeError("is not a regular file", path)
    try:
        t = pq.read_table(path)
    except FileNotFoundError:
        raise ShprobeError("no such file", path) from None
    except Exception as e:
        raise ShprobeError(f"not a Parquet table: {' '.join(str(e).split())[:200]}",
                           path) from None
    if "options" not in table_meta(t) or "content_hash" not in t.column_names:
        raise ShprobeError("not a shprobe batch table", path)
    return _upgrade(t, path)


def _rows_table(rows: list[dict[str, Any]], meta: dict[str, Any]):
    import pyarrow as pa

    clean = [{k: r.get(k) for k in COLUMNS} for r in rows]
    return pa.Table.from_pylist(clean, schema=schema(meta))


#: Bytes of a table row on disk, with room (a row is ~1 kB of numbers and strings, its
#: thumbnail a few kB of PNG), for the free-space check before a batch starts.
ROW_BYTES = 16 << 10


def _write_part(folder: Path, rows: list[dict[str, Any]], meta: dict[str, Any]) -> Path:
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    p = folder / f"part-{time.time_ns():020d}-{os.getpid()}-{secrets.token_hex(3)}.parquet"
    try:
        with atomic_output(p) as tmp:
            pq.write_table(_rows_table(rows, meta), tmp)
    except BaseException as e:
        try:  # a full disk on the first part: no empty parts folder left behind
            folder.rmdir()
        except OSError:
            pass
        if isinstance(e, ShprobeError):  # name the table, not a part of it
            raise ShprobeError(e.message, folder.with_name(folder.name[:-6])) from None
        raise
    return p


def _existing_rows(output: Path, meta: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of a previous table and of parts left by an interrupted run (refused when they
    were made with other options)."""
    import pyarrow.parquet as pq

    tables = []
    if output.exists():
        tables.append((output, read_table(output)))
    folder = parts_dir(output)
    if folder.is_dir():
        for p in sorted(folder.glob("part-*.parquet")):
            try:
                t = pq.read_table(p)
            except Exception:  # a part is renamed into place whole; anything else is not ours
                continue
            tables.append((p, _upgrade(t, p)))
    rows: list[dict[str, Any]] = []
    for p, t in tables:
        have = table_meta(t).get("options")
        want = meta["options"]
        old_hash = (have or {}).get("hash")
        if isinstance(have, dict) and old_hash != want["hash"]:
            raise ShprobeError(f"its content hashes are {old_hash} and this shprobe makes "
                               f"{want['hash']}: they cannot be matched to resume; choose "
                               "another output or pass --force to start afresh", p)
        if have != want:
            raise ShprobeError(f"was made with other options ({have}, now {meta['options']}); "
                               "choose another output or pass --force to start afresh", p)
        rows += t.to_pylist()
    return rows


def _merge(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per path, the last one given winning; sorted by path."""
    by_path: dict[str, dict[str, Any]] = {}
    for r in rows:
        by_path[r["path"]] = r
    return [by_path[k] for k in sorted(by_path)]


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


def run_batch(inputs: str | os.PathLike[str] | Iterable[str | os.PathLike[str]],
              output: str | os.PathLike[str] | None = None,
              settings: BatchSettings | None = None, progress: Progress | None = None, *,
              force: bool = False, **changes: Any):
    """Compute the batch table of INPUTS and return it, sorted by path.

    Parameters
    ----------
    inputs
        Files, folders, globs or lists of paths
        ([`shprobe.batch.expand_inputs`][shprobe.batch.expand_inputs]).
    output
        A ``.parquet`` table: written in parts (every ``flush_rows`` rows or
        ``flush_seconds``) and committed atomically, resumable (module doc); None: none.
    settings
        The run's [`BatchSettings`][shprobe.batch.BatchSettings] (default: lmax 2 on a local Dask
        cluster).
    progress
        Gets one stage counting the probes (`shprobe.progress`).
    force
        Start afresh: an existing table made with other options is refused without it.
    **changes
        Fields of [`BatchSettings`][shprobe.batch.BatchSettings] changed from ``settings``
        (``options=``, ``engine=``, ``layout=``, ``flush_rows=``, ``flush_seconds=``).

    Returns
    -------
    pyarrow.Table
        Columns [`shprobe.batch.COLUMNS`][shprobe.batch.COLUMNS], one row per probe.
    """
    import numpy as np  # noqa: F401  (fail early if the stack is broken)

    settings = settings if settings is not None else BatchSettings()
    changes = {k: v for k, v in changes.items() if v is not None}
    if changes:
        settings = replace(settings, **changes)
    o = settings.options or BatchOptions()
    options = BatchOptions(lmax=int(o.lmax), clamp=bool(o.clamp),
                           reference=None if not o.reference else int(o.reference),
                           thumbnail=int(o.thumbnail or 0), window=bool(o.window),
                           block_bytes=int(o.block_bytes))
    from ..sh import check_lmax

    check_lmax(options.lmax)
    meta = {"options": options.key()}
    out = None if output is None else Path(output)
    if out is not None:
        if out.suffix.lower() != ".parquet":
            raise ShprobeError("the batch table must be a .parquet file", out)
        check_output_path(out, overwrite=True)
    settings = replace(settings, options=options)
    with output_lock(out), interruptible() as interrupted:
        return _run(inputs, out, settings, meta, force, progress, interrupted)


def _run(inputs, out: Path | None, settings: BatchSettings, meta: dict[str, Any],
         force: bool, progress: Progress | None, interrupted: list[int]):
    """[`run_batch`][shprobe.batch.run_batch] once the output is locked."""
    layout, options, engine = settings.layout, settings.options, settings.engine
    old: list[dict[str, Any]] = []
    if out is not None:
        if force:
            shutil.rmtree(parts_dir(out), ignore_errors=True)
        else:
            old = _existing_rows(out, meta)
    jobs = expand_inputs(inputs, layout)
    good = {r["content_hash"]: r for r in old
            if r.get("failure") is None and r.get("content_hash")}
    done = frozenset(good)
    total = len(jobs)
    if out is not None:  # a full disk is said before any work, not after the first part
        check_disk(out.parent, (total + len(old)) * ROW_BYTES + (1 << 20),
                   f"a batch table of {total + len(old):,} rows", out)
    fresh: list[dict[str, Any]] = []
    pending: list[dict[str, Any]] = []
    last = time.monotonic()
    n_done = 0
    flush_rows, flush_seconds = settings.flush_rows, settings.flush_seconds
    if progress is not None:
        progress.begin(f"prefiltering {total:,} probes", total)

    def flush() -> None:
        nonlocal last
        if out is not None and pending:
            _write_part(parts_dir(out), pending, meta)
        pending.clear()
        last = time.monotonic()

    own = None
    client = engine.client
    try:
        if client is None and engine.scheduler != "inline":
            addr = engine.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
            from distributed import Client

            if addr:
                client = own = Client(addr, timeout="30s")
            else:
                cluster = _local_cluster(engine.workers)
                client = own = Client(cluster)
                own._shprobe_cluster = cluster  # closed below
        rows = (_run_inline(jobs, options, done) if client is None
                else _run_dask(jobs, options, done, client, engine.chunk))
        for row in rows:
            if interrupted:  # a Ctrl-C that a library swallowed on its way
                raise KeyboardInterrupt
            if row.pop("skipped", False):
                src = good[row["content_hash"]]
                if src["path"] != row["path"]:  # same content under another path: copy
                    row = dict(src) | {"path": row["path"], "size_bytes": row["size_bytes"],
                                       "seconds": 0.0}
                    fresh.append(row)
                    pending.append(row)
            else:
                fresh.append(row)
                pending.append(row)
            n_done += 1
            if progress is not None:
                progress.update(n_done)
            if len(pending) >= flush_rows or time.monotonic() - last >= flush_seconds:
                flush()
        flush()
        if interrupted:
            raise KeyboardInterrupt
    except BaseException:
        try:
            flush()  # Ctrl-C or a crash: keep what is finished
        except Exception:  # the same full disk again: the first error is the one said
            pass
        raise
    finally:
        if progress is not None:
            progress.end()
        if own is not None:
            cluster = getattr(own, "_shprobe_cluster", None)
            own.close()
            if cluster is not None:
                cluster.close()
    merged = _merge(old + fresh)
    table = _rows_table(merged, meta)
    if out is not None:
        import pyarrow.parquet as pq

        with atomic_output(out, overwrite=True) as tmp:
            pq.write_table(table, tmp)
        shutil.rmtree(parts_dir(out), ignore_errors=True)
    if interrupted:
        raise KeyboardInterrupt
    return table
