"""The array-API path of :mod:`shprobe.sh.rotation`: rotation matrices from quaternions and
ZYZ Euler angles, real-basis Wigner matrices and the rotation of coefficients, differentiable
in every argument.

The Wigner blocks come from the recurrence of Ivanic & Ruedenberg 1996 (J. Phys. Chem. 100,
6342; corrections 1998, 102, 9099): D^l is a polynomial in D^1 and D^(l−1), so it is exact
and differentiable for every rotation (no Euler angles, no gimbal lock). D^1 is R itself in
shprobe's l = 1 order (y, z, x). Each band is three matrix products with constant tables:
D^l = (U₀ P₀ + U₊ P₊ + U₋ P₋) · diag(1/√den_n), where P_i (i = −1, 0, 1) are D^(l−1) with
its edge columns mixed by row i of D^1 (IR's function P) and the U hold IR's u, v, w weights
and index shifts. For lmax ≤ 2, :func:`rotate` uses the closed forms of the NumPy path (l = 1:
a → R a; l = 2: the traceless quadratic form A → R A Rᵀ).
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


@lru_cache(maxsize=64)
def _band_tables(l: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant tables of band l ≥ 2 (IR 1996 Table 2 with the 1998 corrections): U₀, U₊,
    U₋ (2l+1, 2l−1) and 1/√den_n (2l+1,), so that D^l = (U₀P₀ + U₊P₊ + U₋P₋) · rden."""
    n_out, n_in = 2 * l + 1, 2 * l - 1
    u0, up, um = (np.zeros((n_out, n_in)) for _ in range(3))

    def col(a):  # index of order a of band l−1
        return a + l - 1

    for m in range(-l, l + 1):
        d = 1.0 if m == 0 else 0.0
        am = abs(m)
        i = m + l
        cu = np.sqrt((l + m) * (l - m))
        cv = 0.5 * np.sqrt((1 + d) * (l + am - 1) * (l + am)) * (1 - 2 * d)
        cw = -0.5 * np.sqrt(max((l - am - 1) * (l - am), 0)) * (1 - d)
        if abs(m) <= l - 1:
            u0[i, col(m)] += cu
        # V
        if m == 0:
            up[i, col(1)] += cv
            um[i, col(-1)] += cv
        elif m > 0:
            up[i, col(m - 1)] += cv * np.sqrt(1.0 + (m == 1))
            if m != 1:
                um[i, col(-m + 1)] -= cv
        else:
            if m != -1:
                up[i, col(m + 1)] += cv
            um[i, col(-m - 1)] += cv * np.sqrt(1.0 + (m == -1))
        # W (zero weight where |m| ≥ l − 1)
        if cw != 0.0:
            if m > 0:
                up[i, col(m + 1)] += cw
                um[i, col(-m - 1)] += cw
            elif m < 0:
                up[i, col(m - 1)] += cw
                um[i, col(-m + 1)] -= cw
    n = np.arange(-l, l + 1)
    den = np.where(np.abs(n) < l, (l + n) * (l - n), 2.0 * l * (2 * l - 1))
    return u0, up, um, 1.0 / np.sqrt(den)


def wigner_blocks(xp: Any, R: Any, lmax: int) -> list[Any]:
    """[D^0, D^1, …, D^lmax] of rotation matrices R (..., 3, 3), each (..., 2l+1, 2l+1)."""
    batch = tuple(R.shape[:-2])
    blocks = [xp.ones((*batch, 1, 1), dtype=R.dtype, device=_xp.device_of(R))]
    if lmax == 0:
        return blocks
    perm = xp.asarray(np.array(_PERM), device=_xp.device_of(R))
    d1 = xp.take(xp.take(R, perm, axis=R.ndim - 2), perm, axis=R.ndim - 1)
    blocks.append(d1)
    for l in range(2, lmax + 1):
        prev = blocks[-1]
        first, last = prev[..., :, :1], prev[..., :, -1:]

        def p(i: int, prev=prev, first=first, last=last) -> Any:
            r_m1, r_0, r_p1 = (d1[..., i + 1, j][..., None, None] for j in range(3))
            return xp.concat([r_p1 * first + r_m1 * last, r_0 * prev,
                              r_p1 * last - r_m1 * first], axis=-1)

        u0, up, um, rden = (_xp.constant(xp, t, R) for t in _band_tables(l))
        blk = xp.matmul(u0, p(0)) + xp.matmul(up, p(1)) + xp.matmul(um, p(-1))
        blocks.append(blk * rden)
    return blocks


def wigner_d(xp: Any, rotation: Any, lmax: int) -> Any:
    """Dense block-diagonal (..., K, K) Wigner matrices (see the NumPy :func:`wigner_d`),
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
    (the NumPy :func:`rotate`'s semantics; leading axes broadcast)."""
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
        blocks = wigner_blocks(xp, R, lmax)
        for l in range(3, lmax + 1):
            parts.append(xp.matmul(blocks[l], c[..., l * l:(l + 1) ** 2, :]))
    out = xp.concat(parts, axis=-2)
    return out[..., 0] if one_d else out
