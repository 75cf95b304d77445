"""The robust stages of the fit (an MM-estimator): the starts (least squares, least median of
squares, tile subsets), the normalised solve, the robust scale and Tukey's weights."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

__all__ = ["CANDIDATE_ITER", "CANDIDATE_SAMPLES", "LMEDS_TRIALS", "LTS_H", "TILE_TRIALS",
           "TOP_STARTS", "TUKEY_C"]

#: Tukey's biweight constant (95 % efficiency at the normal distribution).
TUKEY_C = 4.685
#: Random subsets tried for the least-median-of-squares start of IRLS.
LMEDS_TRIALS = 300
#: Pixels and iterations for the competing IRLS starts (see :func:`fit_samples`).
CANDIDATE_SAMPLES = 8192
CANDIDATE_ITER = 10
TILE_TRIALS = 100
TOP_STARTS = 5
#: Fraction of the pixels least trimmed squares keeps (breakdown 1 − LTS_H).
LTS_H = 0.75

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


def _weights(u: NDArray, loss: str = "tukey") -> NDArray[np.float64]:
    t = np.clip(u / TUKEY_C, 0.0, 1.0)
    return (1.0 - t * t) ** 2


def _starts(a: NDArray, d: NDArray, y: NDArray, w: NDArray, tau: NDArray, floor: NDArray,
            seed: int) -> list[NDArray[np.float64]]:
    """Starting fits for IRLS and the criterion that ranks fits (the median standardised
    residual, least median of squares). Candidates: least squares on all pixels; least
    median of squares over random 10-pixel subsets; and least squares on random 60 % subsets
    of 4×4 tiles of the normals (the tangent-plane coordinates around their mean; for a ball,
    tiles of the image), so that some start leaves out a whole shadow. Returns the best
    `TOP_STARTS` candidates by that criterion. ``a``: the design matrix of the rows."""
    use = w > 0
    sw = np.sqrt(w)[:, None]

    def crit(x):
        r = (y - a @ x) / tau / floor
        return float(np.median(_standardised(r, 1.0)[use]))

    def ls(sel):
        aw = a[sel] * sw[sel]
        return _solve(aw.T @ aw, aw.T @ (y[sel] * sw[sel]))

    cands = [ls(use), _lmeds_start(a, y, w, seed)]
    m = d[use].mean(axis=0)
    m = m / (np.linalg.norm(m) or 1.0)
    u = np.cross(m, [0.0, 0.0, 1.0] if abs(m[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(m, u)
    pu, pv = d @ u, d @ v
    qu = np.quantile(pu[use], [0.25, 0.5, 0.75])
    qv = np.quantile(pv[use], [0.25, 0.5, 0.75])
    tiles = np.searchsorted(qu, pu) * 4 + np.searchsorted(qv, pv)
    rng = np.random.default_rng(seed + 3)
    for _ in range(TILE_TRIALS):
        keep = rng.choice(16, 6, replace=False)
        sel = use & np.isin(tiles, keep)
        if np.count_nonzero(sel) >= 18:
            cands.append(ls(sel))
    cands.sort(key=crit)
    return cands[:TOP_STARTS]


def _lmeds_start(a: NDArray, y: NDArray, w: NDArray, seed: int, trials: int = LMEDS_TRIALS,
                 size: int = 10) -> NDArray[np.float64]:
    """A start for IRLS that outliers cannot drag: least median of squares over random
    ``size``-pixel subsets (Rousseeuw 1984), scored on ≤ 1024 pixels. With 30 % outliers a
    clean 10-pixel subset turns up in 300 trials with probability 0.9998."""
    rng = np.random.default_rng(seed + 1)
    good = np.flatnonzero(w > 0)
    ev = good if good.size <= 1024 else rng.choice(good, 1024, replace=False)
    a_ev = a[ev]
    y_ev = y[ev]
    tau = np.maximum(np.mean(np.abs(y_ev), axis=0), 1e-30)
    a_all = a[good]
    picks = np.argsort(rng.random((trials, good.size)), axis=1)[:, :size] \
        if good.size <= 4 * size else rng.integers(0, good.size, (trials, size))
    A = a_all[picks]  # (T, size, 9)
    G = A.transpose(0, 2, 1) @ A + 1e-9 * np.eye(9)
    R = A.transpose(0, 2, 1) @ y[good][picks]
    try:
        X = np.linalg.solve(G, R)  # (T, 9, C)
    except np.linalg.LinAlgError:
        X = np.stack([np.linalg.lstsq(g, r, rcond=None)[0] for g, r in zip(G, R, strict=True)])
    T, _, C = X.shape
    F = (a_ev @ X.transpose(1, 0, 2).reshape(9, T * C)).reshape(-1, T, C)  # BLAS
    med = np.median(np.sum(((y_ev[:, None, :] - F) / tau) ** 2, axis=2), axis=0)
    return X[int(np.argmin(med))]
