"""Zonal (circularly symmetric) functions: clamped cosine Â_l, Proposition 3.2, circular window,
Funk–Hecke convolution (LH 2007 §3; R&H 2001 eq. 5–9).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from . import _xp
from .indexing import check_lmax, degrees


def clamped_cosine_factors(lmax: int, like: Any = None) -> NDArray[np.float64]:
    """Â_l for l = 0..lmax, the SH factors of the clamped cosine max(cos θ, 0) (R&H eq. 8–9).

    Â_0 = π, Â_1 = 2π/3, Â_l = 0 for odd l > 1, and for even l

        Â_l = 2π (−1)^(l/2 − 1) / ((l + 2)(l − 1)) · l! / (2^l ((l/2)!)²),

    with l!/(2^l ((l/2)!)²) built by the ratio (l+1)/(l+2) so nothing overflows.
    ``like``: a torch tensor or JAX array whose kind, device and floating dtype the factors
    take (default: NumPy float64).

    Parameters
    ----------
    lmax
        The highest degree, ≥ 0.
    like
        A torch tensor or JAX array whose kind, device and floating dtype the factors take;
        None for NumPy float64.

    Returns
    -------
    ndarray of shape (lmax + 1,)
        Â_0 … Â_lmax.
    """
    xp = _xp.namespace(like)
    if xp is not None:
        return _xp.constant(xp, clamped_cosine_factors(lmax), like)
    lmax = check_lmax(lmax)
    a = np.zeros(lmax + 1)
    a[0] = np.pi
    if lmax >= 1:
        a[1] = 2.0 * np.pi / 3.0
    c = 1.0  # l!/(2^l ((l/2)!)^2) at l = 0
    for l in range(2, lmax + 1, 2):
        c *= (l - 1.0) / l
        a[l] = 2.0 * np.pi * (-1.0) ** (l // 2 - 1) / ((l + 2.0) * (l - 1.0)) * c
    return a


def convolve(coeffs: ArrayLike, factors: ArrayLike) -> NDArray[np.floating]:
    """Funk–Hecke convolution with a zonal kernel: multiply band l by ``factors[l]``.

    With ``factors = clamped_cosine_factors(lmax)`` this turns lighting L_lm into irradiance
    coefficients E_lm = Â_l L_lm (R&H eq. 7). One definition for every array kind
    (``shprobe.sh._xp.convolve``, on NumPy through array-api-compat).

    Parameters
    ----------
    coeffs : array_like
        (..., K, C) or (K,) coefficients; NumPy, torch or JAX (float32 stays float32).
    factors : array_like
        At least lmax + 1 band factors.

    Returns
    -------
    array
        The convolved coefficients, the kind, shape and float type of ``coeffs``;
        differentiable in both arguments for torch tensors and JAX arrays. NaN or infinity in
        either argument is refused (one ``ShprobeError``).
    """
    xp = _xp.namespace(coeffs, factors)
    if xp is not None:
        return _xp.convolve(xp, coeffs, factors)
    try:
        c = np.asarray(coeffs)
        if c.dtype not in (np.float32, np.float64):
            if c.dtype.kind not in "fiub":
                raise TypeError
            c = c.astype(np.float64)
        f = np.asarray(factors)
        if f.dtype.kind not in "fiub":
            raise TypeError
        f = f.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError("coefficients and band factors must be real numbers") from None
    return np.asarray(_xp.convolve(_xp.numpy_namespace(), c, f))


def clamped_cosine_H(lmax: int) -> NDArray[np.float64]:
    """H_l = 2∫₀¹ z P_l(z) dz for l = 0..lmax by the LH eq. 10 recurrence.

    H_0 = 1, H_1 = 2/3, H_l = 0 for odd l ≥ 3, H_{2n+2} = (½ − n)/(2 + n) H_{2n}. By LH eq. 9
    the clamped cosine about n has coefficients π H_l y_lm(n); comparing with R&H eq. 7–8
    (Â_l = √(4π/(2l+1)) A_l, A_l its zonal coefficient) gives Â_l = π H_l.

    Parameters
    ----------
    lmax
        The highest degree, ≥ 0.

    Returns
    -------
    ndarray of shape (lmax + 1,)
        H_0 … H_lmax.
    """
    lmax = check_lmax(lmax)
    h = np.zeros(lmax + 1)
    h[0] = 1.0
    if lmax >= 1:
        h[1] = 2.0 / 3.0
    for n in range(0, (lmax - 2) // 2 + 1):
        h[2 * n + 2] = (0.5 - n) / (2.0 + n) * h[2 * n]
    return h


def legendre_polynomials(z: ArrayLike, lmax: int) -> NDArray[np.float64]:
    """P_l(z) for l = 0..lmax, shape (*z.shape, lmax+1), by Bonnet's recurrence.

    Parameters
    ----------
    z
        Arguments in [−1, 1], any shape.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (*z.shape, lmax + 1)
        P_0(z) … P_lmax(z).
    """
    z = np.asarray(z, dtype=np.float64)
    p = np.empty((*z.shape, lmax + 1))
    p[..., 0] = 1.0
    if lmax >= 1:
        p[..., 1] = z
    for l in range(1, lmax):
        p[..., l + 1] = ((2 * l + 1) * z * p[..., l] - l * p[..., l - 1]) / (l + 1)
    return p


def legendre_moments(
    h: Callable[[NDArray[np.float64]], ArrayLike],
    lmax: int,
    n_quad: int | None = None,
    interval: tuple[float, float] = (-1.0, 1.0),
) -> NDArray[np.float64]:
    """2π ∫ h(z) P_l(z) dz for l = 0..lmax (LH Prop. 3.2), by Gauss–Legendre quadrature.

    ``h`` maps an array of z in [−1, 1] to values of the same shape (it is called once, on
    all nodes). ``interval`` restricts the integral to [a, b] ⊂ [−1, 1] where h vanishes
    outside: put the ends at h's discontinuities so the quadrature converges spectrally.
    ``n_quad`` nodes (default max(2·lmax + 16, 64)); exact when h is a polynomial of degree
    < 2·n_quad − lmax.

    Parameters
    ----------
    h
        Maps an array of z in [−1, 1] to values of the same shape (called once, on all nodes).
    lmax
        The highest degree.
    n_quad
        Gauss–Legendre nodes (default max(2·lmax + 16, 64)).
    interval
        The part [a, b] of [−1, 1] outside which h vanishes.

    Returns
    -------
    ndarray of shape (lmax + 1,)
        2π ∫ h(z) P_l(z) dz for each l.
    """
    lmax = check_lmax(lmax)
    a, b = (float(t) for t in interval)
    if not -1.0 <= a < b <= 1.0:
        raise ShprobeError(f"interval {interval} must satisfy -1 <= a < b <= 1")
    n = max(2 * lmax + 16, 64) if n_quad is None else int(n_quad)
    if n < 1:
        raise ShprobeError(f"n_quad must be positive, got {n_quad}")
    x, w = np.polynomial.legendre.leggauss(n)
    z = 0.5 * (b - a) * x + 0.5 * (b + a)
    w = 0.5 * (b - a) * w
    vals = np.asarray(h(z), dtype=np.float64)
    if vals.shape != z.shape:
        vals = np.broadcast_to(vals, z.shape) if vals.ndim == 0 else vals
        if vals.shape != z.shape:
            raise ShprobeError(f"h must return one value per node, got shape {vals.shape}")
    return 2.0 * np.pi * (w * vals) @ legendre_polynomials(z, lmax)


def _unit_axis(axis: ArrayLike) -> NDArray[np.float64]:
    from .rotation import unit_vectors

    return unit_vectors(axis, "axis")


def zonal_from_moments(moments: ArrayLike, axis: ArrayLike) -> NDArray[np.floating]:
    """b_lm = moments_l · y_lm(axis) (LH eq. 7), shape (..., K) for axes (..., 3).

    ``moments`` (lmax+1,) are 2π∫h P_l (see
    [`legendre_moments`][shprobe.sh.zonal.legendre_moments]); the axis is normalised. Multiply by a
    colour, ``b[..., None] * rgb``, for (..., K, C) lighting. A float32 axis gives float32
    coefficients (computed in float64).

    Parameters
    ----------
    moments
        (lmax + 1,) moments 2π∫h P_l.
    axis
        (..., 3) axes (normalised here).

    Returns
    -------
    ndarray of shape (..., K)
        b_lm = moments_l · y_lm(axis); float32 for a float32 axis.
    """
    from .basis import sh_basis

    mom = np.asarray(moments, dtype=np.float64)
    if mom.ndim != 1 or mom.size == 0:
        raise ShprobeError(f"moments must be a 1-D array of lmax+1 values, got {mom.shape}")
    lmax = mom.size - 1
    out = mom[degrees(lmax)] * sh_basis(_unit_axis(axis), lmax)
    return out.astype(np.float32) if np.asarray(axis).dtype == np.float32 else out


def zonal_coeffs(
    h: Callable[[NDArray[np.float64]], ArrayLike],
    axis: ArrayLike,
    lmax: int,
    n_quad: int | None = None,
    interval: tuple[float, float] = (-1.0, 1.0),
) -> NDArray[np.floating]:
    """SH coefficients (..., K) of f(u) = h(u·n) about axis n (LH Prop. 3.2); float32 for a
    float32 axis.

    Parameters
    ----------
    h
        The profile: maps an array of u·n in [−1, 1] to values of the same shape.
    axis
        (..., 3) axes n (normalised here).
    lmax
        The highest degree.
    n_quad
        Gauss–Legendre nodes (default max(2·lmax + 16, 64)).
    interval
        The part [a, b] of [−1, 1] outside which h vanishes (ends at its discontinuities).

    Returns
    -------
    ndarray of shape (..., K)
        The coefficients, K = (lmax + 1)²; float32 for a float32 axis.
    """
    return zonal_from_moments(legendre_moments(h, lmax, n_quad, interval), axis)


def window_moments(aperture: float, lmax: int) -> NDArray[np.float64]:
    """4π f_l(cos ζ), f_l(z) = (1/(1−z)) ∫_z^1 P_l, by the LH eq. 11 recurrence.

    These are the moments 2π∫h P_l of LH's circular window h = 2/(1−cos ζ) on the cap
    z > cos ζ (total power ∫ L_f = 4π for every aperture ζ, in radians, 0 < ζ ≤ π).

    Parameters
    ----------
    aperture
        The window's angular radius ζ, radians, 0 < ζ ≤ π.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (lmax + 1,)
        The moments 4π f_l(cos ζ).
    """
    lmax = check_lmax(lmax)
    zeta = float(aperture)
    if not 0.0 < zeta <= np.pi:
        raise ShprobeError(f"window aperture must be in (0, π] radians, got {aperture}")
    z = np.cos(zeta)
    f = np.empty(lmax + 1)
    f[0] = 1.0
    if lmax >= 1:
        f[1] = 0.5 * (1.0 + z)
    for l in range(1, lmax):
        f[l + 1] = ((2 * l + 1) * z * f[l] - (l - 1) * f[l - 1]) / (l + 2)
    return 4.0 * np.pi * f


def circular_window(
    axis: ArrayLike,
    aperture: float,
    lmax: int,
    power: float = 4.0 * np.pi,
    radiance: ArrayLike | None = None,
) -> NDArray[np.floating]:
    """SH coefficients of a circular light window of angular radius ``aperture`` (radians)
    about ``axis`` (LH §3.2, eq. 11).

    By default the window has LH's normalisation scaled to total power ``power``:
    L = power / (2π(1 − cos ζ)) inside the cap (= 2/(1 − cos ζ) for power 4π), so
    ∫ L dω = power. With ``radiance`` (a number or a colour (C,)) the window instead has
    that constant radiance inside the cap. Returns (..., K), or (..., K, C) for a colour.

    Parameters
    ----------
    axis
        (..., 3) window centres (normalised here).
    aperture
        The angular radius ζ, radians.
    lmax
        The highest degree.
    power
        The total power ∫L dω (default 4π, LH's normalisation); ignored with ``radiance``.
    radiance
        A constant radiance inside the cap: a number, or a colour (C,).

    Returns
    -------
    ndarray of shape (..., K) or (..., K, C)
        The window's SH coefficients; (..., K, C) for a colour ``radiance``.
    """
    mom = window_moments(aperture, lmax)
    if radiance is None:
        return zonal_from_moments(mom * (float(power) / (4.0 * np.pi)), axis)
    solid = 2.0 * np.pi * (1.0 - np.cos(float(aperture)))
    b = zonal_from_moments(mom * (solid / (4.0 * np.pi)), axis)
    rad = np.asarray(radiance, dtype=b.dtype)
    if rad.ndim == 0:
        return b * rad
    if rad.ndim != 1:
        raise ShprobeError(f"radiance must be a number or a colour (C,), got {rad.shape}")
    return b[..., None] * rad
