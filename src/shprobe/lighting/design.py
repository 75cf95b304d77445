"""Lighting design (R&H 2001 §3.3): editing coefficients band by band or one by one, analytic
lights (directional, cone, hemisphere), blending and rotation, and the edit pipeline that
``shprobe edit`` and the viewer apply.

All functions take lighting coefficients L_lm of shape (K, C) (or (K,)) and return new arrays;
nothing is modified in place. Windows and the non-negativity certificate are
:mod:`shprobe.lighting.windows`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, lmax_of, num_coeffs, sh_basis, sh_index
from ..sh.rotation import one_rotation, rotate, unit_vectors
from ..sh.zonal import circular_window
from .coeffs import as_coeffs, pad_coeffs

__all__ = [
    "Edited",
    "Edits",
    "blend",
    "cone_light",
    "directional_light",
    "edit_lighting",
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
    (Funk–Hecke), by the foundation's ``shprobe.sh.zonal.circular_window`` (LH eq. 11)."""
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
    foundation's Wigner matrices (``shprobe.sh.rotation.rotate``, LH eq. 4–5)."""
    return np.asarray(rotate(as_coeffs(coeffs), one_rotation(rotation)), dtype=np.float64)


# ----------------------------------------------------------------------------- the edit pipeline


@dataclass(frozen=True)
class Edits:
    """Lighting edits in the order :func:`edit_lighting` applies them (``shprobe edit``, the
    viewer): blend, add lights, set/scale/negate coefficients, then bands, rotate, window.

    ``blends``: (coefficients, weight); ``directional``: (direction, rgb irradiance);
    ``cones``: (axis, aperture in degrees, rgb radiance); ``sky``: (sky rgb, ground rgb, up);
    ``sets`` / ``scales``: ((l, m), value or factor); ``negates``: (l, m); ``set_bands`` /
    ``scale_bands``: (l, value or factor); ``negate_bands``: l; ``rotations``: 3×3 matrices
    (or anything :func:`shprobe.sh.rotation.one_rotation` takes); ``window``: None, 'auto' or
    (kind, strength).
    """

    blends: Sequence[tuple[ArrayLike, float]] = ()
    directional: Sequence[tuple[ArrayLike, Any]] = ()
    cones: Sequence[tuple[ArrayLike, float, Any]] = ()
    sky: tuple[Any, Any, ArrayLike] | None = None
    sets: Sequence[tuple[tuple[int, int], Any]] = ()
    scales: Sequence[tuple[tuple[int, int], Any]] = ()
    negates: Sequence[tuple[int, int]] = ()
    set_bands: Sequence[tuple[int, Any]] = ()
    scale_bands: Sequence[tuple[int, Any]] = ()
    negate_bands: Sequence[int] = ()
    rotations: Sequence[Any] = ()
    window: str | tuple[str, float] | None = None


@dataclass(frozen=True)
class Edited:
    """Result of :func:`edit_lighting`: the coefficients and what the window step did."""

    coeffs: NDArray[np.float64]
    window: str | None = None

    def __repr__(self) -> str:
        return (f"Edited(lmax={lmax_of(self.coeffs.shape[0])}, "
                f"channels={self.coeffs.shape[1]}, window={self.window!r})")


#: Largest coefficient magnitude an edit may produce: far above any real lighting, and far
#: enough below the float64 range that the irradiance, windows and renders computed from it
#: do not overflow.
MAX_EDITED = 1e30


def _bounded(fn: Callable[..., Edited]) -> Callable[..., Edited]:
    """Run an edit with floating-point overflow silenced (no warnings on the terminal) and
    refuse, in one line, a result that overflowed or left :data:`MAX_EDITED`."""
    @functools.wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Edited:
        with np.errstate(over="ignore", invalid="ignore"):
            res = fn(*args, **kwargs)
        big = float(np.max(np.abs(res.coeffs), initial=0.0))
        if not big <= MAX_EDITED:
            raise ShprobeError(f"the edits give coefficients of magnitude {big:.3g}, beyond "
                               f"{MAX_EDITED:g}: a weight, scale or intensity is too large")
        return res

    return run


@_bounded
def edit_lighting(base: ArrayLike | None, edits: Edits, lmax: int = 2,
                  weight: float = 1.0) -> Edited:
    """Apply ``edits`` to ``base`` (L_lm, or None: start from darkness) at degree ``lmax``
    (the base is cut or zero-padded; an edit above ``lmax`` is refused, not grown into)."""
    from .windows import apply_window, auto_window, window_bias, window_factors

    lmax = check_lmax(lmax)
    L = np.zeros((num_coeffs(lmax), 3)) if base is None else pad_coeffs(base, lmax) * weight

    def fits(l: int, what: str) -> int:
        if not 0 <= int(l) <= lmax:
            raise ShprobeError(f"{what}: l = {l} is outside 0..{lmax} (the edit's lmax)")
        return int(l)

    for c, w in edits.blends:
        L = blend([(L, 1.0), (pad_coeffs(c, lmax), float(w))])
    for d, rgb in edits.directional:
        L = L + directional_light(d, rgb, lmax)
    for axis, ap, rgb in edits.cones:
        if not 0 < float(ap) <= 180:
            raise ShprobeError(f"cone aperture must be in (0, 180] degrees, got {ap}")
        L = L + cone_light(axis, np.radians(float(ap)), rgb, lmax)
    if edits.sky is not None:
        sky, ground, up = edits.sky
        L = L + sky_light(up, sky, ground, lmax)
    for (l, m), v in edits.sets:
        L = set_coeff(L, fits(l, "set"), m, v)
    for (l, m), f in edits.scales:
        L = scale_coeff(L, fits(l, "scale"), m, f)
    for l, m in edits.negates:
        L = negate_coeff(L, fits(l, "negate"), m)
    for l, v in edits.set_bands:
        L = set_band(L, fits(l, "set band"), v)
    for l, f in edits.scale_bands:
        L = scale_band(L, fits(l, "scale band"), f)
    for l in edits.negate_bands:
        L = negate_band(L, fits(l, "negate band"))
    for r in edits.rotations:
        L = rotate_lighting(L, r)
    spec = edits.window
    if spec is None:
        return Edited(L)
    if spec == "auto":
        ch = auto_window(L)
        desc = (f"window auto -> {ch.kind}" + (f" strength {ch.strength:.4g}" if ch.strength
                                                else "") + f", bias {100 * ch.bias:.2f}% (L2 of E)")
        return Edited(apply_window(L, ch.factors), desc)
    kind, s = spec
    f = window_factors(kind, lmax, s)
    return Edited(apply_window(L, f), f"window {kind} strength {s:g}, bias "
                                      f"{100 * window_bias(L, f):.2f}% (L2 of E)")
