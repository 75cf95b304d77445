"""Projection onto SH (R&H 2001 eq. 10): lighting coefficients from an environment map or from
weighted samples.

- :func:`project` — L_lm = Σ_pixels L(ω) y_lm(ω) dω, any lmax. Lat-long maps use their
  separability (thesis §4.2): per row a cos/sin(mψ) matrix product over the columns, then the
  normalised associated Legendre functions in θ per row. The rows of a lat-long map are circles
  about +Y, so the sum is done in the frame ω' = (z, x, y) whose pole is +Y and turned back by
  one fixed per-band rotation. Other layouts sum over their samples (one numba pass).
- :func:`project_samples` — Σ_s v_s y(d_s) w_s for any samples, no (S, K) temporary.
"""

from __future__ import annotations

import os
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..probes.layouts import Env, LatLong
from ..sh import check_lmax, lmax_of, num_coeffs, recurrence_tables, sh_basis

__all__ = ["project", "project_samples", "total_intensity"]

# Frame whose pole is +Y: ω' = Q ω = (z, x, y) (a cyclic permutation, so a proper rotation).
_Q = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])



@lru_cache(maxsize=32)
def _frame_blocks(lmax: int) -> tuple[NDArray[np.float64], ...]:
    """Per band l, D_l with y_l(Qω) = D_l y_l(ω), computed by a quadrature that is exact for
    band-limited products (Gauss–Legendre in z × uniform φ)."""
    n = lmax + 1
    z, wz = np.polynomial.legendre.leggauss(n)
    nphi = 2 * lmax + 2
    phi = 2.0 * np.pi * np.arange(nphi) / nphi
    s = np.sqrt(1.0 - z * z)
    dirs = np.stack(
        [s[:, None] * np.cos(phi)[None], s[:, None] * np.sin(phi)[None],
         np.broadcast_to(z[:, None], (n, nphi))], axis=-1).reshape(-1, 3)
    w = np.repeat(wz * (2.0 * np.pi / nphi), nphi)
    y = sh_basis(dirs, lmax)
    yq = sh_basis(dirs @ _Q.T, lmax)
    blocks = []
    for l in range(lmax + 1):
        sl = slice(l * l, (l + 1) ** 2)
        blocks.append((yq[:, sl] * w[:, None]).T @ y[:, sl])
    return tuple(blocks)


def _from_pole_y(cp: NDArray[np.float64]) -> NDArray[np.float64]:
    """Coefficients in the world frame from those in the frame ω' = Qω: c = Dᵀ c'.

    c' are the coefficients of f∘Q⁻¹, so c = rotate(c', Q⁻¹). Up to lmax 12 the per-band D is
    built here by exact quadrature (independent of shprobe.rotation); above, by the Wigner
    recurrence of :func:`shprobe.rotation.rotate`, which needs no (nodes × K) table.
    """
    lmax = lmax_of(cp.shape[0])
    if lmax > 12:
        from ..sh.rotation import rotate

        return np.asarray(rotate(cp, _Q.T), dtype=np.float64)
    out = np.empty_like(cp)
    for l, d in enumerate(_frame_blocks(lmax)):
        sl = slice(l * l, (l + 1) ** 2)
        out[sl] = d.T @ cp[sl]
    return out


@lru_cache(maxsize=16)
def _latlong_tables(h: int, w: int, lmax: int) -> tuple[NDArray[np.float32], NDArray[np.float64],
                                                        NDArray[np.int64]]:
    """(trig (M, W) float32 for m = −lmax..lmax, row weights (H, K) = dω_row Λ_l|m|(θ_row),
    index of the trig row of each k)."""
    psi = LatLong.column_azimuth(w)
    m = np.arange(-lmax, lmax + 1)
    # in the frame ω' the azimuth is φ' = −ψ: cos(mφ') = cos(mψ), sin(|m|φ') = −sin(|m|ψ)
    trig = np.where(m[:, None] >= 0, np.cos(np.abs(m)[:, None] * psi[None]),
                    -np.sin(np.abs(m)[:, None] * psi[None]))
    theta = LatLong.row_theta(h)
    pole = np.stack([np.sin(theta), np.zeros(h), np.cos(theta)], axis=-1)
    lam = sh_basis(pole, lmax)  # y_l|m| at φ' = 0: √2 P̄_l|m| sin^|m| θ (m > 0), P̄_l0 (m = 0)
    ks = np.arange(num_coeffs(lmax))
    ls = np.floor(np.sqrt(ks)).astype(np.int64)
    ms = ks - ls * (ls + 1)
    weights = lam[:, ls * (ls + 1) + np.abs(ms)] * LatLong.row_solid_angle(h, w)[:, None]
    trig = np.ascontiguousarray(trig, dtype=np.float32)
    trig.flags.writeable = False
    weights.flags.writeable = False
    return trig, weights, ms + lmax


def _project_latlong(rad: NDArray[np.float32], lmax: int, threads: int | None = None
                     ) -> NDArray[np.float64]:
    """The separable transform: per row Σ_ψ L cos/sin(mψ) (one BLAS product per row, the rows
    split over ``threads`` threads — default: the machine's cores, for images of ≥ 2²⁰ pixels),
    then Σ_θ with the row weights dω_row Λ_l|m|(θ_row)."""
    h, w = rad.shape[:2]
    trig, weights, mrow = _latlong_tables(h, w, lmax)
    if rad.dtype != np.float32:
        rad = rad.astype(np.float32)
    f = np.empty((h, trig.shape[0], rad.shape[2]), np.float32)  # (H, M, C)
    n = threads if threads is not None else (os.cpu_count() or 1) if h * w >= 1 << 20 else 1
    n = max(1, min(int(n), 16, h))
    if n == 1:
        np.matmul(trig[None], rad, out=f)
    else:  # numpy releases the GIL in matmul
        from concurrent.futures import ThreadPoolExecutor

        cuts = np.linspace(0, h, n + 1).astype(int)
        with ThreadPoolExecutor(n) as pool:
            list(pool.map(lambda a, b: np.matmul(trig[None], rad[a:b], out=f[a:b]),
                          cuts[:-1], cuts[1:]))
    cp = np.einsum("hk,hkc->kc", weights, f[:, mrow, :].astype(np.float64))
    return _from_pole_y(cp)


def project_samples(dirs: ArrayLike, values: ArrayLike, weights: ArrayLike | None = None,
                    lmax: int = 2) -> NDArray[np.float64]:
    """Σ_s values_s y_lm(dirs_s) weights_s → (K, C) (or (K,) for 1-D values).

    ``dirs`` (S, 3) unit vectors, ``values`` (S, C) or (S,), ``weights`` (S,) (e.g. solid
    angles; default 4π/S, i.e. uniform random samples). A numba kernel, no (S, K) temporary.
    """
    lmax = check_lmax(lmax)
    d = np.ascontiguousarray(np.asarray(dirs, dtype=np.float64).reshape(-1, 3))
    v = np.asarray(values, dtype=np.float64)
    one = v.ndim == 1
    v = np.ascontiguousarray(v.reshape(d.shape[0], -1))
    if weights is None:
        wt = np.full(d.shape[0], 4.0 * np.pi / max(d.shape[0], 1))
    else:
        wt = np.ascontiguousarray(np.asarray(weights, dtype=np.float64).reshape(-1))
    if wt.shape[0] != d.shape[0] or v.shape[0] != d.shape[0]:
        raise ShprobeError(f"{d.shape[0]} directions, {v.shape[0]} values, {wt.shape[0]} weights")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(wt))):
        raise ShprobeError("values or weights contain NaN or Inf")
    out = _project_kernel(d, v, wt, lmax)
    return out[:, 0] if one else out


def _project_kernel(d: NDArray, v: NDArray, wt: NDArray, lmax: int) -> NDArray[np.float64]:
    """Σ_s v_s y(d_s) w_s by the 3-channel numba kernel (other channel counts in groups of 3)."""
    a, b = recurrence_tables(lmax)
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    nblk = max(1, min(64, d.shape[0] // 4096))
    kern = _kernels()["project_rgb"]
    nc = v.shape[1]
    if nc == 3:
        return kern(d, v, wt, lmax, a, b, nblk).sum(axis=0)
    groups = -(-nc // 3)
    vp = np.zeros((v.shape[0], 3 * groups), dtype=v.dtype)
    vp[:, :nc] = v
    out = [kern(d, np.ascontiguousarray(vp[:, 3 * g: 3 * g + 3]), wt, lmax, a, b,
                nblk).sum(axis=0) for g in range(groups)]
    return np.concatenate(out, axis=1)[:, :nc]


def project(env: Env, lmax: int = 2) -> NDArray[np.float64]:
    """Lighting coefficients L_lm = Σ_pixels L(ω) y_lm(ω) dω (R&H eq. 10) → (K, 3) float64.

    Lat-long maps take the separable path (cos/sin matrix product per row, rows spread over the
    machine's cores, then the normalised Legendre functions in θ); other layouts run one numba
    pass over the pixels with the layout's (cached) direction and solid-angle tables, skipping
    pixels with dω = 0.
    """
    lmax = check_lmax(lmax)
    if not isinstance(env, Env):
        raise ShprobeError("project() needs an Env (see shprobe.load_env)")
    if env.layout.name == "latlong":
        return _project_latlong(env.radiance, lmax)
    d = np.ascontiguousarray(env.directions(), dtype=np.float64).reshape(-1, 3)
    dw = np.ascontiguousarray(env.solid_angles(), dtype=np.float64).reshape(-1)
    rad = env.radiance.reshape(-1, env.radiance.shape[-1])
    return _project_kernel(d, rad, dw, lmax)


def total_intensity(env: Env) -> NDArray[np.float64]:
    """∫ L dω per channel, (3,)."""
    dw = env.solid_angles()
    rad = env.radiance.reshape(-1, env.radiance.shape[-1]).astype(np.float64)
    return dw.reshape(-1) @ rad


def _kernels() -> dict[str, Any]:
    from . import _kernels as k  # numba, imported lazily

    return {"project_rgb": k.project_rgb_kernel, "brute": k.brute_kernel,
            "brute_serial": k.brute_serial}
