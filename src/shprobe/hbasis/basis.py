"""The H-basis H4/H6 (Habel & Wimmer 2010, §4, eq. 8–13), its SH → H matrix T_h, and
hemispherical quadrature.

Conventions (see docs/hbasis.md):

* Normals are given in the **tangent frame**: z is the surface normal, the upper hemisphere
  Ω+ is z ≥ 0, θ is measured from +z and φ from +x towards +y.
* The six functions are exactly those printed in the paper (eq. 8–13), including its minus
  signs on H² and H⁴ (the paper's SH carry the Condon–Shortley phase), and H³ with the root over
  the constant only:

      H¹ = 1/√(2π)                 H⁴ = −√(3/2π) x
      H² = −√(3/2π) y              H⁵ =  √(15/2π) x y
      H³ =  √(3/2π) (2z − 1)       H⁶ = ½√(15/2π) (x² − y²)

  H4 is the first four, H6 all six. They are orthonormal over Ω+ (tests check this by
  quadrature to 1e-12).
* ``sh_to_h_matrix()`` is T_h with (T_h)_ij = ∫_Ω+ H^i(ω) y_j(ω) dω, y_j shprobe's real SH
  (R&H signs, no Condon–Shortley phase, flat index j = l(l+1)+m). The paper omits it; its
  closed form is derived in docs/hbasis.md and reproduced in :data:`T_H_CLOSED_FORM`.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, sh_basis

_C1 = 1.0 / math.sqrt(2.0 * math.pi)  # H¹
_C3 = math.sqrt(3.0 / (2.0 * math.pi))  # H², H³, H⁴
_C5 = math.sqrt(15.0 / (2.0 * math.pi))  # H⁵; H⁶ uses _C5 / 2

_R2 = 1.0 / math.sqrt(2.0)
#: T_h (6×9) in closed form, rows H¹..H⁶, columns shprobe SH k = 0..8 (derivation in
#: docs/hbasis.md). Nonzero entries: 1/√2, √6/4, √2/4, √30/8 and −3√10/16.
T_H_CLOSED_FORM: NDArray[np.float64] = np.array(
    [
        [_R2, 0, math.sqrt(6) / 4, 0, 0, 0, 0, 0, 0],
        [0, -_R2, 0, 0, 0, -3 * math.sqrt(10) / 16, 0, 0, 0],
        [0, 0, math.sqrt(2) / 4, 0, 0, 0, math.sqrt(30) / 8, 0, 0],
        [0, 0, 0, -_R2, 0, 0, 0, -3 * math.sqrt(10) / 16, 0],
        [0, 0, 0, 0, _R2, 0, 0, 0, 0],
        [0, 0, 0, 0, 0, 0, 0, 0, _R2],
    ]
)
T_H_CLOSED_FORM.flags.writeable = False

#: Appendix A of the paper, as printed (rows H¹..H⁶, columns s^4_{-4} .. s^4_4 in the paper's
#: Condon–Shortley-phased SH). shprobe's y_4,±1 are −1 × theirs, so the computed l = 4 block
#: equals this with the m = ±1 columns (rows H² and H⁴) negated.
T_H4_PAPER: NDArray[np.float64] = np.zeros((6, 9))
T_H4_PAPER[1, 3] = -math.sqrt(15) / 16
T_H4_PAPER[2, 4] = -math.sqrt(1.5) / 8
T_H4_PAPER[3, 5] = -math.sqrt(15) / 16
T_H4_PAPER.flags.writeable = False


#: batches at least this large go through the numba kernels
NUMBA_MIN = 4096


@lru_cache(maxsize=1)
def _h_kernel():
    """numba kernel (compiled lazily, cached on disk) for H evaluation."""
    import numba

    c1, c3, c5 = _C1, _C3, _C5

    @numba.njit(cache=True)
    def h_eval(d, out):
        n = out.shape[1]
        for i in range(d.shape[0]):
            x, y, z = d[i, 0], d[i, 1], d[i, 2]
            out[i, 0] = c1
            out[i, 1] = -c3 * y
            out[i, 2] = c3 * (2 * z - 1)
            out[i, 3] = -c3 * x
            if n == 6:
                out[i, 4] = c5 * x * y
                out[i, 5] = 0.5 * c5 * (x * x - y * y)

    return h_eval


@lru_cache(maxsize=1)
def _t_h_kernel():
    """numba kernel for T_h (l ≤ 2) on (N, 9, C) batches: only its 10 nonzeros."""
    import numba

    a, b = T_H_CLOSED_FORM[0, 0], T_H_CLOSED_FORM[0, 2]
    e, f = T_H_CLOSED_FORM[2, 2], T_H_CLOSED_FORM[2, 6]
    g = T_H_CLOSED_FORM[1, 5]

    @numba.njit(cache=True)
    def sh_to_h6(s, out):
        n = out.shape[1]
        for i in range(s.shape[0]):
            for c in range(s.shape[2]):
                out[i, 0, c] = a * s[i, 0, c] + b * s[i, 2, c]
                out[i, 1, c] = -a * s[i, 1, c] + g * s[i, 5, c]
                out[i, 2, c] = e * s[i, 2, c] + f * s[i, 6, c]
                out[i, 3, c] = -a * s[i, 3, c] + g * s[i, 7, c]
                if n == 6:
                    out[i, 4, c] = a * s[i, 4, c]
                    out[i, 5, c] = a * s[i, 8, c]

    return sh_to_h6


def _check_n(n: int) -> int:
    if n not in (4, 6):
        raise ShprobeError(f"the H-basis has 4 or 6 functions (H4, H6), got n={n!r}")
    return int(n)


def h_basis(normals: ArrayLike, n: int = 6) -> NDArray[np.floating]:
    """H¹..Hⁿ (H&W 2010 eq. 8–13) of tangent-frame unit normals (..., 3) → (..., n).

    z is the surface normal. The functions are orthonormal over the upper hemisphere z ≥ 0
    only; below it they are just the same polynomials. float32 input gives float32 output.
    """
    n = _check_n(n)
    d = np.asarray(normals)
    if d.dtype not in (np.float32, np.float64):
        d = d.astype(np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {d.shape}")
    out = np.empty((*d.shape[:-1], n), dtype=d.dtype)
    if d.size >= 3 * NUMBA_MIN:
        _h_kernel()(np.ascontiguousarray(d).reshape(-1, 3), out.reshape(-1, n))
        return out
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    t = d.dtype.type
    out[..., 0] = t(_C1)
    out[..., 1] = t(-_C3) * y
    out[..., 2] = t(_C3) * (2 * z - 1)
    out[..., 3] = t(-_C3) * x
    if n == 6:
        out[..., 4] = t(_C5) * (x * y)
        out[..., 5] = t(0.5 * _C5) * (x * x - y * y)
    return out


def evaluate_h(coeffs: ArrayLike, normals: ArrayLike) -> NDArray[np.floating]:
    """E_H(n) = Σ h_i Hⁱ(n) (H&W eq. 15).

    ``coeffs`` is (..., n, C) or (..., n) with n = 4 or 6, ``normals`` (..., 3) tangent-frame
    normals broadcasting against the leading axes; returns (..., C) or (...).
    """
    c = np.asarray(coeffs)
    nd = np.asarray(normals)
    if c.ndim >= 2 and c.shape[-2] in (4, 6) and c.shape[-1] not in (4, 6):
        b = h_basis(nd, c.shape[-2])
        return np.einsum("...i,...ic->...c", b, c)
    if c.shape[-1] not in (4, 6):
        raise ShprobeError(f"H coefficients must have 4 or 6 on the basis axis, got {c.shape}")
    return np.einsum("...i,...i->...", h_basis(nd, c.shape[-1]), c)


@lru_cache(maxsize=32)
def hemisphere_quadrature(n_z: int = 32, n_phi: int = 64) -> tuple[NDArray, NDArray]:
    """Nodes (N, 3) and weights (N,) over the upper hemisphere, N = n_z · n_phi.

    Gauss–Legendre in z = cos θ on [0, 1] times the uniform rule in φ: exact for every
    polynomial in (x, y, z) of degree ≤ min(2 n_z − 1, n_phi − 1) (dω = dz dφ). The weights
    sum to 2π.
    """
    if n_z < 1 or n_phi < 1:
        raise ShprobeError("quadrature sizes must be positive")
    t, w = np.polynomial.legendre.leggauss(int(n_z))
    z = 0.5 * (t + 1.0)
    wz = 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    ss = np.broadcast_to(s[:, None], zz.shape)
    nodes = np.stack([ss * np.cos(pp), ss * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    weights = np.broadcast_to(wz[:, None] * (2.0 * np.pi / n_phi), zz.shape).reshape(-1)
    nodes.flags.writeable = False
    weights = np.ascontiguousarray(weights)
    weights.flags.writeable = False
    return nodes, weights


@lru_cache(maxsize=16)
def _t_h(lmax: int, n: int) -> NDArray[np.float64]:
    if lmax == 2 and n == 6:
        return T_H_CLOSED_FORM
    # the integrand Hⁱ y_lm is a polynomial of degree ≤ lmax + 2: this rule is exact
    nodes, w = hemisphere_quadrature(lmax // 2 + 3, lmax + 5)
    m = (h_basis(nodes, n) * w[:, None]).T @ sh_basis(nodes, lmax)
    m[np.abs(m) < 1e-15] = 0.0
    m.flags.writeable = False
    return m


def sh_to_h_matrix(lmax: int = 2, n: int = 6) -> NDArray[np.float64]:
    """T_h: the (n, (lmax+1)²) matrix taking shprobe SH coefficients to H coefficients.

    (T_h)_ij = ∫_Ω+ Hⁱ(ω) y_j(ω) dω (H&W §4.1; the paper omits the matrix). For lmax = 2 this
    is :data:`T_H_CLOSED_FORM` (H4: its first 4 rows); for larger lmax the extra columns are
    computed by a quadrature that is exact for these polynomial integrands. The l = 4 block
    (columns 16..24) is the paper's Appendix A with the sign of its m = ±1 columns flipped
    (Condon–Shortley phase, see :data:`T_H4_PAPER`). Applied to a signal's SH coefficients it
    gives the orthogonal projection onto H of the signal restricted to Ω+, exactly when the
    signal has no SH content above ``lmax``.
    """
    lmax = check_lmax(lmax, limit=64)
    n = _check_n(n)
    return _t_h(lmax, 6)[:n] if n != 6 else _t_h(lmax, 6)


def sh_to_h(sh_coeffs: ArrayLike, n: int = 6) -> NDArray[np.floating]:
    """H coefficients (..., n, C) of SH coefficients (..., K, C) (or (K,) → (n,)): T_h · s."""
    c = np.asarray(sh_coeffs)
    if c.dtype not in (np.float32, np.float64):
        c = c.astype(np.float64)
    from ..sh import lmax_of

    k = c.shape[-1] if c.ndim == 1 else c.shape[-2]
    n = _check_n(n)
    if k == 9 and c.ndim >= 2 and c.size >= 9 * NUMBA_MIN:
        cc = np.ascontiguousarray(c).reshape(-1, 9, c.shape[-1])
        out = np.empty((cc.shape[0], n, cc.shape[2]), dtype=c.dtype)
        _t_h_kernel()(cc, out)
        return out.reshape(*c.shape[:-2], n, c.shape[-1])
    t = sh_to_h_matrix(lmax_of(k), n).astype(c.dtype)
    if c.ndim == 1:
        return t @ c
    return np.matmul(t, c)


def project_h(func, n: int = 6, n_z: int = 48, n_phi: int = 96) -> NDArray[np.float64]:
    """Project a hemispherical function into H: h_i = ∫_Ω+ f Hⁱ dω by quadrature.

    ``func`` maps (N, 3) tangent-frame directions to (N,) or (N, C) values. Exact for
    polynomials of degree ≤ min(2 n_z − 3, n_phi − 3).
    """
    nodes, w = hemisphere_quadrature(n_z, n_phi)
    vals = np.asarray(func(np.array(nodes)), dtype=np.float64)
    if vals.shape[0] != nodes.shape[0]:
        raise ShprobeError(f"func returned shape {vals.shape} for {nodes.shape[0]} directions")
    b = h_basis(nodes, _check_n(n)) * w[:, None]
    return b.T @ vals


__all__ = [
    "T_H4_PAPER",
    "T_H_CLOSED_FORM",
    "evaluate_h",
    "h_basis",
    "hemisphere_quadrature",
    "project_h",
    "sh_to_h",
    "sh_to_h_matrix",
]
