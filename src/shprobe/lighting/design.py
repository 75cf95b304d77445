"""Lighting design (R&H 2001 §3.3): editing coefficients band by band or one by one, analytic
lights (directional, cone, hemisphere), blending and rotation, and the edit pipeline that
``shprobe edit`` and the viewer apply.

All functions take lighting coefficients L_lm of shape (K, C) (or (K,)) and return new arrays;
nothing is modified in place. Windows and the non-negativity certificate are
`shprobe.lighting.windows`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, lmax_of, num_coeffs, sh_basis, sh_index
from ..sh.rotation import one_rotation, rotate, unit_vectors
from ..sh.zonal import circular_window
from .coeffs import as_coeffs, pad_coeffs
from .edits import BlendResolver, EditSpec

__all__ = [
    "EditSpec",
    "Edited",
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
class Edited:
    """Result of `edit_lighting`: the coefficients and what the window step did."""

    coeffs: NDArray[np.float64]
    window: str | None = None

    def __repr__(self) -> str:
        return (f"Edited(lmax={lmax_of(self.coeffs.shape[0])}, "
                f"channels={self.coeffs.shape[1]}, window={self.window!r})")


def _steps(spec: EditSpec, blends: BlendResolver) -> list[Callable[[NDArray], NDArray]]:
    """The edits of ``spec`` up to the window, one function of the lighting each, in order."""
    lmax = spec.lmax
    out: list[Callable[[NDArray], NDArray]] = []
    for b in spec.blends:
        out.append(lambda L, b=b: blend([(L, 1.0), (pad_coeffs(blends(b, lmax), lmax),
                                                    b.weight)]))
    for d, rgb in spec.directional:
        out.append(lambda L, d=d, rgb=rgb: L + directional_light(d, rgb, lmax))
    for axis, ap, rgb in spec.cones:
        out.append(lambda L, a=axis, ap=ap, rgb=rgb: L + cone_light(a, np.radians(ap), rgb,
                                                                    lmax))
    if spec.sky is not None:
        sky, ground, up = spec.sky
        out.append(lambda L: L + sky_light(up, sky, ground, lmax))
    out += [lambda L, k=k, v=v: set_coeff(L, *k, v) for k, v in spec.sets]
    out += [lambda L, k=k, f=f: scale_coeff(L, *k, f) for k, f in spec.scales]
    out += [lambda L, k=k: negate_coeff(L, *k) for k in spec.negates]
    out += [lambda L, l=l, v=v: set_band(L, l, v) for l, v in spec.set_bands]
    out += [lambda L, l=l, f=f: scale_band(L, l, f) for l, f in spec.scale_bands]
    out += [lambda L, l=l: negate_band(L, l) for l in spec.negate_bands]
    out += [lambda L, r=r: rotate_lighting(L, r.matrix()) for r in spec.rotations]
    return out


#: Largest coefficient magnitude an edit may produce: far above any real lighting, and far
#: enough below the float64 range that the irradiance, windows and renders computed from it
#: do not overflow.
MAX_EDITED = 1e30


def _bounded(fn: Callable[..., Edited]) -> Callable[..., Edited]:
    """Run an edit with floating-point overflow silenced (no warnings on the terminal) and
    refuse, in one line, a result that overflowed or left `MAX_EDITED`."""
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
def edit_lighting(base: ArrayLike | None, spec: EditSpec,
                  blends: BlendResolver | None = None) -> Edited:
    """Apply the edits of ``spec`` ([`EditSpec`][shprobe.lighting.EditSpec]) to ``base``
    (L_lm, or None: start from darkness) at the spec's degree (the base is cut or zero-padded
    and scaled by the spec's weight; the spec refuses an edit above its degree). ``blends``
    gives the coefficients of a blend (default `shprobe.lighting.source.blend_lighting`:
    presets and files)."""
    from .windows import apply_window, auto_window, window_bias, window_factors

    lmax = spec.lmax
    if blends is None:
        from .source import blend_lighting as blends
    steps = _steps(spec, blends)
    turns = len(spec.rotations)  # the rotations come last
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused, in one line
        L = np.zeros((num_coeffs(lmax), 3)) if base is None else pad_coeffs(base, lmax)
        L = L * spec.weight
        for i, step in enumerate([lambda x: x, *steps]):
            if i == len(steps) - turns + 1:
                unrotated = L
            L = step(L)
            if not np.all(np.isfinite(L)):
                raise ShprobeError("the edits overflow: the lighting is not finite (use "
                                   "smaller weights or factors)")
    if turns == 0:
        unrotated = L
    if spec.window is None:
        return Edited(L)
    if spec.window == "auto":
        # chosen on the lighting before its rotations: a window acts per band, so it commutes
        # with them, and the viewer, which turns the lighting while dragging, chooses the same
        ch = auto_window(unrotated)
        desc = (f"window auto -> {ch.kind}" + (f" strength {ch.strength:.4g}" if ch.strength
                                                else "") + f", bias {100 * ch.bias:.2f}% (L2 of E)")
        return Edited(apply_window(L, ch.factors), desc)
    kind, s = spec.window
    f = window_factors(kind, lmax, s)
    return Edited(apply_window(L, f), f"window {kind} strength {s:g}, bias "
                                      f"{100 * window_bias(L, f):.2f}% (L2 of E)")
