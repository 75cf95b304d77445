"""numba kernels for `shprobe.sh.rotation` (imported lazily: ``import shprobe`` stays fast).

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

  with Z(φ) the real-basis z-rotation (2×2 rotations by mφ on the (m, −m) pairs). As
  d_{n,m} = (−1)^(m−n) d_{m,n}, Jᵀ = S J S with S = diag((−1)^m) = Z(π) on each block, so
  D(R) = Z(γ + π/2) J Z(β + π) J Z(α + π/2): two products with the same table J.
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
    sb = np.sqrt(R[0, 2] * R[0, 2] + R[1, 2] * R[1, 2])
    if sb > 0.0:
        cg = R[0, 2] / sb
        sg = R[1, 2] / sb
    else:
        cg = 1.0
        sg = 0.0
    nrm = np.sqrt(cb * cb + sb * sb)
    cb /= nrm
    sb /= nrm
    ca = cb * (cg * R[0, 0] + sg * R[1, 0]) - sb * R[2, 0]
    sa = -sg * R[0, 0] + cg * R[1, 0]
    nrm = np.sqrt(ca * ca + sa * sa)
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
def _zrot_in(l, cm, sm, src, s0, C, g, t):
    """t = Z(φ) src for channels g..g+3 of one degree-l block; src row m (m = −l..l),
    channel ch at ``s0 + (m + l)·C + ch``; t is 4-channel scratch, row m at ``4(m + l)``
    (channels past C are zero)."""
    for j in range(4):
        ch = g + j
        if ch < C:
            t[4 * l + j] = src[s0 + l * C + ch]
            for m in range(1, l + 1):
                ap = src[s0 + (l + m) * C + ch]
                an = src[s0 + (l - m) * C + ch]
                t[4 * (l + m) + j] = cm[m] * ap - sm[m] * an
                t[4 * (l - m) + j] = sm[m] * ap + cm[m] * an
        else:
            for m in range(-l, l + 1):
                t[4 * (l + m) + j] = 0.0


@nb.njit(cache=True)
def _jmul_z(l, P, Q, cm, sm, src, dst, d0, drow, nch):
    """dst = Z(φ) J src on one degree-l block for up to 4 channels at once; J = d^l(π/2) =
    P ⊕ Q quadrants, Z(φ) from the cos/sin multiples ``cm``, ``sm``. src is 4-channel scratch
    (row m at ``4(m + l)``); dst row m, channel j at ``d0 + (m + l)·drow + j`` for j < nch.
    d^l(π/2) is a checkerboard: P_mn vanishes unless l+m+n is even, Q_mn unless it is odd,
    so half the terms are skipped (while loops: numba's stepped range is markedly slower)."""
    o = pq_offset(l)
    w = l + 1
    for m in range(l + 1):
        r = o + m * w
        u0 = u1 = u2 = u3 = 0.0
        n = (l + m) & 1
        while n <= l:
            p = P[r + n]
            k = 4 * (l + n)
            u0 += p * src[k]
            u1 += p * src[k + 1]
            u2 += p * src[k + 2]
            u3 += p * src[k + 3]
            n += 2
        e = d0 + (l + m) * drow
        if m == 0:
            dst[e] = u0
            if nch > 1:
                dst[e + 1] = u1
            if nch > 2:
                dst[e + 2] = u2
            if nch > 3:
                dst[e + 3] = u3
            continue
        v0 = v1 = v2 = v3 = 0.0
        n = 1 + ((l + m) & 1)
        while n <= l:
            q = Q[r + n]
            k = 4 * (l - n)
            v0 += q * src[k]
            v1 += q * src[k + 1]
            v2 += q * src[k + 2]
            v3 += q * src[k + 3]
            n += 2
        c = cm[m]
        s = sm[m]
        f = d0 + (l - m) * drow
        dst[e] = c * u0 - s * v0
        dst[f] = s * u0 + c * v0
        if nch > 1:
            dst[e + 1] = c * u1 - s * v1
            dst[f + 1] = s * u1 + c * v1
        if nch > 2:
            dst[e + 2] = c * u2 - s * v2
            dst[f + 2] = s * u2 + c * v2
        if nch > 3:
            dst[e + 3] = c * u3 - s * v3
            dst[f + 3] = s * u3 + c * v3


@nb.njit(cache=True)
def _rotate_block(l, P, Q, ang, src, s0, dst, d0, C, t1, t2):
    """dst = D^l(R) src = Z(γ+π/2) J Z(β+π) J Z(α+π/2) src for a block stored (row, channel)
    at s0 / d0, four channels at a time (rows of ``ang``: cos/sin multiples of the three
    angles). From D = Z(γ−π/2) Jᵀ Z(β) J Z(α+π/2) with Jᵀ = S J S, S = diag((−1)^m) and
    S Z(φ) = Z(φ + π)."""
    for g in range(0, C, 4):
        _zrot_in(l, ang[0], ang[1], src, s0, C, g, t1)
        _jmul_z(l, P, Q, ang[2], ang[3], t1, t2, 0, 4, 4)
        _jmul_z(l, P, Q, ang[4], ang[5], t2, dst, d0 + g, C, min(4, C - g))


@nb.njit(cache=True)
def _angles(R, lmax, ang):
    ca, sa, cb, sb, cg, sg = _euler_cs(R)
    _multiples(-sa, ca, lmax, ang[0], ang[1])  # α + π/2
    _multiples(-cb, -sb, lmax, ang[2], ang[3])  # β + π
    _multiples(-sg, cg, lmax, ang[4], ang[5])  # γ + π/2


@nb.njit(cache=True)
def rotate_batch(Rs, coeffs, lmax, P, Q):
    """Rotate coeffs (Nc, K, C) by Rs (Nr, 3, 3); each of Nr, Nc is 1 (shared) or N.

    Returns (N, K, C) and the largest orthogonality error of the rotations. Both inputs
    must be C-contiguous.
    """
    nr = Rs.shape[0]
    nc = coeffs.shape[0]
    n = max(nr, nc)
    K = coeffs.shape[1]
    C = coeffs.shape[2]
    out = np.empty((n, K, C))
    src = coeffs.reshape(-1)
    dst = out.reshape(-1)
    w4 = (2 * lmax + 1) * 4
    scratch = np.empty(6 * (lmax + 1) + 2 * w4)  # one allocation for all scratch
    ang = scratch[: 6 * (lmax + 1)].reshape(6, lmax + 1)
    t1 = scratch[6 * (lmax + 1): 6 * (lmax + 1) + w4]
    t2 = scratch[6 * (lmax + 1) + w4:]
    err = 0.0
    for i in range(n):
        if nr > 1 or i == 0:
            R = Rs[i if nr > 1 else 0]
            err = max(err, _orth_error(R))
            _angles(R, lmax, ang)
        s0 = (i if nc > 1 else 0) * K * C
        d0 = i * K * C
        for l in range(lmax + 1):
            k0 = l * l * C
            _rotate_block(l, P, Q, ang, src, s0 + k0, dst, d0 + k0, C, t1, t2)
    return out, err


@nb.njit(cache=True)
def wigner_full(Rs, lmax, P, Q):
    """(N, 3, 3) rotations → (N, K, K) block-diagonal Wigner matrices, orthogonality error."""
    n = Rs.shape[0]
    K = (lmax + 1) ** 2
    out = np.zeros((n, K, K))
    ang = np.empty((6, lmax + 1))
    w = 2 * lmax + 1
    t1 = np.empty(w * 4)
    t2 = np.empty(w * 4)
    blk = np.empty(w * w)
    err = 0.0
    for i in range(n):
        err = max(err, _orth_error(Rs[i]))
        _angles(Rs[i], lmax, ang)
        for l in range(lmax + 1):
            wl = 2 * l + 1
            eye = np.eye(wl).reshape(-1)
            _rotate_block(l, P, Q, ang, eye, 0, blk, 0, wl, t1, t2)
            k0 = l * l
            for a in range(wl):
                for b in range(wl):
                    out[i, k0 + a, k0 + b] = blk[a * wl + b]
    return out, err


# degree-2 constants: y_2,±2 / y_2,±1 = C1·(xy, yz, xz), y20 = C0 (3z² − 1), y22 = C2 (x² − y²)
_C1 = np.sqrt(15.0 / (4.0 * np.pi))
_C0 = np.sqrt(5.0 / (16.0 * np.pi))
_C2 = np.sqrt(15.0 / (16.0 * np.pi))


@nb.njit(cache=True)
def rotate_low_batch(Rs, coeffs, lmax):
    """Closed form for lmax ≤ 2 (same contract as `rotate_batch`).

    l = 1: the coefficients of a·u turn like a → R a (rows (y, z, x)). l = 2: the band is the
    quadratic form uᵀAu with A = Σ a_m S_m symmetric traceless; f∘R⁻¹ has A' = R A Rᵀ, whose
    entries give a'_m back.
    """
    nr = Rs.shape[0]
    nc = coeffs.shape[0]
    n = max(nr, nc)
    K = coeffs.shape[1]
    C = coeffs.shape[2]
    out = np.empty((n, K, C))
    err = 0.0
    h1 = 0.5 * _C1
    for i in range(n):
        R = Rs[i if nr > 1 else 0]
        if nr > 1 or i == 0:
            err = max(err, _orth_error(R))
        c = coeffs[i if nc > 1 else 0]
        o = out[i]
        for ch in range(C):
            o[0, ch] = c[0, ch]
            if lmax >= 1:
                ax = c[3, ch]
                ay = c[1, ch]
                az = c[2, ch]
                o[3, ch] = R[0, 0] * ax + R[0, 1] * ay + R[0, 2] * az
                o[1, ch] = R[1, 0] * ax + R[1, 1] * ay + R[1, 2] * az
                o[2, ch] = R[2, 0] * ax + R[2, 1] * ay + R[2, 2] * az
            if lmax >= 2:
                a0 = c[6, ch]
                axy = h1 * c[4, ch]
                ayz = h1 * c[5, ch]
                axz = h1 * c[7, ch]
                axx = -_C0 * a0 + _C2 * c[8, ch]
                ayy = -_C0 * a0 - _C2 * c[8, ch]
                azz = 2.0 * _C0 * a0
                # T = R A
                t00 = R[0, 0] * axx + R[0, 1] * axy + R[0, 2] * axz
                t01 = R[0, 0] * axy + R[0, 1] * ayy + R[0, 2] * ayz
                t02 = R[0, 0] * axz + R[0, 1] * ayz + R[0, 2] * azz
                t10 = R[1, 0] * axx + R[1, 1] * axy + R[1, 2] * axz
                t11 = R[1, 0] * axy + R[1, 1] * ayy + R[1, 2] * ayz
                t12 = R[1, 0] * axz + R[1, 1] * ayz + R[1, 2] * azz
                t20 = R[2, 0] * axx + R[2, 1] * axy + R[2, 2] * axz
                t21 = R[2, 0] * axy + R[2, 1] * ayy + R[2, 2] * ayz
                t22 = R[2, 0] * axz + R[2, 1] * ayz + R[2, 2] * azz
                # B = T Rᵀ (the entries needed)
                bxx = t00 * R[0, 0] + t01 * R[0, 1] + t02 * R[0, 2]
                byy = t10 * R[1, 0] + t11 * R[1, 1] + t12 * R[1, 2]
                bzz = t20 * R[2, 0] + t21 * R[2, 1] + t22 * R[2, 2]
                bxy = t00 * R[1, 0] + t01 * R[1, 1] + t02 * R[1, 2]
                byz = t10 * R[2, 0] + t11 * R[2, 1] + t12 * R[2, 2]
                bxz = t00 * R[2, 0] + t01 * R[2, 1] + t02 * R[2, 2]
                o[4, ch] = bxy / h1
                o[5, ch] = byz / h1
                o[7, ch] = bxz / h1
                o[6, ch] = bzz / (2.0 * _C0)
                o[8, ch] = (bxx - byy) / (2.0 * _C2)
    return out, err
