"""Rotation of SH coefficients by real-basis Wigner matrices (Lisle & Huang 2007 §2.2).

Semantics (LH eq. 4–5): ``rotate(coeffs, R)`` turns the *function*. If ``coeffs`` are the
coefficients a_lm of f, the result holds the coefficients a'_lm = Σ_n D^l_mn(R) a_ln of
(R·f)(u) = f(R⁻¹u): a lobe pointing along axis v points along R v afterwards. To turn the
frame instead (express a fixed function in rotated coordinates), pass Rᵀ.

Rotations are given as (..., 3, 3) proper rotation matrices, (..., 4) unit quaternions in
(w, x, y, z) order (scalar first), or anything with an ``.as_matrix()`` method (e.g.
``scipy.spatial.transform.Rotation``); ZYZ Euler angles go through
[`from_euler_zyz`][shprobe.sh.rotation.from_euler_zyz].

The Wigner blocks come from the LH real-basis recurrence for d^l(β) composed with
z-rotations, D^l(R) = D^l(Rz(γ)) d^l(β) D^l(Rz(α)) (LH eq. 6): one algorithm, written once
against the array API (``shprobe.sh._xp_rotation``, the reference, also the torch/JAX path)
and run here by numba kernels (``shprobe.sh._kernels_rotation``, compiled once and cached on
disk) tested against it. Run forward in l at a
general β the recurrence loses accuracy (orthogonality error ~1e-3 by l = 40 at β = 0.5), so
it is evaluated only at β = π/2, where it is stable to l > 400, and d(β) is obtained as
Jᵀ Z(β) J with J = d(π/2) and Z a z-rotation: D(R) = Z(γ−π/2) Jᵀ Z(β) J Z(α+π/2). The Euler
angles are never formed: cos/sin of α, β, γ are read algebraically from R, and α is taken
from the residual Ry(β)ᵀ Rz(γ)ᵀ R, so that gimbal lock (β ≈ 0 or π) is harmless.
For lmax ≤ 2, [`rotate`][shprobe.sh.rotation.rotate] uses a closed form instead (l = 1: a → R a; l =
2: the band as a traceless quadratic form A → R A Rᵀ), tested against the recurrence.
"""

from __future__ import annotations

from functools import cache, lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from . import _xp
from .indexing import ROTATION_LMAX, check_lmax, lmax_of, num_coeffs, sh_lm, unit_vectors

#: Largest deviation from RᵀR = I and det R = 1 accepted for an input rotation matrix.
ORTHO_TOL = 1e-6

_F64 = np.dtype(np.float64)

#: wigner_d refuses to build more than this many bytes of dense matrices (rotate never does).
WIGNER_D_MAX_BYTES = 2 << 30


def from_axis_angle(axis: ArrayLike, degrees: Any) -> NDArray[np.float64]:
    """Rotation matrix turning by ``degrees`` (right-handed) about ``axis`` (Rodrigues):
    R = I + sin t K + (1 − cos t) K², K the cross-product matrix of the unit axis.

    Parameters
    ----------
    axis
        The axis (normalised here).
    degrees
        The angle, degrees, right-handed.

    Returns
    -------
    ndarray of shape (3, 3)
        The rotation matrix.
    """
    a = unit_vectors(axis, "rotation axis")
    try:
        t = np.radians(np.asarray(degrees, dtype=np.float64))
    except (TypeError, ValueError):
        raise ShprobeError(f"rotation angle must be a number, got {degrees!r}") from None
    if not np.all(np.isfinite(t)):
        raise ShprobeError(f"rotation angle must be finite, got {degrees!r}")
    K = np.zeros((*a.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -a[..., 2], a[..., 1], -a[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    s, c = np.sin(t)[..., None, None], np.cos(t)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def from_quaternion(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) in (w, x, y, z) order.

    The quaternion is normalised first; q and −q give the same rotation. A torch tensor or
    JAX array gives the same kind (differentiable in q).

    Parameters
    ----------
    q
        (..., 4) quaternions in (w, x, y, z) order (normalised here).

    Returns
    -------
    ndarray of shape (..., 3, 3)
        The rotation matrices.
    """
    xp = _xp.namespace(q)
    if xp is not None:
        from . import _xp_rotation

        return _xp_rotation.from_quaternion(xp, _xp.asarray(xp, q, _xp.float_dtype(xp, q), q))
    q = _float64(q, "quaternions")
    if q.ndim < 1 or q.shape[-1] != 4:
        raise ShprobeError(f"quaternions must have shape (..., 4) as (w, x, y, z), got {q.shape}")
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(q)) or np.any(n == 0.0):
        raise ShprobeError("quaternion must be finite and non-zero")
    w, x, y, z = np.moveaxis(q / n, -1, 0)
    R = np.empty((*q.shape[:-1], 3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def _rz(t: NDArray[np.float64]) -> NDArray[np.float64]:
    c, s = np.cos(t), np.sin(t)
    R = np.zeros((*t.shape, 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


def _ry(t: NDArray[np.float64]) -> NDArray[np.float64]:
    c, s = np.cos(t), np.sin(t)
    R = np.zeros((*t.shape, 3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 2, 0], R[..., 2, 2], R[..., 1, 1] = c, s, -s, c, 1.0
    return R


def from_euler_zyz(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike) -> NDArray[np.float64]:
    """R = Rz(γ) Ry(β) Rz(α) (LH eq. 6; α is applied first), angles in radians, broadcast.

    Rz(t) = [[c, −s, 0], [s, c, 0], [0, 0, 1]] and Ry(t) = [[c, 0, s], [0, 1, 0], [−s, 0, c]]
    (right-handed, counter-clockwise looking down the axis). Torch tensors or JAX arrays
    give the same kind (differentiable in the angles).

    Parameters
    ----------
    alpha, beta, gamma
        The ZYZ angles in radians (α applied first); they broadcast.

    Returns
    -------
    ndarray of shape (..., 3, 3)
        R = Rz(γ) Ry(β) Rz(α).
    """
    xp = _xp.namespace(alpha, beta, gamma)
    if xp is not None:
        from . import _xp_rotation

        return _xp_rotation.from_euler_zyz(xp, alpha, beta, gamma)
    angles = [_float64(t, "Euler angles") for t in (alpha, beta, gamma)]
    try:
        a, b, g = np.broadcast_arrays(*angles)
    except ValueError:
        a, b, g = (t.shape for t in angles)
        raise ShprobeError(f"Euler angles of shapes {a}, {b} and {g} do not broadcast") from None
    for t, name in ((a, "alpha"), (b, "beta"), (g, "gamma")):
        if not np.isfinite(t).all():
            raise ShprobeError(f"Euler angles ({name}) contain NaN or infinity")
    return _rz(g) @ _ry(b) @ _rz(a)


def as_matrix(rotation: Any) -> NDArray[np.float64]:
    """Rotation matrices (..., 3, 3) float64 from matrices, (w, x, y, z) quaternions (..., 4) or
    objects with ``.as_matrix()``. Raises [`ShprobeError`][shprobe.errors.ShprobeError] for anything
    that is not a proper rotation (orthogonal to `ORTHO_TOL`, det +1).

    Parameters
    ----------
    rotation
        (..., 3, 3) matrices, (..., 4) quaternions (w, x, y, z), or an object with
        ``.as_matrix()``.

    Returns
    -------
    ndarray of shape (..., 3, 3), float64
        The checked rotation matrices.
    """
    R = _matrices(rotation)
    if not np.all(np.isfinite(R)):
        raise ShprobeError("rotation matrix has non-finite entries")
    if R.size:
        err = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max()
        det = np.abs(np.linalg.det(R) - 1.0).max()
        _check_err(max(err, det))
    return R


def one_rotation(rotation: Any) -> NDArray[np.float64]:
    """One checked 3×3 rotation (matrix, (w, x, y, z) quaternion or scipy ``Rotation``).

    Parameters
    ----------
    rotation
        A matrix, a (w, x, y, z) quaternion or a scipy ``Rotation``.

    Returns
    -------
    ndarray of shape (3, 3)
        The checked rotation matrix.
    """
    r = as_matrix(rotation)
    if r.shape != (3, 3):
        raise ShprobeError(f"need one rotation, got shape {r.shape}")
    return r


def _matrices(rotation: Any) -> NDArray[np.float64]:
    """Unchecked (..., 3, 3) C-contiguous float64 matrices."""
    if hasattr(rotation, "as_matrix") and not isinstance(rotation, np.ndarray):
        rotation = rotation.as_matrix()
    r = _float64(rotation, "rotation")
    if r.ndim >= 2 and r.shape[-2:] == (3, 3):
        return np.ascontiguousarray(r)
    if r.ndim >= 1 and r.shape[-1] == 4:
        return from_quaternion(r)
    raise ShprobeError(
        f"rotation must be (..., 3, 3) matrices or (..., 4) quaternions (w, x, y, z), "
        f"got shape {r.shape}"
        + ("; for ZYZ Euler angles pass from_euler_zyz(alpha, beta, gamma)"
           if r.shape[-1:] == (3,) else "")
    )


def _float64(a: Any, what: str) -> NDArray[np.float64]:
    """``a`` as float64; object arrays, strings and complex values are one ShprobeError."""
    try:
        arr = np.asarray(a)
        if arr.dtype.kind == "c":
            raise TypeError
        return np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError(f"{what} must be real numbers") from None


def _check_err(err: float) -> None:
    if not err <= ORTHO_TOL:  # also catches NaN
        raise ShprobeError(
            f"not a proper rotation matrix (RᵀR − I or det − 1 off by {err:.3g} > {ORTHO_TOL})"
        )


@lru_cache(maxsize=256)
def _lmax_of(K: int) -> int:
    return check_lmax(lmax_of(K), ROTATION_LMAX)


@cache
@cache
def _j_tables(lmax: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """J = d(π/2) for l ≤ lmax (P, Q quadrant tables, read-only): prefixes of the tables of
    the next power-of-two degree, so all degrees share a few arrays."""
    bucket = 16
    while bucket < lmax:
        bucket *= 2
    P, Q = _j_full(bucket)
    n = (lmax + 1) * (lmax + 2) * (2 * lmax + 3) // 6
    return P[:n], Q[:n]


@cache
def _j_full(lmax: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    from ._kernels_rotation import d_tables  # numba, imported lazily

    P, Q = d_tables(0.0, 1.0, lmax)
    P.flags.writeable = False
    Q.flags.writeable = False
    return P, Q


def _run_rotate(Rk: NDArray[np.float64], ck: NDArray[np.float64], lmax: int):
    """Kernel dispatch: closed form for lmax ≤ 2, the J-table path above. A degenerate matrix
    (e.g. all zeros) that divides by zero in the kernel is refused like any non-rotation."""
    from ._kernels_rotation import rotate_batch, rotate_low_batch  # numba, imported lazily

    try:
        if lmax <= 2:
            return rotate_low_batch(Rk, ck, lmax)
        return rotate_batch(Rk, ck, lmax, *_j_tables(lmax))
    except ZeroDivisionError:
        raise ShprobeError("rotation matrix is not a rotation (degenerate)") from None


def wigner_d(rotation: Any, lmax: int) -> NDArray[np.float64]:
    """Block-diagonal real-basis Wigner matrices D(R), shape (..., K, K), K = (lmax+1)².

    Entry [k(l,m), k(l,n)] is D^l_mn(R) of LH eq. 4–5 in shprobe's basis (R&H signs), so that
    ``D @ a`` are the coefficients of f∘R⁻¹ when ``a`` are those of f. Each block is
    orthogonal, D(R₁R₂) = D(R₁) D(R₂) and D(Rᵀ) = D(R)ᵀ. Batched over the rotations'
    leading axes. ``rotation``: (..., 3, 3) matrices, (..., 4) unit quaternions (w, x, y, z),
    or a scipy ``Rotation``; ZYZ Euler angles through
    [`from_euler_zyz`][shprobe.sh.rotation.from_euler_zyz]. The dense result is limited to
    ``WIGNER_D_MAX_BYTES`` (lmax ≈ 130 for one rotation). Torch tensors and JAX arrays take the
    array-API path (the same algorithm in whole-array steps, ``shprobe.sh._xp_rotation``, the
    reference the numba kernels are tested against), differentiable in the rotation.

    Parameters
    ----------
    rotation
        (..., 3, 3) rotation matrices, (..., 4) unit quaternions (w, x, y, z) or a scipy
        ``Rotation``.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (..., K, K)
        The block-diagonal real Wigner matrices D(R), K = (lmax + 1)².
    """
    lmax = check_lmax(lmax, ROTATION_LMAX)
    xp = _xp.namespace(rotation)
    if xp is not None:
        from . import _xp_rotation

        r = _xp.asarray(xp, rotation, _xp.float_dtype(xp, rotation), rotation)
        return _xp_rotation.wigner_d(xp, r, lmax)
    R = _matrices(rotation)
    batch = R.shape[:-2]
    size = R.size // 9 * num_coeffs(lmax) ** 2 * 8
    if size > WIGNER_D_MAX_BYTES:
        raise ShprobeError(
            f"wigner_d at lmax={lmax} would be {size / 2**30:.1f} GiB of dense (K, K) "
            f"matrices (limit {WIGNER_D_MAX_BYTES / 2**30:.0f} GiB); rotate() applies the "
            "rotation block by block without forming them")
    from ._kernels_rotation import wigner_full  # numba, imported lazily

    try:
        out, err = wigner_full(R.reshape(-1, 3, 3), lmax, *_j_tables(lmax))
    except ZeroDivisionError:
        raise ShprobeError("rotation matrix is not a rotation (degenerate)") from None
    if R.size:
        _check_err(err)
    K = num_coeffs(lmax)
    return out.reshape(*batch, K, K)


def rotate(coeffs: ArrayLike, rotation: Any) -> NDArray[np.floating]:
    """Coefficients of the turned function f∘R⁻¹ (LH eq. 5): a'_lm = Σ_n D^l_mn(R) a_ln.

    ``coeffs`` is (..., K, C) (or (K,) for one channel) and ``rotation`` is one rotation or a
    batch: (..., 3, 3) matrices, (..., 4) unit quaternions in **scalar-first (w, x, y, z)**
    order ([`from_quaternion`][shprobe.sh.rotation.from_quaternion]), or a
    ``scipy.spatial.transform.Rotation`` (taken through its ``as_matrix()``, so no order question
    arises); the leading axes of both broadcast. Beware: scipy's ``Rotation.as_quat()`` is
    scalar-LAST (x, y, z, w) — pass the Rotation itself, or ``np.roll(q, 1, axis=-1)``. float32
    coefficients stay float32 (the arithmetic is float64). NaN or infinite coefficients are refused
    ([`ShprobeError`][shprobe.errors.ShprobeError]).

    Torch tensors and JAX arrays (coefficients, rotation or both) take the array-API path
    (``shprobe.sh._xp_rotation``): same kind, device and dtype, differentiable in both.

    Parameters
    ----------
    coeffs
        (..., K, C) or (K,) coefficients of f.
    rotation
        One rotation or a batch: (..., 3, 3) matrices, (..., 4) scalar-first quaternions
        (w, x, y, z), or a scipy ``Rotation``; leading axes broadcast with ``coeffs``'.

    Returns
    -------
    ndarray
        The coefficients of f∘R⁻¹, shaped like ``coeffs`` (with the broadcast leading axes).
    """
    xp = _xp.namespace(coeffs, rotation)
    if xp is not None:
        from . import _xp_rotation

        return _xp_rotation.rotate(xp, coeffs, rotation)
    if (type(coeffs) is np.ndarray and coeffs.ndim == 2 and coeffs.dtype is _F64
            and type(rotation) is np.ndarray and rotation.shape == (3, 3)
            and rotation.dtype is _F64):
        # fast path: one (K, C) set, one matrix
        K, C = coeffs.shape
        lmax = _lmax_of(K)
        if not np.isfinite(coeffs).all():
            raise ShprobeError("coefficients contain NaN or infinity")
        out, err = _run_rotate(np.ascontiguousarray(rotation).reshape(1, 3, 3),
                               np.ascontiguousarray(coeffs).reshape(1, K, C), lmax)
        _check_err(err)
        return out.reshape(K, C)
    c = np.asarray(coeffs)
    if c.dtype not in (np.float32, np.float64):
        c = _float64(c, "coefficients")
    if c.ndim == 0:
        raise ShprobeError("coefficients must have shape (..., K, C) or (K,)")
    if not np.isfinite(c).all():
        raise ShprobeError("coefficients contain NaN or infinity")
    one_d = c.ndim == 1
    if one_d:
        c = c[:, None]
    lmax = _lmax_of(c.shape[-2])
    K, C = c.shape[-2:]
    R = _matrices(rotation)
    br, bc = R.shape[:-2], c.shape[:-2]
    try:
        shape = np.broadcast_shapes(br, bc)
    except ValueError:
        raise ShprobeError(
            f"batch shapes of coefficients {bc} and rotations {br} do not broadcast"
        ) from None
    n = int(np.prod(shape)) if shape else 1
    nr = int(np.prod(br)) if br else 1
    ncf = int(np.prod(bc)) if bc else 1
    if nr not in (1, n):
        R = np.broadcast_to(R, (*shape, 3, 3))
        nr = n
    if ncf not in (1, n):
        c = np.broadcast_to(c, (*shape, K, C))
        ncf = n
    Rk = np.ascontiguousarray(R.reshape(nr, 3, 3))
    ck = np.ascontiguousarray(c.reshape(ncf, K, C), dtype=np.float64)
    if n == 0:
        out = np.empty((0, K, C))
    else:
        out, err = _run_rotate(Rk, ck, lmax)
        _check_err(err)
    out = out.reshape(*shape, K, C)
    if one_d:
        out = out[..., 0]
    return out.astype(c.dtype, copy=False)


def z_mirror_signs(lmax: int) -> NDArray[np.float64]:
    """The coefficients of f(x, y, −z) are those of f times these signs ((lmax+1)²,): −1
    where y_lm is odd in z, i.e. l + |m| odd (y_lm ∝ P_l^|m|(z) × a function of x and y, and
    P_l^|m| has the parity of l − |m|). The frame change of left-handed engines.

    Parameters
    ----------
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape ((lmax + 1)²,)
        ±1 per coefficient.
    """
    l, m = sh_lm(np.arange(num_coeffs(check_lmax(lmax))))
    return np.where((l + np.abs(m)) % 2 == 1, -1.0, 1.0)


def frame_from_normal(normals: ArrayLike) -> NDArray[np.float64]:
    """Right-handed frames (..., 3, 3), columns (t, b, n), from unit normals alone (Duff et
    al. 2017). Continuous except at n = (0, 0, −1).

    Parameters
    ----------
    normals
        (..., 3) unit normals.

    Returns
    -------
    ndarray of shape (..., 3, 3)
        Frames with columns (t, b, n).
    """
    n = unit_vectors(normals, "normals", zero="keep")
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sign = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bt = np.stack([b, sign + y * y * a, -y], axis=-1)
    return np.stack([t, bt, n], axis=-1)
