"""Real orthonormal spherical harmonics of any degree (Lisle & Huang 2007, §2.1).

Convention (the one used everywhere in shprobe, see ``shprobe.sh.conventions``): real orthonormal
SH with the signs of Ramamoorthi & Hanrahan 2001, Fig. 2 / eq. 3 — no Condon–Shortley phase —
and flat index ``k = l(l+1) + m``:

    y00 = 0.282095
    y1-1 = 0.488603 y,  y10 = 0.488603 z,  y11 = 0.488603 x
    y2-2 = 1.092548 xy, y2-1 = 1.092548 yz, y20 = 0.315392 (3z² − 1),
    y21 = 1.092548 xz,  y22 = 0.546274 (x² − y²)

Lisle & Huang's unnormalised recurrence starts from Y11 = −x, Y1−1 = −y: it carries the
Condon–Shortley phase (−1)^m, which shprobe removes. Here the recurrence is run on normalised
quantities so that nothing overflows at high degree:

    y_lm  = √2 · P̄_l^|m|(z) · Re (x + iy)^m     (m > 0)
    y_l,-m = √2 · P̄_l^|m|(z) · Im (x + iy)^m    (m > 0)
    y_l0  = P̄_l^0(z)

with (x + iy)^m built by LH's algebraic edge recurrence (no trigonometric calls) and the
normalised z-polynomials P̄ by

    P̄_00 = 1/√(4π),  P̄_mm = √((2m+1)/(2m)) P̄_{m-1,m-1},  P̄_{m+1,m} = √(2m+3) z P̄_mm,
    P̄_lm = a_lm (z P̄_{l-1,m} − b_lm P̄_{l-2,m}),
    a_lm = √((4l²−1)/(l²−m²)),  b_lm = √(((l−1)²−m²)/(4(l−1)²−1)),

the LH interior recurrence with the normalising constants K_lm folded into each step.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import check_memory, cores
from . import _xp
from .indexing import (
    NEAR_UNIT,
    check_lmax,
    num_coeffs,
    recurrence_tables,
    unit_vectors,
)


def _as_dirs(dirs: ArrayLike) -> NDArray[np.floating]:
    try:
        d = np.asarray(dirs)
        if d.dtype.kind == "c":
            raise ShprobeError("directions must be real vectors, got complex values")
        if d.dtype not in (np.float32, np.float64):
            d = d.astype(np.float64)
    except (TypeError, ValueError, OverflowError) as e:
        if isinstance(e, ShprobeError):
            raise
        raise ShprobeError("directions must be numeric (..., 3) vectors") from None
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"directions must have shape (..., 3), got {d.shape}")
    return d


def sh_basis_numpy(dirs: ArrayLike, lmax: int) -> NDArray[np.floating]:
    """The reference of ``sh_basis``: the array-API recurrence run on NumPy.

    Parameters
    ----------
    dirs : array_like
        (..., 3) directions, float32 or float64 (other types become float64).
    lmax : int
        Maximum degree, 0 ≤ lmax ≤ 1024.

    Returns
    -------
    numpy.ndarray
        (..., (lmax+1)²) values in the type of ``dirs``, computed in float64 by
        ``shprobe.sh._xp.sh_basis`` (the one definition of the basis, on NumPy through
        array-api-compat; whole-array operations, no numba: the probe loader uses it).
    """
    d = _as_dirs(dirs)
    lmax = check_lmax(lmax)
    xp = _xp.numpy_namespace()
    flat = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    out = np.empty((flat.shape[0], num_coeffs(lmax)), dtype=d.dtype)
    for i in range(0, flat.shape[0], _REFERENCE_ROWS):  # temporaries that stay in cache
        out[i:i + _REFERENCE_ROWS] = _xp.sh_basis(xp, flat[i:i + _REFERENCE_ROWS], lmax)
    return out.reshape(*d.shape[:-1], num_coeffs(lmax))


def _sh_basis_xp(xp: Any, dirs: Any, lmax: int) -> Any:
    """``sh_basis`` of a torch tensor or JAX array: its memory estimated first (the K columns
    and their stacked copy), computed in float32 for float16/bfloat16 input and in float64
    for float32 input above ``F32_ARITHMETIC_LMAX`` (where P̄ passes the type's range), then
    cast back to the input's type."""
    dt = _xp.float_dtype(xp, dirs)
    d = _xp.asarray(xp, dirs, dt, dirs)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"directions must have shape (..., 3), got {tuple(d.shape)}")
    work = _xp.work_dtype(xp, dt)
    if work == xp.float32 and lmax > F32_ARITHMETIC_LMAX:
        work = xp.float64
    n = int(np.prod(tuple(d.shape[:-1])))
    check_memory(3.0 * n * num_coeffs(lmax) * np.dtype(str(work).rsplit(".", 1)[-1]).itemsize,
                 f"SH values of {n} directions to lmax {lmax}")
    y = _xp.sh_basis(xp, xp.astype(d, work) if work != dt else d, lmax)
    return xp.astype(y, dt) if work != dt else y


#: Directions per whole-array pass of ``sh_basis_numpy``: its temporaries (32 kB columns)
#: come from the allocator's free lists, not from fresh pages faulted in.
_REFERENCE_ROWS = 4096


def sh_basis_scipy(dirs: ArrayLike, lmax: int) -> NDArray[np.float64]:
    """Independent (slow) evaluation of [`sh_basis`][shprobe.sh.sh_basis] for checks and benchmarks.

    scipy.special.sph_harm_y (complex, with the Condon–Shortley phase) turned real with R&H
    signs: y_l0 = Y_l0, y_lm = √2 (−1)^m Re Y_lm, y_l,−m = √2 (−1)^m Im Y_lm (m > 0). θ is
    taken as atan2(√(x²+y²), z), which stays accurate near the poles.

    Parameters
    ----------
    dirs
        (..., 3) unit directions.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (..., (lmax + 1)²), float64
        y_lm at the directions, from SciPy's complex harmonics.
    """
    from scipy.special import sph_harm_y

    d = np.asarray(_as_dirs(dirs), dtype=np.float64)
    lmax = check_lmax(lmax)
    flat = d.reshape(-1, 3)
    theta = np.arctan2(np.hypot(flat[:, 0], flat[:, 1]), flat[:, 2])
    phi = np.arctan2(flat[:, 1], flat[:, 0])
    out = np.empty((len(flat), num_coeffs(lmax)))
    for l in range(lmax + 1):
        m = np.arange(l + 1)
        Y = sph_harm_y(l, m[:, None], theta[None, :], phi[None, :])  # (l+1, N)
        k0 = l * (l + 1)
        out[:, k0] = Y[0].real
        sign = np.sqrt(2.0) * (-1.0) ** m[1:, None]
        out[:, k0 + m[1:]] = (sign * Y[1:].real).T
        out[:, k0 - m[1:]] = (sign * Y[1:].imag).T
    return out.reshape(*d.shape[:-1], num_coeffs(lmax))


#: Largest degree at which float32 output is computed in float32 arithmetic. The z-polynomials
#: P̄_lm (the sinᵐθ factor lives in (x + iy)ᵐ) peak at z = ±1 near 10^(0.2 l): 10²⁶ at l = 128,
#: so float32 (max 3·10³⁸) has room to spare; above this degree float64 arithmetic is used.
F32_ARITHMETIC_LMAX = 128




#: Outputs of at least this many bytes are written with streaming (non-temporal) stores by the
#: table kernel: far larger than the caches, written once, so reading each line in before
#: overwriting it would only double the memory traffic.
STREAM_MIN_BYTES = 32 << 20
#: The same threshold for the unrolled kernels (lmax ≤ 8). Their rows are short and their
#: plain in-place stores keep pace with memory: on the 2-core AMD EPYC box the streamed
#: variants (computed into an L1 buffer, copied out non-temporally) took 1.4–1.9× the plain
#: kernels' CPU time at lmax 2 and 6 into a 10⁶-direction ``out=`` (the table kernel's
#: streamed copy stays 1.3× faster than its plain one at lmax 10–20), so they stream only
#: outputs past this (none in practice; ``STREAM_KERNELS`` kept for machines where it pays).
UNROLLED_STREAM_MIN_BYTES = 1 << 62

#: Outputs of at least this many values per core are filled by one thread per core, each
#: writing its own block of rows (on 2 cores a thread's start and join, ~0.1 ms, is a tenth
#: of what this many values take).
PARALLEL_MIN_VALUES = 1 << 18
#: At most this many blocks of rows are shared out among the threads (each block a numba
#: call of ~10 µs overhead).
PARALLEL_BLOCKS = 32


def _stream_start(out: NDArray[np.floating]) -> int:
    """−1 (plain stores) below ``STREAM_MIN_BYTES`` (``UNROLLED_STREAM_MIN_BYTES`` for rows of
    lmax ≤ 8); else the first flat index of ``out``
    whose address is 64-byte aligned, modulo 64 / itemsize (what the kernel's streaming
    copy needs).

    Only a caller's ``out=`` is streamed: an array ``sh_basis`` has just allocated has no
    pages yet, and the kernel zeroes each (huge) page on first touch, leaving it in the
    cache, where plain stores then land, while streaming stores would write every line
    twice to memory (the zeros and the values)."""
    limit = UNROLLED_STREAM_MIN_BYTES if out.shape[-1] <= 81 else STREAM_MIN_BYTES
    if out.nbytes < limit or not out.flags.aligned:
        return -1
    return ((-out.ctypes.data) % 64) // out.itemsize


@lru_cache(maxsize=64)
def _kernel_tables(lmax: int, dtype: type) -> tuple[NDArray[np.floating], ...]:
    """Tables of the table kernel (``shprobe.sh._kernels.sh_rows``) in ``dtype``: R = the
    (a_lm, a_lm·b_lm) pairs column by column (m = 0 … lmax−2, l = m+2 … lmax within a
    column), d0[m] = P̄_mm, d1[l] = √(2l+1) P̄_{l−1,l−1}."""
    a, b = recurrence_tables(lmax)
    R = np.concatenate([np.stack([a[m + 2:, m], (a * b)[m + 2:, m]], -1).reshape(-1)
                        for m in range(max(lmax - 1, 0))] + [np.zeros(2)])
    m = np.arange(1, lmax + 1)
    d0 = np.cumprod(np.concatenate([[0.5 / np.sqrt(np.pi)],
                                    np.sqrt((2.0 * m + 1.0) / (2.0 * m))]))
    d1 = np.zeros(lmax + 1)
    d1[1:] = np.sqrt(2.0 * m + 1.0) * d0[:-1]
    out = tuple(np.ascontiguousarray(t, dtype=dtype) for t in (R, d0, d1))
    for t in out:
        t.flags.writeable = False
    return out


def sh_basis(
    dirs: ArrayLike, lmax: int, out: NDArray[np.floating] | None = None
) -> NDArray[np.floating]:
    """Real orthonormal SH y_lm of unit directions, for all l ≤ ``lmax``.

    Parameters
    ----------
    dirs : array_like
        (..., 3) unit vectors, float32 or float64 (other types become float64), used as
        given; or a torch tensor / JAX array (the array-API path, differentiable, same
        device and dtype; float16/bfloat16 computed in float32 and cast back).
    lmax : int
        Maximum degree, 0 ≤ lmax ≤ 1024.
    out : numpy.ndarray, optional
        Preallocated C-contiguous (..., (lmax+1)²) array of the float type of ``dirs``
        (NumPy only); it is filled and returned.

    Returns
    -------
    array
        (..., (lmax+1)²) values of the float type of ``dirs``, flat index k = l(l+1)+m, R&H
        signs.

    Notes
    -----
    The normalised algebraic recurrence of Lisle & Huang 2007 §2.1 (no trig; see the module
    docstring), by numba kernels that write each direction's row straight into the output:
    for lmax ≤ 8 one unrolled per degree with the constants folded in
    (``shprobe.sh._kernels_unrolled``, generated by ``tools/gen_sh_unrolled.py``), above that
    a loop over column-packed tables (``shprobe.sh._kernels``, streaming stores into a
    caller's ``out`` of ≥ ``STREAM_MIN_BYTES``); both in the output's precision (float32 up
    to ``F32_ARITHMETIC_LMAX``: within (l + 1) float32 epsilons of the band's scale
    √((2l+1)/4π), tested to l = 64). Outputs of at least ``PARALLEL_MIN_VALUES`` values per
    core are split into one block of rows per core, each filled in its own thread. The
    kernels are tested against ``sh_basis_numpy``, the reference (the array-API recurrence of
    ``shprobe.sh._xp`` on NumPy).

    Bad directions, the one policy: NaN or infinite components are refused
    (``ShprobeError``); directions near unit length (Σ|d|² ≤ ``NEAR_UNIT`` per direction over
    each block of rows) are used as given, bit for bit; larger ones, or ones whose squares overflow
    such as (1e200, 1e200, 0), are normalised first without overflow
    (``shprobe.sh.rotation.unit_vectors``). The memory of the output is estimated first and
    refused past the limit (``shprobe.limits``), on every path.
    """
    xp = _xp.namespace(dirs)
    if xp is not None:
        if out is not None:
            raise ShprobeError("out= is for NumPy arrays only")
        return _sh_basis_xp(xp, dirs, check_lmax(lmax))
    d = _as_dirs(dirs)
    lmax = check_lmax(lmax)
    K = num_coeffs(lmax)
    shape = (*d.shape[:-1], K)
    stream = out is not None  # a fresh array is written with plain stores (see _stream_start)
    if out is None:
        check_memory(float(np.prod(shape)) * d.dtype.itemsize,
                     f"SH values of {int(np.prod(shape[:-1]))} directions to lmax {lmax}")
        out = np.empty(shape, dtype=d.dtype)
    elif (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != d.dtype
          or not out.flags.c_contiguous or not out.flags.writeable):
        raise ShprobeError(
            f"out must be a writeable C-contiguous {d.dtype} array of shape {shape}"
        )
    if out.size == 0:
        return out
    flat = np.ascontiguousarray(d.reshape(-1, 3))
    _fill_rows(flat, out.reshape(-1, K), lmax, stream and _stream_start(out) >= 0, not stream)
    return out


def _fill_rows(flat: NDArray[np.floating], out: NDArray[np.floating], lmax: int, stream: bool,
               fresh: bool) -> None:
    """out (N, K) = the basis of flat (N, 3). Large outputs are cut into blocks of rows
    (up to ``PARALLEL_BLOCKS``) that the calling thread and ``cores() − 1`` pool threads take
    in turn, each block filled by the numba kernel (the kernels release the GIL): a thread
    the shared machine pre-empts, or a pool thread slow to wake, holds up one block, not half
    the output. Smaller outputs stay in the calling thread."""
    n = flat.shape[0]
    workers = min(cores(), out.size // PARALLEL_MIN_VALUES, n // 4)
    if workers <= 1:
        _kernel_rows(flat, out, lmax, stream, fresh)
        return
    blocks = min(PARALLEL_BLOCKS, max(workers, out.size // PARALLEL_MIN_VALUES), n // 4)
    cuts = [n * i // blocks // 4 * 4 for i in range(blocks)] + [n]
    spans = list(itertools.pairwise(cuts))
    taken = itertools.count()  # next() is atomic under the GIL

    def work() -> None:
        for i in iter(taken.__next__, None):
            if i >= len(spans):
                return
            i0, i1 = spans[i]
            _kernel_rows(flat[i0:i1], out[i0:i1], lmax, stream, fresh)

    helpers = [_pool(workers - 1).submit(work) for _ in range(workers - 1)]
    try:
        work()
    finally:
        for f in helpers:  # one not started yet finds no block left: cancel it
            if not f.cancel():
                f.result()  # waits for its block; raises what it raised


_POOLS: list[tuple[int, ThreadPoolExecutor]] = []


def _pool(n: int) -> ThreadPoolExecutor:
    """The helper threads of ``sh_basis`` (at least ``n``), started once per process and
    reused: starting threads on every call costs a scheduling round trip each, and on a busy
    machine far more. A forked child (whose copy of the pool has no threads) starts its own."""
    if not _POOLS or _POOLS[-1][0] != os.getpid() or _POOLS[-1][1]._max_workers < n:
        _POOLS.append((os.getpid(), ThreadPoolExecutor(n, thread_name_prefix="shprobe-sh")))
    return _POOLS[-1][1]


def _kernel_rows(flat: NDArray[np.floating], out: NDArray[np.floating], lmax: int,
                 stream: bool, fresh: bool) -> None:
    """One block of rows through the numba kernel of ``lmax`` (streaming stores if
    ``stream``; ``fresh``: ``out`` was just allocated). The block's directions are used as
    given while their squared lengths sum to at most ``NEAR_UNIT`` per direction; else, or
    on NaN, infinity or overflow, they are normalised first (``unit_vectors``, which refuses
    non-finite ones) and the rows computed again. The unrolled kernels return that sum from
    the pass that computes the rows; otherwise it is one pass before (einsum's own loop: a
    threaded BLAS dot would leave its threads spinning on the cores the other blocks use)."""
    a0 = ((-out.ctypes.data) % 64) // out.itemsize if stream else -1
    limit = NEAR_UNIT * flat.shape[0]
    if lmax <= 8 and a0 < 0:
        from ._kernels_unrolled import KERNELS

        if not KERNELS[lmax](flat, out) <= limit:
            KERNELS[lmax](_unit(flat), out)
        return
    with np.errstate(over="ignore", invalid="ignore"):
        sq = float(np.einsum("i,i->", flat.reshape(-1), flat.reshape(-1)))
    if not sq <= limit:
        flat = _unit(flat)
    if lmax <= 8:
        from ._kernels_unrolled import STREAM_KERNELS

        STREAM_KERNELS[lmax](flat, out, a0)
        return
    from ._kernels import sh_rows

    f32 = out.dtype == np.float32 and lmax <= F32_ARITHMETIC_LMAX
    sh_rows(flat, lmax, *_kernel_tables(lmax, np.float32 if f32 else np.float64), out, a0, fresh)


def _unit(flat: NDArray[np.floating]) -> NDArray[np.floating]:
    """Directions normalised without overflow, in their type (non-finite ones refused)."""
    return np.ascontiguousarray(unit_vectors(flat, "directions"), dtype=flat.dtype)
