"""Windowing and the non-negativity certificate (R&H 2001 §3.3, Sloan 2008).

Windows (factors w_l multiplying band l, ``strength`` s ≥ 0, s = 0 is no window):

* ``hann``      w_l = ½(1 + cos(π l / h)) for l < h, else 0, with h = (lmax + 1) / s;
* ``lanczos``   w_l = sinc(l / h) = sin(π l/h) / (π l/h) for l < h, else 0, h as above;
* ``gaussian``  w_l = exp(−s · l(l + 1))  (heat-kernel smoothing);
* ``laplacian`` w_l = 1 / (1 + s · l²(l + 1)²)  (Sloan 2008, "Stupid SH tricks": the g that
  minimises ‖f − g‖² + λ‖Δg‖², with λ = s).

Non-negativity certificate ([`min_irradiance`][shprobe.lighting.min_irradiance]): for lmax ≤ 2, E(n)
= nᵀAn + 2bᵀn + c on |n| = 1 (R&H eq. 11 split into blocks). For any μ below the smallest eigenvalue
λ₁ of A,

    E(n) = nᵀ(A − μI)n + 2bᵀn + c + μ ≥ d(μ) = c + μ − bᵀ(A − μI)⁻¹b,

a rigorous lower bound (the Lagrangian dual of the trust-region problem, which has no duality
gap). d is concave; its maximiser solves the secular equation Σ β_i² / (λ_i − μ)² = 1
(β = Qᵀb), found by bisection; the primal point n = −(A − μI)⁻¹b (plus the λ₁ eigenvector in the
"hard case" β₁ = 0) attains the bound. The certificate reports both: min E ∈ [lower, attained].
For lmax > 2 the minimum is numerical: a dense Fibonacci grid, then refinement from the best
grid points until the minimum changes by less than a stated tolerance (``tolerance``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, degrees, lmax_of, sh_basis
from ..sh.zonal import clamped_cosine_factors, convolve
from .coeffs import as_coeffs
from .irradiance import quadratic_form

WINDOWS = ("hann", "lanczos", "gaussian", "laplacian")

#: A window choice: None (no window), 'auto' (:func:`auto_window`) or (kind, strength).
WindowSpec = str | tuple[str, float] | None

__all__ = [
    "WINDOWS",
    "IrradianceMinimum",
    "WindowChoice",
    "WindowSpec",
    "apply_window",
    "auto_window",
    "min_irradiance",
    "parse_window",
    "window_bias",
    "window_factors",
    "window_text",
]


# ----------------------------------------------------------------------------- the spec


def parse_window(text: object) -> WindowSpec:
    """The one window grammar: None, '' or 'none' → None; 'auto'; 'KIND:STRENGTH' (KIND one of
    [`WINDOWS`][shprobe.lighting.WINDOWS], STRENGTH a finite number ≥ 0) → (kind, strength)."""
    if text is None:
        return None
    if not isinstance(text, str):
        raise ShprobeError(f"window must be text ('auto' or KIND:STRENGTH), got "
                           f"{type(text).__name__}")
    t = text.strip()
    if t.lower() in ("", "none"):
        return None
    if t.lower() == "auto":
        return "auto"
    kind, _, s = t.partition(":")
    try:
        strength = float(s) if len(s) <= 40 else float("nan")
    except ValueError:
        strength = float("nan")
    if kind not in WINDOWS or not (np.isfinite(strength) and 0 <= strength <= 1e9):
        raise ShprobeError(f"window {t[:60]!r}: expected 'auto' or KIND:STRENGTH with KIND one "
                           f"of {', '.join(WINDOWS)} and STRENGTH a number >= 0")
    return kind, strength


def window_text(spec: WindowSpec) -> str:
    """`parse_window`'s text of a window choice ('none', 'auto' or 'KIND:STRENGTH')."""
    if spec is None:
        return "none"
    if isinstance(spec, str):
        return spec
    return f"{spec[0]}:{float(spec[1])!r}"


# ----------------------------------------------------------------------------- windows


def window_factors(kind: str, lmax: int, strength: float) -> NDArray[np.float64]:
    """Window factors w_l, l = 0..lmax (see the module doc for the four kinds); w_0 = 1.
    A torch tensor or JAX array ``strength`` gives factors of that kind, differentiable in
    it (``shprobe.lighting._xp``).

    Parameters
    ----------
    kind
        One of ``WINDOWS``.
    lmax
        The highest degree.
    strength
        The window's strength (a torch tensor or JAX array makes the factors one).

    Returns
    -------
    ndarray of shape (lmax + 1,)
        w_0 … w_lmax, w_0 = 1.
    """
    from ..sh import _xp

    xp = _xp.namespace(strength)
    if xp is not None:
        from . import _xp as lx

        if kind not in WINDOWS:
            raise ShprobeError(f"unknown window {kind!r}; choose from {', '.join(WINDOWS)}")
        return lx.window_factors(xp, kind, lmax, strength)
    lmax = check_lmax(lmax)
    s = float(strength)
    if not np.isfinite(s) or s < 0:
        raise ShprobeError(f"window strength must be >= 0, got {strength}")
    l = np.arange(lmax + 1, dtype=np.float64)
    if kind in ("hann", "lanczos"):
        if s == 0:
            return np.ones(lmax + 1)
        h = (lmax + 1) / s
        x = l / h
        w = 0.5 * (1 + np.cos(np.pi * x)) if kind == "hann" else np.sinc(x)
        return np.where(x < 1, w, 0.0)
    if kind == "gaussian":
        return np.exp(-s * l * (l + 1))
    if kind == "laplacian":
        return 1.0 / (1.0 + s * (l * (l + 1)) ** 2)
    raise ShprobeError(f"unknown window {kind!r}; choose from {', '.join(WINDOWS)}")


def apply_window(coeffs: ArrayLike, factors: ArrayLike) -> NDArray[np.float64]:
    """L_lm · w_l.

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients.
    factors
        (lmax + 1,) window factors w_l.

    Returns
    -------
    ndarray of shape (K, C)
        L_lm · w_l.
    """
    return np.asarray(convolve(as_coeffs(coeffs), factors), dtype=np.float64)


def window_bias(coeffs: ArrayLike, factors: ArrayLike) -> float:
    """Relative L2 change of the irradiance over the sphere caused by a window (Parseval):
    √(Σ ((1 − w_l) Â_l L_lm)²) / √(Σ (Â_l L_lm)²), summed over channels."""
    c = as_coeffs(coeffs)
    lmax = lmax_of(c.shape[0])
    E = convolve(c, clamped_cosine_factors(lmax))
    dE = convolve(E, 1.0 - np.asarray(factors, dtype=np.float64)[: lmax + 1])
    den = np.sqrt((E**2).sum())
    return float(np.sqrt((dE**2).sum()) / den) if den > 0 else 0.0


# ----------------------------------------------------------------------------- certificate


@dataclass
class IrradianceMinimum:
    """min over the unit sphere of E(n), per channel.

    ``minimum``: the smallest E found (attained at ``direction``); ``lower_bound``: a proven
    lower bound (lmax ≤ 2: the Lagrangian dual value, equal to ``minimum`` to rounding;
    higher lmax: NaN, the search is numerical); ``exact``: whether the bound is certified.
    ``tolerance`` (lmax > 2): the refinement stopped when a halving of its step moved the
    minimum by less than this (``change``, the last move); 0 for the exact lmax ≤ 2 case.
    """

    minimum: NDArray[np.float64]
    lower_bound: NDArray[np.float64]
    direction: NDArray[np.float64]
    exact: bool
    method: str
    tolerance: float = 0.0
    change: float = 0.0

    @property
    def nonnegative(self) -> bool:
        """True when E ≥ 0 everywhere on the sphere is established (lmax ≤ 2: certified)."""
        bound = self.lower_bound if self.exact else self.minimum
        return bool(np.all(bound >= 0.0))


def _trust_region_min(A: NDArray, b: NDArray, c: float) -> tuple[float, float, NDArray]:
    """(attained min, dual lower bound, argmin) of nᵀAn + 2bᵀn + c over |n| = 1."""
    lam, Q = np.linalg.eigh(A)
    beta = Q.T @ b
    scale = max(1.0, float(np.abs(lam).max()), float(np.linalg.norm(b)), abs(c))
    tiny = 1e-13 * scale

    (l0, l1, l2), (q0, q1, q2) = lam.tolist(), (beta**2).tolist()  # floats: bisection is hot

    def g(mu: float) -> float:
        return q0 / (l0 - mu) ** 2 + q1 / (l1 - mu) ** 2 + q2 / (l2 - mu) ** 2 - 1.0

    def dual(mu: float) -> float:
        return float(c + mu - np.sum(beta**2 / (lam - mu)))

    hi = lam[0] - tiny
    cands: list[NDArray] = []
    if g(hi) < 0:  # hard case: the bound is reached at μ = λ₁
        mu = lam[0]
        rest = np.zeros(3)
        mask = np.abs(lam - mu) > tiny
        rest[mask] = -beta[mask] / (lam[mask] - mu)
        tau = np.sqrt(max(0.0, 1.0 - float(rest @ rest)))
        for sgn in (1.0, -1.0):
            z = rest.copy()
            z[~mask] = 0.0
            z[0] += sgn * tau
            cands.append(Q @ z)
        lower = dual(hi)
    else:
        lo = lam[0] - float(np.linalg.norm(b)) - tiny  # g(lo) ≤ 0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            if g(mid) < 0:
                lo = mid
            else:
                hi = mid
        mu = lo
        z = -beta / (lam - mu)
        cands.append(Q @ z)
        lower = max(dual(lo), dual(hi))
    cands += [Q[:, i] * s for i in range(3) for s in (1.0, -1.0)]
    best, arg = np.inf, cands[0]
    for n in cands:
        nn = np.linalg.norm(n)
        if nn == 0:
            continue
        n = n / nn
        v = float(n @ A @ n + 2 * b @ n + c)
        if v < best:
            best, arg = v, n
    return best, min(lower, best), arg


def _fibonacci(n: int) -> NDArray[np.float64]:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


#: Tolerance of the numerical minimum (lmax > 2), relative to the mean irradiance.
MIN_TOL = 1e-9


def min_irradiance(coeffs: ArrayLike, grid: int = 20000) -> IrradianceMinimum:
    """Minimum of E(n) = Σ Â_l L_lm y_lm(n) over the unit sphere, per channel.

    lmax ≤ 2: exact, by the trust-region dual of nᵀMn (R&H eq. 11) — see the module doc.
    lmax > 2: numerical — a Fibonacci grid of ``grid`` points, then refinement from the 8
    best well-separated grid points (`shprobe.lighting.sphere_search.refine_max`: compass
    search on the sphere, exact SH sums) until a halving of the step moves the minimum by less
    than ``MIN_TOL`` × the mean irradiance E₀₀Y₀₀ (reported as ``tolerance``).

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients.
    grid
        Points of the Fibonacci grid searched first when lmax > 2.

    Returns
    -------
    IrradianceMinimum
        The minimum per channel, where it is and how it was found (exact for lmax ≤ 2).
    """
    c = as_coeffs(coeffs)
    lmax = lmax_of(c.shape[0])
    C = c.shape[1]
    mins, lows, dirs = np.empty(C), np.empty(C), np.empty((C, 3))
    if lmax <= 2:
        M = quadratic_form(c)
        for ch in range(C):
            mins[ch], lows[ch], dirs[ch] = _trust_region_min(M[ch, :3, :3], M[ch, :3, 3],
                                                             float(M[ch, 3, 3]))
        return IrradianceMinimum(mins, lows, dirs, True, "trust-region dual (R&H eq. 11)")
    from .sphere_search import refine_max

    E_lm = convolve(c, clamped_cosine_factors(lmax))
    pts = _fibonacci(max(int(grid), 100))
    vals = sh_basis(pts, lmax) @ E_lm
    step = float(np.sqrt(4.0 * np.pi / len(pts)))
    scale = max(abs(float(E_lm[0].max())) * 0.5 / np.sqrt(np.pi), 1e-300)  # mean E
    tol = MIN_TOL * scale
    changes = np.empty(C)
    for ch in range(C):
        def f(n, ch=ch):
            return -(sh_basis(n, lmax) @ E_lm[:, ch])

        sm = refine_max(f, pts, -vals[:, ch], step=step, tol=tol, starts=8)
        mins[ch], lows[ch], dirs[ch], changes[ch] = -sm.value, np.nan, sm.direction, sm.change
    return IrradianceMinimum(mins, lows, dirs, False,
                             f"grid {len(pts)} + compass refinement to tol {tol:.2g}",
                             tolerance=tol, change=float(changes.max()))


@dataclass
class WindowChoice:
    """Result of [`auto_window`][shprobe.lighting.auto_window]: the window kind and strength chosen,
    its factors, the minimum irradiance before and after, and the bias (relative L2 change of E) it
    costs. ``kind`` is ``"none"`` when the lighting is already non-negative."""

    kind: str
    strength: float
    factors: NDArray[np.float64]
    before: IrradianceMinimum
    after: IrradianceMinimum
    bias: float
    candidates: dict[str, tuple[float, float]]  # kind -> (strength, bias) of each kind tried


def _threshold(c: NDArray, kind: str, lmax: int, ok) -> float | None:
    """Smallest strength s of ``kind`` with ok(windowed) (scan, then bisection)."""
    if kind in ("hann", "lanczos"):
        grid = np.linspace(0, lmax + 1, 65)[1:]
    else:
        grid = np.concatenate([[0.0], np.geomspace(1e-6, 1e4, 64)])[1:]
    prev = 0.0
    for s in grid:
        if ok(apply_window(c, window_factors(kind, lmax, s))):
            lo, hi = prev, float(s)
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                if ok(apply_window(c, window_factors(kind, lmax, mid))):
                    hi = mid
                else:
                    lo = mid
            return hi
        prev = float(s)
    return None


def auto_window(coeffs: ArrayLike, kinds: Sequence[str] = WINDOWS) -> WindowChoice:
    """The mildest window making E(n) ≥ 0 on the whole sphere: for each kind the smallest
    strength whose windowed lighting passes [`min_irradiance`][shprobe.lighting.min_irradiance] (for
    lmax ≤ 2 the certified lower bound must be ≥ 0), then the kind with the least `window_bias`.

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients.
    kinds
        The window kinds to try.

    Returns
    -------
    WindowChoice
        The chosen kind and strength (none when E ≥ 0 already).
    """
    c = as_coeffs(coeffs)
    lmax = lmax_of(c.shape[0])
    before = min_irradiance(c)
    if before.nonnegative:
        f = np.ones(lmax + 1)
        return WindowChoice("none", 0.0, f, before, before, 0.0, {})
    if lmax <= 2:
        def ok(x):
            return min_irradiance(x).nonnegative
    else:  # grid test during the search; the final choice is re-checked with refinement
        pts = _fibonacci(20000)
        Y = sh_basis(pts, lmax) * clamped_cosine_factors(lmax)[degrees(lmax)]

        def ok(x):
            return bool((Y @ x).min() >= 0)
    cands: dict[str, tuple[float, float]] = {}
    for kind in kinds:
        s = _threshold(c, kind, lmax, ok)
        if s is None:
            continue
        if lmax > 2:  # make sure refinement agrees; strengthen a little if not
            for _ in range(20):
                if min_irradiance(apply_window(c, window_factors(kind, lmax, s))).nonnegative:
                    break
                s *= 1.05
        cands[kind] = (s, window_bias(c, window_factors(kind, lmax, s)))
    if not cands:
        raise ShprobeError("no window makes this lighting non-negative (is L_00 negative?)")
    kind = min(cands, key=lambda k: cands[k][1])
    s, bias = cands[kind]
    f = window_factors(kind, lmax, s)
    return WindowChoice(kind, s, f, before, min_irradiance(apply_window(c, f)), bias, cands)
