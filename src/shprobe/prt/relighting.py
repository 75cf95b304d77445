"""Run time: rotate the lighting into the scene's frame and dot it with the transfer vectors
(Lisle & Huang 2007 §1 step 2–3 and §4).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import lmax_of, num_coeffs
from ..sh.rotation import one_rotation, rotate
from .transfer import Transfer


def scene_lighting(coeffs: ArrayLike, rotation: ArrayLike | None = None) -> NDArray[np.float64]:
    """Lighting coefficients (K, C) seen in the frame of a scene turned by ``rotation``.

    Turning the scene by R relative to the lighting is turning the lighting by R⁻¹:
    L' = rotate(L, R⁻¹), the coefficients of L∘R.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim == 1:
        c = c[:, None]
    if c.ndim != 2:
        raise ShprobeError(f"lighting coefficients must be (K,) or (K, C), got {c.shape}")
    lmax_of(c.shape[0])
    if rotation is None:
        return c
    return np.asarray(rotate(c, one_rotation(rotation).T), dtype=np.float64)


def relight(transfer: Transfer | ArrayLike, coeffs: ArrayLike, rotation: ArrayLike | None = None,
            lmax: int | None = None, mode: str | None = None,
            bounces: int | None = None) -> NDArray[np.float32]:
    """Per-vertex exit radiance (V, 3) = transfer · rotate(L, R⁻¹), per channel (LH §4).

    transfer: a [`Transfer`][shprobe.prt.Transfer] or a (V, K) / (V, K, 3) transfer array. coeffs:
    lighting L_lm
    (K', 3) or (K',) (grey). rotation: 3×3 rotation of the scene relative to the lighting (None:
    none). lmax: degree to use (default: the smaller of the transfer's and the lighting's) — the
    first (lmax+1)² transfer columns, no re-bake. mode, bounces: the model, picked at run time
    from a [`Transfer`][shprobe.prt.Transfer] ([`Transfer.select`][shprobe.prt.Transfer.select]:
    'unshadowed' always, 'shadowed' when the bake cast rays, 'interreflected' with at most the baked
    bounces; default the baked model). For the unshadowed model with albedo ρ the result is ρ/π ·
    E(n) (R&H eq. 7).
    """
    if isinstance(transfer, Transfer):
        lt = transfer.lmax
    else:
        if mode is not None or bounces is not None:
            raise ShprobeError("mode and bounces pick a model of a Transfer, not of an array")
        t = _numbers(transfer, "transfer")
        if t.ndim not in (2, 3) or (t.ndim == 3 and t.shape[2] != 3):
            raise ShprobeError(f"transfer must be (V, K) or (V, K, 3), got {t.shape}")
        lt = lmax_of(t.shape[1])
    c = _numbers(coeffs, "lighting coefficients")
    if c.ndim not in (1, 2):
        raise ShprobeError(f"lighting coefficients must be (K,) or (K, C), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ShprobeError("lighting coefficients hold NaN or infinity")
    lc = lmax_of(c.shape[0])
    use = min(lt, lc) if lmax is None else int(lmax)
    if use > min(lt, lc) or use < 0:
        have = "the transfer" if lt < lc else "the lighting"
        raise ShprobeError(f"lmax={use} not available: the transfer has degree {lt} and the "
                           f"lighting degree {lc} ({(lc + 1) ** 2} coefficients); the highest "
                           f"usable is {min(lt, lc)}, set by {have} — project the lighting "
                           f"with lmax={use} or more, or pass lmax<={min(lt, lc)}")
    k = num_coeffs(use)
    if isinstance(transfer, Transfer):
        tk = transfer.select(mode, bounces, use)
    else:
        tk = t[:, :k]
    light = scene_lighting(c[:k], rotation)
    if light.shape[1] == 1:
        light = np.repeat(light, 3, axis=1)
    if light.shape[1] != 3:
        raise ShprobeError(f"lighting must have 1 or 3 channels, got {light.shape[1]}")
    light = light.astype(tk.dtype if tk.dtype in (np.float32, np.float64) else np.float64)
    with np.errstate(invalid="ignore", over="ignore"):  # refused below, in one line
        if tk.ndim == 2:
            out = np.asarray(tk @ light, dtype=np.float32)
        else:
            # one matmul: (V, K·3) @ (K·3, 3), the lighting on the block diagonal per channel
            m = np.zeros((k, 3, 3), dtype=light.dtype)
            m[:, [0, 1, 2], [0, 1, 2]] = light
            out = np.asarray(tk.reshape(tk.shape[0], k * 3) @ m.reshape(k * 3, 3),
                             dtype=np.float32)
    # the lighting is finite (checked above): a non-finite radiance is a non-finite transfer
    # (or an overflow), found here on the (V, 3) result rather than on the (V, K, C) input
    if not np.all(np.isfinite(out)):
        raise ShprobeError("relit radiance is not finite: the transfer holds NaN or infinity "
                           "(or the product overflows float32)")
    return out


def _numbers(value: ArrayLike, what: str) -> NDArray:
    """``value`` as a float array (kept float32 when it is), or one line saying it is not
    numbers."""
    try:
        a = np.asarray(value)
        if a.dtype.kind not in "f":
            a = a.astype(np.float64)
    except (TypeError, ValueError):
        raise ShprobeError(f"{what} must be numbers") from None
    return a
