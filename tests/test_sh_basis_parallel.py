"""sh_basis on several cores: a large output is split into one block of rows per core, each
filled in its own thread; the rows equal those of one call per small batch (bit for bit),
for the unrolled kernels and the table kernel, plain and streaming stores, any alignment."""

from __future__ import annotations

import threading

import numpy as np

from shprobe.sh import sh_basis

from .conftest import random_dirs


def _serial(d, lmax):
    return np.concatenate([sh_basis(d[i:i + 64], lmax) for i in range(0, len(d), 64)])


def test_blocks_on_several_threads_equal_serial_rows(monkeypatch):
    import shprobe.sh.basis as basis

    d = random_dirs(2003, seed=5)
    for lmax, dtype in ((0, np.float64), (2, np.float32), (6, np.float64), (9, np.float32),
                        (20, np.float64)):
        dd = d.astype(dtype)
        want = _serial(dd, lmax)
        monkeypatch.setattr(basis, "PARALLEL_MIN_VALUES", 1)
        monkeypatch.setattr(basis, "cores", lambda: 3)  # 3 blocks, odd sizes
        started = []
        real_start = threading.Thread.start

        def start(self, started=started, real_start=real_start):
            started.append(self)
            real_start(self)

        monkeypatch.setattr(threading.Thread, "start", start)
        np.testing.assert_array_equal(sh_basis(dd, lmax), want)  # fresh output
        assert len(started) == 2  # the caller fills the first block
        monkeypatch.setattr(basis, "STREAM_MIN_BYTES", 0)
        monkeypatch.setattr(basis, "UNROLLED_STREAM_MIN_BYTES", 0)
        K = (lmax + 1) ** 2
        big = np.full(len(d) * K + 7, np.nan, dtype)
        for off in (0, 1, 3):  # streaming stores, each block aligned on its own
            out = big[off:off + len(d) * K].reshape(len(d), K)
            np.testing.assert_array_equal(sh_basis(dd, lmax, out=out), want)
        assert np.isnan(big[len(d) * K + 3:]).all()
        monkeypatch.undo()


def test_small_outputs_stay_in_the_calling_thread(monkeypatch):
    import shprobe.sh.basis as basis

    started = []
    monkeypatch.setattr(threading.Thread, "start", lambda self: started.append(self))
    n = basis.PARALLEL_MIN_VALUES // 9  # under one block per core at lmax 2
    sh_basis(random_dirs(n, seed=1), 2)
    assert started == []
