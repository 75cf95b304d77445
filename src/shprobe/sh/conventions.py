"""SH conventions: shprobe's own, and converters to/from Condon–Shortley phase and 4π
normalisation (entries of the one registry, `shprobe.sh.registry`, which has the others:
3DGS, glTF, kaolin, e3nn, three.js, Filament, Unity).

shprobe (everywhere): real orthonormal SH with the signs of Ramamoorthi & Hanrahan 2001
(no Condon–Shortley phase), flat index k = l(l+1) + m, coefficient arrays (..., K, C):

    y_lm   = √2 K_lm P_l^m(cos θ) cos(mφ)     (m > 0)
    y_l,−m = √2 K_lm P_l^m(cos θ) sin(mφ)     (m > 0)
    y_l0   = K_l0 P_l(cos θ)

with P_l^m *without* the (−1)^m phase and ∫ y_lm² = 1. Other conventions:

* **Condon–Shortley phase** (google/spherical-harmonics, DirectXMath ``XMSHEval*``, cmft,
  cmgen / Filament, Lisle & Huang's eq. 1 recurrence): y^CS_lm = (−1)^|m| y_lm, e.g.
  y^CS_1,−1 = −0.488603 y, y^CS_11 = −0.488603 x. Since the function is the same,
  coefficients convert by the same factor: a^CS_lm = (−1)^|m| a_lm (an involution).
* **pyshtools '4pi'** (geodesy): Y^4π_lm = √(4π) y_lm with ``csphase=1`` (its default) and
  √(4π) (−1)^m y_lm with ``csphase=-1``; coefficients a^4π = a / √(4π) (times (−1)^m for
  ``csphase=-1``). pyshtools 'ortho' is shprobe's basis (times (−1)^m with ``csphase=-1``).
  pyshtools stores real coefficients as ``cilm[i, l, m]``, i = 0 for cos (m ≥ 0), i = 1 for
  sin (the y_l,−m coefficient); see `to_shtools` / `from_shtools`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .indexing import lmax_of, num_coeffs
from .registry import convert, cs_signs

_SQRT_4PI = float(np.sqrt(4.0 * np.pi))


def _coeffs(coeffs: ArrayLike) -> tuple[NDArray[np.floating], int]:
    c = np.asarray(coeffs)
    if c.dtype not in (np.float32, np.float64):
        c = c.astype(np.float64)
    if c.ndim == 0:
        raise ShprobeError("coefficients must have shape (..., K, C) or (K,)")
    kaxis = -1 if c.ndim == 1 else -2
    return c, lmax_of(c.shape[kaxis])


def _per_k(c: NDArray[np.floating], factor: NDArray[np.float64]) -> NDArray[np.floating]:
    f = factor.astype(c.dtype)
    return c * (f if c.ndim == 1 else f[:, None])


def to_condon_shortley(coeffs: ArrayLike) -> NDArray[np.floating]:
    """shprobe coefficients (..., K, C) or (K,) → coefficients in the CS-phase real basis
    (google/spherical-harmonics, DirectXMath, cmft, cmgen): a^CS_lm = (−1)^|m| a_lm."""
    return convert(coeffs, to="cs")


def from_condon_shortley(coeffs: ArrayLike) -> NDArray[np.floating]:
    """CS-phase real coefficients → shprobe's (the same sign flip; it is an involution)."""
    return convert(coeffs, from_="cs")


def to_4pi(coeffs: ArrayLike, csphase: int = 1) -> NDArray[np.floating]:
    """shprobe coefficients → pyshtools '4pi' real coefficients in shprobe's flat layout:
    a^4π = a / √(4π), times (−1)^|m| when ``csphase=-1``."""
    return convert(coeffs, to=_four_pi_name(csphase))


def from_4pi(coeffs: ArrayLike, csphase: int = 1) -> NDArray[np.floating]:
    """pyshtools '4pi' real coefficients (flat layout) → shprobe: a = √(4π) a^4π (× (−1)^|m|
    for ``csphase=-1``)."""
    return convert(coeffs, from_=_four_pi_name(csphase))


def _four_pi_name(csphase: int) -> str:
    _cs_factor(0, csphase)
    return "4pi" if csphase == 1 else "4pi-cs"


def _cs_factor(lmax: int, csphase: int) -> NDArray[np.float64]:
    if csphase not in (1, -1):
        raise ShprobeError(f"csphase must be 1 or -1, got {csphase!r}")
    return np.ones(num_coeffs(lmax)) if csphase == 1 else cs_signs(lmax)


_NORMS = {"4pi": 1.0 / _SQRT_4PI, "ortho": 1.0}


def to_shtools(
    coeffs: ArrayLike, normalization: str = "4pi", csphase: int = 1
) -> NDArray[np.float64]:
    """shprobe coefficients (K,) → pyshtools ``cilm`` (2, lmax+1, lmax+1); (K, C) →
    (C, 2, lmax+1, lmax+1). ``normalization`` is '4pi' or 'ortho'."""
    c, lmax = _coeffs(coeffs)
    if normalization not in _NORMS:
        raise ShprobeError(f"normalization must be '4pi' or 'ortho', got {normalization!r}")
    if c.ndim > 2:
        raise ShprobeError(f"to_shtools takes (K,) or (K, C) coefficients, got {c.shape}")
    scaled = np.asarray(c, dtype=np.float64) * _NORMS[normalization]
    scaled = _per_k(scaled, _cs_factor(lmax, csphase))
    chans = scaled[:, None] if scaled.ndim == 1 else scaled
    cilm = np.zeros((chans.shape[1], 2, lmax + 1, lmax + 1))
    for l in range(lmax + 1):
        k0 = l * (l + 1)
        m = np.arange(l + 1)
        cilm[:, 0, l, : l + 1] = chans[k0 + m].T
        cilm[:, 1, l, 1 : l + 1] = chans[k0 - m[1:]].T
    return cilm[0] if c.ndim == 1 else cilm


def from_shtools(
    cilm: ArrayLike, normalization: str = "4pi", csphase: int = 1
) -> NDArray[np.float64]:
    """pyshtools real ``cilm`` (2, L+1, L+1) → shprobe (K,); (C, 2, L+1, L+1) → (K, C)."""
    a = np.asarray(cilm, dtype=np.float64)
    if normalization not in _NORMS:
        raise ShprobeError(f"normalization must be '4pi' or 'ortho', got {normalization!r}")
    if a.ndim not in (3, 4) or a.shape[-3] != 2 or a.shape[-1] != a.shape[-2]:
        raise ShprobeError(f"cilm must have shape ([C,] 2, L+1, L+1), got {a.shape}")
    one = a.ndim == 3
    a = a[None] if one else a
    lmax = a.shape[-1] - 1
    out = np.zeros((num_coeffs(lmax), a.shape[0]))
    for l in range(lmax + 1):
        k0 = l * (l + 1)
        m = np.arange(l + 1)
        out[k0 + m] = a[:, 0, l, : l + 1].T
        out[k0 - m[1:]] = a[:, 1, l, 1 : l + 1].T
    out = _per_k(out / _NORMS[normalization], _cs_factor(lmax, csphase))
    return out[:, 0] if one else out
