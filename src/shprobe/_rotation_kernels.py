"""numba kernels for :mod:`shprobe.rotation` (imported lazily: ``import shprobe`` stays fast).

Real-basis Wigner matrices in shprobe's basis (R&H signs), Lisle & Huang 2007 §2.2.

* ``d_tables(cb, sb, lmax)`` runs the LH recurrence for d^l(β). It only ever produces the
  same-sign quadrants: ``P`` holds d_{m,n} (m, n ≥ 0) and ``Q`` holds d_{−m,−n} (index 0 of Q
  unused), both packed per degree as (l+1)² row-major entries from offset l(l+1)(2l+1)/6.
  LH's basis carries the Condon–Shortley phase; removing it multiplies d_mn by (−1)^(m+n),
  which is d(−β), so the recurrence runs with sin β → −sin β.
* The recurrence is exact in exact arithmetic but, run forward in l, loses accuracy away
  from β = π/2 (orthogonality error 1e-3 at l = 40, β = 0.5); at β = π/2 it stays at
  ~1e-15 to l = 400. So it is evaluated once at β = π/2, giving J = d(π/2), and every
  rotation uses the identity Ry(β) = Rz(−π/2) Ry(−π/2) Rz(β) Ry(π/2) Rz(π/2), i.e.

      D(R) = Z(γ − π/2) Jᵀ Z(β) J Z(α + π/2)      for R = Rz(γ) Ry(β) Rz(α)   (LH eq. 6)

  with Z(φ) the real-basis z-rotation (2×2 rotations by mφ on the (m, −m) pairs).
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def pq_offset(l):
    return l * (l + 1) * (2 * l + 1) // 6


@nb.njit(cache=True)
def d_tables(cb, sb, lmax):
    """P, Q tables of d^l(β), l ≤ lmax, by the LH §2.2 recurrence (sign-adjusted, see above)."""
    size = pq_offset(lmax + 1)
    P = np.zeros(size)
    Q = np.zeros(size)
    sb = -sb
    P[0] = 1.0
    if lmax >= 1:
        o = pq_offset(1)
        P[o + 0] = cb
        P[o + 1] = sb
        P[o + 2] = -sb
        P[o + 3] = cb
        Q[o + 3] = 1.0
    for l in range(2, lmax + 1):
        o0 = pq_offset(l)
        o1 = pq_offset(l - 1)
        o2 = pq_offset(l - 2)
        w0 = l + 1
        w1 = l
        w2 = l - 1
        fl = float(l)
        inv_ll1 = 1.0 / (fl * (fl - 1.0))
        for m in range(l):
            for n in range(l):
                a = fl * (2.0 * fl - 1.0) / np.sqrt((fl * fl - m * m) * (fl * fl - n * n))
                mn = m * n * inv_ll1
                p1 = P[o1 + m * w1 + n]
                q1 = Q[o1 + m * w1 + n]
                p2 = 0.0
                q2 = 0.0
                if m < l - 1 and n < l - 1:
                    b = np.sqrt(((fl - 1.0) ** 2 - m * m) * ((fl - 1.0) ** 2 - n * n)) / (
                        (fl - 1.0) * (2.0 * fl - 1.0))
                    p2 = b * P[o2 + m * w2 + n]
                    q2 = b * Q[o2 + m * w2 + n]
                P[o0 + m * w0 + n] = a * (cb * p1 - mn * q1 - p2)
                if m > 0 and n > 0:
                    Q[o0 + m * w0 + n] = a * (-mn * p1 + cb * q1 - q2)
        # edges: column n = l, rows by the symmetry d_{n,m} = (−1)^(m−n) d_{m,n}
        for m in range(l):
            e = np.sqrt(fl * (fl - 0.5) / (fl * fl - m * m)) * sb
            p = e * P[o1 + m * w1 + (l - 1)]
            q = e * Q[o1 + m * w1 + (l - 1)] if m > 0 else 0.0
            sgn = 1.0 if (l - m) % 2 == 0 else -1.0
            P[o0 + m * w0 + l] = p
            Q[o0 + m * w0 + l] = q
            P[o0 + l * w0 + m] = sgn * p
            Q[o0 + l * w0 + m] = sgn * q
        pc = P[o1 + (l - 1) * w1 + (l - 1)]
        qc = Q[o1 + (l - 1) * w1 + (l - 1)]
        P[o0 + l * w0 + l] = 0.5 * cb * pc + 0.5 * qc
        Q[o0 + l * w0 + l] = 0.5 * pc + 0.5 * cb * qc
    return P, Q


@nb.njit(cache=True)
def _euler_cs(R):
    """cos/sin of the ZYZ Euler angles of R = Rz(γ) Ry(β) Rz(α), without trig calls.

    β from (R22, |(R02, R12)|); γ from (R02, R12); α from the residual Ry(β)ᵀ Rz(γ)ᵀ R = Rz(α),
    so that at gimbal lock (sin β ≈ 0) the split of α + γ is arbitrary but the product exact.
    """
    cb = R[2, 2]
    sb = np.hypot(R[0, 2], R[1, 2])
    if sb > 0.0:
        cg = R[0, 2] / sb
        sg = R[1, 2] / sb
    else:
        cg = 1.0
        sg = 0.0
    nrm = np.hypot(cb, sb)
    cb /= nrm
    sb /= nrm
    ca = cb * (cg * R[0, 0] + sg * R[1, 0]) - sb * R[2, 0]
    sa = -sg * R[0, 0] + cg * R[1, 0]
    nrm = np.hypot(ca, sa)
    if nrm > 0.0:
        ca /= nrm
        sa /= nrm
    else:
        ca = 1.0
        sa = 0.0
    return ca, sa, cb, sb, cg, sg


@nb.njit(cache=True)
def _orth_error(R):
    e = 0.0
    for i in range(3):
        for j in range(3):
            s = R[i, 0] * R[j, 0] + R[i, 1] * R[j, 1] + R[i, 2] * R[j, 2]
            if i == j:
                s -= 1.0
            e = e + abs(s) if s != s else max(e, abs(s))
    det = (R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
           - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
           + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0]))
    e = max(e, abs(det - 1.0))
    return e if e == e else np.inf  # NaN input → inf


@nb.njit(cache=True)
def _multiples(c, s, lmax, cm, sm):
    """cos(mφ), sin(mφ) for m ≤ lmax from (cos φ, sin φ) by the algebraic recurrence."""
    cm[0] = 1.0
    sm[0] = 0.0
    for m in range(1, lmax + 1):
        cm[m] = cm[m - 1] * c - sm[m - 1] * s
        sm[m] = sm[m - 1] * c + cm[m - 1] * s


@nb.njit(cache=True)
def _zrot(l, cm, sm, src, dst):
    """dst = Z(φ) src on one degree-l block (rows m + l)."""
    C = src.shape[1]
    for ch in range(C):
        dst[l, ch] = src[l, ch]
    for m in range(1, l + 1):
        c = cm[m]
        s = sm[m]
        for ch in range(C):
            ap = src[l + m, ch]
            an = src[l - m, ch]
            dst[l + m, ch] = c * ap - s * an
            dst[l - m, ch] = s * ap + c * an


@nb.njit(cache=True)
def _jmul(l, P, Q, src, dst, transpose):
    """dst = J src (or Jᵀ src) on one degree-l block; J = d^l(π/2) as P ⊕ Q quadrants."""
    C = src.shape[1]
    o = pq_offset(l)
    w = l + 1
    for m in range(l + 1):
        for ch in range(C):
            dst[l + m, ch] = 0.0
            dst[l - m, ch] = 0.0
    for m in range(l + 1):
        for n in range(l + 1):
            if transpose:
                p = P[o + n * w + m]
                q = Q[o + n * w + m]
            else:
                p = P[o + m * w + n]
                q = Q[o + m * w + n]
            for ch in range(C):
                dst[l + m, ch] += p * src[l + n, ch]
            if m > 0 and n > 0:
                for ch in range(C):
                    dst[l - m, ch] += q * src[l - n, ch]


@nb.njit(cache=True)
def _rotate_block(l, P, Q, ang, src, dst, t1, t2):
    """dst = D^l(R) src; ``ang`` rows: cos/sin multiples of α+π/2, β, γ−π/2."""
    _zrot(l, ang[0], ang[1], src, t1)
    _jmul(l, P, Q, t1, t2, False)
    _zrot(l, ang[2], ang[3], t2, t1)
    _jmul(l, P, Q, t1, t2, True)
    _zrot(l, ang[4], ang[5], t2, dst)


@nb.njit(cache=True)
def _angles(R, lmax, ang):
    ca, sa, cb, sb, cg, sg = _euler_cs(R)
    _multiples(-sa, ca, lmax, ang[0], ang[1])  # α + π/2
    _multiples(cb, sb, lmax, ang[2], ang[3])  # β
    _multiples(sg, -cg, lmax, ang[4], ang[5])  # γ − π/2


@nb.njit(cache=True)
def rotate_batch(Rs, coeffs, lmax, P, Q):
    """Rotate coeffs (Nc, K, C) by Rs (Nr, 3, 3); each of Nr, Nc is 1 (shared) or N.

    Returns (N, K, C) and the largest orthogonality error of the rotations.
    """
    nr = Rs.shape[0]
    nc = coeffs.shape[0]
    n = max(nr, nc)
    K = coeffs.shape[1]
    C = coeffs.shape[2]
    out = np.empty((n, K, C))
    ang = np.empty((6, lmax + 1))
    t1 = np.empty((2 * lmax + 1, C))
    t2 = np.empty((2 * lmax + 1, C))
    err = 0.0
    for i in range(n):
        if nr > 1 or i == 0:
            R = Rs[i if nr > 1 else 0]
            err = max(err, _orth_error(R))
            _angles(R, lmax, ang)
        c = coeffs[i if nc > 1 else 0]
        o = out[i]
        for l in range(lmax + 1):
            k0 = l * l
            w = 2 * l + 1
            _rotate_block(l, P, Q, ang, c[k0:k0 + w], o[k0:k0 + w], t1, t2)
    return out, err


@nb.njit(cache=True)
def wigner_full(Rs, lmax, P, Q):
    """(N, 3, 3) rotations → (N, K, K) block-diagonal Wigner matrices, orthogonality error."""
    n = Rs.shape[0]
    K = (lmax + 1) ** 2
    out = np.zeros((n, K, K))
    ang = np.empty((6, lmax + 1))
    w = 2 * lmax + 1
    eye = np.eye(w)
    t1 = np.empty((w, w))
    t2 = np.empty((w, w))
    blk = np.empty((w, w))
    err = 0.0
    for i in range(n):
        err = max(err, _orth_error(Rs[i]))
        _angles(Rs[i], lmax, ang)
        for l in range(lmax + 1):
            wl = 2 * l + 1
            k0 = l * l
            _rotate_block(l, P, Q, ang, eye[:wl, :wl], blk[:wl, :wl], t1[:wl, :wl],
                          t2[:wl, :wl])
            out[i, k0:k0 + wl, k0:k0 + wl] = blk[:wl, :wl]
    return out, err
