"""numba kernels of the H-basis (imported lazily: importing this module imports numba).

* ``h_rows`` — H¹..Hⁿ (Habel & Wimmer 2010 eq. 8–13) for rows of unit normals.
* ``t_h_c1``, ``t_h_c3``, ``t_h_any`` — SH (l ≤ 2) → H4/H6 with T_h (H&W §4.1; closed form in
  docs/hbasis.md), touching only its 10 nonzeros, for one channel, RGB and any channel count.
  Each row's 9 inputs are loaded before the first store (the output may not alias the input,
  and loading first lets LLVM keep them in registers), and the result is written straight
  into the caller's array: the kernels are memory-bound, moving exactly the bytes they must.

The constants are module globals, which numba folds in at compile time (``cache=True``).
"""

from __future__ import annotations

import math

import numba

C1 = 1.0 / math.sqrt(2.0 * math.pi)  # H¹
C3 = math.sqrt(3.0 / (2.0 * math.pi))  # H², H³, H⁴
C5 = math.sqrt(15.0 / (2.0 * math.pi))  # H⁵; H⁶ uses C5 / 2
C6 = 0.5 * C5

# T_h's nonzeros (docs/hbasis.md §2): 1/√2, √6/4, √2/4, √30/8, −3√10/16
A = 1.0 / math.sqrt(2.0)
B = math.sqrt(6.0) / 4.0
E = math.sqrt(2.0) / 4.0
F = math.sqrt(30.0) / 8.0
G = -3.0 * math.sqrt(10.0) / 16.0


@numba.njit(cache=True)
def h_rows(d, out):  # pragma: no cover - compiled
    """out[i] = (H¹..Hⁿ)(d[i]) for d (N, 3), out (N, n), n = 4 or 6."""
    six = out.shape[1] == 6
    for i in range(d.shape[0]):
        x = d[i, 0]
        y = d[i, 1]
        z = d[i, 2]
        out[i, 0] = C1
        out[i, 1] = -C3 * y
        out[i, 2] = C3 * (2.0 * z - 1.0)
        out[i, 3] = -C3 * x
        if six:
            out[i, 4] = C5 * x * y
            out[i, 5] = C6 * (x * x - y * y)


@numba.njit(cache=True)
def t_h_c1(s, out):  # pragma: no cover - compiled
    """One channel: s (N, 9) SH coefficients → out (N, n) H coefficients, n = 4 or 6."""
    six = out.shape[1] == 6
    for i in range(s.shape[0]):
        s0 = s[i, 0]
        s1 = s[i, 1]
        s2 = s[i, 2]
        s3 = s[i, 3]
        s4 = s[i, 4]
        s5 = s[i, 5]
        s6 = s[i, 6]
        s7 = s[i, 7]
        s8 = s[i, 8]
        out[i, 0] = A * s0 + B * s2
        out[i, 1] = G * s5 - A * s1
        out[i, 2] = E * s2 + F * s6
        out[i, 3] = G * s7 - A * s3
        if six:
            out[i, 4] = A * s4
            out[i, 5] = A * s8


@numba.njit(cache=True)
def t_h_c3(s, out):  # pragma: no cover - compiled
    """RGB: s (N, 27) = (N, 9, 3) flattened → out (N, 3n) = (N, n, 3) flattened."""
    six = out.shape[1] == 18
    for i in range(s.shape[0]):
        for c in range(3):
            s0 = s[i, c]
            s1 = s[i, 3 + c]
            s2 = s[i, 6 + c]
            s3 = s[i, 9 + c]
            s4 = s[i, 12 + c]
            s5 = s[i, 15 + c]
            s6 = s[i, 18 + c]
            s7 = s[i, 21 + c]
            s8 = s[i, 24 + c]
            out[i, c] = A * s0 + B * s2
            out[i, 3 + c] = G * s5 - A * s1
            out[i, 6 + c] = E * s2 + F * s6
            out[i, 9 + c] = G * s7 - A * s3
            if six:
                out[i, 12 + c] = A * s4
                out[i, 15 + c] = A * s8


@numba.njit(cache=True)
def t_h_any(s, out):  # pragma: no cover - compiled
    """Any channel count: s (N, 9, C) → out (N, n, C)."""
    six = out.shape[1] == 6
    for i in range(s.shape[0]):
        for c in range(s.shape[2]):
            s0 = s[i, 0, c]
            s1 = s[i, 1, c]
            s2 = s[i, 2, c]
            s3 = s[i, 3, c]
            s4 = s[i, 4, c]
            s5 = s[i, 5, c]
            s6 = s[i, 6, c]
            s7 = s[i, 7, c]
            s8 = s[i, 8, c]
            out[i, 0, c] = A * s0 + B * s2
            out[i, 1, c] = G * s5 - A * s1
            out[i, 2, c] = E * s2 + F * s6
            out[i, 3, c] = G * s7 - A * s3
            if six:
                out[i, 4, c] = A * s4
                out[i, 5, c] = A * s8
