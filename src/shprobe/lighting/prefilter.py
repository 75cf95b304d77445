"""Prefiltering (R&H 2001 eq. 10), irradiance (eq. 7, 11–13), the brute-force reference and the
error report.

- :func:`project` — lighting coefficients L_lm = Σ_pixels L(ω) y_lm(ω) dω (R&H eq. 10), any
  lmax. Lat-long maps use their separability (thesis §4.2): per row a cos/sin(mψ) matrix product
  over the columns, then the normalised associated Legendre functions in θ per row. The rows of
  a lat-long map are circles about +Y, so the sum is done in the frame ω' = (z, x, y) whose pole
  is +Y and turned back by one fixed per-band rotation. Other layouts sum over their samples.
- :func:`irradiance` — E(n) = Σ Â_l L_lm y_lm(n) (eq. 7) for any lmax;
  :func:`irradiance_matrix` (eq. 11–12), :func:`irradiance_quadratic` (eq. 13),
  :func:`irradiance_from_matrix` (nᵀMn with n = (x, y, z, 1)).
- :func:`reference_irradiance` — Σ_pixels L max(0, n·ω) dω, O(T·S), numba, chunked.
- :func:`error_report` — R&H's metric: |E_SH − E_ref| as a fraction of ∫L dω.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._version import __version__
from ..errors import ShprobeError
from ..probes.layouts import Env, Layout, get_layout, load_env
from ..sh import check_lmax, lmax_of, num_coeffs, recurrence_tables, sh_basis
from ..sh.zonal import clamped_cosine_factors, convolve

__all__ = [
    "RH_CONSTANTS",
    "ErrorReport",
    "ErrorRow",
    "coeffs_document",
    "error_report",
    "irradiance",
    "irradiance_from_matrix",
    "irradiance_map",
    "irradiance_matrix",
    "irradiance_quadratic",
    "load_env",
    "project",
    "project_samples",
    "read_coeffs_json",
    "reference_irradiance",
    "total_intensity",
]

#: Row labels of R&H Fig. 2 for k = 0..8.
RH_LABELS = ("L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22")

# Frame whose pole is +Y: ω' = Q ω = (z, x, y) (a cyclic permutation, so a proper rotation).
_Q = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


# ----------------------------------------------------------------------------- projection


def _check_coeffs(coeffs: ArrayLike) -> NDArray[np.float64]:
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim == 0:
        raise ShprobeError("coefficients must be an array (K,) or (..., K, C)")
    lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    return c


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
                                                        NDArray[np.int64], NDArray[np.int64]]:
    """(trig (M, W) float32 for m = −lmax..lmax; row weights by m, (M, lmax+1, H) float64:
    [m, l, row] = dω_row Λ_l|m|(θ_row), zero for l < |m|; the (m, l) place of each k)."""
    from ..probes.layouts import LatLong

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
    by_m = np.zeros((2 * lmax + 1, lmax + 1, h))
    by_m[ms + lmax, ls] = weights.T
    trig = np.ascontiguousarray(trig, dtype=np.float32)
    for t in (trig, by_m):
        t.flags.writeable = False
    return trig, by_m, ms + lmax, ls


#: Below this many multiply-adds (pixels × channels × (2 lmax + 1)) the per-row products run
#: on one thread: starting threads and splitting the rows costs more than they save there
#: (2²⁶: 1024×512 at lmax 8 and 2048×1024 at lmax 2 stay on one thread, 4096×2048 splits).
LATLONG_THREAD_MIN_WORK = 1 << 26


def _latlong_threads(work: int) -> int:
    """Threads for ``work`` multiply-adds of per-row products: one below
    ``LATLONG_THREAD_MIN_WORK``; above, the cores that are idle (cores − 1-minute load
    average, counting this one), at least one — on a saturated machine extra threads only
    queue behind other work and the split costs more than it gives."""
    cores = os.cpu_count() or 1
    if work < LATLONG_THREAD_MIN_WORK or cores == 1:
        return 1
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - platforms without a load average
        load = 0.0
    return max(1, min(cores, int(cores - load + 1.0)))


def _project_latlong(rad: NDArray[np.float32], lmax: int, threads: int | None = None
                     ) -> NDArray[np.float64]:
    """The separable transform: per row Σ_ψ L cos/sin(mψ) (one BLAS product per row; the rows
    split over ``threads`` threads — default :func:`_latlong_threads`: one below
    ``LATLONG_THREAD_MIN_WORK`` multiply-adds, else the idle cores), then Σ_θ with the row weights
    dω_row Λ_l|m|(θ_row), one batched product over m."""
    h, w = rad.shape[:2]
    trig, by_m, mi, li = _latlong_tables(h, w, lmax)
    if rad.dtype != np.float32:
        rad = rad.astype(np.float32)
    f = np.empty((h, trig.shape[0], rad.shape[2]), np.float32)  # (H, M, C)
    if threads is None:
        threads = _latlong_threads(h * w * rad.shape[2] * trig.shape[0])
    n = max(1, min(int(threads), 16, h))
    if n == 1:
        np.matmul(trig[None], rad, out=f)
    else:  # numpy releases the GIL in matmul; the calling thread takes the first share
        import threading

        cuts = np.linspace(0, h, n + 1).astype(int)

        def rows(a: int, b: int) -> None:
            np.matmul(trig[None], rad[a:b], out=f[a:b])

        pool = [threading.Thread(target=rows, args=(cuts[i], cuts[i + 1])) for i in range(1, n)]
        for t in pool:
            t.start()
        rows(cuts[0], cuts[1])
        for t in pool:
            t.join()
    g = np.matmul(by_m, f.transpose(1, 0, 2).astype(np.float64))  # (M, lmax+1, C)
    return _from_pole_y(g[mi, li])


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


# ----------------------------------------------------------------------------- irradiance


def irradiance_coeffs(coeffs: ArrayLike) -> NDArray[np.float64]:
    """E_lm = Â_l L_lm (R&H eq. 7), same shape as ``coeffs``."""
    c = _check_coeffs(coeffs)
    lmax = lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    return convolve(c, clamped_cosine_factors(lmax))


def irradiance(coeffs: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """E(n) = Σ_lm Â_l L_lm y_lm(n) (R&H eq. 7), any lmax.

    ``coeffs`` (K, C) or (K,); ``normals`` (..., 3) unit vectors → (..., C) or (...,).
    """
    e = irradiance_coeffs(coeffs)
    lmax = lmax_of(e.shape[0])
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim < 1 or n.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {n.shape}")
    y = sh_basis(n, lmax)
    return y @ e


def _rh_constants() -> tuple[float, float, float, float, float]:
    """c1..c5 of R&H eq. 12 from Â_l (eq. 9) and the normalisations (eq. 3), unrounded."""
    a0, a1, a2 = np.pi, 2.0 * np.pi / 3.0, np.pi / 4.0
    k22 = 0.25 * math.sqrt(15.0 / np.pi)  # y22 = k22 (x² − y²); y2-2, y2-1, y21 = 2 k22 ·
    k20 = 0.25 * math.sqrt(5.0 / np.pi)  # y20 = k20 (3z² − 1)
    k1 = math.sqrt(3.0 / (4.0 * np.pi))
    k0 = 0.5 / math.sqrt(np.pi)
    return a2 * k22, a1 * k1 / 2.0, 3.0 * a2 * k20, a0 * k0, a2 * k20


#: (c1, c2, c3, c4, c5) of R&H eq. 12, exact; they round to 0.429043, 0.511664, 0.743125,
#: 0.886227, 0.247708.
RH_CONSTANTS: tuple[float, float, float, float, float] = _rh_constants()


def _nine(coeffs: ArrayLike) -> NDArray[np.float64]:
    c = _check_coeffs(coeffs)
    if c.ndim == 1:
        c = c[:, None]
    if c.shape[-2] < 9:
        raise ShprobeError(f"eq. 11–13 need lmax ≥ 2 (9 coefficients), got {c.shape[-2]}")
    return c[..., :9, :]


def irradiance_matrix(coeffs: ArrayLike) -> NDArray[np.float64]:
    """M of R&H eq. 11–12 per channel, (..., C, 4, 4), with E(n) = nᵀ M n, n = (x, y, z, 1).

    Uses L_lm for l ≤ 2 (higher bands are ignored). Our signs and order are R&H's, so M is
    their matrix verbatim.
    """
    c1, c2, c3, c4, c5 = RH_CONSTANTS
    L = np.moveaxis(_nine(coeffs), -2, 0)  # (9, ..., C)
    L00, L1m1, L10, L11, L2m2, L2m1, L20, L21, L22 = L
    m = np.empty((*L00.shape, 4, 4))
    m[..., 0, :] = np.stack([c1 * L22, c1 * L2m2, c1 * L21, c2 * L11], axis=-1)
    m[..., 1, :] = np.stack([c1 * L2m2, -c1 * L22, c1 * L2m1, c2 * L1m1], axis=-1)
    m[..., 2, :] = np.stack([c1 * L21, c1 * L2m1, c3 * L20, c2 * L10], axis=-1)
    m[..., 3, :] = np.stack([c2 * L11, c2 * L1m1, c2 * L10, c4 * L00 - c5 * L20], axis=-1)
    return m


def irradiance_from_matrix(m: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """E = nᵀ M n with n = (x, y, z, 1) (R&H eq. 11); ``m`` (C, 4, 4) → (..., C)."""
    mm = np.asarray(m, dtype=np.float64)
    if mm.shape[-2:] != (4, 4):
        raise ShprobeError(f"M must have shape (..., 4, 4), got {mm.shape}")
    n = np.asarray(normals, dtype=np.float64)
    n4 = np.concatenate([n, np.ones((*n.shape[:-1], 1))], axis=-1)
    return np.einsum("...i,cij,...j->...c", n4, mm.reshape(-1, 4, 4), n4)


def irradiance_quadratic(coeffs: ArrayLike, normals: ArrayLike) -> NDArray[np.float64]:
    """The expanded polynomial of R&H eq. 13 → (..., C)."""
    c1, c2, c3, c4, c5 = RH_CONSTANTS
    L00, L1m1, L10, L11, L2m2, L2m1, L20, L21, L22 = _nine(coeffs)
    n = np.asarray(normals, dtype=np.float64)[..., None]
    x, y, z = n[..., 0, :], n[..., 1, :], n[..., 2, :]
    return (c1 * L22 * (x * x - y * y) + c3 * L20 * z * z + c4 * L00 - c5 * L20
            + 2.0 * c1 * (L2m2 * x * y + L21 * x * z + L2m1 * y * z)
            + 2.0 * c2 * (L11 * x + L1m1 * y + L10 * z))


def irradiance_map(coeffs: ArrayLike, layout: str | Layout = "latlong",
                   size: int | tuple[int, int] = 128) -> Env:
    """An irradiance environment map E(n) (eq. 7) on the grid of any layout → Env.

    ``size`` as in ``Layout.grid_shape`` (lat-long H or (W, H); angular / mirror ball N; cube
    face N). ``layout='angular'`` gives the view of R&H Fig. 3 (centre +Z, rim −Z). Pixels
    outside an angular disc are 0.
    """
    lay = get_layout(layout)
    grid = lay.grid_shape(size)
    c = _check_coeffs(coeffs)
    if c.ndim == 1:
        c = np.repeat(c[:, None], 3, axis=1)
    dirs = lay.pixel_directions(grid)
    valid = lay.valid_mask(grid)
    e = np.zeros((*grid, c.shape[-1]), dtype=np.float32)
    e[valid] = irradiance(c, dirs[valid])
    return Env(e, lay)


# ----------------------------------------------------------------------------- brute force


def _sample_chunks(env: Env, subdivide: int, chunk: int
                   ) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """(dirs (S, 3), L·dω (S, 3)) in chunks of about ``chunk`` samples; each pixel split into
    ``subdivide``² sub-pixels of constant radiance with their exact solid angles."""
    k = int(subdivide)
    if k < 1:
        raise ShprobeError(f"subdivide must be ≥ 1, got {subdivide}")
    rad = env.radiance
    if env.layout.name == "latlong":
        from ..probes.layouts import LatLong

        h, w = rad.shape[:2]
        hk, wk = h * k, w * k
        ct, st = LatLong.row_cos_theta(hk), LatLong.row_sin_theta(hk)
        cx, cz = LatLong.column_xz(wk)
        dw = LatLong.row_solid_angle(hk, wk)
        rows = max(1, chunk // wk)
        for j0 in range(0, hk, rows):
            j1 = min(hk, j0 + rows)
            nr = j1 - j0
            d = np.empty((nr, wk, 3))
            d[..., 0] = st[j0:j1, None] * cx[None]
            d[..., 1] = ct[j0:j1, None]
            d[..., 2] = st[j0:j1, None] * cz[None]
            src = np.repeat(rad[np.arange(j0, j1) // k], k, axis=1).astype(np.float64)
            yield d.reshape(-1, 3), (src * dw[j0:j1, None, None]).reshape(-1, 3)
        return
    if k > 1:
        rad = np.repeat(np.repeat(rad, k, axis=-3), k, axis=-2)
        env = Env(rad, env.layout, env.path)
    dirs, vals, dws = env.samples()
    for s0 in range(0, dirs.shape[0], chunk):
        s1 = s0 + chunk
        yield dirs[s0:s1], vals[s0:s1].astype(np.float64) * dws[s0:s1, None]


def reference_irradiance(env: Env, normals: ArrayLike, chunk: int = 1 << 18,
                         subdivide: int = 1, progress=None) -> NDArray[np.float64]:
    """Brute-force irradiance Σ_pixels L(ω) max(0, n·ω) dω for any normals (..., 3) → (..., 3).

    O(T·S); a numba kernel parallel over normals, fed ``chunk`` samples at a time so memory
    stays bounded. ``subdivide=k`` splits every pixel into k×k sub-pixels (exact sub-solid
    angles, constant radiance) to check convergence; lat-long builds them chunk by chunk, the
    other layouts build their k²-times larger pixel tables whole (memory O(k²·S)).
    ``progress(done, total)`` is called with
    the normal–sample pairs done so far, every ~2²³ pairs, when given.
    """
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim < 1 or n.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {n.shape}")
    flat = np.ascontiguousarray(n.reshape(-1, 3))
    t = flat.shape[0]
    out = np.zeros((t, 3))
    kern = _kernels()["brute"]
    total = t * int(np.prod(env.grid)) * int(subdivide) ** 2
    done = 0
    for d, lw in _sample_chunks(env, subdivide, int(chunk)):
        dT, lwT = np.ascontiguousarray(d.T), np.ascontiguousarray(lw.T)
        block = max(256, (1 << 23) // max(1, d.shape[0]))  # normals per call
        for i in range(0, t, block):
            kern(flat[i:i + block], dT, lwT, out[i:i + block])
            done += min(block, t - i) * d.shape[0]
            if progress is not None:
                progress(min(done, total), total)
    return out.reshape(*n.shape[:-1], 3)


# ----------------------------------------------------------------------------- error report


@dataclass(frozen=True)
class ErrorRow:
    """Errors of the order-lmax SH irradiance against the brute-force reference.

    ``mean_frac`` / ``max_frac``: mean and max |E_SH − E_ref| / ∫L dω (R&H's metric; per
    channel, mean weighted by the normals' solid angles, max over normals and channels);
    ``mean_rel``: mean |ΔE| / E_ref over normals with E_ref > 0; ``smape``: mean
    2|ΔE| / (|E_SH| + |E_ref|).
    """

    lmax: int
    mean_frac: float
    max_frac: float
    mean_rel: float
    smape: float


@dataclass(frozen=True)
class ErrorReport:
    """Per-lmax error rows, the total intensity ∫L dω (3,) and the number of normals."""

    rows: tuple[ErrorRow, ...]
    total_intensity: NDArray[np.float64]
    n_normals: int

    def row(self, lmax: int) -> ErrorRow:
        for r in self.rows:
            if r.lmax == lmax:
                return r
        raise KeyError(lmax)


def _normal_grid(h: int = 32) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    from ..probes.layouts import LatLong

    lay = LatLong()
    grid = (h, 2 * h)
    return lay.pixel_directions(grid).reshape(-1, 3), lay.solid_angles(grid).reshape(-1)


def error_report(env: Env, lmax_values: tuple[int, ...] = (1, 2, 3, 4),
                 normals: ArrayLike | None = None, reference: ArrayLike | None = None,
                 progress=None, normal_grid: int = 32) -> ErrorReport:
    """R&H's error metric (§3.1) for each lmax: SH irradiance vs :func:`reference_irradiance`.

    ``normals`` default: the pixel centres of a (2N)×N lat-long grid, N = ``normal_grid``,
    weighted by their solid angles (given normals are weighted equally). ``reference`` may
    pass a precomputed E_ref.
    """
    if normals is None:
        nrm, wts = _normal_grid(normal_grid)
    else:
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        wts = np.ones(nrm.shape[0])
    wts = wts / wts.sum()
    ref = (reference_irradiance(env, nrm, progress=progress) if reference is None
           else np.asarray(reference, dtype=np.float64).reshape(-1, 3))
    tot = total_intensity(env)
    if not np.all(tot > 0):
        raise ShprobeError("the environment has a channel with zero total intensity", env.path)
    lmax_values = tuple(check_lmax(int(x)) for x in lmax_values)
    coeffs = project(env, max(lmax_values))
    rows = []
    for lm in lmax_values:
        e = irradiance(coeffs[: num_coeffs(lm)], nrm)
        err = np.abs(e - ref)
        frac = err / tot
        pos = ref > 0
        rel = np.where(pos, err / np.where(pos, ref, 1.0), 0.0)
        denom = np.abs(e) + np.abs(ref)
        sm = np.where(denom > 0, 2.0 * err / np.where(denom > 0, denom, 1.0), 0.0)
        wpos = wts[:, None] * pos
        rows.append(ErrorRow(
            lmax=lm,
            mean_frac=float((wts[:, None] * frac).sum() / 3.0),
            max_frac=float(frac.max()),
            mean_rel=float((wpos * rel).sum() / max(wpos.sum(), 1e-300)),
            smape=float((wts[:, None] * sm).sum() / 3.0),
        ))
    return ErrorReport(tuple(rows), tot, nrm.shape[0])


# ----------------------------------------------------------------------------- JSON


def coeffs_document(coeffs: ArrayLike, source: str | None = None, layout: str | None = None
                    ) -> dict[str, Any]:
    """The JSON document of ``shprobe prefilter --format json``.

    Keys: shprobe_version, source, layout, lmax, convention, labels, coefficients [k][rgb],
    irradiance_coefficients [k][rgb] (Â_l L_lm) and, for lmax ≥ 2, M [rgb][4][4] (eq. 11–12).
    """
    c = _check_coeffs(coeffs)
    if c.ndim == 1:
        c = np.repeat(c[:, None], 3, axis=1)
    lmax = lmax_of(c.shape[0])
    doc: dict[str, Any] = {
        "shprobe_version": __version__,
        "source": source,
        "layout": layout,
        "lmax": lmax,
        "convention": "real orthonormal SH, R&H 2001 signs (no Condon-Shortley phase), "
                      "k = l(l+1)+m, world +Y up; E(n) = sum_k irradiance_coefficients[k] y_k(n)",
        "labels": [f"L{l}{m}" for l in range(lmax + 1) for m in range(-l, l + 1)],
        "coefficients": c.tolist(),
        "irradiance_coefficients": irradiance_coeffs(c).tolist(),
    }
    if lmax >= 2:
        doc["M"] = irradiance_matrix(c).tolist()
    return doc


def read_coeffs_json(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Coefficients (K, C) from a shprobe JSON document (``shprobe prefilter --format json``,
    or any JSON object with ``coefficients`` [k][rgb] in shprobe's convention).

    Other formats (Condon–Shortley JSON, three.js, glTF, shaders, cmgen) are refused here:
    :func:`shprobe.export.import_coeffs` reads every format and converts it.
    """
    from .export import parse_coeffs

    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        raise ShprobeError("no such file", path) from None
    except UnicodeDecodeError:
        raise ShprobeError("not a text file", path) from None
    c, fmt = parse_coeffs(text, os.fspath(path))
    if fmt != "json":
        raise ShprobeError(f"holds {fmt} coefficients, not a shprobe JSON document (read it "
                           "with shprobe.export.import_coeffs)", path)
    return c


def _kernels() -> dict[str, Any]:
    from . import _kernels as k  # numba, imported lazily

    return {"project_rgb": k.project_rgb_kernel, "brute": k.brute_kernel}
