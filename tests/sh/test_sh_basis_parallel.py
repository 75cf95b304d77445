"""sh_basis on several cores: a large output is cut into blocks of rows that the calling
thread and pool threads take in turn; the rows equal those of one call per small batch (bit
for bit), for the unrolled kernels and the table kernel, plain and streaming stores, any
alignment; an error in a pool thread reaches the caller; small outputs stay serial."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from shprobe import ShprobeError
from shprobe.sh import sh_basis
from tests.conftest import random_dirs


def _serial(d, lmax):
    return np.concatenate([sh_basis(d[i:i + 64], lmax) for i in range(0, len(d), 64)])


@pytest.fixture
def blocks(monkeypatch):
    """Every output parallel (3 'cores'), and a record of the threads that filled blocks."""
    import shprobe.sh.basis as basis

    monkeypatch.setattr(basis, "PARALLEL_MIN_VALUES", 1)
    monkeypatch.setattr(basis, "cores", lambda: 3)
    seen = []
    real = basis._kernel_rows

    def spy(flat, out, *args):
        seen.append((threading.get_ident(), len(flat)))
        return real(flat, out, *args)

    monkeypatch.setattr(basis, "_kernel_rows", spy)
    return seen


def test_blocks_on_several_threads_equal_serial_rows(blocks, monkeypatch):
    import shprobe.sh.basis as basis

    d = random_dirs(2003, seed=5)
    for lmax, dtype in ((0, np.float64), (2, np.float32), (6, np.float64), (9, np.float32),
                        (20, np.float64)):
        dd = d.astype(dtype)
        monkeypatch.setattr(basis, "cores", lambda: 1)
        want = _serial(dd, lmax)
        monkeypatch.setattr(basis, "cores", lambda: 3)
        blocks.clear()
        np.testing.assert_array_equal(sh_basis(dd, lmax), want)  # fresh output
        assert len(blocks) == basis.PARALLEL_BLOCKS  # every block once, all rows
        assert sum(n for _, n in blocks) == len(d)
        monkeypatch.setattr(basis, "STREAM_MIN_BYTES", 0)
        monkeypatch.setattr(basis, "UNROLLED_STREAM_MIN_BYTES", 0)
        K = (lmax + 1) ** 2
        big = np.full(len(d) * K + 7, np.nan, dtype)
        for off in (0, 1, 3):  # streaming stores, each block aligned on its own
            out = big[off:off + len(d) * K].reshape(len(d), K)
            np.testing.assert_array_equal(sh_basis(dd, lmax, out=out), want)
        assert np.isnan(big[len(d) * K + 3:]).all()


def test_pool_threads_fill_blocks_and_their_errors_reach_the_caller(monkeypatch):
    import shprobe.sh.basis as basis

    monkeypatch.setattr(basis, "PARALLEL_MIN_VALUES", 1)
    monkeypatch.setattr(basis, "cores", lambda: 2)
    main = threading.get_ident()
    helper_in = threading.Event()
    seen = []
    real = basis._kernel_rows

    def spy(flat, out, *args):
        # the calling thread waits (at most 10 s) until a pool thread has taken a block
        if threading.get_ident() == main:
            helper_in.wait(10)
        else:
            helper_in.set()
            if fail:
                raise ShprobeError("raised in a pool thread")
        seen.append(threading.get_ident())
        return real(flat, out, *args)

    monkeypatch.setattr(basis, "_kernel_rows", spy)
    fail = False
    d = random_dirs(4000, seed=2)
    np.testing.assert_array_equal(sh_basis(d, 2), _serial(d, 2))
    assert main in seen and len(set(seen)) >= 2  # the caller and at least one pool thread
    helper_in.clear()
    fail = True
    with pytest.raises(ShprobeError, match="pool thread"):
        sh_basis(d, 2)


def test_small_outputs_stay_in_the_calling_thread(monkeypatch):
    import shprobe.sh.basis as basis

    submitted = []
    monkeypatch.setattr(basis, "_pool", lambda n: submitted.append(n))
    n = basis.PARALLEL_MIN_VALUES // 9  # under one block per core at lmax 2
    sh_basis(random_dirs(n, seed=1), 2)
    assert submitted == []


def test_a_forked_child_fills_blocks_too():
    # the child's copy of the pool has no threads: it starts its own (and never waits on
    # the parent's); the values are the serial ones. In a fresh interpreter: forking this
    # one (which may hold JAX's threads) is not safe.
    import subprocess
    import sys

    code = """
import multiprocessing, numpy as np
import shprobe.sh.basis as basis
from shprobe.sh import sh_basis
basis.PARALLEL_MIN_VALUES = 1
basis.cores = lambda: 3
d = np.random.default_rng(9).normal(size=(3001, 3))
d /= np.linalg.norm(d, axis=1, keepdims=True)
want = sh_basis(d, 4)  # the parent's pool now exists
with multiprocessing.get_context("fork").Pool(1) as p:
    got = p.apply_async(sh_basis, (d, 4)).get(timeout=60)
basis.cores = lambda: 1
assert (got == want).all() and (want == sh_basis(d, 4)).all()
print("ok")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr
