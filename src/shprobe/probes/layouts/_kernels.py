"""numba kernel of `shprobe.probes.layouts`: the disc layouts' pixel tables (imported lazily).

The solid angles and directions of an n × n disc image, computed on one quadrant (rows and
columns ``< (n+1)//2``: a ≤ 0, b ≥ 0) and mirrored (the tables are symmetric in a and in b).
The radial maps and the quadrature are those described in ``layouts._disc_tables``; ``kind``
0 is the angular map, 1 the mirror ball.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _theta(kind, r):
    return math.pi * r if kind == 0 else 2.0 * math.asin(min(r, 1.0))


@numba.njit(cache=True, inline="always")
def _jac(kind, r):
    """dω / (da db) at radius r; 0 outside the disc."""
    if r >= 1.0:
        return 0.0
    if kind == 1:
        return 4.0
    if r == 0.0:
        return math.pi * math.pi
    return math.pi * math.sin(math.pi * r) / r


@numba.njit(cache=True, inline="always")
def _dir(kind, a, b, out):
    r = math.hypot(a, b)
    th = _theta(kind, min(r, 1.0))
    s = math.sin(th)
    if r > 0.0:
        out[0] = s * a / r
        out[1] = s * b / r
    else:
        out[0] = 0.0
        out[1] = 0.0
    out[2] = math.cos(th)


@numba.njit(cache=True)
def _rim(kind, a0, a1, b0, b1, t, wt, with_dirs, vec):
    """∫∫ over [a0, a1] × [b0, b1] ∩ disc of jac (returned) and of jac·ω (into ``vec``).

    The outer x range is split where the clipped inner limits change; the substitution
    x = end ∓ len·t² takes the √(1 − x²) branch point at x = ±1 out of the integrand.
    """
    lo_x = max(a0, -1.0)
    hi_x = min(a1, 1.0)
    brk = np.empty(6)
    brk[0] = a0
    brk[1] = a1
    s0 = math.sqrt(max(1.0 - b0 * b0, 0.0))
    s1 = math.sqrt(max(1.0 - b1 * b1, 0.0))
    brk[2], brk[3], brk[4], brk[5] = s0, -s0, s1, -s1
    for k in range(6):
        brk[k] = min(max(brk[k], lo_x), hi_x)
    brk.sort()
    omega = 0.0
    vec[:] = 0.0
    d = np.empty(3)
    nq = t.size
    for k in range(5):
        lo, hi = brk[k], brk[k + 1]
        ln = hi - lo
        if ln <= 0.0:
            continue
        for i in range(nq):
            x = hi - ln * t[i] * t[i] if hi >= 1.0 else lo + ln * t[i] * t[i]
            wx = 2.0 * ln * t[i] * wt[i]
            s = math.sqrt(max(1.0 - x * x, 0.0))
            ylo = max(b0, -s)
            ly = min(b1, s) - ylo
            if ly <= 0.0:
                continue
            for m in range(nq):
                y = ylo + ly * t[m]
                jw = _jac(kind, min(math.hypot(x, y), 1.0)) * wx * ly * wt[m]
                omega += jw
                if with_dirs:
                    _dir(kind, x, y, d)
                    vec[0] += jw * d[0]
                    vec[1] += jw * d[1]
                    vec[2] += jw * d[2]
    return omega


@numba.njit(cache=True, parallel=True)
def disc_tables(kind, n, omega_exact, tq, wq, t16, w16, t6, w6):
    """(solid angles (n, n), directions (n, n, 3)) of a disc layout.

    Interior pixels: tensor Gauss (``tq``, ``wq`` on [0, 1]) of the Jacobian, unless
    ``omega_exact`` (n × n) is given; rim pixels: `_rim` with 16 nodes; rim pixels whose
    centre is outside the disc look along their mean direction (6 nodes). Pixels outside the
    disc: 0 and (0, 0, 0).
    """
    half = (n + 1) // 2
    h = 2.0 / n
    exact = omega_exact.shape[0] == n
    omega = np.zeros((n, n))
    dirs = np.zeros((n, n, 3))
    for j in numba.prange(half):
        vec = np.empty(3)
        d = np.zeros(3)
        b1 = 1.0 - j * h
        b0 = b1 - h
        for i in range(half):
            a0 = -1.0 + i * h
            a1 = a0 + h
            # nearest and farthest point of the pixel square from the centre
            na = 0.0 if a0 * a1 < 0.0 else min(abs(a0), abs(a1))
            nb = 0.0 if b0 * b1 < 0.0 else min(abs(b0), abs(b1))
            fa = max(abs(a0), abs(a1))
            fb = max(abs(b0), abs(b1))
            if math.hypot(na, nb) >= 1.0:
                continue  # outside the disc
            inside = math.hypot(fa, fb) <= 1.0
            ac = 0.5 * (a0 + a1)
            bc = 0.5 * (b0 + b1)
            if exact:
                om = omega_exact[j, i]
            elif inside:
                om = 0.0
                for p in range(tq.size):
                    y = b1 - h * tq[p]
                    for q in range(tq.size):
                        om += _jac(kind, math.hypot(a0 + h * tq[q], y)) * wq[p] * wq[q]
                om *= h * h
            else:
                om = _rim(kind, a0, a1, b0, b1, t16, w16, False, vec)
            if om <= 0.0:
                continue
            if not inside and math.hypot(ac, bc) >= 1.0:
                _rim(kind, a0, a1, b0, b1, t6, w6, True, vec)
                vn = math.sqrt(vec[0] ** 2 + vec[1] ** 2 + vec[2] ** 2)
                for c in range(3):
                    d[c] = vec[c] / vn if vn > 0.0 else 0.0
            else:
                _dir(kind, ac, bc, d)
            # the four mirror images: a → −a flips x, b → −b flips y
            _put(omega, dirs, j, i, om, d, 1.0, 1.0)
            _put(omega, dirs, j, n - 1 - i, om, d, -1.0, 1.0)
            _put(omega, dirs, n - 1 - j, i, om, d, 1.0, -1.0)
            _put(omega, dirs, n - 1 - j, n - 1 - i, om, d, -1.0, -1.0)
    return omega, dirs


@numba.njit(cache=True, inline="always")
def _put(omega, dirs, j, i, om, d, sx, sy):
    omega[j, i] = om
    dirs[j, i, 0] = sx * d[0]
    dirs[j, i, 1] = sy * d[1]
    dirs[j, i, 2] = d[2]
