"""The array-API path of `shprobe.sh.rotation`: rotation matrices from quaternions and
ZYZ Euler angles, real-basis Wigner matrices and the rotation of coefficients, differentiable
in every argument.

The Wigner blocks come from the one algorithm of shprobe (Lisle & Huang 2007 §2.2, LH eq. 6):
d^l(β) by the LH recurrence evaluated once at β = π/2, J = d(π/2) (stable to l > 400, where the
recurrence run at a general β is not), and every rotation as D(R) = Z(γ+π/2) J Z(β+π) J
Z(α+π/2), Z(φ) the real-basis z-rotations (2×2 turns by mφ of the (m, −m) pairs). The cos/sin
of α, β, γ are read algebraically from R (no Euler angles, no trig), guarded at gimbal lock so
that gradients stay finite. These whole-array functions are the reference; the numba kernels
of the NumPy path (``shprobe.sh._kernels_rotation``) run the same steps and are tested against
them. For lmax ≤ 2, `rotate` uses closed forms (l = 1: a → R a; l = 2: the traceless
quadratic form A → R A Rᵀ), like the NumPy path.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import ShprobeError
from . import _xp
from .indexing import lmax_of

#: shprobe's l = 1 order (y1−1 ∝ y, y10 ∝ z, y11 ∝ x): D^1[i, j] = R[_PERM[i], _PERM[j]]
_PERM = (1, 2, 0)
_ORTHO_TOL = 1e-6


def from_quaternion(xp: Any, q: Any) -> Any:
    """Rotation matrices (..., 3, 3) from (w, x, y, z) quaternions (..., 4), normalised."""
    if q.ndim < 1 or q.shape[-1] != 4:
        raise ShprobeError(
            f"quaternions must have shape (..., 4) as (w, x, y, z), got {tuple(q.shape)}")
    dt = q.dtype
    if _xp.work_dtype(xp, dt) != dt:
        return xp.astype(from_quaternion(xp, xp.astype(q, _xp.work_dtype(xp, dt))), dt)
    _xp.check_finite(xp, q, "quaternions")
    n2 = xp.sum(q * q, axis=-1, keepdims=True)
    if not _xp.is_tracing(n2) and bool(xp.any(n2 == 0)):
        raise ShprobeError("quaternion must be finite and non-zero")
    q = q / xp.sqrt(n2)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def from_euler_zyz(xp: Any, alpha: Any, beta: Any, gamma: Any) -> Any:
    """R = Rz(γ) Ry(β) Rz(α) (the NumPy path's convention), broadcast over the angles."""
    dt = _xp.float_dtype(xp, alpha, beta, gamma)
    work = _xp.work_dtype(xp, dt)
    like = _xp.first_array(alpha, beta, gamma)
    a, b, g = (_xp.asarray(xp, t, work, like) for t in (alpha, beta, gamma))
    try:
        shape = np.broadcast_shapes(tuple(a.shape), tuple(b.shape), tuple(g.shape))
    except ValueError:
        raise ShprobeError(f"Euler angles of shapes {tuple(a.shape)}, {tuple(b.shape)} and "
                           f"{tuple(g.shape)} do not broadcast") from None
    for t, name in ((a, "alpha"), (b, "beta"), (g, "gamma")):
        _xp.check_finite(xp, t, f"Euler angles ({name})")
    a, b, g = (xp.broadcast_to(t, shape) for t in (a, b, g))
    zero, one = xp.zeros_like(a), xp.ones_like(a)

    def mat(rows):
        return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)

    def rz(t):
        c, s = xp.cos(t), xp.sin(t)
        return mat([[c, -s, zero], [s, c, zero], [zero, zero, one]])

    cb, sb = xp.cos(b), xp.sin(b)
    ry = mat([[cb, zero, sb], [zero, one, zero], [-sb, zero, cb]])
    return xp.astype(xp.matmul(xp.matmul(rz(g), ry), rz(a)), dt)


def as_matrix(xp: Any, rotation: Any) -> Any:
    """(..., 3, 3) matrices from matrices or (..., 4) quaternions of ``xp``, checked to be
    proper rotations (skipped while JAX traces)."""
    r = rotation
    if r.ndim >= 1 and r.shape[-1] == 4:
        return from_quaternion(xp, r)
    if r.ndim < 2 or tuple(r.shape[-2:]) != (3, 3):
        raise ShprobeError(
            "rotation must be (..., 3, 3) matrices or (..., 4) quaternions (w, x, y, z), "
            f"got shape {tuple(r.shape)}")
    _xp.check_finite(xp, r, "rotation matrices")
    if not _xp.is_tracing(r) and r.shape[0] != 0:
        eye = xp.eye(3, dtype=r.dtype, device=_xp.device_of(r))
        err = _xp.host_float(xp.max(xp.abs(xp.matmul(r, xp.matrix_transpose(r)) - eye)))
        det = _xp.host_float(xp.max(xp.abs(xp.linalg.det(r) - 1.0)))
        tol = max(_ORTHO_TOL, 50 * float(np.finfo(_np_dtype(xp, r.dtype)).eps))
        if not max(err, det) <= tol:
            raise ShprobeError(f"not a proper rotation matrix (RᵀR − I or det − 1 off by "
                               f"{max(err, det):.3g} > {tol:.3g})")
    return r


def _np_dtype(xp: Any, dt: Any) -> Any:
    return np.float32 if dt == xp.float32 else np.float64


@lru_cache(maxsize=8)
def d_half_pi(lmax: int) -> tuple[np.ndarray, ...]:
    """J^l = d^l(π/2) for l ≤ lmax, dense (2l+1, 2l+1) in shprobe's real basis (rows and
    columns m = −l … l), by the recurrence of Lisle & Huang 2007 §2.2 for d^l(β) at β = π/2
    (where it is stable to l > 400), read-only.

    The recurrence gives the same-sign quadrants P_mn = d_mn and Q_mn = d_−m,−n (m, n ≥ 0;
    a y-rotation never mixes the cos-type m ≥ 0 and the sin-type m < 0 functions). LH's basis
    carries the Condon–Shortley phase; without it d_mn is multiplied by (−1)^(m+n), which is
    d(−β), so the recurrence runs with sin β → −sin β. Each degree is one whole-array step
    over (m, n) from the two before it; ``shprobe.sh._kernels_rotation.d_tables`` is the
    compiled copy the NumPy path uses, tested against this."""
    cb, sb = 0.0, -1.0  # cos, −sin of π/2
    P = [np.ones((1, 1)), np.array([[cb, sb], [-sb, cb]])]
    Q = [np.zeros((1, 1)), np.array([[0.0, 0.0], [0.0, 1.0]])]
    for l in range(2, lmax + 1):
        fl = float(l)
        m = np.arange(l)[:, None]
        n = np.arange(l)[None, :]
        a = fl * (2 * fl - 1) / np.sqrt((fl * fl - m * m) * (fl * fl - n * n))
        mn = m * n / (fl * (fl - 1))
        p1, q1 = P[l - 1][:l, :l], Q[l - 1][:l, :l]
        p2 = np.zeros((l, l))
        q2 = np.zeros((l, l))
        mm, nn = np.arange(l - 1)[:, None], np.arange(l - 1)[None, :]
        b = np.sqrt(((fl - 1) ** 2 - mm * mm) * ((fl - 1) ** 2 - nn * nn)) / (
            (fl - 1) * (2 * fl - 1))
        p2[:l - 1, :l - 1] = b * P[l - 2]
        q2[:l - 1, :l - 1] = b * Q[l - 2]
        pl = np.zeros((l + 1, l + 1))
        ql = np.zeros((l + 1, l + 1))
        pl[:l, :l] = a * (cb * p1 - mn * q1 - p2)
        ql[1:l, 1:l] = (a * (-mn * p1 + cb * q1 - q2))[1:, 1:]
        # the edges (column n = l, and row l by d_n,m = (−1)^(m−n) d_m,n), the corner
        mr = np.arange(l)
        e = np.sqrt(fl * (fl - 0.5) / (fl * fl - mr * mr)) * sb
        pe = e * P[l - 1][:l, l - 1]
        qe = np.where(mr > 0, e * Q[l - 1][:l, l - 1], 0.0)
        sgn = np.where((l - mr) % 2 == 0, 1.0, -1.0)
        pl[:l, l], ql[:l, l] = pe, qe
        pl[l, :l], ql[l, :l] = sgn * pe, sgn * qe
        pc, qc = P[l - 1][l - 1, l - 1], Q[l - 1][l - 1, l - 1]
        pl[l, l] = 0.5 * cb * pc + 0.5 * qc
        ql[l, l] = 0.5 * pc + 0.5 * cb * qc
        P.append(pl)
        Q.append(ql)
    out = []
    for l in range(lmax + 1):
        J = np.zeros((2 * l + 1, 2 * l + 1))
        J[l:, l:] = P[l]
        J[:l, :l] = Q[l][1:, 1:][::-1, ::-1]  # rows/columns −l … −1
        J.flags.writeable = False
        out.append(J)
    return tuple(out)


def _euler_cs(xp: Any, R: Any) -> tuple[Any, ...]:
    """cos/sin of the ZYZ Euler angles of R = Rz(γ) Ry(β) Rz(α), read algebraically (no trig):
    β from (R22, |(R02, R12)|), γ from (R02, R12), α from the residual Ry(β)ᵀ Rz(γ)ᵀ R, so at
    gimbal lock (sin β = 0) the split of α + γ is arbitrary and the product exact. Guarded so
    that gradients stay finite there (the derivative along a z-rotation is exact)."""
    r = [[R[..., i, j] for j in range(3)] for i in range(3)]
    sb2 = r[0][2] * r[0][2] + r[1][2] * r[1][2]
    lock = sb2 == 0
    sb_safe = xp.sqrt(xp.where(lock, xp.ones_like(sb2), sb2))
    sb = xp.where(lock, xp.zeros_like(sb2), sb_safe)
    cg = xp.where(lock, xp.ones_like(sb2), r[0][2] / sb_safe)
    sg = xp.where(lock, xp.zeros_like(sb2), r[1][2] / sb_safe)
    cb = r[2][2]
    nrm = xp.sqrt(cb * cb + sb * sb)
    cb, sb = cb / nrm, sb / nrm
    ca = cb * (cg * r[0][0] + sg * r[1][0]) - sb * r[2][0]
    sa = -sg * r[0][0] + cg * r[1][0]
    nrm = xp.sqrt(ca * ca + sa * sa)
    return ca / nrm, sa / nrm, cb, sb, cg, sg


def _multiples(xp: Any, c: Any, s: Any, lmax: int) -> tuple[list[Any], list[Any]]:
    """[cos mφ], [sin mφ] for m = 0 … lmax from cos φ, sin φ (the algebraic recurrence)."""
    cm, sm = [xp.ones_like(c), c], [xp.zeros_like(s), s]
    for _ in range(2, lmax + 1):
        cm.append(cm[-1] * c - sm[-1] * s)
        sm.append(sm[-1] * c + cm[-2] * s)
    return cm, sm


def _zrot(xp: Any, x: Any, l: int, cm: Any, sm: Any) -> Any:
    """Z(φ) x on a degree-l block x (..., 2l+1, C): the (m, −m) pairs turned by mφ;
    ``cm``, ``sm`` (..., lmax+1) cos/sin multiples of φ."""
    if l == 0:
        return x
    c = cm[..., 1:l + 1, None]
    s = sm[..., 1:l + 1, None]
    pos = x[..., l + 1:, :]
    neg = xp.flip(x[..., :l, :], axis=-2)  # m = 1 … l of the sin-type half
    new_pos = c * pos - s * neg
    new_neg = s * pos + c * neg
    return xp.concat([xp.flip(new_neg, axis=-2), x[..., l:l + 1, :], new_pos], axis=-2)


class _Turn:
    """D^l(R) = Z(γ + π/2) J Z(β + π) J Z(α + π/2) (LH eq. 6 with d(β) = Jᵀ Z(β) J, Jᵀ = S J S,
    S = diag((−1)^m) = Z(π)), for a batch of rotation matrices R (..., 3, 3): the one Wigner
    algorithm of shprobe (the numba kernels of the NumPy path run the same steps)."""

    def __init__(self, xp: Any, R: Any, lmax: int) -> None:
        ca, sa, cb, sb, cg, sg = _euler_cs(xp, R)
        self.xp, self.R = xp, R
        self.angles = [self._stack(_multiples(xp, c, s, lmax))
                       for c, s in ((-sa, ca), (-cb, -sb), (-sg, cg))]
        self.J = d_half_pi(lmax)

    def _stack(self, cs: tuple[list[Any], list[Any]]) -> tuple[Any, Any]:
        return tuple(self.xp.stack(v, axis=-1) for v in cs)  # type: ignore[return-value]

    def apply(self, l: int, x: Any) -> Any:
        """D^l(R) x for a block x (..., 2l+1, C)."""
        xp = self.xp
        J = _xp.constant(xp, self.J[l], self.R)
        (ca, sa), (cb, sb), (cg, sg) = self.angles
        y = xp.matmul(J, _zrot(xp, x, l, ca, sa))
        y = xp.matmul(J, _zrot(xp, y, l, cb, sb))
        return _zrot(xp, y, l, cg, sg)


def wigner_blocks(xp: Any, R: Any, lmax: int) -> list[Any]:
    """[D^0, D^1, …, D^lmax] of rotation matrices R (..., 3, 3), each (..., 2l+1, 2l+1):
    D^1 is R in shprobe's l = 1 order (y, z, x), the higher blocks the turn of the identity."""
    batch = tuple(R.shape[:-2])
    blocks = [xp.ones((*batch, 1, 1), dtype=R.dtype, device=_xp.device_of(R))]
    if lmax == 0:
        return blocks
    perm = xp.asarray(np.array(_PERM), device=_xp.device_of(R))
    blocks.append(xp.take(xp.take(R, perm, axis=R.ndim - 2), perm, axis=R.ndim - 1))
    if lmax >= 2:
        turn = _Turn(xp, R, lmax)
        for l in range(2, lmax + 1):
            eye = xp.eye(2 * l + 1, dtype=R.dtype, device=_xp.device_of(R))
            blocks.append(turn.apply(l, xp.broadcast_to(eye, (*batch, 2 * l + 1, 2 * l + 1))))
    return blocks


def wigner_d(xp: Any, rotation: Any, lmax: int) -> Any:
    """Dense block-diagonal (..., K, K) Wigner matrices (see the NumPy ``wigner_d``),
    computed in float32 for float16/bfloat16 rotations and cast back."""
    dt = rotation.dtype
    work = _xp.work_dtype(xp, dt)
    if work != dt:
        return xp.astype(wigner_d(xp, xp.astype(rotation, work), lmax), dt)
    R = as_matrix(xp, rotation)
    blocks = wigner_blocks(xp, R, lmax)
    batch = tuple(R.shape[:-2])
    K = (lmax + 1) ** 2
    rows = []
    for l, blk in enumerate(blocks):
        left = xp.zeros((*batch, 2 * l + 1, l * l), dtype=R.dtype, device=_xp.device_of(R))
        right = xp.zeros((*batch, 2 * l + 1, K - (l + 1) ** 2), dtype=R.dtype,
                         device=_xp.device_of(R))
        rows.append(xp.concat([left, blk, right], axis=-1))
    return xp.concat(rows, axis=-2)


_K2 = float(np.sqrt(15.0 / np.pi) / 2.0)  # y2−2 = K2 xy, y2−1 = K2 yz, y21 = K2 xz
_K20 = float(np.sqrt(5.0 / np.pi) / 4.0)  # y20 = K20 (3z² − 1)
_K22 = _K2 / 2.0  # y22 = K22 (x² − y²)


def _rotate_band2(xp: Any, R: Any, a: Any) -> Any:
    """Band 2 (..., 5, C) turned as the traceless quadratic form A → R A Rᵀ."""
    am2, am1, a0, ap1, ap2 = (a[..., i, :] for i in range(5))
    h = 0.5 * _K2
    rows = [[-_K20 * a0 + _K22 * ap2, h * am2, h * ap1],
            [h * am2, -_K20 * a0 - _K22 * ap2, h * am1],
            [h * ap1, h * am1, 2.0 * _K20 * a0]]
    A = xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)  # (..., C, 3, 3)
    Rc = R[..., None, :, :]
    B = xp.matmul(xp.matmul(Rc, A), xp.matrix_transpose(Rc))
    out = [B[..., 0, 1] / h, B[..., 1, 2] / h, B[..., 2, 2] / (2.0 * _K20),
           B[..., 0, 2] / h, (B[..., 0, 0] - B[..., 1, 1]) / (2.0 * _K22)]
    return xp.stack(out, axis=-2)


def rotate(xp: Any, coeffs: Any, rotation: Any) -> Any:
    """Coefficients of f∘R⁻¹ for (..., K, C) or (K,) coefficients and a batch of rotations
    (the NumPy `rotate`'s semantics; leading axes broadcast)."""
    if hasattr(rotation, "as_matrix") and not hasattr(rotation, "dtype"):
        rotation = np.asarray(rotation.as_matrix(), dtype=np.float64)  # scipy Rotation
    dt = _xp.float_dtype(xp, coeffs, rotation)
    work = _xp.work_dtype(xp, dt)
    if work != dt:  # float16 / bfloat16: computed in float32, cast back
        like = _xp.first_array(coeffs, rotation)
        c32, r32 = (x if isinstance(x, np.ndarray) or not hasattr(x, "dtype")
                    else _xp.asarray(xp, x, work, like) for x in (coeffs, rotation))
        return xp.astype(rotate(xp, c32, r32), dt)
    like = _xp.first_array(coeffs, rotation)
    c = _xp.asarray(xp, coeffs, dt, like)
    if c.ndim == 0:
        raise ShprobeError("coefficients must have shape (..., K, C) or (K,)")
    _xp.check_finite(xp, c, "coefficients")
    one_d = c.ndim == 1
    if one_d:
        c = c[:, None]
    from .indexing import ROTATION_LMAX, check_lmax

    lmax = check_lmax(lmax_of(c.shape[-2]), ROTATION_LMAX)
    rot = _xp.asarray(xp, rotation, dt, like)
    R = as_matrix(xp, rot)
    try:
        shape = np.broadcast_shapes(tuple(R.shape[:-2]), tuple(c.shape[:-2]))
    except ValueError:
        raise ShprobeError(f"batch shapes of coefficients {tuple(c.shape[:-2])} and rotations "
                           f"{tuple(R.shape[:-2])} do not broadcast") from None
    R = xp.broadcast_to(R, (*shape, 3, 3))
    c = xp.broadcast_to(c, (*shape, *c.shape[-2:]))
    parts = [c[..., :1, :]]
    if lmax >= 1:
        perm = xp.asarray(np.array(_PERM), device=_xp.device_of(R))
        d1 = xp.take(xp.take(R, perm, axis=R.ndim - 2), perm, axis=R.ndim - 1)
        parts.append(xp.matmul(d1, c[..., 1:4, :]))
    if lmax >= 2:
        parts.append(_rotate_band2(xp, R, c[..., 4:9, :]))
    if lmax >= 3:
        turn = _Turn(xp, R, lmax)
        for l in range(3, lmax + 1):
            parts.append(turn.apply(l, c[..., l * l:(l + 1) ** 2, :]))
    out = xp.concat(parts, axis=-2)
    return out[..., 0] if one_d else out
