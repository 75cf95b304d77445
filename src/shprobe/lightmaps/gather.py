"""The radiance gather: per texel, stratified hemisphere rays traced with Embree, the distant
sky (SH, lmax 2), an optional sun with shadow rays, and diffuse bounces that read the
previous bounce's lightmap at the hit points.

Estimator, per texel with tangent frame (x, y, z = N) and S stratified directions ωₛ of density
p on the tangent hemisphere (uniform; for a plain bake mostly cosine-weighted:
`shprobe.lightmaps.hits`), each of weight cₛ = 1/(S p(ωₛ)):

    L_lm = ∫_Ω+ L_sky y_lm dω  −  Σ_{ωₛ blocked} cₛ L_sky(ωₛ) y_lm(ωₛ)
           + Σ_{ωₛ hits a front face} cₛ ρ(q)/π · E_{k−1}(q) · y_lm(ωₛ)  +  E_sun y_lm(s)

The first term is exact (a 15-node hemispherical rule; the integrand is a polynomial of degree
4), so the unoccluded sky is a control variate: an open texel has no noise at all. The plain
irradiance E(N) uses the same sum with z = cos θ in place of y_lm; bounce k reads
E_{k−1} bilinearly from the (dilated) lightmap of the bounce before at the hit's lightmap UV.
Rays below the geometric face, and hits on back faces, carry no light; a texel whose rays
mostly hit back faces lies inside geometry and is invalid (dilated over afterwards).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..hbasis import hemisphere_quadrature
from ..progress import Progress, stage
from ..scene.raycast import RayCaster
from ..sh import sh_basis
from .atlas import Atlas, Texels
from .hits import HitTables, grid, hit_tables, uniform_share
from .hits import wrap_bilinear as _srgb_free
from .settings import LightmapSettings

__all__ = ["BYTES_PER_HIT", "Gathered", "bilinear", "gather", "gather_tile", "join",
           "ray_origins", "sample_albedo", "tile_size"]

#: kept per ray that hits a front face (texel, UV, albedo weight, direction)
BYTES_PER_HIT = 4 + 8 + 12 + 12
#: rays traced per Embree batch (one tile of texels): small enough that even a short bake has
#: several tiles to share out between the threads, large enough that each call is mostly Embree
RAYS_PER_BATCH = 1 << 17


@dataclass(eq=False)
class Gathered:
    """What one gather pass leaves for the bounces and the projection.

    Parameters
    ----------
    direct_sh : ndarray (P, 9, 3)
        Radiance SH in the tangent frame from the sky and sun (occlusion included).
    direct_e : ndarray (P, 3)
        Plain irradiance at N from the sky and sun.
    hit_texel : ndarray (M,)
        Texel of each front-face hit.
    hit_uv : ndarray (M, 2)
        Lightmap UV of the hit point.
    hit_weight : ndarray (M, 3)
        The ray's weight 1/(S p(ω)) · albedo / π at the hit.
    hit_dir : ndarray (M, 3)
        Tangent-frame direction of the ray.
    valid : ndarray (P,) bool
        False where most rays hit back faces.
    half_e : ndarray (2, P, 3)
        The plain direct irradiance from each half of the samples (noise estimate).
    """

    direct_sh: NDArray[np.float64] = field(repr=False)
    direct_e: NDArray[np.float64] = field(repr=False)
    hit_texel: NDArray[np.int64] = field(repr=False)
    hit_uv: NDArray[np.float32] = field(repr=False)
    hit_weight: NDArray[np.float32] = field(repr=False)
    hit_dir: NDArray[np.float32] = field(repr=False)
    valid: NDArray[np.bool_] = field(repr=False)
    half_e: NDArray[np.float64] = field(repr=False)


def sample_albedo(atlas: Atlas, prim: NDArray, face_local: NDArray, bary: NDArray,
                  override: NDArray | None) -> NDArray[np.float64]:
    """Diffuse albedo (N, 3) at surface points: the override, else base colour factor ×
    base colour texture at TEXCOORD_0.

    Parameters
    ----------
    atlas : Atlas
        The baked primitives.
    prim, face_local : ndarray (N,)
        Primitive and face within it.
    bary : ndarray (N, 3)
        Barycentrics.
    override : ndarray (3,), optional
        The settings' albedo.

    Returns
    -------
    ndarray (N, 3)
        Albedo in [0, 1].
    """
    out = np.empty((len(prim), 3))
    if override is not None:
        out[:] = override
        return out
    for i, p in enumerate(atlas.primitives):
        sel = np.flatnonzero(prim == i)
        if not len(sel):
            continue
        a = np.broadcast_to(np.clip(p.base_color[:3], 0, 1), (len(sel), 3)).copy()
        if p.base_texture is not None and p.uv0 is not None:
            uv = (p.uv0[p.faces[face_local[sel]]] * bary[sel][:, :, None]).sum(1)
            a *= _srgb_free(p.base_texture, uv)
        out[sel] = a
    return np.clip(out, 0.0, 1.0)


def bilinear(image: NDArray, uv: NDArray) -> NDArray:
    """Bilinear lookup of a lightmap (H, W, C) at lightmap UVs (N, 2), clamped to the edge.

    Parameters
    ----------
    image : ndarray (H, W, C)
        Texel values, row 0 at v = 0.
    uv : ndarray (N, 2)
        Lightmap UVs.

    Returns
    -------
    ndarray (N, C)
        The filtered values.
    """
    h, w = image.shape[:2]
    x = np.clip(np.asarray(uv[:, 0], dtype=np.float64) * w - 0.5, 0, w - 1)
    y = np.clip(np.asarray(uv[:, 1], dtype=np.float64) * h - 0.5, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2 if w > 1 else 0)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2 if h > 1 else 0)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    return ((image[y0, x0] * (1 - fx) + image[y0, x1] * fx) * (1 - fy)
            + (image[y1, x0] * (1 - fx) + image[y1, x1] * fx) * fy)


def _sky(coeffs: NDArray, dirs: NDArray) -> NDArray:
    return sh_basis(dirs.reshape(-1, 3), 2).reshape(*dirs.shape[:-1], 9) @ coeffs


def tile_size(settings: LightmapSettings) -> int:
    """Texels per tile: one Embree batch of rays. Each tile draws its directions from its own
    seed (settings.seed, first texel), so a bake is the same however its tiles are run.

    Parameters
    ----------
    settings : LightmapSettings
        The samples per texel.

    Returns
    -------
    int
        Texels per tile.
    """
    return max(1, RAYS_PER_BATCH // int(settings.samples))


def ray_origins(tx: Texels, caster: RayCaster) -> NDArray[np.float64]:
    """The texels' ray origins: their points moved off their faces (RayCaster.offset_points,
    10⁻⁴ of the scene's extent).

    Parameters
    ----------
    tx : Texels
        Covered texels.
    caster : RayCaster
        Over all primitives' faces.

    Returns
    -------
    ndarray (P, 3)
        World-space origins.
    """
    fn = caster.face_normals[tx.face]
    return caster.offset_points(tx.points, fn, 1e-4 / caster.scale, tx.face)[0]


def gather_tile(atlas: Atlas, tx: Texels, span: tuple[int, int], sky: NDArray,
                settings: LightmapSettings, caster: RayCaster,
                origins: NDArray | None = None, tables: HitTables | None = None) -> Gathered:
    """Trace the hemispheres of texels ``a`` to ``b`` (module docstring).

    Parameters
    ----------
    atlas : Atlas
        The baked primitives.
    tx : Texels
        Covered texels with points and frames.
    span : (int, int)
        The texel range, first and past-the-end.
    sky : ndarray (9, C)
        World-frame radiance SH of the distant environment, C = 3·k channels: k sets of
        red, green, blue (the bake's transfer adds one set per sky coefficient).
    settings : LightmapSettings
        Samples, seed, albedo, sun.
    caster : RayCaster
        Over all primitives' faces, in atlas order.
    origins : ndarray (b − a, 3), optional
        The range's ray origins (`ray_origins`), else computed here.
    tables : HitTables, optional
        The atlas's per-face tables (`shprobe.lightmaps.hits.hit_tables`), else made
        here.

    Returns
    -------
    Gathered
        Direct terms of the range and its front-face hits (texel indices global).
    """
    a, b = span
    S, n = int(settings.samples), b - a
    rng = np.random.default_rng([int(settings.seed), int(a)])
    frames, face = tx.frames[a:b], tx.face[a:b]
    fn = caster.face_normals[face]
    if origins is None:
        origins, _ = caster.offset_points(tx.points[a:b], fn, 1e-4 / caster.scale, face)
    if tables is None:
        tables = hit_tables(atlas, settings.albedo_rgb)
    nodes, w = hemisphere_quadrature(3, 5)
    l_nodes = _sky(sky, np.matmul(nodes, frames))  # (n, Q, C)
    direct_sh = np.matmul((w[:, None] * sh_basis(nodes, 2)).T, l_nodes)  # (n, 9, C)
    direct_e = np.tensordot(w * nodes[:, 2], l_nodes, axes=([0], [1]))  # (n, C)
    from ._kernels import blocked_sums
    from ._kernels_hits import directions, hit_records

    dt, dw, wt = np.empty((n, S, 3)), np.empty((n, S, 3)), np.empty((n, S))
    dw32, below = np.empty((n * S, 3), np.float32), np.empty((n, S), bool)
    directions(rng.random((n, S, 2)), *grid(S), uniform_share(settings.basis),
               np.ascontiguousarray(frames), np.ascontiguousarray(fn), dt, dw, dw32, below, wt)
    f, u, v = caster.first_hit_local(np.repeat(caster.local(origins), S, axis=0), dw32)
    f, u, v = f.reshape(n, S), u.reshape(n, S), v.reshape(n, S)
    direct_sh, direct_e = np.ascontiguousarray(direct_sh), np.ascontiguousarray(direct_e)
    half = np.stack([direct_e, direct_e])
    front = np.empty((n, S), bool)
    back = np.empty(n)
    blocked_sums(dt, dw, below, f, np.ascontiguousarray(caster.face_normals),
                 np.ascontiguousarray(sky, dtype=np.float64), wt, direct_sh, direct_e,
                 half, front, back)
    m = int(front.sum())
    ps, rec = np.empty((m, 2), np.int64), np.empty((m, 5))
    hit_records(f, u, v, front, tables.uv1, tables.uv0, tables.base, tables.tex, tables.texels,
                tables.tex_info, ps, rec)
    pi, si, huv, alb = ps[:, 0], ps[:, 1], rec[:, :2], rec[:, 2:]
    if settings.sun is not None:
        _add_sun(frames, settings, caster, origins, fn, direct_sh, direct_e, half)
    return Gathered(direct_sh, direct_e, pi + a, huv.astype(np.float32),
                    (alb * (wt[pi, si, None] / np.pi)).astype(np.float32),
                    dt[pi, si].astype(np.float32),
                    back <= 0.5, half)


def blocked_sums_numpy(dt: NDArray, dw: NDArray, below: NDArray, f: NDArray,
                       face_normals: NDArray, sky: NDArray, c: NDArray
                       ) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """The control variate's corrections over a tile's rays: the reference of the numba
    kernel ``_kernels.blocked_sums`` (module docstring's estimator).

    Parameters
    ----------
    dt, dw : ndarray (n, S, 3)
        Ray directions in the tangent frames and in world space.
    below : ndarray (n, S) bool
        Rays below their texel's face.
    f : ndarray (n, S)
        Face hit, or −1.
    face_normals : ndarray (F, 3)
        Unit face normals.
    sky : ndarray (9, C)
        World radiance SH.
    c : ndarray (n, S)
        The rays' weights 1/(S p(ω)).

    Returns
    -------
    tuple of ndarray
        The subtrahends of direct_sh (n, 9, C), direct_e (n, C) and half (2, n, C); front-face
        hits (n, S); the share of back-face hits and rays below (n,).
    """
    blocked = (f >= 0) | below
    backface = (f >= 0) & (np.einsum("psj,psj->ps", dw,
                                     face_normals[np.maximum(f, 0)]) > 0)
    yk = sh_basis(dt.reshape(-1, 3), 2).reshape(*dt.shape[:2], 9)
    ls = _sky(sky, dw) * (blocked * c)[..., None]
    lz = ls * dt[..., 2:3]
    return (np.matmul(yk.transpose(0, 2, 1), ls), lz.sum(1),
            np.stack([2 * lz[:, 0::2].sum(1), 2 * lz[:, 1::2].sum(1)]),
            (f >= 0) & ~backface & ~below, (backface | below).mean(1))


def join(parts: list[Gathered]) -> Gathered:
    """The tiles' gathers, in texel order, as one.

    Parameters
    ----------
    parts : list of Gathered
        From `gather_tile`, ranges in order.

    Returns
    -------
    Gathered
        Their concatenation.
    """
    cat = np.concatenate
    return Gathered(cat([g.direct_sh for g in parts]), cat([g.direct_e for g in parts]),
                    cat([g.hit_texel for g in parts]), cat([g.hit_uv for g in parts]),
                    cat([g.hit_weight for g in parts]), cat([g.hit_dir for g in parts]),
                    cat([g.valid for g in parts]), cat([g.half_e for g in parts], axis=1))


def gather(atlas: Atlas, tx: Texels, sky: NDArray, settings: LightmapSettings,
           caster: RayCaster, progress: Progress | None = None) -> Gathered:
    """Trace every texel's hemisphere once, tile by tile (module docstring).

    Parameters
    ----------
    atlas : Atlas
        The baked primitives.
    tx : Texels
        Covered texels with points and frames.
    sky : ndarray (9, C)
        World-frame radiance SH, C = 3·k channels (see `gather_tile`).
    settings : LightmapSettings
        Samples, seed, albedo, sun.
    caster : RayCaster
        Over all primitives' faces, in atlas order.
    progress : Progress, optional
        Reporter.

    Returns
    -------
    Gathered
        Direct terms and the front-face hits.
    """
    from concurrent.futures import ThreadPoolExecutor

    from ..limits import cores

    t = tile_size(settings)
    ranges = [(a, min(tx.count, a + t)) for a in range(0, tx.count, t)]
    # the ray origins of all texels at once: the caster builds its per-part scenes here, not
    # raced by the threads
    origins = ray_origins(tx, caster)
    tables = hit_tables(atlas, settings.albedo_rgb)
    # tiles in threads: Embree and NumPy's large operations release the GIL, and every tile
    # has its own seed, so the result does not depend on the order they finish in
    with stage(progress, "tracing texel rays", total=tx.count) as bar, \
            ThreadPoolExecutor(max_workers=min(cores(), len(ranges))) as pool:
        jobs = [pool.submit(gather_tile, atlas, tx, (a, b), sky, settings, caster, origins[a:b],
                            tables)
                for a, b in ranges]
        parts = []
        for job, (a, b) in zip(jobs, ranges, strict=True):
            parts.append(job.result())
            bar.advance(b - a)
    return join(parts)


def _add_sun(frames: NDArray, settings: LightmapSettings, caster: RayCaster, origins: NDArray,
             fn: NDArray, direct_sh: NDArray, direct_e: NDArray, half: NDArray) -> None:
    d, rgb = (np.asarray(x, dtype=np.float64) for x in settings.sun)  # type: ignore[union-attr]
    d = d / np.linalg.norm(d)
    st = np.einsum("pij,j->pi", frames, d)
    lit = (st[:, 2] > 0) & (fn @ d > 0)
    idx = np.flatnonzero(lit)
    if len(idx):
        occ = caster.occluded(origins[idx], np.broadcast_to(d, (len(idx), 3)))
        idx = idx[~occ]
    # the sun is in the first three channels (the lighting's colours) only: any further
    # channels are the sky's transfer, which the sun is no part of
    direct_sh[idx, :, :3] += sh_basis(st[idx], 2)[:, :, None] * rgb
    e = st[idx, 2:3] * rgb
    direct_e[idx, :3] += e
    half[:, idx, :3] += e
