"""The array-API path of the lighting functions (torch tensors, JAX arrays, CuPy): irradiance
(R&H 2001 eq. 7), its matrix and polynomial (eq. 11–13), projection of samples (eq. 10) and
the window factors, written once against the array API (``shprobe.sh._xp``) and
differentiable in every array argument. The NumPy path of each public function is unchanged;
the public functions dispatch here for non-NumPy arrays.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ShprobeError
from ..sh import _xp, check_lmax, lmax_of
from ..sh.zonal import clamped_cosine_factors
from .coeffs import RH_CONSTANTS


def _coeffs(xp: Any, coeffs: Any, dt: Any, like: Any) -> Any:
    c = _xp.asarray(xp, coeffs, dt, like)
    if c.ndim == 0:
        raise ShprobeError("coefficients must be an array (K,) or (..., K, C)")
    lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    _xp.check_finite(xp, c, "coefficients")
    return c


def irradiance(xp: Any, coeffs: Any, normals: Any, basis: Any = None) -> Any:
    """E(n) = Σ Â_l L_lm y_lm(n/|n|): (K, C) or (K,) coefficients, (..., 3) normals.
    ``basis(n, lmax)``: the SH values of the unit normals (default the reference
    ``shprobe.sh._xp.sh_basis``; the NumPy path passes the numba ``sh_basis``)."""
    dt = _xp.float_dtype(xp, coeffs, normals)
    like = _xp.first_array(coeffs, normals)
    c = _coeffs(xp, coeffs, dt, like)
    if c.ndim > 2:
        raise ShprobeError(f"irradiance takes (K, C) or (K,) coefficients, got {tuple(c.shape)}")
    lmax = lmax_of(c.shape[0])
    n = _xp.unit_vectors(xp, _xp.asarray(xp, normals, dt, like), "normal")
    e = _xp.convolve(xp, c, clamped_cosine_factors(lmax))
    y = _xp.sh_basis(xp, n, lmax) if basis is None else basis(n, lmax)
    return xp.matmul(y, e) if e.ndim == 2 else xp.matmul(y, e[:, None])[..., 0]


def _nine(xp: Any, coeffs: Any, dt: Any, like: Any) -> list[Any]:
    c = _coeffs(xp, coeffs, dt, like)
    if c.ndim == 1:
        c = c[:, None]
    if c.shape[-2] < 9:
        raise ShprobeError(f"eq. 11–13 need lmax ≥ 2 (9 coefficients), got {c.shape[-2]}")
    return [c[..., k, :] for k in range(9)]


def irradiance_matrix(xp: Any, coeffs: Any) -> Any:
    """M of R&H eq. 11–12 per channel, (..., C, 4, 4)."""
    c1, c2, c3, c4, c5 = RH_CONSTANTS
    dt = _xp.float_dtype(xp, coeffs)
    L00, L1m1, L10, L11, L2m2, L2m1, L20, L21, L22 = _nine(xp, coeffs, dt, coeffs)
    rows = [[c1 * L22, c1 * L2m2, c1 * L21, c2 * L11],
            [c1 * L2m2, -c1 * L22, c1 * L2m1, c2 * L1m1],
            [c1 * L21, c1 * L2m1, c3 * L20, c2 * L10],
            [c2 * L11, c2 * L1m1, c2 * L10, c4 * L00 - c5 * L20]]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def irradiance_quadratic(xp: Any, coeffs: Any, normals: Any) -> Any:
    """The polynomial of R&H eq. 13 → (..., C)."""
    c1, c2, c3, c4, c5 = RH_CONSTANTS
    dt = _xp.float_dtype(xp, coeffs, normals)
    like = _xp.first_array(coeffs, normals)
    L00, L1m1, L10, L11, L2m2, L2m1, L20, L21, L22 = _nine(xp, coeffs, dt, like)
    n = _xp.unit_vectors(xp, _xp.asarray(xp, normals, dt, like), "normal")[..., None]
    x, y, z = n[..., 0, :], n[..., 1, :], n[..., 2, :]
    return (c1 * L22 * (x * x - y * y) + c3 * L20 * z * z + c4 * L00 - c5 * L20
            + 2.0 * c1 * (L2m2 * x * y + L21 * x * z + L2m1 * y * z)
            + 2.0 * c2 * (L11 * x + L1m1 * y + L10 * z))


def project_samples(xp: Any, dirs: Any, values: Any, weights: Any, lmax: int) -> Any:
    """Σ_s values_s y(dirs_s) weights_s → (K, C) or (K,)."""
    lmax = check_lmax(lmax)
    dt = _xp.float_dtype(xp, values, dirs, weights)
    like = _xp.first_array(dirs, values, weights)
    d = _xp.asarray(xp, dirs, dt, like)
    v = _xp.asarray(xp, values, dt, like)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"directions must have shape (S, 3), got {tuple(d.shape)}")
    d = xp.reshape(d, (-1, 3))
    if d.shape[0] == 0:
        raise ShprobeError("project_samples needs at least one sample, got 0 directions")
    one = v.ndim == 1
    v = xp.reshape(v, (d.shape[0], -1)) if v.shape[0] == d.shape[0] else v
    if weights is None:
        w = xp.full((d.shape[0],), 4.0 * math.pi / max(d.shape[0], 1), dtype=dt,
                    device=_xp.device_of(d))
    else:
        w = xp.reshape(_xp.asarray(xp, weights, dt, like), (-1,))
    if w.shape[0] != d.shape[0] or v.shape[0] != d.shape[0]:
        raise ShprobeError(f"{d.shape[0]} directions, {v.shape[0]} values, {w.shape[0]} weights")
    _xp.check_finite(xp, v, "values")
    _xp.check_finite(xp, w, "weights")
    _xp.check_finite(xp, d, "directions")
    y = _xp.sh_basis(xp, d, lmax)  # (S, K)
    out = xp.matmul(xp.matrix_transpose(y), v * w[:, None])
    return out[:, 0] if one else out


def window_factors(xp: Any, kind: str, lmax: int, strength: Any) -> Any:
    """The four windows of
    [`shprobe.lighting.windows.window_factors`][shprobe.lighting.window_factors] with a strength of
    ``xp`` (differentiable in it), (lmax+1,)."""
    lmax = check_lmax(lmax)
    dt = _xp.float_dtype(xp, strength)
    s = _xp.asarray(xp, strength, dt, strength)
    if not _xp.is_tracing(s):
        sv = _xp.host_float(s)
        if not np.isfinite(sv) or sv < 0:
            raise ShprobeError(f"window strength must be >= 0, got {sv}")
    l = _xp.constant(xp, np.arange(lmax + 1), s, dt)
    if kind in ("hann", "lanczos"):
        x = l * s / (lmax + 1)  # l / h with h = (lmax + 1) / s
        if kind == "hann":
            w = 0.5 * (1 + xp.cos(math.pi * x))
        else:  # sinc, with its limit 1 at x = 0 (and a gradient there)
            px = math.pi * xp.where(x == 0, xp.ones_like(x), x)
            w = xp.where(x == 0, 1 - (math.pi * x) ** 2 / 6, xp.sin(px) / px)
        return xp.where(x < 1, w, xp.zeros_like(w))
    if kind == "gaussian":
        return xp.exp(-s * l * (l + 1))
    if kind == "laplacian":
        return 1.0 / (1.0 + s * (l * (l + 1)) ** 2)
    raise ShprobeError(f"unknown window {kind!r}")  # windows.window_factors checks it first
