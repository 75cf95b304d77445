"""Projection onto SH (R&H 2001 eq. 10): lighting coefficients from an environment map or from
weighted samples.

- [`project`][shprobe.lighting.project] — L_lm = Σ_pixels L(ω) y_lm(ω) dω, any lmax. Lat-long maps
  use their separability (thesis §4.2): per row a cos/sin(mψ) matrix product over the columns, then
  the normalised associated Legendre functions in θ per row. The rows of a lat-long map are circles
  about +Y, so the sum is done in the frame ω' = (z, x, y) whose pole is +Y and turned back by
  one fixed per-band rotation. Other layouts sum over their samples (one numba pass).
- [`project_samples`][shprobe.lighting.project_samples] — Σ_s v_s y(d_s) w_s for any samples, no (S,
  K) temporary.
- `project_file` — the same sum streamed from an image file a block of rows at a time
  (lat-long and cube crosses / strips), so memory does not grow with the image.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..probes.env import Env
from ..probes.layouts import (
    CUBE_ARRANGEMENTS,
    CUBE_AXES,
    Cube,
    LatLong,
    cube_arrangement,
    detect_layout,
    get_layout,
)
from ..sh import check_lmax, lmax_of, num_coeffs, recurrence_tables, sh_basis_numpy
from ..sh.rotation import ROTATION_LMAX

__all__ = [
    "FileProjection",
    "project",
    "project_file",
    "project_samples",
    "projection_bytes",
    "total_intensity",
]

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
    # a few hundred nodes: the NumPy recurrence (no compiled kernel to start for this)
    y = sh_basis_numpy(dirs, lmax)
    yq = sh_basis_numpy(dirs @ _Q.T, lmax)
    blocks = []
    for l in range(lmax + 1):
        sl = slice(l * l, (l + 1) ** 2)
        blocks.append((yq[:, sl] * w[:, None]).T @ y[:, sl])
    return tuple(blocks)


def _from_pole_y(cp: NDArray[np.float64]) -> NDArray[np.float64]:
    """Coefficients in the world frame from those in the frame ω' = Qω: c = Dᵀ c'.

    c' are the coefficients of f∘Q⁻¹, so c = rotate(c', Q⁻¹). Up to lmax 12 the per-band D is
    built here by exact quadrature (independent of shprobe.sh.rotation); above, by the Wigner
    recurrence of [`shprobe.sh.rotation.rotate`][shprobe.sh.rotation.rotate], which needs no (nodes
    × K) table.
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


def latlong_pole_factors(h: int, w: int, lmax: int
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64],
                                    NDArray[np.int64]]:
    """The separable factors of the SH on an H × W lat-long grid, in the frame ω' = (z, x, y)
    whose pole is +Y: (trig (M, W) for m = −lmax..lmax; Λ (M, lmax+1, H): [m, l, row] =
    y_l|m|(θ_row) at φ' = 0, zero for l < |m|; the (m, l) place of each flat index k).
    Projection and synthesis both build on these (y_lm' = trig_m(ψ) Λ_lm(θ))."""
    psi = LatLong.column_azimuth(w)
    m = np.arange(-lmax, lmax + 1)
    # in the frame ω' the azimuth is φ' = −ψ: cos(mφ') = cos(mψ), sin(|m|φ') = −sin(|m|ψ)
    trig = np.where(m[:, None] >= 0, np.cos(np.abs(m)[:, None] * psi[None]),
                    -np.sin(np.abs(m)[:, None] * psi[None]))
    theta = LatLong.row_theta(h)
    pole = np.stack([np.sin(theta), np.zeros(h), np.cos(theta)], axis=-1)
    # y_l|m| at φ' = 0: √2 P̄_l|m| sin^|m| θ (m > 0), P̄_l0 (m = 0); one direction per row, so
    # the NumPy recurrence (no compiled kernel to start in a process that only projects)
    basis = sh_basis_numpy(pole, lmax)
    ks = np.arange(num_coeffs(lmax))
    ls = np.floor(np.sqrt(ks)).astype(np.int64)
    ms = ks - ls * (ls + 1)
    lam = np.zeros((2 * lmax + 1, lmax + 1, h))
    lam[ms + lmax, ls] = basis[:, ls * (ls + 1) + np.abs(ms)].T
    return trig, lam, ms + lmax, ls


@lru_cache(maxsize=16)
def _latlong_tables(h: int, w: int, lmax: int) -> tuple[NDArray[np.float32], NDArray[np.float64],
                                                        NDArray[np.int64], NDArray[np.int64]]:
    """(trig (M, W) float32; row weights by m (M, lmax+1, H) float64: [m, l, row] =
    dω_row Λ_l|m|(θ_row); the (m, l) place of each k)."""
    trig, lam, mi, li = latlong_pole_factors(h, w, lmax)
    by_m = lam * LatLong.row_solid_angle(h, w)
    trig = np.ascontiguousarray(trig, dtype=np.float32)
    for t in (trig, by_m):
        t.flags.writeable = False
    return trig, by_m, mi, li


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
    split over ``threads`` threads — default `_latlong_threads`: one below
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
    Torch tensors and JAX arrays take the array-API path (``shprobe.lighting._xp``, one
    (S, K) basis table): same kind, device and dtype, differentiable in all three arrays.

    Parameters
    ----------
    dirs
        (S, 3) unit directions.
    values
        (S, C) or (S,) sample values.
    weights
        (S,) weights (e.g. solid angles); default 4π/S, as for uniform random samples.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (K, C) or (K,)
        Σ_s values_s y_lm(dirs_s) weights_s.
    """
    from ..sh import _xp

    xp = _xp.namespace(dirs, values, weights)
    if xp is not None:
        from . import _xp as lx

        return lx.project_samples(xp, dirs, values, weights, lmax)
    lmax = check_lmax(lmax)
    d = np.ascontiguousarray(np.asarray(dirs, dtype=np.float64).reshape(-1, 3))
    if d.shape[0] == 0:
        raise ShprobeError("project_samples needs at least one sample, got 0 directions")
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
    from ._kernels import project_rgb_kernel as kern  # numba, imported lazily

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

    Parameters
    ----------
    env
        The environment map (`load_env`, `procedural_env`, `env_from_function`).
    lmax
        The highest degree of the projection.

    Returns
    -------
    ndarray of shape (K, 3), float64
        The lighting coefficients L_lm, K = (lmax + 1)².
    """
    lmax = check_lmax(lmax)
    if not isinstance(env, Env):
        raise ShprobeError("project() needs an Env (see shprobe.load_env)")
    if env.layout.name == "latlong" and lmax > ROTATION_LMAX:
        raise ShprobeError(f"lat-long projection goes to lmax {ROTATION_LMAX} (its frame turn "
                           f"is a Wigner rotation), not {lmax}", env.path)
    check_memory(projection_bytes(env.grid, env.layout.name, lmax, env.radiance.shape[-1]),
                 f"projecting a {'x'.join(map(str, env.grid[::-1]))} {env.layout.name} map to "
                 f"lmax {lmax}", env.path)
    if env.layout.name == "latlong":
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported below
            c = _project_latlong(env.radiance, lmax)
    else:
        d = np.ascontiguousarray(env.directions(), dtype=np.float64).reshape(-1, 3)
        dw = np.ascontiguousarray(env.solid_angles(), dtype=np.float64).reshape(-1)
        rad = env.radiance.reshape(-1, env.radiance.shape[-1])
        c = _project_kernel(d, rad, dw, lmax)
    if not np.all(np.isfinite(c)):  # e.g. pixels near float32's largest value overflowing
        raise ShprobeError("the projection overflowed (radiance too large to sum): "
                           "rescale the probe", env.path)
    return c


def projection_bytes(grid: tuple[int, ...], layout: str, lmax: int, channels: int = 3) -> float:
    """Estimated working memory of [`project`][shprobe.lighting.project] beyond the image itself, in
    bytes."""
    K, M = (lmax + 1) ** 2, 2 * lmax + 1
    if layout == "latlong":
        h, w = grid[:2]
        # trig table (M, W) f32, row weights and pole basis (H, K) f64 ×2, per-row products
        # (H, M, C) f32, their float64 gather (H, K, C)
        return 4.0 * M * w + 16.0 * h * K + 4.0 * h * M * channels + 8.0 * h * K * channels
    px = float(np.prod(grid))
    return px * (24 + 8 + 8 * channels) + 8.0 * K * (K + 64 * channels)


def total_intensity(env: Env) -> NDArray[np.float64]:
    """∫ L dω per channel, (3,).

    Parameters
    ----------
    env
        The environment map.

    Returns
    -------
    ndarray of shape (3,)
        ∫ L dω per channel.
    """
    dw = env.solid_angles()
    rad = env.radiance.reshape(-1, env.radiance.shape[-1]).astype(np.float64)
    return dw.reshape(-1) @ rad


# ----------------------------------------------------------------------------- streaming


@dataclass(frozen=True)
class FileProjection:
    """Result of `project_file`: ``coeffs`` (K, 3) float64, the ``layout`` name, the
    image file's ``width`` × ``height`` and whether it was ``streamed`` (False: the layout
    has no streaming path and the image was read whole)."""

    coeffs: NDArray[np.float64]
    layout: str
    width: int
    height: int
    streamed: bool

    def __repr__(self) -> str:
        return (f"FileProjection({self.layout} {self.width}x{self.height}, "
                f"lmax {lmax_of(self.coeffs.shape[0])}, streamed={self.streamed})")


def project_file(path: str | os.PathLike[str], lmax: int = 2, layout: str | None = None,
                 clamp: bool = False, block_bytes: int | None = None,
                 on_block: Callable[[int, NDArray[np.float32]], None] | None = None
                 ) -> FileProjection:
    """[`project`][shprobe.lighting.project] of an image file, streamed: the file is read a block of
    rows at a time (`shprobe.probes.streaming.ImageRows`) and each block's share of R&H eq. 10 is
    added up, so peak memory is one block (16 MB by default) plus the small tables, whatever the
    image size. Equal to ``project(load_env(path, layout), lmax)`` to float rounding. This is
    shprobe's streaming entry point, the equivalent of a lazy ``load_env`` for projection
    (``shprobe prefilter`` takes it for big probes, ``shprobe batch`` always).

    Radiance files are decoded and reduced in one pass (each scanline's Σ_ψ L cos/sin(mψ)
    while it is in cache, `row_sums`), in float32 as
    [`project`][shprobe.lighting.project]'s matrix product but in another order: equal to it to
    float32 rounding.

    Lat-long maps use the separable sum of [`project`][shprobe.lighting.project] (the same cached
    tables, one row block at a time); cube crosses and strips sum each face's rows as they pass
    (directions and exact texel solid angles made per block). Angular maps and mirror balls have no
    streaming path: the image is read whole (``streamed=False``). ``on_block(y0, block)`` sees
    every decoded block of image rows (e.g. to build a thumbnail in the same pass).
    """
    from ..probes.streaming import BLOCK_BYTES, ImageRows

    lmax = check_lmax(lmax)
    with ImageRows(path, clamp=clamp, block_bytes=block_bytes or BLOCK_BYTES) as im:
        w, h = im.width, im.height
        name = (get_layout(layout).name if layout not in (None, "auto")
                else detect_layout((h, w), path))
        if name == "latlong":
            coeffs = _stream_latlong(im, lmax, on_block)
        elif name == "cube":
            coeffs = _stream_cube(im, lmax, on_block)
        else:
            from ..probes.env import env_from_image

            img = np.empty((h, w, 3), np.float32)
            for y0, blk in im.blocks():
                img[y0:y0 + blk.shape[0]] = blk
                if on_block is not None:
                    on_block(y0, blk)
            return FileProjection(project(env_from_image(img, name, path), lmax), name, w, h,
                                  False)
    return FileProjection(coeffs, name, w, h, True)


def _stream_latlong(im: Any, lmax: int, on_block) -> NDArray[np.float64]:
    h, w = LatLong().check_grid((im.height, im.width), im.path)
    trig, by_m, mi, li = _latlong_tables(h, w, lmax)
    g = np.zeros((by_m.shape[0], by_m.shape[1], 3))
    if on_block is None:  # per row Σ_ψ L cos/sin(mψ); fused with decoding for Radiance files
        for y0, f in im.row_sums(trig):
            g += np.matmul(by_m[:, :, y0:y0 + f.shape[0]], f.transpose(1, 0, 2))
        return _from_pole_y(g[mi, li])
    for y0, blk in im.blocks():
        f = np.matmul(trig[None], blk)  # (rows, M, C) float32, as _project_latlong
        g += np.matmul(by_m[:, :, y0:y0 + blk.shape[0]], f.transpose(1, 0, 2).astype(np.float64))
        on_block(y0, blk)
    return _from_pole_y(g[mi, li])


def cube_face_rows(face: int, n: int, j0: int, j1: int
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Directions ``(j1−j0, N, 3)`` and exact solid angles ``(j1−j0, N)`` of texel rows
    j0..j1 of one cube face: `Cube.pixel_directions` and `Cube.solid_angles`
    (same formulas, see `shprobe.probes.layouts`) for a band of rows only."""
    c = -1.0 + 2.0 * (np.arange(n) + 0.5) / n
    tc = c[j0:j1]
    u = 1.0 / np.sqrt(1.0 + c[None, :] ** 2 + tc[:, None] ** 2)
    ax = CUBE_AXES[face]
    d = (u[..., None] * ax[0] + (c[None, :] * u)[..., None] * ax[1]
         + (tc[:, None] * u)[..., None] * ax[2])
    e = -1.0 + 2.0 * np.arange(n + 1) / n
    er = e[j0:j1 + 1]
    a = np.arctan2(er[:, None] * e[None, :], np.sqrt(er[:, None] ** 2 + e[None, :] ** 2 + 1))
    dw = a[1:, 1:] - a[1:, :-1] - a[:-1, 1:] + a[:-1, :-1]
    return d, dw


def _stream_cube(im: Any, lmax: int, on_block) -> NDArray[np.float64]:
    arr = cube_arrangement((im.height, im.width), im.path)
    (fw, _), pos = CUBE_ARRANGEMENTS[arr]
    n = im.width // fw
    Cube().check_grid((6, n, n), im.path)
    out = np.zeros((num_coeffs(lmax), 3))
    for y0, blk in im.blocks():
        y1 = y0 + blk.shape[0]
        for k, (col, row, rot) in enumerate(pos):
            a, b = max(y0, row * n), min(y1, (row + 1) * n)
            if a >= b:
                continue
            px = blk[a - y0:b - y0, col * n:(col + 1) * n]
            j0, j1 = a - row * n, b - row * n
            if rot:  # the face is turned by 180°: image row j is face row n−1−j, reversed
                px = px[::-1, ::-1]
                j0, j1 = n - j1, n - j0
            d, dw = cube_face_rows(k, n, j0, j1)
            out += _project_kernel(np.ascontiguousarray(d.reshape(-1, 3)),
                                   np.ascontiguousarray(px.reshape(-1, 3), dtype=np.float64),
                                   np.ascontiguousarray(dw.reshape(-1)), lmax)
        if on_block is not None:
            on_block(y0, blk)
    return out
