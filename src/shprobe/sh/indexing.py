"""The bookkeeping of the SH maths: flat indices k = l(l+1)+m, degrees, the checks of a degree
argument, the recurrence tables of the basis (Lisle & Huang 2007 §2.1) and unit vectors.

Below `shprobe.sh.basis`, `shprobe.sh.rotation` and the array-API path (`shprobe.sh._xp`), which all
use it, so that none of them needs another.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError

#: Largest degree shprobe accepts.
LMAX_LIMIT = 1024


def num_coeffs(lmax: int) -> int:
    """K = (lmax + 1)², the number of coefficients up to degree ``lmax``.

    Parameters
    ----------
    lmax
        The highest degree, ≥ 0.

    Returns
    -------
    int
        (lmax + 1)².
    """
    return (lmax + 1) ** 2


@overload
def sh_index(l: int, m: int) -> int: ...
@overload
def sh_index(l: ArrayLike, m: ArrayLike) -> NDArray[np.int64]: ...
def sh_index(l, m):
    """Flat index k = l(l+1) + m; integers, or integer arrays (broadcast).

    Parameters
    ----------
    l, m
        Degree and order, |m| ≤ l (integers or integer arrays, broadcast).

    Returns
    -------
    int or ndarray of int64
        k = l(l + 1) + m.
    """
    if np.ndim(l) == 0 and np.ndim(m) == 0:
        l, m = int(l), int(m)
        if l < 0 or abs(m) > l:
            raise ShprobeError(f"no spherical harmonic with l={l}, m={m}")
        return l * (l + 1) + m
    la, ma = np.broadcast_arrays(np.asarray(l, dtype=np.int64), np.asarray(m, dtype=np.int64))
    bad = (la < 0) | (np.abs(ma) > la)
    if bad.any():
        i = np.argmax(bad.reshape(-1))
        raise ShprobeError(f"no spherical harmonic with l={la.reshape(-1)[i]}, "
                           f"m={ma.reshape(-1)[i]}")
    return la * (la + 1) + ma


@overload
def sh_lm(k: int) -> tuple[int, int]: ...
@overload
def sh_lm(k: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]: ...
def sh_lm(k):
    """Inverse of [`sh_index`][shprobe.sh.sh_index]: (l, m) of flat index ``k`` (an integer or
    integer array).

    Parameters
    ----------
    k
        A flat index ≥ 0, or an integer array of them.

    Returns
    -------
    tuple
        (l, m), integers or int64 arrays.
    """
    ka = np.asarray(k, dtype=np.int64)
    if (ka < 0).any():
        raise ShprobeError(f"flat SH index must be >= 0, got {k}")
    l = np.sqrt(ka).astype(np.int64)
    l += (l + 1) ** 2 <= ka  # exact integer correction of the float square root
    l -= l * l > ka
    m = ka - l * (l + 1)
    if ka.ndim == 0:
        return int(l), int(m)
    return l, m


def lmax_of(n_coeffs: int) -> int:
    """lmax such that (lmax+1)² = ``n_coeffs``; error if ``n_coeffs`` is not a square.

    Parameters
    ----------
    n_coeffs
        A number of coefficients K.

    Returns
    -------
    int
        The degree whose (lmax + 1)² is K; a one-line ShprobeError when K is not a square.
    """
    l = math.isqrt(max(int(n_coeffs), 0)) - 1
    if l < 0 or (l + 1) ** 2 != n_coeffs:
        raise ShprobeError(f"{n_coeffs} coefficients is not (lmax+1)² for any lmax")
    return l


def degrees(lmax: int) -> NDArray[np.int64]:
    """Degree l of every flat index up to ``lmax`` (length K).

    Parameters
    ----------
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (K,), int64
        l of each flat index k.
    """
    return np.repeat(np.arange(lmax + 1), 2 * np.arange(lmax + 1) + 1)


def check_lmax(lmax: int, limit: int = LMAX_LIMIT) -> int:
    """Validate a degree argument: an integer (or integral number) in 0..``limit``; anything
    else (None, NaN, inf, 2.5, a string, an array) is one
    [`ShprobeError`][shprobe.errors.ShprobeError].

    Parameters
    ----------
    lmax
        The degree given.
    limit
        The largest degree allowed.

    Returns
    -------
    int
        The degree as an int.
    """
    try:
        ok = not isinstance(lmax, bool | str | bytes) and float(lmax) == int(lmax)
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        if type(lmax).__module__.startswith("jax"):  # a tracer: the value comes at run time
            raise ShprobeError("SH degree must be a Python int known before tracing (under "
                               "jax.jit pass it as a static argument), got a traced value")
        raise ShprobeError(f"SH degree must be an integer, got {lmax!r}")
    lmax = int(lmax)
    if lmax < 0 or lmax > limit:
        raise ShprobeError(f"SH degree lmax={lmax} out of range 0..{limit}")
    return lmax


@lru_cache(maxsize=64)
def recurrence_tables(lmax: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """a_lm and b_lm of the normalised interior recurrence, shape (lmax+1, lmax+1) [l, m].

    Parameters
    ----------
    lmax
        The highest degree.

    Returns
    -------
    tuple of ndarray, each of shape (lmax + 1, lmax + 1)
        a_lm and b_lm, indexed [l, m].
    """
    a = np.zeros((lmax + 1, lmax + 1))
    b = np.zeros((lmax + 1, lmax + 1))
    for m in range(lmax + 1):
        for l in range(m + 2, lmax + 1):
            a[l, m] = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b[l, m] = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
    a.flags.writeable = False
    b.flags.writeable = False
    return a, b


#: Largest degree :func:`rotate` / :func:`wigner_d` accept (the d(π/2) table grows as lmax³/3).
ROTATION_LMAX = 256

#: :func:`sh_basis` uses directions as given while their squared lengths sum to at most this
#: per direction (unit vectors: 1); beyond, or on overflow, it normalises them first.
NEAR_UNIT = 16.0


def unit_vectors(v: ArrayLike, what: str = "direction",
                 zero: str = "refuse") -> NDArray[np.float64]:
    """Unit vectors (..., 3) float64 from any non-zero finite vectors, without overflow (each is
    scaled by its largest component first, so (1e200, 1e200, 0) works).

    The one policy for zero-length input, ``zero``: ``"refuse"`` (a one-line error, the
    default) or ``"keep"`` (zero vectors stay zero, e.g. pixels outside a layout's disc).
    Non-finite vectors are always refused.
    """
    try:
        d = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise ShprobeError(f"{what} must be numeric (..., 3) vectors") from None
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"{what} must have shape (..., 3), got {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ShprobeError(f"{what} must be finite vectors")
    big = np.abs(d).max(axis=-1, keepdims=True)
    if zero == "refuse" and np.any(big == 0.0):
        raise ShprobeError(f"{what} must be a non-zero vector")
    s = d / np.where(big > 0, big, 1.0)
    n = np.linalg.norm(s, axis=-1, keepdims=True)
    return s / np.where(n > 0, n, 1.0)
