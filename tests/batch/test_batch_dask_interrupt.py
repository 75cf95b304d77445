"""Ctrl-C to a `shprobe batch` driver on its own Dask cluster: the batch ends with exit 130
and one line, the rows it finished are committed as parts, and a resume keeps them and
computes only the rest (a real process, a real LocalCluster; heavy: run alone)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from shprobe.batch import parts_dir, read_table
from shprobe.batch.lock import lock_path
from shprobe.probes.env import write_env
from shprobe.probes.environments import procedural_env

pytest.importorskip("distributed")
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals")


def test_sigint_stops_a_dask_driver_and_loses_no_finished_row(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    n = 120  # tens of seconds of work on one worker: Ctrl-C comes in the middle
    for i in range(n):
        write_env(lib / f"p{i:03d}.hdr", procedural_env(384 + 4 * i, 192 + 2 * i))
    out = tmp_path / "T.parquet"
    cmd = [sys.executable, "-m", "shprobe", "batch", str(lib), "-o", str(out), "-j", "1",
           "--reference", "32"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not lock_path(out).exists():
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(6)  # the cluster starts, some probes finish
        assert proc.poll() is None, "the batch ended before Ctrl-C: make it longer"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert [x for x in err.splitlines() if x.strip()][-1] in ("shprobe: error: aborted",
                                                               "shprobe: error: interrupted")
    assert not out.exists() and not lock_path(out).exists()
    kept = {}
    for p in parts_dir(out).glob("part-*.parquet"):
        kept.update({r["path"]: r["seconds"] for r in pq.read_table(p).to_pylist()})
    assert len(kept) < n
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=400)
    assert r.returncode == 0, r.stderr
    rows = read_table(out).to_pylist()
    assert len(rows) == n and all(x["failure"] is None for x in rows)
    assert {x["path"]: x["seconds"] for x in rows if x["path"] in kept} == kept
