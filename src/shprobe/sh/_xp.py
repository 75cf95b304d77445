"""The array-API path of the SH maths: torch tensors, JAX arrays (and CuPy) through the same
public functions, one implementation written against the array API standard (via
``array-api-compat``), differentiable by whatever autodiff the namespace has.

The public functions dispatch at their top: `namespace` returns ``None`` for NumPy
input (lists, numbers, ``np.ndarray``), which keeps the numba path untouched, and the
array-API namespace otherwise. Nothing here imports torch, JAX or array-api-compat until an
array of theirs arrives (or a NumPy function runs a reference formula here through
`numpy_namespace`), so ``import shprobe`` stays light.

These functions are the one definition of each formula: the NumPy public functions run them
on NumPy (array-api-compat's namespace) or call a numba kernel tested against them
(docs/architecture.md, "Kernels and their references").

The basis is the normalised recurrence of `shprobe.sh.basis` (Lisle & Huang 2007 §2.1)
written with whole-array operations: P̄_lm(z) by the interior recurrence, (x + iy)^m by the
algebraic edge recurrence, so y_lm is a polynomial in (x, y, z) and its gradient is exact
everywhere (no θ, φ, no division).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ShprobeError

_PLAIN = (np.ndarray, np.generic, list, tuple, int, float, bool)


def namespace(*arrays: Any) -> Any:
    """``None`` when every argument is NumPy-like (the numba path), else the array-API
    namespace of the non-NumPy arrays (one namespace; mixing torch and JAX is refused)."""
    others = [a for a in arrays if a is not None and not isinstance(a, _PLAIN)]
    if not others:
        return None
    try:
        import array_api_compat as aac
    except ImportError:  # pragma: no cover - depends on the installed extras
        if any(type(a).__module__.split(".")[0] in ("torch", "jax", "jaxlib", "cupy")
               for a in others):
            raise ShprobeError("torch/JAX arrays need array-api-compat (a core dependency "
                               "of shprobe): pip install array-api-compat") from None
        return None
    arrs = [a for a in others if aac.is_array_api_obj(a) and not aac.is_numpy_array(a)]
    if not arrs:
        return None
    for a in arrs:
        _check_storage(a)
    try:
        return aac.array_namespace(*arrs)
    except TypeError as e:
        raise ShprobeError(f"arrays of different libraries cannot be mixed: {e}") from None


def _check_storage(a: Any) -> None:
    """Refuse, in one line, tensors whose values cannot be read or computed with: torch's
    meta tensors (no data) and sparse layouts (the formulas need strided arrays)."""
    if getattr(a, "is_meta", False):
        raise ShprobeError("meta tensors hold no values: move the tensor to a real device "
                           "(.to('cpu') or a GPU) first")
    layout = getattr(a, "layout", None)
    if layout is not None and type(a).__module__.split(".")[0] == "torch":
        import torch

        if layout != torch.strided:
            raise ShprobeError(f"{layout} tensors are not supported: pass tensor.to_dense()")


def work_dtype(xp: Any, dt: Any) -> Any:
    """The dtype the formulas compute in for input of dtype ``dt``: float16 and bfloat16 are
    widened to float32 (their range ends at 65504 / their precision at 3 digits, which the
    recurrences pass; the result is cast back), other dtypes are kept."""
    for name in ("float16", "bfloat16"):
        if getattr(xp, name, None) is not None and dt == getattr(xp, name):
            return xp.float32
    if str(dt).rsplit(".", 1)[-1] in ("float16", "bfloat16"):
        return xp.float32
    return dt


def numpy_namespace() -> Any:
    """The array-API namespace of NumPy (array-api-compat's wrapper), on which the NumPy
    public functions run the reference formulas of this module."""
    import array_api_compat.numpy as npx

    return npx


def device_of(x: Any) -> Any:
    """The device of array ``x`` (None for None: NumPy's host)."""
    if x is None:
        return None
    import array_api_compat as aac

    return aac.device(x)


def is_tracing(x: Any) -> bool:
    """True for a JAX tracer (inside jit/grad): its values cannot be checked on the host."""
    mod = type(x).__module__
    if not mod.startswith("jax"):
        return False
    import jax

    return isinstance(x, jax.core.Tracer)


def _is_numpy(xp: Any) -> bool:
    return getattr(xp, "__name__", "") == "array_api_compat.numpy"


def float_dtype(xp: Any, *arrays: Any) -> Any:
    """The floating dtype of the first floating array among ``arrays`` (NumPy arrays count
    when ``xp`` is NumPy's namespace), else the namespace's default float."""
    for a in arrays:
        if a is None or isinstance(a, (list, tuple, int, float, bool)):
            continue
        if isinstance(a, (np.ndarray, np.generic)):
            if _is_numpy(xp) and a.dtype in (np.float32, np.float64):
                return a.dtype
            continue
        if hasattr(a, "dtype") and xp.isdtype(a.dtype, "real floating"):
            return a.dtype
    return xp.asarray(0.0).dtype


def first_array(*arrays: Any) -> Any:
    """The first argument that is an array of a non-NumPy library (None when all are
    NumPy-like: NumPy's namespace)."""
    return next((a for a in arrays if a is not None and not isinstance(a, _PLAIN)), None)


def asarray(xp: Any, x: Any, dtype: Any, like: Any) -> Any:
    """``x`` (an array of ``xp``, NumPy or a number) as an ``xp`` array of ``dtype`` on the
    device of ``like``; complex and non-numeric input is refused in one line."""
    if isinstance(x, _PLAIN):
        a = np.asarray(x)
        if a.dtype.kind not in "fiub":
            raise ShprobeError(f"expected real numbers, got {a.dtype}")
        return xp.asarray(a, dtype=dtype, device=device_of(like))
    if not xp.isdtype(x.dtype, ("real floating", "integral", "bool")):
        raise ShprobeError(f"expected real numbers, got {x.dtype}")
    return xp.astype(x, dtype) if x.dtype != dtype else x


def host_float(x: Any) -> float:
    """A 0-d array's value on the host (a check, outside any gradient)."""
    detach = getattr(x, "detach", None)
    return float(detach() if detach is not None else x)


def check_finite(xp: Any, x: Any, what: str) -> None:
    """One [`ShprobeError`][shprobe.errors.ShprobeError] for NaN or infinity (skipped while JAX
    traces)."""
    if is_tracing(x):
        return
    if not bool(xp.all(xp.isfinite(x))):
        raise ShprobeError(f"{what} contain NaN or infinity")


def unit_vectors(xp: Any, d: Any, what: str = "direction") -> Any:
    """Unit vectors (..., 3) without overflow (scaled by the largest component first); zero
    and non-finite vectors refused (the policy of `shprobe.sh.rotation.unit_vectors`)."""
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"{what} must have shape (..., 3), got {tuple(d.shape)}")
    check_finite(xp, d, what + "s")
    big = xp.max(xp.abs(d), axis=-1, keepdims=True)
    if not is_tracing(big) and bool(xp.any(big == 0)):
        raise ShprobeError(f"{what} must be a non-zero vector")
    safe = xp.where(big > 0, big, xp.ones_like(big))
    s = d / safe
    n = xp.sqrt(xp.sum(s * s, axis=-1, keepdims=True))
    return s / n


def sh_basis(xp: Any, d: Any, lmax: int) -> Any:
    """y_lm (..., K) of directions ``d`` (..., 3) of ``xp`` (see the module doc). Directions
    are used as given when they are near unit (the same rule as the NumPy path)."""
    from .indexing import NEAR_UNIT, recurrence_tables

    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"directions must have shape (..., 3), got {tuple(d.shape)}")
    if not is_tracing(d) and d.shape[0] != 0:
        sq = host_float(xp.sum(d * d))
        n = max(1, int(np.prod(d.shape[:-1])))
        if not sq <= NEAR_UNIT * n:  # NaN, inf, overflow or far from unit length
            d = unit_vectors(xp, d, "direction")
    # contiguous x, y, z (strided views make every operation slower), and the K columns
    # stacked along a new first axis then moved last (a view): stacking on the last axis
    # directly writes with stride K
    x, y, z = _unstack3(xp, d)
    a, b = recurrence_tables(lmax)
    cols: list[Any] = [None] * ((lmax + 1) ** 2)
    pmm = xp.full_like(x, 0.5 / np.sqrt(np.pi))
    cols[0] = pmm
    c = s = None  # Re, Im (x + iy)^m
    for m in range(lmax + 1):
        if m == 1:
            c, s = x, y
            pmm = pmm * float(np.sqrt(3.0 / 2.0) * np.sqrt(2.0))  # √2 folded in for m > 0
        elif m > 1:
            c, s = x * c - y * s, x * s + y * c
            pmm = pmm * float(np.sqrt((2.0 * m + 1.0) / (2.0 * m)))
        p2 = pmm
        _put(cols, m, m, p2, c, s)
        if m + 1 <= lmax:
            p1 = float(np.sqrt(2.0 * m + 3.0)) * (z * pmm)
            _put(cols, m + 1, m, p1, c, s)
            for l in range(m + 2, lmax + 1):
                p = float(a[l, m]) * (z * p1) - float(a[l, m] * b[l, m]) * p2
                _put(cols, l, m, p, c, s)
                p2, p1 = p1, p
    return xp.moveaxis(xp.stack(cols, axis=0), 0, -1)


def _unstack3(xp: Any, d: Any) -> tuple[Any, Any, Any]:
    flat = xp.asarray(xp.reshape(xp.moveaxis(d, -1, 0), (3, -1)), copy=True)
    shape = tuple(d.shape[:-1])
    return tuple(xp.reshape(flat[i, :], shape) for i in range(3))  # type: ignore[return-value]


def _put(cols: list[Any], l: int, m: int, p: Any, c: Any, s: Any) -> None:
    k0 = l * (l + 1)
    if m == 0:
        if l > 0:
            cols[k0] = p
        return
    cols[k0 + m] = p * c
    cols[k0 - m] = p * s


def band_factors(xp: Any, factors: Any, lmax: int, dtype: Any, like: Any) -> Any:
    """Per-band ``factors`` (≥ lmax + 1) spread to per-coefficient (K,) in ``xp``."""
    from .indexing import degrees

    f = factors if not isinstance(factors, _PLAIN) else np.asarray(factors, dtype=np.float64)
    if f.shape[-1] < lmax + 1:
        raise ShprobeError(f"need {lmax + 1} band factors, got {f.shape[-1]}")
    idx = degrees(lmax)
    if isinstance(f, np.ndarray):
        return xp.asarray(f[..., idx], dtype=dtype, device=device_of(like))
    f = asarray(xp, f, dtype, like)
    return xp.take(f, xp.asarray(idx, device=device_of(f)), axis=f.ndim - 1)


def convolve(xp: Any, coeffs: Any, factors: Any) -> Any:
    """Band l times ``factors[l]`` for (..., K, C) or (K,) coefficients of ``xp`` (the
    Funk–Hecke convolution with a zonal kernel); NaN or infinity in either is refused."""
    from .indexing import lmax_of

    dt = float_dtype(xp, coeffs, factors)
    like = first_array(coeffs, factors)
    c = asarray(xp, coeffs, dt, like)
    if c.ndim == 0:
        raise ShprobeError("coefficients must have shape (..., K, C) or (K,)")
    check_finite(xp, c, "coefficients")
    lmax = lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    per_k = band_factors(xp, factors, lmax, dt, like)
    check_finite(xp, per_k, "band factors")
    return c * (per_k if c.ndim == 1 else per_k[..., None])


def constant(xp: Any, table: Any, like: Any, dtype: Any = None) -> Any:
    """A NumPy table as an ``xp`` array on ``like``'s device, in ``dtype`` (default: the
    float dtype of ``like``)."""
    dt = dtype if dtype is not None else float_dtype(xp, like)
    return xp.asarray(np.array(table, dtype=np.float64), dtype=dt, device=device_of(like))
