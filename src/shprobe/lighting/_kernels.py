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


@numba.njit(cache=True, fastmath=True, inline="always")
def _brute_one(nrm, i, dT, lwT, out):
    nx, ny, nz = nrm[i, 0], nrm[i, 1], nrm[i, 2]
    r = 0.0
    g = 0.0
    bb = 0.0
    for j in range(dT.shape[1]):
        c = nx * dT[0, j] + ny * dT[1, j] + nz * dT[2, j]
        c = max(c, 0.0)
        r += c * lwT[0, j]
        g += c * lwT[1, j]
        bb += c * lwT[2, j]
    out[i, 0] += r
    out[i, 1] += g
    out[i, 2] += bb


# Two functions, not one compiled twice: numba's on-disk cache is keyed by the function's
# name, so a serial and a parallel compilation of one function share a cache entry and one
# silently loads the other (a parallel launch per small batch cost ~16 ms on the loaded box).
@numba.njit(cache=True, parallel=True, fastmath=True)
def brute_kernel(nrm, dT, lwT, out):  # pragma: no cover - compiled
    """Σ_j max(0, n·ω_j) L_j dω_j for many normals (parallel over them) …"""
    for i in numba.prange(nrm.shape[0]):
        _brute_one(nrm, i, dT, lwT, out)


@numba.njit(cache=True, fastmath=True)
def brute_serial(nrm, dT, lwT, out):  # pragma: no cover - compiled
    """… and for a few at a time (small batches: no thread start-up per call)."""
    for i in range(nrm.shape[0]):
        _brute_one(nrm, i, dT, lwT, out)


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


# ----------------------------------------------------------------------------- exact E on a
# lat-long map, row by row: for a normal n the lit pixels of a row (n·ω > 0) are one cyclic run
# of columns, so Σ_lit L dω (n·ω) = n · Σ_lit L dω ω comes from per-row prefix sums (O(H) per
# normal instead of O(H·W)); the run's ends are found in closed form and then checked pixel by
# pixel with the same sign test as the brute-force sum, so the same pixels count.


@numba.njit(cache=True, inline="always")
def _lit(nx, nz, a, s, cx, cz, j, w):
    jj = j  # 0 ≤ j < 5w: subtract instead of an integer division
    while jj >= w:
        jj -= w
    return a + s * (nx * cx[jj] + nz * cz[jj]) > 0.0


@numba.njit(cache=True, inline="always")
def _acos_guess(x):
    # arccos to ~7e-5 rad (Abramowitz & Stegun 4.4.45): only a first guess of a run's ends,
    # which the sign test then corrects pixel by pixel (a tenth of a column at W = 8192)
    ax = abs(x)
    r = math.sqrt(1.0 - ax) * (1.5707288 + ax * (-0.2121144 + ax * (0.0742610
                                                                  - 0.0187293 * ax)))
    return r if x >= 0.0 else math.pi - r


@numba.njit(cache=True)
def latlong_exact_into(nx, ny, nz, ct, st, cx, cz, pre, e):  # pragma: no cover - compiled
    """E_c(n) = Σ_pixels L_c dω max(0, n·ω) → e (C,), from ``pre`` (H, W+1, 3C): per row the
    prefix sums over columns of L_c dω, L_c dω ω_x/sinθ, L_c dω ω_z/sinθ (channel-major)."""
    h = ct.shape[0]
    w = cx.shape[0]
    nch = e.shape[0]
    for c in range(nch):
        e[c] = 0.0
    rho = math.sqrt(nx * nx + nz * nz)
    # ω_x/sinθ = −sin ψ, ω_z/sinθ = cos ψ: n_x ω_x + n_z ω_z = ρ sinθ cos(ψ − β)
    beta = math.atan2(-nx, nz)
    scale = w / (2.0 * math.pi)
    jc = beta * scale - 0.5  # the column index where ψ = β
    for r in range(h):
        a = ny * ct[r]
        s = st[r]
        bb = s * rho
        if a - bb > 0.0:  # the whole row is lit
            lo = 0
            cnt = w
        elif a + bb <= 0.0:
            continue
        else:
            hw = _acos_guess(min(1.0, max(-1.0, -a / bb))) * scale
            lo = math.ceil(jc - hw) + 2 * w  # ≥ w, so lo − 1 ≥ 0 below: see _lit
            hi = math.floor(jc + hw) + 2 * w
            # the closed form can be off by one at either end: check with the sign test
            while hi >= lo and not _lit(nx, nz, a, s, cx, cz, lo, w):
                lo += 1
            while hi >= lo and not _lit(nx, nz, a, s, cx, cz, hi, w):
                hi -= 1
            if hi < lo:  # a run narrower than a pixel: its centre column, if lit
                lo = math.floor(jc + 0.5) + 2 * w
                if not _lit(nx, nz, a, s, cx, cz, lo, w):
                    continue
                hi = lo
            while hi - lo + 1 < w and _lit(nx, nz, a, s, cx, cz, lo - 1, w):
                lo -= 1
            while hi - lo + 1 < w and _lit(nx, nz, a, s, cx, cz, hi + 1, w):
                hi += 1
            cnt = hi - lo + 1
            while lo >= w:
                lo -= w
        end = lo + cnt
        for c in range(nch):
            if end <= w:
                s0 = pre[r, end, 3 * c] - pre[r, lo, 3 * c]
                sx = pre[r, end, 3 * c + 1] - pre[r, lo, 3 * c + 1]
                sz = pre[r, end, 3 * c + 2] - pre[r, lo, 3 * c + 2]
            else:
                s0 = pre[r, w, 3 * c] - pre[r, lo, 3 * c] + pre[r, end - w, 3 * c]
                sx = pre[r, w, 3 * c + 1] - pre[r, lo, 3 * c + 1] + pre[r, end - w, 3 * c + 1]
                sz = pre[r, w, 3 * c + 2] - pre[r, lo, 3 * c + 2] + pre[r, end - w, 3 * c + 2]
            e[c] += a * s0 + s * (nx * sx + nz * sz)


@numba.njit(cache=True)
def latlong_exact(nrm, ct, st, cx, cz, pre, out):  # pragma: no cover - compiled
    """`latlong_exact_into` for normals (T, 3) → out (T, C): serially (small batches) …"""
    for i in range(nrm.shape[0]):
        latlong_exact_into(nrm[i, 0], nrm[i, 1], nrm[i, 2], ct, st, cx, cz, pre, out[i])


@numba.njit(cache=True, parallel=True)
def latlong_exact_parallel(nrm, ct, st, cx, cz, pre, out):  # pragma: no cover - compiled
    """… and in parallel over the normals (many)."""
    for i in numba.prange(nrm.shape[0]):
        latlong_exact_into(nrm[i, 0], nrm[i, 1], nrm[i, 2], ct, st, cx, cz, pre, out[i])


@numba.njit(cache=True)
def latlong_error(nrm, ct, st, cx, cz, pre, elm, a, b, inv_tot, out, chan
                  ):  # pragma: no cover - compiled
    """max_c |Σ_k E_lm,c y_k(n) − E_ref,c(n)| · inv_tot_c per normal → out (T,), and the
    channel where it occurs → chan (T,): the error of the SH irradiance (R&H eq. 7) against
    the exact sum, for the refinement's candidates (one call per batch, no temporaries)."""
    k = elm.shape[0]
    lmax = int(np.sqrt(k) + 0.5) - 1  # elm holds (lmax + 1)² coefficients
    nch = elm.shape[1]
    y = np.empty(k)
    e = np.empty(nch)
    for i in range(nrm.shape[0]):
        x, yy, z = nrm[i, 0], nrm[i, 1], nrm[i, 2]
        latlong_exact_into(x, yy, z, ct, st, cx, cz, pre, e)
        sh_into(x, yy, z, lmax, a, b, y)
        best = -1.0
        bc = 0
        for c in range(nch):
            v = 0.0
            for q in range(k):
                v += y[q] * elm[q, c]
            d = abs(v - e[c]) * inv_tot[c]
            if d > best:
                best = d
                bc = c
        out[i] = best
        chan[i] = bc
