"""Lighting design (R&H 2001 §3.3): editing coefficients band by band or one by one, analytic
lights (directional, cone, hemisphere), blending and rotation, and the edit pipeline that
``shprobe edit`` and the viewer apply.

All functions take lighting coefficients L_lm of shape (K, C) (or (K,)) and return new arrays;
nothing is modified in place. Windows and the non-negativity certificate are
:mod:`shprobe.lighting.windows`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, lmax_of, num_coeffs, sh_basis, sh_index
from ..sh.rotation import one_rotation, rotate, unit_vectors
from ..sh.zonal import circular_window
from .coeffs import as_coeffs, pad_coeffs

__all__ = [
    "blend",
    "cone_light",
    "directional_light",
    "negate_band",
    "negate_coeff",
    "rotate_lighting",
    "scale_band",
    "scale_coeff",
    "set_band",
    "set_coeff",
    "sky_light",
]


# ----------------------------------------------------------------------------- editing


def _value(value: Any, C: int) -> NDArray[np.float64]:
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.size not in (1, C):
        raise ShprobeError(f"value must be a scalar or {C} numbers (one per channel), got {v}")
    return np.broadcast_to(v, (C,))


def _room(coeffs: ArrayLike, l: int) -> NDArray[np.float64]:
    c = as_coeffs(coeffs)
    lmax = lmax_of(c.shape[0])
    return pad_coeffs(c, l) if l > lmax else c


def set_coeff(coeffs: ArrayLike, l: int, m: int, value: Any) -> NDArray[np.float64]:
    """L_lm := value (scalar or per channel); grows the array if l > lmax."""
    c = _room(coeffs, l)
    c[sh_index(l, m)] = _value(value, c.shape[1])
    return c


def scale_coeff(coeffs: ArrayLike, l: int, m: int, factor: Any) -> NDArray[np.float64]:
    """L_lm := factor · L_lm."""
    c = _room(coeffs, l)
    c[sh_index(l, m)] *= _value(factor, c.shape[1])
    return c


def negate_coeff(coeffs: ArrayLike, l: int, m: int) -> NDArray[np.float64]:
    """L_lm := −L_lm."""
    return scale_coeff(coeffs, l, m, -1.0)


def _band(l: int) -> slice:
    if l < 0:
        raise ShprobeError(f"band must be >= 0, got {l}")
    return slice(l * l, (l + 1) ** 2)


def set_band(coeffs: ArrayLike, l: int, value: Any) -> NDArray[np.float64]:
    """Every L_lm of band l := value."""
    c = _room(coeffs, l)
    c[_band(l)] = _value(value, c.shape[1])
    return c


def scale_band(coeffs: ArrayLike, l: int, factor: Any) -> NDArray[np.float64]:
    """Band l scaled by ``factor`` (e.g. 0 removes it)."""
    c = _room(coeffs, l)
    c[_band(l)] *= _value(factor, c.shape[1])
    return c


def negate_band(coeffs: ArrayLike, l: int) -> NDArray[np.float64]:
    """Band l negated (for odd l this mirrors the lighting through the origin)."""
    return scale_band(coeffs, l, -1.0)


# ----------------------------------------------------------------------------- analytic lights


def _rgb(x: Any) -> NDArray[np.float64]:
    return np.atleast_1d(np.asarray(x, dtype=np.float64))


def directional_light(direction: ArrayLike, intensity: Any = 1.0,
                      lmax: int = 2) -> NDArray[np.float64]:
    """A distant point source of irradiance ``intensity`` (per channel) arriving from
    ``direction``: L(ω) = I δ(ω, d), so L_lm = I y_lm(d). Its irradiance is
    E(n) ≈ I max(n·d, 0) (exactly so for lmax → ∞; R&H's 9 terms are the low-pass version)."""
    y = sh_basis(unit_vectors(direction), check_lmax(lmax))
    return y[:, None] * _rgb(intensity)[None, :]


def cone_light(axis: ArrayLike, aperture: float, radiance: Any = 1.0,
               lmax: int = 2) -> NDArray[np.float64]:
    """A circular window (disc light) of constant ``radiance`` and half-angle ``aperture`` ζ
    (radians, 0 < ζ ≤ π) around ``axis``: L_lm = radiance · (2π ∫ h P_l) · y_lm(axis)
    (Funk–Hecke), by the foundation's ``shprobe.zonal.circular_window`` (LH eq. 11)."""
    return np.asarray(circular_window(unit_vectors(axis), float(aperture), check_lmax(lmax),
                                      radiance=_rgb(radiance)), dtype=np.float64)


def sky_light(up: ArrayLike = (0.0, 1.0, 0.0), sky: Any = 1.0, ground: Any = 0.0,
              lmax: int = 2) -> NDArray[np.float64]:
    """Hemisphere light: radiance ``sky`` over the hemisphere around ``up``, ``ground`` below."""
    u = unit_vectors(up)
    return cone_light(u, np.pi / 2, sky, lmax) + cone_light(-u, np.pi / 2, ground, lmax)


def blend(items: Iterable[tuple[ArrayLike, float]]) -> NDArray[np.float64]:
    """Σ wᵢ Lᵢ over (coefficients, weight) pairs; lower-degree inputs are zero-padded and
    single-channel inputs broadcast over the channels of the others."""
    items = [(as_coeffs(c), float(w)) for c, w in items]
    if not items:
        raise ShprobeError("nothing to blend")
    lmax = max(lmax_of(c.shape[0]) for c, _ in items)
    C = max(c.shape[1] for c, _ in items)
    out = np.zeros((num_coeffs(lmax), C))
    for c, w in items:
        if c.shape[1] not in (1, C):
            raise ShprobeError(f"cannot blend {c.shape[1]}-channel with {C}-channel lighting")
        out += w * pad_coeffs(c, lmax)
    return out


def rotate_lighting(coeffs: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
    """The lighting turned by ``rotation`` (3×3 matrix): coefficients of L∘R⁻¹, via the
    foundation's Wigner matrices (``shprobe.rotation.rotate``, LH eq. 4–5)."""
    return np.asarray(rotate(as_coeffs(coeffs), one_rotation(rotation)), dtype=np.float64)
