"""The maximum of a function on the unit sphere, by refinement from a grid.

A sampled maximum depends on the grid: the worst normal of a 2048-point grid is not the worst
normal. `refine_max` starts from the best grid points (spread apart, one per bump) and runs
a batched compass search in each start's tangent plane — 8 moves of angle h plus the best point
of a quadratic fitted to those 9 values, move while one improves, then halve h — recording the
global maximum after every level of h. It stops when a level changes the maximum by less than
``tol`` and no start's fitted quadratic promises more than ``tol`` within 2h (at least
``min_levels`` levels, at most ``max_levels``): the stated tolerance of the reported maximum.

Every evaluation is exact (the caller's function: brute-force E, or the SH sum); nothing is
interpolated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["SphereMax", "pick_starts", "refine_max", "tangent_patch"]

_ANGLES = np.arange(8) * (np.pi / 4)
_COS, _SIN = np.cos(_ANGLES), np.sin(_ANGLES)


@dataclass(frozen=True)
class SphereMax:
    """``value`` = f(``direction``), the converged maximum; ``change``: how much the last level
    of refinement moved it (< ``tolerance`` when ``converged``); ``grid_value``: the maximum
    over the starting points; ``evaluations``: points evaluated during refinement."""

    value: float
    direction: NDArray[np.float64]
    tolerance: float
    change: float
    converged: bool
    grid_value: float
    evaluations: int
    levels: int

    def __repr__(self) -> str:
        d = ", ".join(f"{x:+.4f}" for x in self.direction)
        return (f"SphereMax(value={self.value:.6g} at ({d}), grid {self.grid_value:.6g}, "
                f"change {self.change:.2g} < tol {self.tolerance:.2g}: {self.converged})")


def pick_starts(points: NDArray[np.float64], values: NDArray[np.float64], k: int,
                min_angle: float) -> NDArray[np.int64]:
    """Indices of up to ``k`` best points (largest ``values``), each at least ``min_angle``
    radians from the ones picked before (one start per bump, greedy)."""
    order = np.argsort(-values, kind="stable")
    cmin = np.cos(min_angle)
    picked: list[int] = []
    for i in order[: max(64 * k, 256)]:
        if all(points[i] @ points[j] < cmin for j in picked):
            picked.append(int(i))
            if len(picked) == k:
                break
    return np.asarray(picked, dtype=np.int64)


def _cross(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a × b for (N, 3) rows (np.cross's arithmetic without its axis handling: it is hot)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def _tangent_frames(p: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    a = np.where(np.abs(p[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = _cross(p, a)
    u /= np.sqrt((u * u).sum(axis=1, keepdims=True))
    return u, _cross(p, u)


def tangent_patch(centre: NDArray[np.float64], half: float, n: int) -> NDArray[np.float64]:
    """n×n unit vectors within ±``half`` rad of ``centre`` ((n², 3); a square grid in the
    tangent plane, projected back to the sphere): the dense checks of a refined extremum."""
    c = np.asarray(centre, dtype=np.float64).reshape(1, 3)
    c = c / np.linalg.norm(c)  # the frame and the offsets: one unit centre
    u, w = _tangent_frames(c)
    t = np.linspace(-half, half, int(n))
    x, y = np.meshgrid(t, t)
    p = c + x[..., None] * u + y[..., None] * w
    return (p / np.linalg.norm(p, axis=-1, keepdims=True)).reshape(-1, 3)


def _quadratic_design() -> tuple[NDArray, NDArray, NDArray]:
    """Least-squares fit of q(x, y) = c + gx x + gy y + ½(a x² + 2b xy + d y²) to the centre and
    the 8 compass points at unit radius (scaled by h later), and a polar probe of the disc of
    radius 2 where the fitted model's maximum is looked for."""
    xs = np.concatenate([[0.0], _COS])
    ys = np.concatenate([[0.0], _SIN])
    A = np.stack([np.ones(9), xs, ys, 0.5 * xs**2, xs * ys, 0.5 * ys**2], 1)
    r = np.array([0.25, 0.5, 0.75, 1.0, 1.5, 2.0])
    t = np.arange(16) * (np.pi / 8)
    px = np.concatenate([[0.0], (r[:, None] * np.cos(t)).ravel()])
    py = np.concatenate([[0.0], (r[:, None] * np.sin(t)).ravel()])
    P = np.stack([np.ones_like(px), px, py, 0.5 * px**2, px * py, 0.5 * py**2], 1)
    return np.linalg.pinv(A), P, np.stack([px, py], 1)


_FIT, _PROBE, _PROBE_XY = _quadratic_design()


def refine_max(f: Callable[[NDArray[np.float64]], NDArray[np.float64]],
               points: NDArray[np.float64], values: NDArray[np.float64], *, step: float,
               tol: float, starts: int = 4, levels: tuple[int, int] = (2, 40),
               polish: bool = True) -> SphereMax:
    """Maximise ``f`` ((M, 3) unit vectors → (M,)) on the sphere from grid ``points`` (N, 3)
    with known ``values`` (N,): ``starts`` seeds by `pick_starts` (2·``step`` apart),
    compass search from h = ``step`` (about the grid spacing), halving h per level, at least
    ``levels[0]`` and at most ``levels[1]`` levels.

    Each compass move also fits a quadratic to the 9 values around a start and tries the
    model's best point within 2h (a Newton-like jump). A level ends when no start improves by
    more than ``tol``/20 (at most 50 moves); the search stops when that level raised the
    maximum by less than ``tol`` *and* no start's fitted model promises more than ``tol`` above
    the maximum within 2h (so a level that merely failed to move is not taken for convergence).
    From the third level on, starts that cannot catch up with the best are dropped. ``polish``:
    finally sweep 11×11 patches of spacing h, h/3, … (to 1e-5 rad) about the best point
    (narrow tops at kinks).
    ``change`` reports the larger of the two.
    """
    min_levels, max_levels = (int(x) for x in levels)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    vals = np.asarray(values, dtype=np.float64).reshape(-1)
    g = int(np.argmax(vals))
    grid_best = float(vals[g])
    idx = pick_starts(pts, vals, int(starts), 2.0 * step)
    p = pts[idx].copy()
    v = vals[idx].copy()
    n = len(p)
    best = grid_best
    h = float(step)
    evals = 0
    change = np.inf
    level = 0
    rows = np.arange(n)

    def on_sphere(base, u, w, x, y):  # exp map: the point at tangent offset (x, y) from base
        r = np.hypot(x, y)
        q = (np.cos(r)[..., None] * base[:, None]
             + np.sinc(r / np.pi)[..., None]
             * (x[..., None] * u[:, None] + y[..., None] * w[:, None]))
        return q / np.sqrt((q * q).sum(axis=-1, keepdims=True))

    while level < max_levels:
        level += 1
        v_start = v.copy()
        promise = np.full(n, np.inf)
        for _ in range(50):  # moves at this h until no start improves by > tol/20
            u, w = _tangent_frames(p)
            cx = np.broadcast_to(h * _COS, (n, 8))
            cy = np.broadcast_to(h * _SIN, (n, 8))
            cand = on_sphere(p, u, w, cx, cy)
            cv = np.asarray(f(cand.reshape(-1, 3)), dtype=np.float64).reshape(n, 8)
            evals += cv.size
            coef = np.concatenate([v[:, None], cv], 1) @ _FIT.T  # (n, 6) in units of h
            model = coef @ _PROBE.T  # (n, 97): the model on the disc of radius 2h
            k = np.argmax(model, axis=1)
            promise = model[rows, k] - v
            jx, jy = h * _PROBE_XY[k, 0], h * _PROBE_XY[k, 1]
            # the model's stationary point, where it is a maximum within 2h (Newton step)
            a, b, d = coef[:, 3], coef[:, 4], coef[:, 5]
            det = a * d - b * b
            ok = (a < 0) & (det > 0)
            sdet = np.where(ok, det, 1.0)
            sx = (-d * coef[:, 1] + b * coef[:, 2]) / sdet
            sy = (b * coef[:, 1] - a * coef[:, 2]) / sdet
            gn = 0.5 * (coef[:, 1] * sx + coef[:, 2] * sy)
            ok &= (np.hypot(sx, sy) <= 2.0) & (gn > promise)
            promise = np.where(ok, gn, promise)
            jx, jy = np.where(ok, h * sx, jx), np.where(ok, h * sy, jy)
            jump = on_sphere(p, u, w, jx[:, None], jy[:, None])[:, 0]
            jv = np.asarray(f(jump), dtype=np.float64).reshape(n)
            evals += n
            allc = np.concatenate([cand, jump[:, None]], 1)
            allv = np.concatenate([cv, jv[:, None]], 1)
            j = np.argmax(allv, axis=1)
            gain_now = allv[rows, j] - v
            up = gain_now > 0
            p[up] = allc[up, j[up]]
            v[up] = allv[up, j[up]]
            if not (gain_now > 0.05 * tol).any():  # creeping by less than tol/20: next level
                break
        new = max(best, float(v.max()))
        gain = max(0.0, float((v + np.maximum(promise, 0.0)).max()) - new)
        change = max(new - best, gain)
        best = new
        if level >= min_levels and change < 0.5 * tol:  # half: a margin for kinks
            break
        h *= 0.5
        if level >= 2:  # drop starts that cannot catch up: gains shrink ~4x per level
            reach = v + 2.0 * (v - v_start) + np.maximum(promise, 0.0) + tol
            keep = reach >= best
            keep[int(np.argmax(v))] = True
            p, v = p[keep], v[keep]
            n = len(p)
            rows = np.arange(n)
    polish_change = 0.0
    if polish and best > grid_best:
        # kinks (E_ref's gradient jumps where a bright pixel crosses the horizon of n) can stop
        # a compass short of a narrow top: sweep 11×11 patches about the best point, spacing h,
        # h/3, h/9, … down to 1e-5 rad, each centred on the last one's best; at each spacing
        # the sweep is repeated (at most 20 times) until it gains less than tol/2, and that
        # last gain counts towards ``change``
        i = int(np.argmax(v))
        q, qv = p[i : i + 1].copy(), float(v[i])
        hh = h
        while hh > 1e-5:
            t = hh * np.arange(-5, 6)
            x, y = (a.ravel()[None] for a in np.meshgrid(t, t))
            for _ in range(20):
                u, w = _tangent_frames(q)
                cand = on_sphere(q, u, w, x, y)[0]
                cv = np.asarray(f(cand), dtype=np.float64)
                evals += cv.size
                k = int(np.argmax(cv))
                sweep_gain = max(0.0, float(cv[k]) - qv)
                if cv[k] > qv:
                    q, qv = cand[k : k + 1], float(cv[k])
                if sweep_gain <= 0.5 * tol:
                    break
            polish_change = max(polish_change, sweep_gain)
            hh /= 3.0
        change = max(change, polish_change)
        if qv > best:
            p[i], v[i] = q[0], qv
            best = qv
    arg = p[int(np.argmax(v))] if best > grid_best else pts[g]
    return SphereMax(best, arg.copy(), float(tol), float(change), bool(change < 0.5 * tol),
                     grid_best, evals, level)
