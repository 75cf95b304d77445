"""Linear least squares for the nine lighting coefficients, robust (IRLS) and with the
conditioning of the normal equations reported per coefficient.

A diffuse surface of albedo ρ shows radiance ρ E(n)/π with E(n) = Σ_{l≤2} Â_l L_lm y_lm(n)
(R&H 2001 eq. 7): linear in the nine L_lm, so pixels with known normals give a linear
least-squares problem whose 9×9 normal equations are solved once for all three channels (the
design matrix depends only on the normals). Pixels of a chrome ball give radiance samples
L(ω) directly; the same solver fits Σ y_lm(ω) L_lm to them, weighted by each pixel's solid
angle (with full coverage this is the projection of R&H eq. 10).

Robustness: iteratively reweighted least squares with Huber then Tukey biweights of the
per-pixel residual (the three channels' residuals, each divided by a robust scale, combined
as an RMS), so cast shadows, highlights and other outliers get weight 0 and are reported as
rejected. Clipped (saturated) pixels are removed before the fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting.coeffs import RH_LABELS
from ..sh import sh_basis
from ..sh.zonal import clamped_cosine_factors

__all__ = ["LightingFit", "design_factors", "fit_samples"]

#: Per-coefficient condition (see :attr:`LightingFit.conditioning`) above which a coefficient
#: is reported as poorly determined.
POOR_CONDITION = 10.0
#: Tukey's biweight constant (95 % efficiency at the normal distribution) and Huber's.
TUKEY_C = 4.685
HUBER_C = 1.345
#: Pixels used for the IRLS iterations; the final weighted solve uses every pixel.
IRLS_SAMPLES = 1 << 17
_CHUNK = 1 << 19


def design_factors(model: str) -> NDArray[np.float64]:
    """Factor per coefficient that turns y_lm into a design-matrix column: ``"diffuse"``
    Â_l/π (radiance of a white Lambertian surface, R&H eq. 7), ``"mirror"`` 1 (radiance
    seen directly, a chrome ball)."""
    if model == "diffuse":
        return np.repeat(clamped_cosine_factors(2), [1, 3, 5]) / np.pi
    if model == "mirror":
        return np.ones(9)
    raise ShprobeError(f"model must be 'diffuse' or 'mirror', got {model!r}")


@dataclass(repr=False)
class LightingFit:
    """Nine RGB lighting coefficients fitted to pixels, with their quality.

    ``coeffs`` (9, 3): L_lm (radiance) divided by ``albedo`` — with ``albedo`` 1 they are
    albedo × exposure × L_lm, the one scale a photograph cannot separate. ``stderr`` (9, 3):
    standard errors from the inliers' residual (σ √(G⁻¹)_kk). ``conditioning`` (9,): per
    coefficient √((Ĝ⁻¹)_kk) of the normal matrix with unit diagonal Ĝ = D G D — 1 when the
    coefficient's basis image is orthogonal to the others over the pixels used, large when
    the pixels cannot tell it from a combination of the others (a visible hemisphere).
    ``condition``: the 2-norm condition number of Ĝ. ``weights`` (P,): final IRLS weights
    (0 = rejected), ``fitted`` and ``residual`` (P, 3) in the pixels' units.
    """

    coeffs: NDArray[np.float64]
    albedo: float
    stderr: NDArray[np.float64]
    conditioning: NDArray[np.float64]
    condition: float
    weights: NDArray[np.float32]
    fitted: NDArray[np.float32]
    residual: NDArray[np.float32]
    clipped: NDArray[np.bool_]
    rms: float
    iterations: int
    model: str = "diffuse"
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def rejected(self) -> NDArray[np.bool_]:
        """(P,) pixels left out of the fit: clipped, or given weight < 0.5 by the M-estimator
        (Tukey weights fall to 0 beyond 4.685 robust standard deviations)."""
        return self.clipped | (self.weights < 0.5)

    @property
    def rejected_fraction(self) -> float:
        return float(self.rejected.mean()) if self.rejected.size else 0.0

    @property
    def poorly_determined(self) -> tuple[str, ...]:
        """Labels (L00 … L22) of the coefficients whose conditioning exceeds
        :data:`POOR_CONDITION`."""
        return tuple(RH_LABELS[k] for k in np.flatnonzero(self.conditioning > POOR_CONDITION))

    def summary(self) -> str:
        """One line: RMS residual, fraction rejected, poorly determined coefficients."""
        poor = ", ".join(self.poorly_determined) or "none"
        return (f"{self.weights.size} pixels, RMS residual {self.rms:.4g} "
                f"({100 * self.info.get('rms_relative', 0.0):.2f} % of the mean), "
                f"{100 * self.rejected_fraction:.2f} % rejected "
                f"({int(self.clipped.sum())} clipped), condition {self.condition:.3g}, "
                f"poorly determined: {poor}")

    def __repr__(self) -> str:
        return (f"LightingFit(model={self.model!r}, pixels={self.weights.size}, "
                f"rms={self.rms:.4g}, rejected={100 * self.rejected_fraction:.2f}%, "
                f"condition={self.condition:.3g})")


def _design(dirs: NDArray, factors: NDArray) -> NDArray[np.float64]:
    return sh_basis(np.ascontiguousarray(dirs, dtype=np.float64), 2) * factors


def _normal_equations(dirs: NDArray, y: NDArray, w: NDArray, factors: NDArray
                      ) -> tuple[NDArray, NDArray]:
    """G = Σ w a aᵀ (9, 9) and R = Σ w a yᵀ (9, C), built chunk by chunk."""
    G = np.zeros((9, 9))
    R = np.zeros((9, y.shape[1]))
    for s in range(0, dirs.shape[0], _CHUNK):
        a = _design(dirs[s:s + _CHUNK], factors)
        aw = a * w[s:s + _CHUNK, None]
        G += aw.T @ a
        R += aw.T @ y[s:s + _CHUNK]
    return G, R


def _predict(dirs: NDArray, X: NDArray, factors: NDArray) -> NDArray[np.float64]:
    out = np.empty((dirs.shape[0], X.shape[1]))
    for s in range(0, dirs.shape[0], _CHUNK):
        out[s:s + _CHUNK] = _design(dirs[s:s + _CHUNK], factors) @ X
    return out


def _solve(G: NDArray, R: NDArray) -> NDArray[np.float64]:
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gn = G / np.outer(d, d)
    try:
        return np.linalg.solve(Gn, R / d[:, None]) / d[:, None]
    except np.linalg.LinAlgError:
        raise ShprobeError("the pixels do not determine the lighting (singular normal "
                           "equations: too few pixels or normals)") from None


def _scale(r: NDArray, w: NDArray, floor: NDArray) -> NDArray[np.float64]:
    """Robust residual scale per channel: 1.4826 × median |r| over the pixels in use."""
    use = w > 0
    if not use.any():
        return floor
    return np.maximum(1.4826 * np.median(np.abs(r[use]), axis=0), floor)


def _standardised(r: NDArray, s: NDArray) -> NDArray[np.float64]:
    return np.sqrt(np.mean((r / s) ** 2, axis=1))


def _weights(u: NDArray, loss: str) -> NDArray[np.float64]:
    if loss == "huber":
        return np.minimum(1.0, HUBER_C / np.maximum(u, 1e-300))
    t = np.clip(u / TUKEY_C, 0.0, 1.0)
    return (1.0 - t * t) ** 2


def fit_samples(dirs: ArrayLike, values: ArrayLike, *, model: str = "diffuse",
                weights: ArrayLike | None = None, albedo: ArrayLike | float = 1.0,
                saturation: float | None = None, robust: bool = True,
                scale_floor: float = 0.01, max_iter: int = 30,
                irls_samples: int = IRLS_SAMPLES, seed: int = 0) -> LightingFit:
    """Fit nine RGB lighting coefficients to pixel values.

    ``dirs`` (P, 3): unit surface normals (``model="diffuse"``: value = ρ E(n)/π) or
    reflected directions (``model="mirror"``: value = ρ L(ω)). ``values`` (P, 3) linear.
    ``weights`` (P,): prior weights (a chrome ball's solid angle per pixel; default 1).
    ``albedo``: a number (the coefficients are divided by it), or known per-pixel albedo
    (P,) / (P, 3) (values are divided by it, weights multiplied by its square, per channel).
    ``saturation``: pixels with any channel ≥ it are clipped and left out. ``robust``: IRLS
    (Huber, then Tukey) — else plain weighted least squares. The residual scale never falls
    below ``scale_floor`` × the mean |value|, so model error at that level is not rejected.
    IRLS runs on at most ``irls_samples`` pixels (a fixed random subset); the final solve and
    the weights are over every pixel.
    """
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
        if not (np.isfinite(scalar_albedo) and scalar_albedo > 0):
            raise ShprobeError(f"albedo must be a positive number, got {albedo}")
        ys, wch = y, None
    else:
        a = a.reshape(P, -1)
        if np.any(a <= 0) or not np.all(np.isfinite(a)):
            raise ShprobeError("per-pixel albedo must be positive and finite")
        ys = y / a
        wch = np.broadcast_to(a * a, y.shape)
    clipped = np.zeros(P, bool)
    if saturation is not None:
        clipped = np.any(y >= saturation, axis=1)
    base = np.where(clipped, 0.0, prior)
    n_used = int(np.count_nonzero(base > 0))
    if n_used < 9:
        raise ShprobeError(f"only {n_used} usable pixels ({int(clipped.sum())} of {P} clipped)"
                           ": nothing to fit")
    floor = np.maximum(scale_floor * np.mean(np.abs(ys[base > 0]), axis=0), 1e-30)

    def solve(idx, w):
        if wch is None:
            G, R = _normal_equations(d[idx], ys[idx], w, factors)
            return _solve(G, R), G
        X = np.empty((9, y.shape[1]))
        G0 = None
        for c in range(y.shape[1]):
            G, R = _normal_equations(d[idx], ys[idx, c:c + 1], w * wch[idx, c], factors)
            X[:, c:c + 1] = _solve(G, R)
            G0 = G if G0 is None else G0
        return X, G0

    # IRLS on a subset, then weights and the final solve on every pixel
    idx = np.arange(P)
    if robust and P > irls_samples:
        idx = np.sort(np.random.default_rng(seed).choice(P, irls_samples, replace=False))
    w_sub = base[idx]
    X, _ = solve(idx, w_sub)
    it = 0
    if robust:
        for it in range(1, max_iter + 1):
            r = ys[idx] - _predict(d[idx], X, factors)
            s = _scale(r, w_sub, floor)
            loss = "huber" if it <= 3 else "tukey"
            w_new = base[idx] * _weights(_standardised(r, s), loss)
            if not np.count_nonzero(w_new) >= 9:
                break
            X_new, _ = solve(idx, w_new)
            step = np.abs(X_new - X).max()
            X, w_sub = X_new, w_new
            if it > 3 and step <= 1e-7 * max(np.abs(X).max(), 1e-300):
                break
        r = ys - _predict(d, X, factors)
        s = _scale(r[idx], w_sub, floor)
        w = base * _weights(_standardised(r, s), "tukey")
        X, G = solve(idx_all := np.arange(P), w)
        del idx_all
    else:
        w = base
        X, G = solve(np.arange(P), w)
    fitted = _predict(d, X, factors)
    res = ys - fitted
    inl = w >= 0.5
    if wch is not None:
        fitted = fitted * a
        res = y - fitted
    n_in = max(int(inl.sum()), 1)
    rms = float(np.sqrt(np.mean(res[inl] ** 2))) if inl.any() else float("nan")
    sig = np.sqrt(np.sum(w[inl, None] * res[inl] ** 2, axis=0) / max(n_in - 9, 1)) \
        if wch is None else np.sqrt(np.mean(res[inl] ** 2, axis=0))
    dg = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gn = G / np.outer(dg, dg)
    Gi = np.linalg.inv(Gn)
    cond_k = np.sqrt(np.maximum(np.diag(Gi), 0.0))
    stderr = np.sqrt(np.maximum(np.diag(Gi), 0.0))[:, None] / dg[:, None] * sig[None, :]
    mean_abs = float(np.mean(np.abs(y[inl]))) if inl.any() else 0.0
    info = {"rms_relative": rms / mean_abs if mean_abs > 0 else 0.0, "used": n_in,
            "scale": s.tolist() if robust else None}
    return LightingFit(
        coeffs=X / scalar_albedo, albedo=scalar_albedo, stderr=stderr / scalar_albedo,
        conditioning=cond_k, condition=float(np.linalg.cond(Gn)),
        weights=w.astype(np.float32), fitted=fitted.astype(np.float32),
        residual=res.astype(np.float32), clipped=clipped, rms=rms, iterations=it,
        model=model, info=info)
