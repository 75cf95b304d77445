"""Linear least squares for the nine lighting coefficients, robust (IRLS) and with the
conditioning of the normal equations reported per coefficient.

A diffuse surface of albedo ρ shows radiance ρ E(n)/π with E(n) = Σ_{l≤2} Â_l L_lm y_lm(n)
(R&H 2001 eq. 7): linear in the nine L_lm, so pixels with known normals give a linear
least-squares problem whose 9×9 normal equations are solved once for all three channels (the
design matrix depends only on the normals). Pixels of a chrome ball give radiance samples
L(ω) directly; the same solver fits Σ y_lm(ω) L_lm to them, weighted by each pixel's solid
angle (with full coverage this is the projection of R&H eq. 10).

Robustness: an MM-estimator. Several starts (least squares; least median of squares over
random pixel subsets; least squares over random subsets of 4×4 tiles of the normals, so some
start leaves a whole shadow out) are refined by least-trimmed-squares concentration steps
keeping 75 % of the pixels; the least trimmed sum wins and fixes the robust scale (MAD) for
Tukey-biweight IRLS. Residuals are per pixel: the three channels' residuals in units of
their mean value, each divided by the scale, combined as an RMS. A cast shadow or highlight
covering up to a quarter of the object cannot drag the fit; outliers get weight 0 and are
reported as rejected. Clipped pixels (saturated, or black) are removed before the fit.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import sh_basis
from ..sh.zonal import clamped_cosine_factors
from .result import POOR_CONDITION, LightingFit
from .robust import (  # noqa: F401  (the constants stay importable from here)
    CANDIDATE_ITER,
    CANDIDATE_SAMPLES,
    LMEDS_TRIALS,
    LTS_H,
    TILE_TRIALS,
    TOP_STARTS,
    TUKEY_C,
    _lmeds_start,
    _scale,
    _solve,
    _standardised,
    _starts,
    _weights,
)
from .settings import IRLS_SAMPLES, MAX_RADIUS, FitSettings

__all__ = ["IRLS_SAMPLES", "MAX_RADIUS", "POOR_CONDITION", "FitSettings", "LightingFit",
           "design_factors", "fit_samples"]

_CHUNK = 1 << 19
#: Albedos a fit accepts: the lighting is the pixels over the albedo, and outside this range
#: the quotient of ordinary pixel values leaves the floating-point range.
ALBEDO_RANGE = (1e-30, 1e30)


def design_factors(model: str) -> NDArray[np.float64]:
    """Factor per coefficient that turns y_lm into a design-matrix column: ``"diffuse"``
    Â_l/π (radiance of a white Lambertian surface, R&H eq. 7), ``"mirror"`` 1 (radiance
    seen directly, a chrome ball).

    Parameters
    ----------
    model
        "diffuse" or "mirror".

    Returns
    -------
    ndarray of shape (9,)
        The factor of each coefficient's column.
    """
    if model == "diffuse":
        return np.repeat(clamped_cosine_factors(2), [1, 3, 5]) / np.pi
    if model == "mirror":
        return np.ones(9)
    raise ShprobeError(f"model must be 'diffuse' or 'mirror', got {model!r}")


def check_level(value: float | None, name: str) -> None:
    """A clipping level (``saturation``, ``black level``) is None or a finite number: NaN
    would compare false with every pixel and silently clip nothing."""
    if value is not None and not np.isfinite(value):
        raise ShprobeError(f"{name} must be a finite number, got {value}")


def _design(dirs: NDArray, factors: NDArray) -> NDArray[np.float64]:
    return sh_basis(np.ascontiguousarray(dirs, dtype=np.float64), 2) * factors


def fit_samples(dirs: ArrayLike, values: ArrayLike, settings: FitSettings | None = None, *,
                weights: ArrayLike | None = None, albedo: ArrayLike | float = 1.0,
                **changes: Any) -> LightingFit:
    """Fit nine RGB lighting coefficients to pixel values.

    Parameters
    ----------
    dirs
        (P, 3) unit surface normals (diffuse) or reflected directions (mirror).
    values
        (P, 3) linear pixel values.
    settings
        The fit's [`FitSettings`][shprobe.fitting.FitSettings] (default: its defaults).
    weights
        (P,) prior weights (a chrome ball's solid angle per pixel; default 1).
    albedo
        A number (the coefficients are divided by it), or known per-pixel albedo (P,) /
        (P, 3).
    **changes
        Fields of [`FitSettings`][shprobe.fitting.FitSettings] changed from ``settings``
        (``robust=False``).

    Returns
    -------
    LightingFit
        Coefficients, standard errors, weights, rejected pixels, fitted values.

    Notes
    -----
    ``dirs`` (P, 3): unit surface normals (``model="diffuse"``: value = ρ E(n)/π) or
    reflected directions (``model="mirror"``: value = ρ L(ω)). ``values`` (P, 3) linear.
    ``weights`` (P,): prior weights (a chrome ball's solid angle per pixel; default 1).
    ``albedo``: a number (the coefficients are divided by it), or known per-pixel albedo
    (P,) / (P, 3) (values are divided by it, weights multiplied by its square, per channel).
    ``saturation``: pixels with any channel ≥ it are clipped and left out; ``black``: so are
    pixels with any channel ≤ it (black-clipped; the photo fits pass 0). ``robust``: the
    MM-estimator of the module docstring — else plain weighted least squares. The residual
    scale never falls below ``scale_floor`` × the mean |value|, so model error at that level
    (the l ≥ 4 part of real irradiance) is not rejected. The starts run on at most
    ``CANDIDATE_SAMPLES`` pixels and IRLS on at most ``irls_samples`` (fixed random subsets;
    the coefficients and standard errors are that subset's); the weights, rejected pixels,
    fitted values and residuals are over every pixel.
    """
    s = settings if settings is not None else FitSettings()
    if changes:
        s = replace(s, **changes)
    model, saturation, black, robust = s.model, s.saturation, s.black, s.robust
    scale_floor, max_iter, irls_samples, seed = s.scale_floor, s.max_iter, s.irls_samples, s.seed
    factors = design_factors(model)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    y = np.asarray(values, dtype=np.float64)
    if y.ndim == 1:
        y = y[:, None]
    P = d.shape[0]
    if y.shape[0] != P:
        raise ShprobeError(f"{P} directions but {y.shape[0]} values")
    if P == 0:
        raise ShprobeError("no pixels to fit")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(d))):
        raise ShprobeError("pixel values or normals contain NaN or infinity")
    prior = np.ones(P) if weights is None else np.asarray(weights, np.float64).reshape(P)
    scalar_albedo = 1.0
    a = np.asarray(albedo, dtype=np.float64)
    if a.ndim == 0:
        scalar_albedo = float(a)
        if not (np.isfinite(scalar_albedo) and ALBEDO_RANGE[0] <= scalar_albedo
                <= ALBEDO_RANGE[1]):
            raise ShprobeError(f"albedo must be a positive number in [{ALBEDO_RANGE[0]:g}, "
                               f"{ALBEDO_RANGE[1]:g}] (the lighting is the pixels divided by "
                               f"it), got {albedo}")
        ys, wch = y, None
    else:
        a = a.reshape(P, -1)
        if not np.all((a >= ALBEDO_RANGE[0]) & (a <= ALBEDO_RANGE[1])):
            raise ShprobeError(f"per-pixel albedo must be in [{ALBEDO_RANGE[0]:g}, "
                               f"{ALBEDO_RANGE[1]:g}] (positive and finite)")
        ys = y / a
        wch = np.broadcast_to(a * a, y.shape)
    check_level(saturation, "saturation")
    check_level(black, "black level")
    clipped = np.zeros(P, bool)
    for c in range(y.shape[1]):  # per channel (a reduction over a length-3 axis is slow)
        if saturation is not None:
            clipped |= y[:, c] >= saturation
        if black is not None:
            clipped |= y[:, c] <= black
    base = np.where(clipped, 0.0, prior)
    n_used = int(np.count_nonzero(base > 0))
    if n_used < 9:
        raise ShprobeError(f"only {n_used} usable pixels ({int(clipped.sum())} of {P} clipped)"
                           ": nothing to fit")
    floor = np.full(y.shape[1], float(scale_floor))

    C = y.shape[1]

    def solve_a(A, sub, w):
        """Weighted least squares on the rows ``sub`` with their design ``A``."""
        if wch is None:
            aw = A * w[:, None]
            return _solve(aw.T @ A, aw.T @ ys[sub])
        X = np.empty((9, C))
        for c in range(C):
            aw = A * (w * wch[sub, c])[:, None]
            X[:, c:c + 1] = _solve(aw.T @ A, aw.T @ ys[sub, c:c + 1])
        return X

    def u_of(A, sub, X):
        return _standardised((ys[sub] - A @ X) / tau, 1.0)

    def full_pass(X, scale):
        """One pass over every pixel (chunked): weights (Tukey at ``scale``, or the prior
        weights when None) and the normal equations; the solution and G."""
        w = base.copy()
        G = np.zeros((9, 9)) if wch is None else np.zeros((C, 9, 9))
        R = np.zeros((9, C))
        for s0 in range(0, P, _CHUNK):
            sl = slice(s0, s0 + _CHUNK)
            A = _design(d[sl], factors)
            if scale is not None:
                w[sl] *= _weights(_standardised((ys[sl] - A @ X) / tau, scale))
            if wch is None:
                aw = A * w[sl, None]
                G += aw.T @ A
                R += aw.T @ ys[sl]
            else:
                for c in range(C):
                    aw = A * (w[sl] * wch[sl, c])[:, None]
                    G[c] += aw.T @ A
                    R[:, c] += aw.T @ ys[sl, c]
        if wch is None:
            return _solve(G, R), G, w
        X = np.stack([_solve(G[c], R[:, c:c + 1])[:, 0] for c in range(C)], axis=1)
        return X, G[0], w

    # the robust stages on subsets whose design matrices are built once
    idx = np.flatnonzero(base > 0)
    rng = np.random.default_rng(seed)
    if idx.size > irls_samples:
        idx = np.sort(rng.choice(idx, irls_samples, replace=False))
    tau = np.maximum(np.mean(np.abs(ys[idx]), axis=0), 1e-30)  # the residuals' unit
    it = 0
    s = None
    if robust:
        A_idx = _design(d[idx], factors)

        def csteps(A, sub, X, iters):
            """Concentration steps of least trimmed squares (Rousseeuw & Van Driessen
            2006): refit on the fraction LTS_H of pixels with the smallest residuals; the
            trimmed sum of squares never increases."""
            h = max(int(LTS_H * sub.size), 9)
            obj = np.inf
            for _ in range(iters):
                u = u_of(A, sub, X)
                keep = np.argpartition(u, h - 1)[:h]
                new_obj = float(np.sum(u[keep] ** 2))
                if new_obj >= obj * (1 - 1e-9):
                    break
                obj = new_obj
                w = np.zeros(sub.size)
                w[keep] = base[sub][keep]
                X = solve_a(A, sub, w)
            return X, obj

        def irls(A, sub, X, scale, iters):
            """Tukey IRLS with the scale held fixed (an MM-estimator's last stage)."""
            k = 0
            for k in range(1, iters + 1):  # noqa: B007 (k is returned)
                w_new = base[sub] * _weights(_standardised((ys[sub] - A @ X) / tau, scale))
                if not np.count_nonzero(w_new) >= 9:
                    break
                X_new = solve_a(A, sub, w_new)
                step = np.abs(X_new - X).max()
                X = X_new
                if step <= 1e-6 * max(np.abs(X).max(), 1e-300):
                    break
            return X, k

        # starts (least squares, least median of squares, tile subsets) refined by LTS
        # concentration steps on a small subset; the least trimmed sum of squares wins, so
        # a shadow the nine parameters half-absorb from one start is left out by another
        pos = np.arange(idx.size) if idx.size <= CANDIDATE_SAMPLES else np.sort(
            rng.choice(idx.size, CANDIDATE_SAMPLES, replace=False))
        small, A_small = idx[pos], A_idx[pos]
        starts = _starts(A_small, d[small], ys[small], base[small], tau, floor, seed)
        best, X = np.inf, None
        for start in starts:
            Xc, obj = csteps(A_small, small, start, CANDIDATE_ITER)
            if obj < best:
                best, X = obj, Xc
        X, _ = csteps(A_idx, idx, X, CANDIDATE_ITER)
        # robust scale from the LTS fit (MAD over the usable pixels), then fixed
        s = _scale((ys[idx] - A_idx @ X) / tau, base[idx], floor)
        X, it = irls(A_idx, idx, X, s, max_iter)
    if robust and idx.size < n_used:
        # subsampled: IRLS has converged on idx (X is its solution); one pass over every
        # pixel gives the weights and the fitted values
        w = base.copy()
    else:
        X, G, w = full_pass(X if robust else None, s)
    fitted = np.empty((P, C), np.float32)
    res = np.empty((P, C), np.float32)
    sq = np.zeros(C)
    wsq = np.zeros(C)
    abs_in = 0.0
    n_in = 0
    for s0 in range(0, P, _CHUNK):  # weights, fitted values and residual statistics, chunked
        sl = slice(s0, s0 + _CHUNK)
        f = _design(d[sl], factors) @ X
        if robust and idx.size < n_used:
            w[sl] *= _weights(_standardised((ys[sl] - f) / tau, s))
        if wch is not None:
            f *= a[sl]
        r = y[sl] - f
        fitted[sl] = f
        res[sl] = r
        m = w[sl] >= 0.5 * prior[sl]
        m &= w[sl] > 0
        r2 = r[m] ** 2
        sq += r2.sum(axis=0)
        wsq += (w[sl][m, None] * r2).sum(axis=0)
        abs_in += float(np.abs(y[sl][m]).sum())
        n_in += int(m.sum())
    if robust and idx.size < n_used:
        wi = w[idx]
        aw = A_idx * wi[:, None] if wch is None else A_idx * (wi * wch[idx, 0])[:, None]
        G = aw.T @ A_idx  # the subset's: X came from it, so do the standard errors
    w_rel = np.where(prior > 0, w / np.where(prior > 0, prior, 1.0), 0.0)  # IRLS factor
    inl = w_rel >= 0.5
    n_in = max(n_in, 1)
    rms = float(np.sqrt(sq.sum() / (n_in * C))) if inl.any() else float("nan")
    sig = np.sqrt(wsq / max(n_in - 9, 1)) if wch is None else np.sqrt(sq / n_in)
    dg = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gn = G / np.outer(dg, dg)
    Gi = np.linalg.inv(Gn)
    cond_k = np.sqrt(np.maximum(np.diag(Gi), 0.0))
    stderr = np.sqrt(np.maximum(np.diag(Gi), 0.0))[:, None] / dg[:, None] * sig[None, :]
    mean_abs = abs_in / (n_in * C)
    info = {"rms_relative": rms / mean_abs if mean_abs > 0 else 0.0, "used": n_in,
            "scale": None if s is None else s.tolist()}
    return LightingFit(
        coeffs=X / scalar_albedo, albedo=scalar_albedo, stderr=stderr / scalar_albedo,
        conditioning=cond_k, condition=float(np.linalg.cond(Gn)),
        weights=w_rel.astype(np.float32), fitted=fitted, residual=res, clipped=clipped,
        rms=rms, iterations=it,
        model=model, info=info)
