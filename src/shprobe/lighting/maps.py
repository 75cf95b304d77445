"""Images ↔ coefficients as plain array functions, batched over leading axes and
differentiable when the arrays are torch tensors or JAX arrays (one implementation written
against the array API; NumPy arrays work the same way, in float64).

- [`project_latlong`][shprobe.lighting.maps.project_latlong] — (..., H, W, C) lat-long radiance →
  (..., K, C) lighting coefficients with the exact pixel solid angles (R&H 2001 eq. 10), equal to
  [`shprobe.lighting.projection.project`][shprobe.lighting.project] of the same image;
- [`project_cube`][shprobe.lighting.maps.project_cube] — (..., 6, N, N, C) cube faces (shprobe's
  face order and orientation, [`shprobe.probes.layouts.Cube`][shprobe.probes.layouts.Cube]) → (...,
  K, C), exact texel solid angles;
- [`latlong_radiance`][shprobe.lighting.maps.latlong_radiance],
  [`latlong_irradiance`][shprobe.lighting.maps.latlong_irradiance] — (..., K, C) coefficients → the
  (..., H, W, C) lat-long map of L(ω) or of E(n) = Σ Â_l L_lm y_lm(n) (R&H eq. 7).

The lat-long transforms are separable (as ``project``'s): the rows of a lat-long map are
circles about +Y, so in the frame ω' = (z, x, y) whose pole is +Y each y'_lm is
Λ_l|m|(θ_row) · trig_m(ψ_column). A transform is three matrix products with cached tables —
(M, W) trig, (M, L, H) row weights, and the (K, M·L) matrix that gathers the (m, l) grid and
turns the pole-Y frame back — never a (pixels × K) table.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..probes.layouts import Cube, LatLong
from ..sh import _xp, check_lmax, lmax_of, num_coeffs, sh_basis
from ..sh.zonal import clamped_cosine_factors

__all__ = ["latlong_irradiance", "latlong_radiance", "project_cube", "project_latlong"]


@lru_cache(maxsize=16)
def _latlong_tables(h: int, w: int, lmax: int) -> tuple[NDArray[np.float64], ...]:
    """float64 (trig (M, W); lam (M, L, H) = Λ_l|m|(θ_row), zero for l < |m|; dω per row
    (H,); A (K, M·L) gathering the (m, l) grid and turning the frame ω' = (z, x, y) back)."""
    from .projection import _from_pole_y, latlong_pole_factors

    trig, lam, mi, li = latlong_pole_factors(h, w, lmax)
    k = np.arange(mi.size)
    sel = np.zeros((k.size, lam.shape[0] * lam.shape[1]))
    sel[k, mi * lam.shape[1] + li] = 1.0
    A = _from_pole_y(sel)  # c = A g: the world-frame coefficients of the (m, l) grid g
    out = (trig, lam, LatLong.row_solid_angle(h, w), A)
    for t in out:
        t.flags.writeable = False
    return out


def _setup(a: Any, what: str) -> tuple[Any, Any, Any]:
    """(namespace, array, dtype): NumPy input is computed in float64 with NumPy itself."""
    xp = _xp.namespace(a)
    if xp is None:
        try:
            arr = np.asarray(a, dtype=np.float64)
        except (TypeError, ValueError):
            raise ShprobeError(f"{what} must be a real numeric array") from None
        if not np.isfinite(arr).all():
            raise ShprobeError(f"{what} contain NaN or infinity")
        return np, arr, np.float64
    dt = _xp.float_dtype(xp, a)
    arr = _xp.asarray(xp, a, dt, a)
    _xp.check_finite(xp, arr, what)
    return xp, arr, dt


def _table(xp: Any, t: NDArray[np.float64], like: Any, dt: Any) -> Any:
    return t if xp is np else _xp.constant(xp, t, like, dt)


def project_latlong(radiance: Any, lmax: int = 2) -> Any:
    """Lighting coefficients (..., K, C) of lat-long radiance maps (..., H, W, C), W = 2H,
    row 0 = +Y (the [`LatLong`][shprobe.probes.layouts.LatLong] layout), with exact solid
    angles: L_lm = Σ_pixels L(ω) y_lm(ω) dω (R&H eq. 10).

    Parameters
    ----------
    radiance
        (..., H, W, C) lat-long maps, W = 2H (NumPy, torch or JAX).
    lmax
        The highest degree.

    Returns
    -------
    array of shape (..., K, C)
        The lighting coefficients, of the input's kind.
    """
    lmax = check_lmax(lmax)
    xp, rad, dt = _setup(radiance, "radiance values")
    if rad.ndim < 3:
        raise ShprobeError(f"radiance must be (..., H, W, C), got shape {tuple(rad.shape)}")
    h, w = LatLong().check_grid(tuple(rad.shape[-3:-1]))
    batch, nch = tuple(rad.shape[:-3]), int(rad.shape[-1])
    nb = int(np.prod(batch)) if batch else 1
    m, k = 2 * lmax + 1, num_coeffs(lmax)
    # the batch folded into the columns of three 2-D/3-D products (no broadcast copies of
    # the tables): the maps transposed (W, H·B·C), f (M, H, B·C), g (M·L, B·C), the result
    # and its transpose; then the tables
    check_memory(8.0 * (nb * nch * (h * w + m * h + m * (lmax + 1) + 2 * k)
                        + m * (w + (lmax + 1) * (h + k))),
                 f"projecting {nb} {w}x{h} lat-long map{'s' * (nb != 1)} to lmax {lmax}")
    trig, lam, dw, A = (_table(xp, t, rad, dt) for t in _latlong_tables(h, w, lmax))
    r = _permute(xp, xp.reshape(rad, (nb, h, w, nch)), (2, 1, 0, 3))  # (W, H, B, C)
    f = xp.matmul(trig, xp.reshape(r, (w, h * nb * nch)))  # per row Σ_ψ L trig_m(ψ)
    g = xp.matmul(lam * dw, xp.reshape(f, (m, h, nb * nch)))  # (M, L, B·C)
    out = xp.matmul(A, xp.reshape(g, (m * (lmax + 1), nb * nch)))  # (K, B·C)
    out = _permute(xp, xp.reshape(out, (k, nb, nch)), (1, 0, 2))
    return xp.reshape(out, (*batch, k, nch))


def _permute(xp: Any, a: Any, axes: tuple[int, ...]) -> Any:
    """``permute_dims`` (``transpose`` for NumPy before 2.0)."""
    f = getattr(xp, "permute_dims", None)
    return f(a, axes) if f is not None else xp.transpose(a, axes)


def latlong_radiance(coeffs: Any, size: int = 64) -> Any:
    """The lat-long map (..., H, W, C) of L(ω) = Σ L_lm y_lm(ω) from coefficients
    (..., K, C) (or (K,) → (H, W)), H = ``size``, W = 2H, pixel centres as
    [`LatLong`][shprobe.probes.layouts.LatLong]; the adjoint of
    [`project_latlong`][shprobe.lighting.maps.project_latlong]'s transform without the solid
    angles.

    Parameters
    ----------
    coeffs
        (..., K, C) or (K,) lighting coefficients.
    size
        H; W = 2H.

    Returns
    -------
    array of shape (..., H, W, C) or (H, W)
        L(ω) at the pixel centres.
    """
    xp, c, dt = _setup(coeffs, "coefficients")
    if c.ndim == 0:
        raise ShprobeError("coefficients must be (..., K, C) or (K,)")
    one = c.ndim == 1
    if one:
        c = c[:, None]
    lmax = lmax_of(c.shape[-2])
    h, w = LatLong().grid_shape(int(size))
    check_memory(8.0 * h * w * c.shape[-1] * max(1, int(np.prod(c.shape[:-2]))),
                 f"{w}x{h} lat-long maps")
    trig, lam, _, A = (_table(xp, t, c, dt) for t in _latlong_tables(h, w, lmax))
    M, L = lam.shape[0], lam.shape[1]
    g = xp.matmul(xp.matrix_transpose(A), c)  # (..., M·L, C) in the pole-Y frame
    g = xp.reshape(g, (*g.shape[:-2], M, L, g.shape[-1]))
    f = xp.matmul(xp.matrix_transpose(lam), g)  # (..., M, H, C)
    f = _moveaxis(xp, f, -3, -2)  # (..., H, M, C)
    out = xp.matmul(xp.matrix_transpose(trig), f)  # (..., H, W, C)
    return out[..., 0] if one else out


def latlong_irradiance(coeffs: Any, size: int = 64) -> Any:
    """The lat-long map of irradiance E(n) = Σ Â_l L_lm y_lm(n) (R&H eq. 7, not divided by
    π) from lighting coefficients (..., K, C) or (K,).

    Parameters
    ----------
    coeffs
        (..., K, C) or (K,) lighting coefficients.
    size
        H; W = 2H.

    Returns
    -------
    array of shape (..., H, W, C) or (H, W)
        E(n) at the pixel centres.
    """
    xp, c, dt = _setup(coeffs, "coefficients")
    if c.ndim == 0:
        raise ShprobeError("coefficients must be (..., K, C) or (K,)")
    lmax = lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    per_k = np.repeat(clamped_cosine_factors(lmax), 2 * np.arange(lmax + 1) + 1)
    f = _table(xp, per_k, c, dt)
    return latlong_radiance(c * (f if c.ndim == 1 else f[:, None]), size)


@lru_cache(maxsize=8)
def _cube_table(n: int, lmax: int) -> NDArray[np.float64]:
    """(K, 6N²): y_lm(texel centre) · exact texel solid angle."""
    cube = Cube()
    d = cube.pixel_directions((6, n, n)).reshape(-1, 3)
    dw = cube.solid_angles((6, n, n)).reshape(-1)
    t = np.ascontiguousarray((sh_basis(d, lmax) * dw[:, None]).T)
    t.flags.writeable = False
    return t


def project_cube(radiance: Any, lmax: int = 2) -> Any:
    """Lighting coefficients (..., K, C) of cube maps (..., 6, N, N, C) — faces +X −X +Y −Y
    +Z −Z as [`Cube`][shprobe.probes.layouts.Cube] orders and orients them — with the exact
    texel solid angles (the sum of
    [`shprobe.lighting.projection.project`][shprobe.lighting.project]).

    Parameters
    ----------
    radiance
        (..., 6, N, N, C) cube maps (NumPy, torch or JAX).
    lmax
        The highest degree.

    Returns
    -------
    array of shape (..., K, C)
        The lighting coefficients, of the input's kind.
    """
    lmax = check_lmax(lmax)
    xp, rad, dt = _setup(radiance, "radiance values")
    if rad.ndim < 4 or rad.shape[-4] != 6 or rad.shape[-3] != rad.shape[-2]:
        raise ShprobeError(f"cube radiance must be (..., 6, N, N, C), got {tuple(rad.shape)}")
    n = int(rad.shape[-2])
    check_memory(8.0 * 6 * n * n * num_coeffs(lmax), f"the SH table of a {n}² cube map")
    t = _table(xp, _cube_table(n, lmax), rad, dt)
    flat = xp.reshape(rad, (*rad.shape[:-4], 6 * n * n, rad.shape[-1]))
    return xp.matmul(t, flat)


def _moveaxis(xp: Any, a: Any, src: int, dst: int) -> Any:
    """``moveaxis`` of two adjacent axes for namespaces without it (a permutation)."""
    if hasattr(xp, "moveaxis"):
        return xp.moveaxis(a, src, dst)
    axes = list(range(a.ndim))
    s, d = src % a.ndim, dst % a.ndim
    axes.insert(d, axes.pop(s))
    return xp.permute_dims(a, tuple(axes))
