"""numba kernels of the lighting layer: projection, brute-force irradiance and the quadratic
form of the shading path (imported lazily: numba is slow to import)."""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def sh_into(x, y, z, lmax, a, b, out):
    # the normalised LH recurrence of shprobe.sh, for one direction
    sqrt2 = math.sqrt(2.0)
    c = 1.0
    s = 0.0
    pmm = 0.5 / math.sqrt(math.pi)
    for m in range(lmax + 1):
        if m > 0:
            c, s = x * c - y * s, x * s + y * c
            pmm = pmm * math.sqrt((2.0 * m + 1.0) / (2.0 * m))
        p1 = pmm
        p2 = 0.0
        for l in range(m, lmax + 1):
            if l == m:
                p = pmm
            elif l == m + 1:
                p = math.sqrt(2.0 * m + 3.0) * z * pmm
            else:
                p = a[l, m] * (z * p1 - b[l, m] * p2)
            p2 = p1
            p1 = p
            k0 = l * (l + 1)
            if m == 0:
                out[k0] = p
            else:
                out[k0 + m] = sqrt2 * p * c
                out[k0 - m] = sqrt2 * p * s


def _brute(nrm, dT, lwT, out):  # pragma: no cover - compiled twice below
    t = nrm.shape[0]
    s = dT.shape[1]
    for i in numba.prange(t):
        nx, ny, nz = nrm[i, 0], nrm[i, 1], nrm[i, 2]
        r = 0.0
        g = 0.0
        bb = 0.0
        for j in range(s):
            c = nx * dT[0, j] + ny * dT[1, j] + nz * dT[2, j]
            c = max(c, 0.0)
            r += c * lwT[0, j]
            g += c * lwT[1, j]
            bb += c * lwT[2, j]
        out[i, 0] += r
        out[i, 1] += g
        out[i, 2] += bb


#: Σ_j max(0, n·ω_j) L_j dω_j for many normals (parallel over them) …
brute_kernel = numba.njit(cache=True, parallel=True, fastmath=True)(_brute)
#: … and for a few at a time (the refinement's small batches: no thread start-up per call)
brute_serial = numba.njit(cache=True, fastmath=True)(_brute)


@numba.njit(cache=True, parallel=True, fastmath=True)
def project_rgb_kernel(d, v, w, lmax, a, b, nblk):
    """Σ_s v_s y(d_s) w_s for 3 channels in ``nblk`` blocks → (nblk, K, 3); pixels with
    w = 0 are skipped; l ≤ 2 uses the closed forms of R&H eq. 3, higher l the recurrence."""
    ns = d.shape[0]
    k = (lmax + 1) * (lmax + 1)
    out = np.zeros((nblk, k, 3))
    step = (ns + nblk - 1) // nblk
    c0 = 0.5 / math.sqrt(math.pi)
    c1 = math.sqrt(3.0 / (4.0 * math.pi))
    c2 = 0.5 * math.sqrt(15.0 / math.pi)
    c20 = 0.25 * math.sqrt(5.0 / math.pi)
    c22 = 0.25 * math.sqrt(15.0 / math.pi)
    for blk in numba.prange(nblk):
        y = np.empty(k)
        acc = np.zeros((k, 3))
        for s in range(blk * step, min(ns, (blk + 1) * step)):
            ws = w[s]
            if ws == 0.0:
                continue
            x, yy, z = d[s, 0], d[s, 1], d[s, 2]
            if lmax <= 2:
                y[0] = c0
                if lmax >= 1:
                    y[1] = c1 * yy
                    y[2] = c1 * z
                    y[3] = c1 * x
                if lmax == 2:
                    y[4] = c2 * x * yy
                    y[5] = c2 * yy * z
                    y[6] = c20 * (3.0 * z * z - 1.0)
                    y[7] = c2 * x * z
                    y[8] = c22 * (x * x - yy * yy)
            else:
                sh_into(x, yy, z, lmax, a, b, y)
            r = v[s, 0] * ws
            g = v[s, 1] * ws
            bb = v[s, 2] * ws
            for i in range(k):
                acc[i, 0] += y[i] * r
                acc[i, 1] += y[i] * g
                acc[i, 2] += y[i] * bb
        out[blk] = acc
    return out


@numba.njit(cache=True, fastmath=False, nogil=True)
def quad_eval(n, q, out):  # pragma: no cover - compiled
    # q: (C, 10) = [xx, yy, zz, xy, xz, yz, x, y, z, 1] weights of E(n) = nᵀMn (R&H eq. 11),
    # at n/|n|; returns the number of zero or non-finite normals (their rows are 0)
    bad = 0
    for i in range(n.shape[0]):
        x = np.float64(n[i, 0])
        y = np.float64(n[i, 1])
        z = np.float64(n[i, 2])
        r2 = x * x + y * y + z * z
        if not (r2 > 0.0 and r2 < np.inf):
            bad += 1
            for c in range(q.shape[0]):
                out[i, c] = 0.0
            continue
        if abs(r2 - 1.0) > 1e-6:  # unit to float32 precision: used as given (|Δn| < 5e-7)
            s = 1.0 / math.sqrt(r2)
            x, y, z = x * s, y * s, z * s
        xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
        for c in range(q.shape[0]):
            out[i, c] = (q[c, 0] * xx + q[c, 1] * yy + q[c, 2] * zz + q[c, 3] * xy
                         + q[c, 4] * xz + q[c, 5] * yz + q[c, 6] * x + q[c, 7] * y
                         + q[c, 8] * z + q[c, 9])
    return bad
