"""shprobe batch on a real distributed.LocalCluster (2 worker processes × 1 thread, on
127.0.0.1, no dashboard): the cluster's table equals the in-process one row for row, and a
worker killed mid-batch loses nothing."""

from __future__ import annotations

import logging
import os
import signal

import dask
import numpy as np
import pytest

from shprobe.batch import BatchOptions, Engine, run_batch
from shprobe.batch.engine import LOCAL_CLUSTER_CONFIG, _local_cluster
from shprobe.probes.env import env_from_function, write_env
from shprobe.probes.environments import procedural_env
from shprobe.progress import Recorder

INLINE = Engine(scheduler="inline")  # the batch in this process
REF4 = BatchOptions(reference=4)  # rows with the exact-irradiance error

distributed = pytest.importorskip("distributed")

#: columns that depend on the run, not on the probe
TIMING = ["seconds"]


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, host="127.0.0.1",
                                  silence_logs=logging.ERROR) as c:
        yield c


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    root = tmp_path_factory.mktemp("lib")
    for i in range(6):
        write_env(root / f"p{i}.{'exr' if i % 2 else 'hdr'}", procedural_env(96 + 32 * i,
                                                                            48 + 16 * i))
    write_env(root / "cube.exr", env_from_function(lambda d: 1 + 0.5 * d, "cube", 12))
    (root / "broken.hdr").write_bytes(b"#?RADIANCE\n\n-Y 4 +X 8\n\x02\x02")
    return root


@pytest.fixture(scope="module")
def inline(library):
    return run_batch([library], None, options=REF4, engine=INLINE).table


def _close(x, y, where: str) -> None:
    """Equal values, floats to rounding, recursively through lists; nulls where nulls are."""
    if isinstance(x, float) and isinstance(y, float):
        assert x == y or abs(x - y) <= 1e-12 + 1e-9 * max(abs(x), abs(y)), (where, x, y)
    elif isinstance(x, list) and isinstance(y, list):
        assert len(x) == len(y), where
        for i, (u, v) in enumerate(zip(x, y, strict=True)):
            _close(u, v, f"{where}[{i}]")
    else:
        assert x == y, (where, x, y)  # text, hashes, errors, nulls, integers: exactly


def _same_rows(a, b) -> None:
    """Row for row: every column equal, floating-point values to rounding (a worker's BLAS and
    thread count may sum in another order than this process: last bits only)."""
    a, b = a.drop(TIMING), b.drop(TIMING)
    assert a.schema.equals(b.schema) and a.num_rows == b.num_rows
    for name in a.column_names:
        if not a.column(name).equals(b.column(name)):
            _close(a.column(name).to_pylist(), b.column(name).to_pylist(), name)


def test_cluster_table_equals_inline(cluster, library, inline, tmp_path):
    out = tmp_path / "t.parquet"
    t = run_batch([library], out, options=REF4,
                  engine=Engine(scheduler=cluster.scheduler_address)).table
    assert t.num_rows == 8 and t.column("failure").null_count == 7
    _same_rows(t, inline)
    assert np.isfinite(np.asarray(t.column("seconds"))).all()
    # tasks of 3 probes (8 probes: 3 + 3 + 2): the same rows
    _same_rows(run_batch([library], None, options=REF4,
                         engine=Engine(scheduler=cluster.scheduler_address, chunk=3)).table, inline)
    # a user's cluster keeps its heap (Dask's MALLOC_TRIM_THRESHOLD_=65536): a second 16 MiB
    # buffer is mapped afresh, page by page
    with distributed.Client(cluster) as client:
        for state in client.run(_worker_state).values():
            assert state["faults"] > 3000, state


def test_killed_worker_loses_nothing(cluster, library, inline, tmp_path):
    client = distributed.Client(cluster)
    try:
        pids = client.run(os.getpid)
        killed = []

        class KillOne(Recorder):  # a shprobe.progress reporter
            def update(self, done):
                if done == 2 and not killed:  # mid-batch: the others are queued or running
                    pid = sorted(pids.values())[0]
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)

        t = run_batch([library], tmp_path / "t.parquet", options=REF4,
                      engine=Engine(client=client), progress=KillOne()).table
        assert killed
        client.wait_for_workers(2, timeout=60)  # the nanny restarted it
        assert killed[0] not in client.run(os.getpid).values()
    finally:
        client.close()
    _same_rows(t, inline)


def _worker_state():
    """In a worker: its Dask settings, and the page faults of a second 16 MiB buffer."""
    import resource

    import dask

    a = bytearray(16 << 20)
    del a
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = bytearray(16 << 20)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0
    del a
    return {k: dask.config.get(k) for k in LOCAL_CLUSTER_CONFIG} | {"faults": faults}


def test_own_local_cluster(library, inline):
    """The cluster `shprobe batch` starts: its settings reach the workers, the batch plugin
    lets them reuse freed buffers (Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536), rows as
    in-process."""
    cluster = _local_cluster(1)
    try:
        with distributed.Client(cluster) as client:
            t = run_batch([library], None, options=REF4, engine=Engine(client=client)).table
            state = next(iter(client.run(_worker_state).values()))
            with distributed.get_task_stream(client) as stream:  # chunk below 1: one a task
                t0 = run_batch([library], None, options=REF4,
                               engine=Engine(client=client, chunk=0)).table
    finally:
        cluster.close()
    _same_rows(t, inline)
    _same_rows(t0, inline)
    assert sum(str(d["key"]).startswith("shprobe-probes-") for d in stream.data) == 8
    assert state.pop("faults") < 300
    assert state == LOCAL_CLUSTER_CONFIG


class _Poison:
    """Worker plugin: in every worker (restarted ones too), a probe named ``poison*`` kills
    the worker process, as a decoder crash would."""

    name = "shprobe-test-poison"

    def setup(self, worker):
        from shprobe.batch import cluster

        real = cluster.probe_row

        def probe_row(path, *a, **k):
            if os.path.basename(path).startswith("poison"):
                os._exit(1)
            return real(path, *a, **k)

        cluster.probe_row = probe_row


def test_probe_that_kills_workers_is_one_error_row(library, inline, tmp_path):
    """A task of several probes whose worker dies is split into one task per probe: only the
    probe that kills workers becomes an error row, every other row is as in-process."""
    from distributed.diagnostics.plugin import WorkerPlugin

    poison = tmp_path / "poison.hdr"
    poison.write_bytes((library / "p0.hdr").read_bytes())
    # one worker, one task on it at a time, no retries: the task that dies is exactly the one
    # that held the poison (a queued innocent probe would otherwise die with it)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}):
        cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                           dashboard_address=None, host="127.0.0.1",
                                           silence_logs=logging.CRITICAL)
    try:
        with distributed.Client(cluster) as client:
            client.register_plugin(type("Poison", (_Poison, WorkerPlugin), {})())
            t = run_batch([library, poison], None, options=REF4, engine=Engine(client=client,
                          chunk=3)).table
    finally:
        cluster.close()
    paths = t.column("path").to_pylist()
    errors = dict(zip(paths, t.column("failure").to_pylist(), strict=True))
    assert "worker failed" in errors.pop(str(poison))
    assert [os.path.basename(n) for n, e in errors.items() if e] == ["broken.hdr"]
    keep = [i for i, n in enumerate(paths) if n != str(poison)]
    _same_rows(t.take(keep).sort_by("path"), inline.sort_by("path"))
