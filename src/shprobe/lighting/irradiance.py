"""Irradiance from lighting coefficients (R&H 2001 eq. 7, 11–13), in one module: Â_l L_lm,
E(n) for any lmax, the matrix M (eq. 11–12), the polynomial (eq. 13), the quadratic form as
shading uses it, and irradiance maps on any layout.

Normals, the one policy of every function here and of
[`shprobe.lighting.reference.reference_irradiance`][shprobe.lighting.reference_irradiance]: a normal
is a direction, so it is normalised first (a non-unit n gives the irradiance of n/|n|); a zero or
non-finite normal has no direction and is refused. Coefficients holding NaN or infinity are refused
likewise (one [`ShprobeError`][shprobe.errors.ShprobeError]).

[`irradiance`][shprobe.lighting.irradiance.irradiance],
[`irradiance_matrix`][shprobe.lighting.irradiance_matrix] and
[`irradiance_quadratic`][shprobe.lighting.irradiance_quadratic] also take torch tensors and JAX
arrays (``shprobe.lighting._xp``): same kind, device and dtype, differentiable in coefficients and
normals.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..probes.env import Env
from ..probes.layouts import Layout, get_layout
from ..sh import _xp, lmax_of, sh_basis
from ..sh.rotation import unit_vectors
from ..sh.zonal import clamped_cosine_factors, convolve
from .coeffs import as_coeffs, as_rgb, check_coeffs, nine

__all__ = [
    "irradiance",
    "irradiance_coeffs",
    "irradiance_from_matrix",
    "irradiance_map",
    "irradiance_matrix",
    "irradiance_quadratic",
    "quadratic_form",
    "shade_irradiance",
    "unit_normals",
]


def irradiance_coeffs(coeffs: ArrayLike) -> NDArray[np.float64]:
    """E_lm = Â_l L_lm (R&H eq. 7), same shape as ``coeffs``.

    Parameters
    ----------
    coeffs
        (..., K, C) or (K,) lighting coefficients.

    Returns
    -------
    ndarray
        E_lm, shaped like ``coeffs``.
    """
    c = check_coeffs(coeffs)
    lmax = lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    return convolve(c, clamped_cosine_factors(lmax))


def irradiance(coeffs: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """E(n) = Σ_lm Â_l L_lm y_lm(n) (R&H eq. 7), any lmax.

    ``coeffs`` (K, C) or (K,); ``normals`` (..., 3) unit vectors → (..., C) or (...,).

    Parameters
    ----------
    coeffs
        (K, C) or (K,) lighting coefficients L_lm, any lmax.
    normals
        (..., 3) normals (normalised here; zero or non-finite ones are refused).

    Returns
    -------
    ndarray of shape (..., C) or (...,)
        The irradiance E(n).
    """
    xp = _xp.namespace(coeffs, normals)
    if xp is not None:
        from . import _xp as lx

        return lx.irradiance(xp, coeffs, normals)
    c = _finite(check_coeffs(coeffs))
    n = unit_normals(normals)
    check_memory(8.0 * n.size / 3 * (c.shape[0] + 2 * (c.shape[-1] if c.ndim > 1 else 1)),
                 f"irradiance at {n.size // 3} normals, lmax {lmax_of(c.shape[0])}")
    from . import _xp as lx

    # the reference formula on NumPy, with the basis from the numba kernel (tested against
    # the reference basis)
    return np.asarray(lx.irradiance(_xp.numpy_namespace(), c, n, basis=sh_basis))


def unit_normals(normals: ArrayLike) -> NDArray[np.float64]:
    """Normals (..., 3) as unit vectors by the module's policy (zero / non-finite refused)."""
    a = np.asarray(normals)
    if a.dtype.kind == "c":
        raise ShprobeError("normals must be real vectors, got complex values")
    return unit_vectors(a, "normals")


def _finite(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """The coefficients' policy (as [`as_coeffs`][shprobe.lighting.as_coeffs]): NaN or
    infinity is refused."""
    if not np.isfinite(c).all():
        raise ShprobeError("coefficients contain NaN or infinity")
    return c


def _nine(coeffs: ArrayLike) -> NDArray[np.float64]:
    c = _finite(check_coeffs(coeffs))
    if c.ndim == 1:
        c = c[:, None]
    if c.shape[-2] < 9:
        raise ShprobeError(f"eq. 11–13 need lmax ≥ 2 (9 coefficients), got {c.shape[-2]}")
    return c[..., :9, :]


def irradiance_matrix(coeffs: ArrayLike) -> NDArray[np.float64]:
    """M of R&H eq. 11–12 per channel, (..., C, 4, 4), with E(n) = nᵀ M n, n = (x, y, z, 1).

    Uses L_lm for l ≤ 2 (higher bands are ignored). Our signs and order are R&H's, so M is
    their matrix verbatim.

    Parameters
    ----------
    coeffs
        (..., K, C) lighting coefficients; the l ≤ 2 ones are used.

    Returns
    -------
    ndarray of shape (..., C, 4, 4)
        M per channel, E(n) = nᵀ M n with n = (x, y, z, 1).
    """
    xp = _xp.namespace(coeffs)
    if xp is not None:
        from . import _xp as lx

        return lx.irradiance_matrix(xp, coeffs)
    from . import _xp as lx

    return np.asarray(lx.irradiance_matrix(_xp.numpy_namespace(), _nine(coeffs)))


def irradiance_from_matrix(m: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """E = nᵀ M n with n = (x, y, z, 1) (R&H eq. 11); ``m`` (C, 4, 4) → (..., C).

    Parameters
    ----------
    m
        (C, 4, 4) matrices of [`irradiance_matrix`][shprobe.lighting.irradiance_matrix].
    normals
        (..., 3) normals.

    Returns
    -------
    ndarray of shape (..., C)
        E = nᵀ M n.
    """
    mm = np.asarray(m, dtype=np.float64)
    if mm.shape[-2:] != (4, 4):
        raise ShprobeError(f"M must have shape (..., 4, 4), got {mm.shape}")
    n = unit_normals(normals)
    n4 = np.concatenate([n, np.ones((*n.shape[:-1], 1))], axis=-1)
    return np.einsum("...i,cij,...j->...c", n4, mm.reshape(-1, 4, 4), n4)


def irradiance_quadratic(coeffs: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """The expanded polynomial of R&H eq. 13 → (..., C).

    Parameters
    ----------
    coeffs
        (9, C) (or more) lighting coefficients; the l ≤ 2 ones are used.
    normals
        (..., 3) normals.

    Returns
    -------
    ndarray of shape (..., C)
        E(n) by the expanded polynomial of R&H eq. 13.
    """
    xp = _xp.namespace(coeffs, normals)
    if xp is not None:
        from . import _xp as lx

        return lx.irradiance_quadratic(xp, coeffs, normals)
    from . import _xp as lx

    return np.asarray(lx.irradiance_quadratic(_xp.numpy_namespace(), _nine(coeffs),
                                              unit_normals(normals)))


def irradiance_map(coeffs: ArrayLike, layout: str | Layout = "latlong",
                   size: int | tuple[int, int] = 128) -> Env:
    """An irradiance environment map E(n) (eq. 7) on the grid of any layout → Env.

    ``size`` as in ``Layout.grid_shape`` (lat-long H or (W, H); angular / mirror ball N; cube
    face N). ``layout='angular'`` gives the view of R&H Fig. 3 (centre +Z, rim −Z). Pixels
    outside an angular disc are 0.

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients L_lm.
    layout
        The layout's name or object ('latlong', 'angular', 'mirrorball', 'cube').
    size
        As in ``Layout.grid_shape``: lat-long H or (W, H); angular / mirror ball N; cube face N.

    Returns
    -------
    Env
        The irradiance map E(n) on the layout's grid.
    """
    lay = get_layout(layout)
    grid = lay.grid_shape(size)
    c = check_coeffs(coeffs)
    if c.ndim == 1:
        c = as_rgb(c)  # one channel: grey light
    px = int(np.prod(grid))
    check_memory(px * (8.0 * (c.shape[-2] + 4) + 4.0 * c.shape[-1]),
                 f"an irradiance map of {px} pixels at lmax {lmax_of(c.shape[-2])}")
    dirs = lay.pixel_directions(grid)
    valid = lay.valid_mask(grid)
    e = np.zeros((*grid, c.shape[-1]), dtype=np.float32)
    e[valid] = irradiance(c, dirs[valid])
    return Env(e, lay)


def quadratic_form(coeffs: ArrayLike) -> NDArray[np.float64]:
    """M of R&H eq. 11–12 per channel, (C, 4, 4), E(n) = nᵀMn with n = (x, y, z, 1):
    [`irradiance_matrix`][shprobe.lighting.irradiance_matrix] of the coefficients zero-padded to
    lmax 2 (so lmax 0 and 1 are accepted; lmax > 2 is refused rather than truncated).

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients, lmax ≤ 2.

    Returns
    -------
    ndarray of shape (C, 4, 4)
        M per channel.
    """
    return irradiance_matrix(nine(coeffs))


def shade_irradiance(coeffs: ArrayLike, normals: ArrayLike,
                     dtype: Any = np.float32) -> NDArray[np.floating]:
    """Irradiance E(n) = Σ Â_l L_lm y_lm(n) (R&H eq. 7) at ``normals`` (..., 3), the shading
    path of the renderer.

    ``coeffs`` are lighting coefficients L_lm, (K, C) or (K,). Returns (..., C) (or (...)
    for 1-D coefficients). For lmax ≤ 2 the quadratic polynomial of eq. 11–13 is evaluated by
    a numba kernel (one pass over the normals, each normalised on the fly); higher lmax uses
    the SH basis.

    Parameters
    ----------
    coeffs
        (K, C) or (K,) lighting coefficients.
    normals
        (..., 3) normals (normalised on the fly).
    dtype
        The result's float type.

    Returns
    -------
    ndarray of shape (..., C) or (...,)
        E(n).
    """
    one = np.ndim(coeffs) == 1
    c = as_coeffs(coeffs, finite=False)
    n = np.asarray(normals)
    if n.ndim < 1 or n.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {n.shape}")
    if n.dtype.kind not in "fiu":
        raise ShprobeError(f"normals must be real numbers, got {n.dtype}")
    lead = n.shape[:-1]
    flat = np.ascontiguousarray(n.reshape(-1, 3))
    if flat.dtype not in (np.float32, np.float64):
        flat = flat.astype(np.float64)
    if lmax_of(c.shape[0]) <= 2:
        M = quadratic_form(c)
        q = np.stack([M[:, 0, 0], M[:, 1, 1], M[:, 2, 2], 2 * M[:, 0, 1], 2 * M[:, 0, 2],
                      2 * M[:, 1, 2], 2 * M[:, 0, 3], 2 * M[:, 1, 3], 2 * M[:, 2, 3],
                      M[:, 3, 3]], axis=-1)
        from ._kernels import quad_eval  # numba, imported lazily

        out = np.empty((flat.shape[0], c.shape[1]), dtype=dtype)
        bad = quad_eval(flat, np.ascontiguousarray(q), out)
        if bad:
            raise ShprobeError(f"{bad} of {flat.shape[0]} normals are zero or not finite")
    else:
        out = irradiance(c, flat).astype(dtype)
    out = out.reshape(*lead, c.shape[1])
    return out[..., 0] if one else out
