"""Zonal (circularly symmetric) functions: clamped cosine Â_l, Proposition 3.2, circular window,
Funk–Hecke convolution (LH 2007 §3; R&H 2001 eq. 5–9).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .sh import check_lmax, degrees, lmax_of


def clamped_cosine_factors(lmax: int) -> NDArray[np.float64]:
    """Â_l for l = 0..lmax, the SH factors of the clamped cosine max(cos θ, 0) (R&H eq. 8–9).

    Â_0 = π, Â_1 = 2π/3, Â_l = 0 for odd l > 1, and for even l

        Â_l = 2π (−1)^(l/2 − 1) / ((l + 2)(l − 1)) · l! / (2^l ((l/2)!)²),

    with l!/(2^l ((l/2)!)²) built by the ratio (l+1)/(l+2) so nothing overflows.
    """
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

    ``coeffs`` is (..., K, C) or (K,); ``factors`` has at least lmax+1 entries. With
    ``factors = clamped_cosine_factors(lmax)`` this turns lighting L_lm into irradiance
    coefficients E_lm = Â_l L_lm (R&H eq. 7).
    """
    c = np.asarray(coeffs)
    if c.dtype not in (np.float32, np.float64):
        c = c.astype(np.float64)
    f = np.asarray(factors, dtype=np.float64)
    kaxis = -1 if c.ndim == 1 else -2
    lmax = lmax_of(c.shape[kaxis])
    if f.shape[-1] < lmax + 1:
        from .errors import ShprobeError

        raise ShprobeError(f"need {lmax + 1} band factors, got {f.shape[-1]}")
    per_k = f[..., degrees(lmax)].astype(c.dtype)
    return c * (per_k if c.ndim == 1 else per_k[..., None])
