"""numba kernel for :func:`shprobe.sh.sh_basis` (imported lazily; compiled once, cached on disk).

Same normalised recurrence as ``shprobe.sh.sh_basis_numpy`` (see the ``shprobe.sh`` module
docstring), run per direction with the result written straight into the output row.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def sh_rows(dirs, lmax, a, b, diag, out):
    """out[i, k] = y_k(dirs[i]) for dirs (N, 3), out (N, (lmax+1)²) (any float types).

    ``a``, ``b``: interior recurrence tables [l, m]; ``diag[m]`` = √((2m+1)/(2m)).
    """
    n = dirs.shape[0]
    p00 = 0.5 / np.sqrt(np.pi)
    sqrt2 = np.sqrt(2.0)
    for i in range(n):
        x = np.float64(dirs[i, 0])
        y = np.float64(dirs[i, 1])
        z = np.float64(dirs[i, 2])
        row = out[i]
        # m = 0 column: plain Legendre-like recurrence
        p2 = p00
        row[0] = p2
        if lmax >= 1:
            p1 = np.sqrt(3.0) * z * p2
            row[2] = p1
            for l in range(2, lmax + 1):
                p = a[l, 0] * (z * p1 - b[l, 0] * p2)
                row[l * (l + 1)] = p
                p2 = p1
                p1 = p
        c = sqrt2  # √2 Re (x+iy)^m
        s = 0.0  # √2 Im (x+iy)^m
        pmm = p00
        for m in range(1, lmax + 1):
            c, s = x * c - y * s, x * s + y * c
            pmm = pmm * diag[m]
            k0 = m * (m + 1)
            row[k0 + m] = pmm * c
            row[k0 - m] = pmm * s
            if m < lmax:
                p2 = pmm
                p1 = np.sqrt(2.0 * m + 3.0) * z * pmm
                k0 = (m + 1) * (m + 2)
                row[k0 + m] = p1 * c
                row[k0 - m] = p1 * s
                for l in range(m + 2, lmax + 1):
                    p = a[l, m] * (z * p1 - b[l, m] * p2)
                    k0 = l * (l + 1)
                    row[k0 + m] = p * c
                    row[k0 - m] = p * s
                    p2 = p1
                    p1 = p
