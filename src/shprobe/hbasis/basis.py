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
  closed form is derived in docs/hbasis.md and reproduced in
  [`T_H_CLOSED_FORM`][shprobe.hbasis.T_H_CLOSED_FORM].
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


#: batches at least this large go through the numba kernels (``._kernels``)
NUMBA_MIN = 4096
#: one-channel float64 SH → H outputs at least this large are written with streaming stores
#: (``._kernels.t_h_c1_stream``): they would not stay in the caches anyway, so the stores skip
#: reading the lines in first.
STREAM_MIN_BYTES = 8 << 20


def _check_n(n: int) -> int:
    if isinstance(n, bool) or n not in (4, 6):
        raise ShprobeError(f"the H-basis has 4 or 6 functions (H4, H6), got n={n!r}")
    return int(n)


def _float_array(a: ArrayLike, what: str) -> NDArray[np.floating]:
    """float32 stays float32, anything else numeric becomes float64; non-numeric input (object
    arrays, strings) and NaN or infinite values are one
    [`ShprobeError`][shprobe.errors.ShprobeError]."""
    try:
        x = np.asarray(a)
        if x.dtype not in (np.float32, np.float64):
            if x.dtype.kind not in "biuf":
                raise TypeError
            x = x.astype(np.float64)
    except (TypeError, ValueError):
        raise ShprobeError(f"{what} must be an array of numbers") from None
    # two reductions, no temporaries: NaN propagates through min/max, ±inf shows in one of them
    if x.size and not (np.isfinite(x.min()) and np.isfinite(x.max())):
        raise ShprobeError(f"{what} hold NaN or infinite values")
    return x


def _check_out(out: object, shape: tuple[int, ...], dtype: np.dtype) -> NDArray[np.floating]:
    if (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != dtype
            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ShprobeError(f"out must be a writeable C-contiguous {dtype} array of shape {shape}")
    return out


def h_basis(normals: ArrayLike, n: int = 6,
            out: NDArray[np.floating] | None = None) -> NDArray[np.floating]:
    """H¹..Hⁿ (H&W 2010 eq. 8–13) of tangent-frame unit normals (..., 3) → (..., n).

    z is the surface normal. The functions are orthonormal over the upper hemisphere z ≥ 0
    only; below it they are just the same polynomials. float32 input gives float32 output
    (other types become float64). ``out``: an optional preallocated C-contiguous (..., n)
    array of the normals' float type, filled and returned. Batches of ≥ 4096 normals run a
    single-threaded numba kernel that writes each row straight into the output.

    Parameters
    ----------
    normals
        (..., 3) tangent-frame unit normals (z along the surface normal).
    n
        4 (H4) or 6 (H6).
    out
        A preallocated C-contiguous (..., n) array of the normals' float type.

    Returns
    -------
    ndarray of shape (..., n)
        H¹ … Hⁿ at the normals.
    """
    n = _check_n(n)
    d = _float_array(normals, "normals")
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {d.shape}")
    shape = (*d.shape[:-1], n)
    out = np.empty(shape, dtype=d.dtype) if out is None else _check_out(out, shape, d.dtype)
    if d.size >= 3 * NUMBA_MIN:
        from ._kernels import h_rows

        h_rows(np.ascontiguousarray(d).reshape(-1, 3), out.reshape(-1, n))
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
    """E_H(n) = Σᵢ hᵢ Hⁱ(n) (H&W 2010 eq. 15).

    Layout (as for SH coefficients, docs/architecture.md): ``coeffs`` is (..., n, C) with the
    basis count n = 4 (H4) or 6 (H6) on axis −2 and C channels last — so a (6, 6) array is six
    functions of six channels — or a 1-D (n,) single channel. ``normals`` (..., 3) are
    tangent-frame unit normals whose leading axes broadcast against the coefficients'
    leading axes. Returns (..., C), or (...) for 1-D coefficients. One-channel per-point
    coefficients are (P, n, 1), not (P, n).

    Parameters
    ----------
    coeffs
        (..., n, C) or (n,) H coefficients, n = 4 or 6.
    normals
        (..., 3) tangent-frame unit normals.

    Returns
    -------
    ndarray of shape (..., C) or (...,)
        E_H(n).
    """
    c = _float_array(coeffs, "H coefficients")
    nd = _float_array(normals, "normals")
    if nd.ndim < 1 or nd.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {nd.shape}")
    if c.ndim == 1:
        if c.shape[0] not in (4, 6):
            raise ShprobeError(f"H coefficients must be (n,) or (..., n, C) with n = 4 or 6, "
                               f"got shape {c.shape}")
        return h_basis(nd, c.shape[0]) @ c
    if c.ndim == 0 or c.shape[-2] not in (4, 6):
        raise ShprobeError(f"H coefficients must be (..., n, C) with n = 4 or 6 on axis -2 "
                           f"(one channel: (..., n, 1)), got shape {c.shape}")
    try:
        np.broadcast_shapes(c.shape[:-2], nd.shape[:-1])
    except ValueError:
        raise ShprobeError(f"H coefficients {c.shape} (leading axes {c.shape[:-2]}) do not "
                           f"broadcast against normals {nd.shape}") from None
    return np.einsum("...i,...ic->...c", h_basis(nd, c.shape[-2]), c)


@lru_cache(maxsize=32)
def hemisphere_quadrature(n_z: int = 32, n_phi: int = 64) -> tuple[NDArray, NDArray]:
    """Nodes (N, 3) and weights (N,) over the upper hemisphere, N = n_z · n_phi.

    Gauss–Legendre in z = cos θ on [0, 1] times the uniform rule in φ: exact for every
    polynomial in (x, y, z) of degree ≤ min(2 n_z − 1, n_phi − 1) (dω = dz dφ). The weights
    sum to 2π.

    Parameters
    ----------
    n_z
        Gauss–Legendre nodes in z.
    n_phi
        Uniform nodes in φ.

    Returns
    -------
    tuple
        Nodes (N, 3) and weights (N,), N = n_z · n_phi.
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
    is [`T_H_CLOSED_FORM`][shprobe.hbasis.T_H_CLOSED_FORM] (H4: its first 4 rows); for larger lmax
    the extra columns are computed by a quadrature that is exact for these polynomial integrands.
    The l = 4 block (columns 16..24) is the paper's Appendix A with the sign of its m = ±1 columns
    flipped (Condon–Shortley phase, see [`T_H4_PAPER`][shprobe.hbasis.T_H4_PAPER]). Applied to a
    signal's SH coefficients it gives the orthogonal projection onto H of the signal restricted to
    Ω+, exactly when the signal has no SH content above ``lmax``.

    Parameters
    ----------
    lmax
        The highest SH degree of the coefficients converted.
    n
        4 (H4) or 6 (H6).

    Returns
    -------
    ndarray of shape (n, (lmax + 1)²)
        T_h, taking SH coefficients to H coefficients.
    """
    lmax = check_lmax(lmax, limit=64)
    n = _check_n(n)
    return _t_h(lmax, 6)[:n] if n != 6 else _t_h(lmax, 6)


def sh_to_h(sh_coeffs: ArrayLike, n: int = 6,
            out: NDArray[np.floating] | None = None) -> NDArray[np.floating]:
    """H coefficients T_h · s (H&W 2010 §4.1) of SH coefficients.

    Layout as everywhere in shprobe: ``sh_coeffs`` is (..., K, C) with K = (lmax+1)² on axis
    −2 and C channels last, giving (..., n, C); a 1-D (K,) single set gives (n,). N sets of one
    channel are (N, K, 1), not (N, K). The matrix is
    [`sh_to_h_matrix`][shprobe.hbasis.sh_to_h_matrix] (lmax, n). float32 stays float32. ``out``: an
    optional preallocated C-contiguous array of the result's shape and float type, filled and
    returned. For K = 9 and ≥ 4096 sets a single-threaded numba kernel applies only T_h's 10
    nonzeros and writes straight into the output (one-channel, RGB and general-C variants;
    one-channel float64 outputs of ≥ ``STREAM_MIN_BYTES`` with streaming stores).

    Parameters
    ----------
    sh_coeffs
        (..., K, C) or (K,) SH coefficients.
    n
        4 (H4) or 6 (H6).
    out
        A preallocated C-contiguous array of the result's shape and float type.

    Returns
    -------
    ndarray of shape (..., n, C) or (n,)
        The H coefficients.
    """
    n = _check_n(n)
    c = _float_array(sh_coeffs, "SH coefficients")
    if c.ndim == 0:
        raise ShprobeError("SH coefficients must be (K,) or (..., K, C), got a scalar")
    k = c.shape[-1] if c.ndim == 1 else c.shape[-2]
    if k < 1 or math.isqrt(k) ** 2 != k:
        raise ShprobeError(
            f"SH coefficients must be (..., K, C) with K = (lmax+1)² on axis -2 and channels "
            f"last (for one channel pass (..., K, 1), or a single set (K,)); got shape "
            f"{c.shape}, whose axis -2 ({k}) is not a square")
    shape = (n,) if c.ndim == 1 else (*c.shape[:-2], n, c.shape[-1])
    out = np.empty(shape, dtype=c.dtype) if out is None else _check_out(out, shape, c.dtype)
    if k == 9 and c.ndim >= 2 and c.size >= 9 * NUMBA_MIN:
        from ._kernels import t_h_any, t_h_c1, t_h_c1_stream, t_h_c3

        nch = c.shape[-1]
        cc = np.ascontiguousarray(c)
        if nch == 1 and out.itemsize == 8 and out.nbytes >= STREAM_MIN_BYTES:
            t_h_c1_stream(cc.reshape(-1), out.reshape(-1))
        elif nch == 1:
            t_h_c1(cc.reshape(-1, 9), out.reshape(-1, n))
        elif nch == 3:
            t_h_c3(cc.reshape(-1, 27), out.reshape(-1, 3 * n))
        else:
            t_h_any(cc.reshape(-1, 9, nch), out.reshape(-1, n, nch))
        return out
    t = sh_to_h_matrix(math.isqrt(k) - 1, n).astype(c.dtype)
    return np.matmul(t, c, out=out)


def project_h(func, n: int = 6, n_z: int = 48, n_phi: int = 96) -> NDArray[np.float64]:
    """Project a hemispherical function into H: h_i = ∫_Ω+ f Hⁱ dω by quadrature.

    Parameters
    ----------
    func : callable
        Maps (N, 3) tangent-frame directions to (N,) or (N, C) real values.
    n : int
        Number of H-basis functions (4, 6 or 9).
    n_z, n_phi : int
        Quadrature nodes in z and in azimuth; exact for polynomials of degree
        ≤ min(2 n_z − 3, n_phi − 3).

    Returns
    -------
    numpy.ndarray
        (n,) or (n, C) float64 coefficients. Anything but a callable returning finite real
        values of the right length is refused in one line (``ShprobeError``).
    """
    if not callable(func):
        raise ShprobeError(f"project_h needs a function of (N, 3) directions, got "
                           f"{type(func).__name__}")
    nodes, w = hemisphere_quadrature(n_z, n_phi)
    try:
        vals = np.asarray(func(np.array(nodes)))
        if vals.dtype.kind not in "fiub":
            raise TypeError
        vals = vals.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ShprobeError("project_h: the function must return real numbers") from None
    if not np.isfinite(vals).all():
        raise ShprobeError("project_h: the function returned NaN or infinity")
    if vals.ndim == 0 or vals.shape[0] != nodes.shape[0]:
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
