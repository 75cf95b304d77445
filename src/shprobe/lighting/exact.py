"""The exact irradiance's building blocks: a map's pixels as samples (directions and L dω, each
pixel optionally split into sub-pixels with their exact solid angles), and E_ref at many normals
from tables built once (``_Exact``: per-row prefix sums on lat-long maps), which the error
report (`shprobe.lighting.reference`) evaluates on its grid and refines."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..probes.env import Env
from ..probes.layouts import LatLong
from .irradiance import irradiance


def _sample_chunks(env: Env, subdivide: int, chunk: int
                   ) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """(dirs (S, 3), L·dω (S, 3)) in chunks of about ``chunk`` samples; each pixel split into
    ``subdivide``² sub-pixels of constant radiance with their exact solid angles."""
    k = int(subdivide)
    if k < 1:
        raise ShprobeError(f"subdivide must be ≥ 1, got {subdivide}")
    rad = env.radiance
    if env.layout.name == "latlong":
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


class _Exact:
    """E_ref(n) = Σ_pixels L max(0, n·ω) dω at any normals, tables built once, for the error
    report's grid and its refinement (many small batches).

    Lat-long maps: the lit pixels of a row are one cyclic run of columns, so the sum is read off
    per-row prefix sums of L dω, L dω ω_x, L dω ω_z
    (`shprobe.lighting._kernels.latlong_exact_into`): O(H) per normal instead of O(H·W), the same
    pixels and products re-associated (exact to rounding; checked against
    [`reference_irradiance`][shprobe.lighting.reference_irradiance] in the tests), 72 bytes per
    pixel kept, 120 at the peak of the build (the weighted radiance and one product beside them).
    Other layouts: the brute-force sum, serially (48 bytes per sample, built on first use).
    """

    def __init__(self, env: Env, chunk: int = 1 << 18):
        rad = env.radiance
        self.latlong = env.layout.name == "latlong"
        if self.latlong:
            h, w, nch = rad.shape
            # the tables (3 sums) + L dω + one product of it, float64 per channel
            check_memory(8.0 * nch * (3 * h * (w + 1) + 2 * h * w),
                         f"row sums of a {w}x{h} map", env.path)
            self.ct, self.st = LatLong.row_cos_theta(h), LatLong.row_sin_theta(h)
            self.cx, self.cz = LatLong.column_xz(w)
            ldw = rad.astype(np.float64)  # a copy: scaled in place
            ldw *= LatLong.row_solid_angle(h, w)[:, None, None]
            pre = np.zeros((h, w + 1, nch, 3))
            np.cumsum(ldw, axis=1, out=pre[:, 1:, :, 0])
            np.cumsum(ldw * self.cx[None, :, None], axis=1, out=pre[:, 1:, :, 1])
            ldw *= self.cz[None, :, None]  # its last use
            np.cumsum(ldw, axis=1, out=pre[:, 1:, :, 2])
            self.pre = pre.reshape(h, w + 1, 3 * nch)
            self.nch = nch
        else:
            self.env, self.chunk, self.tables = env, chunk, None
            self.nch = 3

    def __call__(self, normals: ArrayLike) -> NDArray[np.float64]:
        """E_ref at unit normals (M, 3) → (M, C)."""
        flat = np.ascontiguousarray(np.asarray(normals, dtype=np.float64).reshape(-1, 3))
        out = np.zeros((flat.shape[0], self.nch))
        if self.latlong:
            from ._kernels import latlong_exact, latlong_exact_parallel  # numba, lazily

            kern = latlong_exact_parallel if flat.shape[0] > 65536 else latlong_exact
            kern(flat, self.ct, self.st, self.cx, self.cz, self.pre, out)
            return out
        from ._kernels import brute_serial  # numba, imported lazily

        if self.tables is None:
            self.tables = [(np.ascontiguousarray(d.T), np.ascontiguousarray(lw.T))
                           for d, lw in _sample_chunks(self.env, 1, self.chunk)]
        for dT, lwT in self.tables:
            brute_serial(flat, dT, lwT, out)
        return out

    def error_fn(self, coeffs: NDArray[np.float64], tot: NDArray[np.float64]):
        """n (M, 3) → (max_c |E_SH,c − E_ref,c| / ∫L_c (M,), channel (M,)) for the SH
        lighting ``coeffs`` (K, C) (R&H eq. 7): one kernel call per batch on lat-long maps."""
        from ..sh import lmax_of, recurrence_tables
        from .irradiance import irradiance_coeffs

        elm = np.ascontiguousarray(irradiance_coeffs(coeffs), dtype=np.float64)
        inv = np.ascontiguousarray(1.0 / np.asarray(tot, dtype=np.float64))
        if not self.latlong:
            def slow(n):
                d = np.abs(irradiance(coeffs, n) - self(n)) * inv
                return d.max(axis=1), d.argmax(axis=1)

            return slow
        from ._kernels import latlong_error  # numba, imported lazily

        lmax = lmax_of(elm.shape[0])
        a, b = (np.ascontiguousarray(t) for t in recurrence_tables(max(lmax, 1)))

        def fast(n):
            flat = np.ascontiguousarray(np.asarray(n, dtype=np.float64).reshape(-1, 3))
            out = np.empty(flat.shape[0])
            chan = np.empty(flat.shape[0], dtype=np.int64)
            latlong_error(flat, self.ct, self.st, self.cx, self.cz, self.pre, elm, a, b, inv,
                          out, chan)
            return out, chan

        return fast
