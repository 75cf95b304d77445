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
The table on disk is `shprobe.batch.table`'s; where the probes run, `shprobe.batch.cluster`'s.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ShprobeError
from ..files import atomic_output, check_output_path
from ..limits import check_disk
from .cluster import (  # noqa: F401  (re-exported: importable from here as before)
    _M_MMAP_THRESHOLD,
    _M_TRIM_THRESHOLD,
    LOCAL_CLUSTER_CONFIG,
    MAX_CHUNK,
    TASKS_PER_WORKER,
    WORKER_MMAP_THRESHOLD,
    WORKER_TRIM_THRESHOLD,
    _by_size,
    _keep_heap,
    _local_cluster,
    _plugin,
    _run_dask,
    _run_inline,
    _task,
    _warm,
    _WarmPlugin,
    chunk_size,
)
from .inputs import expand_inputs
from .lock import interruptible, output_lock
from .result import BatchResult
from .rows import BatchOptions
from .settings import BatchSettings, Engine
from .table import (  # noqa: F401  (re-exported: importable from here as before)
    ROW_BYTES,
    _existing_rows,
    _merge,
    _rows_table,
    _upgrade,
    _write_part,
    parts_dir,
    read_table,
    table_meta,
)

__all__ = ["BatchResult", "BatchSettings", "Engine", "parts_dir", "read_table", "run_batch"]

#: Progress callback: (done, total) after each probe.
Progress = Callable[[int, int], None]


def run_batch(inputs: str | os.PathLike[str] | Iterable[str | os.PathLike[str]],
              output: str | os.PathLike[str] | None = None,
              settings: BatchSettings | None = None, progress: Progress | None = None, *,
              force: bool = False, **changes: Any):
    """Compute the batch table of INPUTS (sorted by path) and return it with the run's figures.

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
    BatchResult
        ``table``: columns [`shprobe.batch.COLUMNS`][shprobe.batch.COLUMNS], one row per
        probe; the output, the rows computed, the seconds; ``as_dict()``.
    """
    import numpy as np  # noqa: F401  (fail early if the stack is broken)

    t0 = time.perf_counter()

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
        table, computed = _run(inputs, out, settings, meta, force, progress, interrupted)
    return BatchResult(table, out, computed, time.perf_counter() - t0)


def _run(inputs, out: Path | None, settings: BatchSettings, meta: dict[str, Any],
         force: bool, progress: Progress | None, interrupted: list[int]):
    """[`run_batch`][shprobe.batch.run_batch] once the output is locked: (the table, the
    rows computed)."""
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
    return table, len(fresh)
