"""The R&H 2001 table values and signs (DEVELOPERS.md, Conventions)."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe import ShprobeError, sh_basis, sh_index, sh_lm
from tests.conftest import random_dirs


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_rh_table(dtype):
    d = random_dirs(50, seed=1, dtype=dtype)
    x, y, z = d.T.astype(np.float64)
    want = np.stack([
        np.full_like(x, 0.282095),
        0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
        1.092548 * x * z, 0.546274 * (x * x - y * y),
    ], axis=-1)
    got = sh_basis(d, 2)
    assert got.dtype == dtype and got.shape == (50, 9)
    np.testing.assert_allclose(got, want, atol=2e-6)


def test_index_roundtrip():
    for k in range(400):
        l, m = sh_lm(k)
        assert abs(m) <= l and sh_index(l, m) == k
    assert sh_index(2, -2) == 4 and sh_index(1, 1) == 3
    # arrays: every (l, m) up to l = 300 in order, and back; bad pairs refused
    l = np.repeat(np.arange(301), 2 * np.arange(301) + 1)
    m = np.concatenate([np.arange(-j, j + 1) for j in range(301)])
    np.testing.assert_array_equal(sh_index(l, m), np.arange(301 ** 2))
    lb, mb = sh_lm(np.arange(301 ** 2).reshape(-1, 7))
    np.testing.assert_array_equal(lb.reshape(-1), l)
    np.testing.assert_array_equal(mb.reshape(-1), m)
    assert sh_lm(10**12 + 5) == (10**6, 5 - 10**6)
    with pytest.raises(ShprobeError):
        sh_index([1, 2], [2, 0])


def test_batched_shape():
    d = random_dirs(24, seed=2).reshape(2, 3, 4, 3)
    assert sh_basis(d, 3).shape == (2, 3, 4, 16)
