"""The coefficient core: one validation of SH coefficient arrays, their labels, the R&H
constants and basis normalisations, Condon–Shortley signs, padding to a degree.

Every function of the lighting layer and above that takes coefficients goes through
[`as_coeffs`][shprobe.lighting.as_coeffs]; the coefficient document (JSON) is
`shprobe.lighting.document`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, lmax_of, num_coeffs
from ..sh.conventions import cs_signs

__all__ = [
    "RH_CONSTANTS",
    "RH_LABELS",
    "as_coeffs",
    "as_rgb",
    "basis_constants",
    "check_coeffs",
    "coeff_lmax",
    "cs_signs",
    "labels",
    "nine",
    "pad_coeffs",
]

#: Row labels of R&H Fig. 2 for k = 0..8.
RH_LABELS = ("L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22")


def labels(lmax: int) -> list[str]:
    """``L{l}{m}`` for every flat index k = l(l+1)+m up to ``lmax`` (R&H Fig. 2 names).

    Parameters
    ----------
    lmax
        The highest degree.

    Returns
    -------
    list of str
        One label per flat index.
    """
    return [f"L{l}{m}" for l in range(check_lmax(lmax) + 1) for m in range(-l, l + 1)]


def as_coeffs(coeffs: Any, where: Any = None, what: str = "coefficients",
              finite: bool = True) -> NDArray[np.float64]:
    """A float64 (K, C) copy of coefficients; (K,) becomes (K, 1); K must be (lmax+1)².

    Refuses, with one line naming ``where`` (a file, when the data came from one), anything
    that is not a real numeric array of that shape, and (``finite``) NaN or infinity.

    Parameters
    ----------
    coeffs
        Coefficients, (K, C) or (K,).
    where
        The file they came from, named in the error.
    what
        What they are, named in the error.
    finite
        Refuse NaN and infinity.

    Returns
    -------
    ndarray of shape (K, C), float64
        A checked copy.
    """
    if isinstance(coeffs, (str, bytes, dict)) or coeffs is None:
        raise ShprobeError(f"{what} must be a numeric array, got {type(coeffs).__name__}",
                           where)
    try:
        a = np.asarray(coeffs)
        if a.dtype.kind == "c":
            raise ShprobeError(f"{what} must be real, got complex values", where)
        c = np.array(a, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError(f"{what} is not a numeric array", where) from None
    if c.ndim == 1:
        c = c[:, None]
    if c.ndim != 2 or c.shape[1] == 0:
        raise ShprobeError(f"{what} must be (K, C) or (K,), got shape {c.shape}", where)
    try:
        lmax_of(c.shape[0])
    except ShprobeError as e:
        raise ShprobeError(f"{what}: {e.message}", where) from None
    if finite and not np.all(np.isfinite(c)):
        raise ShprobeError(f"{what} contain NaN or infinity", where)
    return c


def as_rgb(coeffs: Any, where: Any = None, what: str = "lighting") -> NDArray[np.float64]:
    """Lighting coefficients as (K, 3) RGB: [`as_coeffs`][shprobe.lighting.as_coeffs], one channel
    (or (K,)) repeated to three; any other channel count refused in one line naming ``where``."""
    c = as_coeffs(coeffs, where, what)
    if c.shape[1] == 1:
        return np.repeat(c, 3, axis=1)
    if c.shape[1] != 3:
        raise ShprobeError(f"{what} needs 1 or 3 channels, got {c.shape[1]}", where)
    return c


def check_coeffs(coeffs: ArrayLike) -> NDArray[np.float64]:
    """Batched coefficients as float64, (K,) or (..., K, C), K = (lmax+1)² checked (no copy
    when already float64)."""
    try:
        c = np.asarray(coeffs, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError("coefficients are not a numeric array") from None
    coeff_lmax(c)
    return c


def coeff_lmax(coeffs: ArrayLike) -> int:
    """The degree of a (K,) or (..., K, C) coefficient array (K on axis −2, or the only axis)."""
    c = np.asarray(coeffs)
    if c.ndim == 0:
        raise ShprobeError("coefficients must be an array (K,) or (..., K, C)")
    return lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])


def pad_coeffs(coeffs: ArrayLike, lmax: int) -> NDArray[np.float64]:
    """Coefficients padded with zeros (or truncated) to degree ``lmax``, (K', C).

    Parameters
    ----------
    coeffs
        (K, C) coefficients.
    lmax
        The degree wanted.

    Returns
    -------
    ndarray of shape (K', C)
        The coefficients zero-padded or truncated, K' = (lmax + 1)².
    """
    c = as_coeffs(coeffs)
    out = np.zeros((num_coeffs(check_lmax(lmax)), c.shape[1]))
    k = min(out.shape[0], c.shape[0])
    out[:k] = c[:k]
    return out


def nine(coeffs: ArrayLike) -> NDArray[np.float64]:
    """(9, C): coefficients of lmax ≤ 2 zero-padded to the nine of R&H eq. 11–13; a higher
    degree is refused rather than truncated."""
    c = as_coeffs(coeffs)
    if c.shape[0] > 9:
        raise ShprobeError(f"the quadratic form needs lmax <= 2, got lmax={lmax_of(c.shape[0])}")
    return pad_coeffs(c, 2)


def _rh_constants() -> tuple[float, float, float, float, float]:
    """c1..c5 of R&H eq. 12 from Â_l (eq. 9) and the normalisations (eq. 3), unrounded."""
    a0, a1, a2 = np.pi, 2.0 * np.pi / 3.0, np.pi / 4.0
    k22 = 0.25 * math.sqrt(15.0 / np.pi)  # y22 = k22 (x² − y²); y2-2, y2-1, y21 = 2 k22 ·
    k20 = 0.25 * math.sqrt(5.0 / np.pi)  # y20 = k20 (3z² − 1)
    k1 = math.sqrt(3.0 / (4.0 * np.pi))
    k0 = 0.5 / math.sqrt(np.pi)
    return a2 * k22, a1 * k1 / 2.0, 3.0 * a2 * k20, a0 * k0, a2 * k20


#: (c1, c2, c3, c4, c5) of R&H eq. 12, exact; they round to 0.429043, 0.511664, 0.743125,
#: 0.886227, 0.247708.
RH_CONSTANTS: tuple[float, float, float, float, float] = _rh_constants()


def basis_constants() -> NDArray[np.float64]:
    """K_k of the R&H basis polynomials for k = 0..8 (y_k = K_k · poly_k, R&H eq. 3), exact
    (the registry's, `shprobe.sh.registry.basis_constants`)."""
    from ..sh.registry import basis_constants as constants

    return constants(2)
