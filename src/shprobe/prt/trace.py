"""One traced bake (Lisle & Huang 2007 §4; Sloan et al. 2002 §5): the shadowed transfer of every
vertex by Embree occlusion rays, and for an interreflected bake the bounce gather matrix and
the bounces.

- shadowed: ρ/π Σ_j V(ω_j) max(0, n·ω_j) y(ω_j) 4π/N over the N directions of
  `shprobe.prt.directions` (only those with n·ω > 0 are traced);
- interreflected: the shadowed term plus k bounces; bounce b gathers, along every blocked ray
  that hits a front face, the previous bounce's transfer interpolated barycentrically over the
  hit triangle: T_b(v) = ρ_v/π Σ_j max(0, n·ω_j) T_{b−1}(hit_j) 4π/N. Back-face hits block
  light but send none.

Some vertices (`DenseVertices`, chosen by `shprobe.prt.refine`) may trace more directions than
the rest, as Fibonacci directions or on the adaptive grid of `shprobe.prt.hemisphere`; a ``pick``
callback may name more vertices to trace so once the first pass is done.

Threads: ``threads`` workers run the ray casting (Embree queries from embreex, which releases the
GIL), the numba ray-set and visibility kernels (``nogil``) and the sparse bounce products (scipy,
GIL released) on blocks of vertices. No kernel here is numba-``parallel`` and the bake does no
BLAS work of note; Embree's BVH build (milliseconds) uses Embree's own threads, which embreex
does not let us set.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..progress import Progress, track
from ..scene.raycast import RayCaster
from ..sh import num_coeffs, sh_basis
from ..sh.rotation import wigner_d
from .directions import RAYS_PER_CHUNK, ray_origins, ray_source
from .geometry import BakeScene
from .hemisphere import (
    ADAPTIVE_LEVELS,
    MAX_ADAPTIVE_LEVELS,
    QUADRATURES,
    TraceContext,
    adaptive_grid,
    trace_adaptive,
)
from .settings import PrtSettings
from .transfer import Transfer, as_stored, check_int, coloured, times_albedo

__all__ = ["MAX_ADAPTIVE_LEVELS", "QUADRATURES", "DenseVertices", "GatherBlocks",
           "TraceContext", "bake_bytes", "check_threads", "trace_bake"]

#: Bytes of the gather matrix per upward direction of an interreflected bake (CSR values and
#: indices of the hits' three corners, after repeated entries are merged, and the COO blocks
#: they are built from; fitted to the peak resident memory of the bunny + ground quick bakes,
#: bench/bench_prt_memory.py).
GATHER_BYTES_PER_RAY = 10.5
#: Bytes per cell (vertex × coefficient × channel) a traced bake holds besides its float32
#: layers: the float64 visibility sums and their albedo-weighted copy (24), and in a bake
#: with bounces the bounce's product, its output and the running total (12 more): 28 bytes
#: per cell for a shadowed bake, 48 for an interreflected one, as measured (unrefined bunny +
#: ground, lmax 2 to 16).
CELL_WORK_BYTES = 24.0
BOUNCE_CELL_BYTES = 12.0
#: The bounce gather matrix G as blocks of rows: (vertex indices, CSR rows (n, V)).
GatherBlocks = list[tuple[NDArray[np.int64], Any]]
#: ``pick(direct, cumulative, blocks, albedo)`` → vertex indices to trace as the dense ones.
PickFn = Callable[..., NDArray[np.int64]]


@dataclass(frozen=True)
class DenseVertices:
    """Vertices traced with ``samples`` directions instead of the bake's: ``mask`` (V,) bool,
    on ``quadrature`` (``"fibonacci"``: their own seeded Fibonacci set; ``"adaptive"``: an
    equal-area grid of √(samples/2) cells a side refined ``levels`` times where visibility
    changes, `shprobe.prt.hemisphere`). ``extra`` (V,) bool: more vertices on the same quadrature
    with ``extra_samples`` directions (those of ``mask`` keep theirs)."""

    mask: NDArray[np.bool_]
    samples: int
    quadrature: str = "fibonacci"
    levels: int = ADAPTIVE_LEVELS
    extra: NDArray[np.bool_] | None = None
    extra_samples: int = 0

    def __post_init__(self) -> None:
        if check_int(self.levels, 0, "adaptive levels") > MAX_ADAPTIVE_LEVELS:
            raise ShprobeError(f"adaptive levels must be at most {MAX_ADAPTIVE_LEVELS}, got "
                               f"{self.levels}")
        if self.quadrature not in QUADRATURES:
            raise ShprobeError(f"dense quadrature must be one of {', '.join(QUADRATURES)}, "
                               f"got {self.quadrature!r}")


def check_threads(threads: Any) -> int:
    """None → all cores; otherwise an integer >= 1."""
    if threads is None:
        return max(1, os.cpu_count() or 1)
    return check_int(threads, 1, "threads")


def bake_bytes(n_vertices: int, lmax: int, samples: int, layers: int, channels: int = 1,
               threads: int = 1, extra: float = 0.0) -> float:
    """Bytes a traced bake holds (the cost model of `trace_bake`'s memory check and of
    [`shprobe.prt.baking.estimate_bake`][shprobe.prt.estimate_bake]): the stored layers (float32),
    the float64 sums and bounce products (`CELL_WORK_BYTES`, `BOUNCE_CELL_BYTES`), one worker block
    of SH rows per thread, for an interreflected bake (``layers`` > 1) the gather matrix
    (`GATHER_BYTES_PER_RAY` per upward direction), and ``extra`` (the picks' sums, the
    adaptive grids)."""
    cells = float(n_vertices) * num_coeffs(lmax) * channels
    gather = GATHER_BYTES_PER_RAY * 0.5 * samples * n_vertices if layers > 1 else 0.0
    return (cells * (4.0 * layers + CELL_WORK_BYTES * (layers > 0)
                     + BOUNCE_CELL_BYTES * (layers > 1))
            + 8.0 * samples * num_coeffs(lmax) * threads + gather + extra)


def _groups(n_vertices: int, samples: int, dense: DenseVertices | None
            ) -> list[tuple[NDArray[np.int64], int]]:
    """(vertex indices, directions) of each group: every vertex at ``samples``; with ``dense``
    its vertices at their own count, then its ``extra`` ones."""
    if dense is None:
        return [(np.arange(n_vertices), samples)]
    mask = np.asarray(dense.mask, dtype=bool)
    if mask.shape != (n_vertices,):
        raise ShprobeError(f"dense mask has shape {mask.shape}, not ({n_vertices},)")
    ns = check_int(dense.samples, 16, "dense samples per vertex")
    groups = [(np.flatnonzero(~mask), samples), (np.flatnonzero(mask), ns)]
    if dense.extra is not None and np.any(dense.extra):
        more = np.asarray(dense.extra, dtype=bool) & ~mask
        groups[0] = (groups[0][0][~more[groups[0][0]]], samples)
        groups.append((np.flatnonzero(more),
                       check_int(dense.extra_samples, 16, "extra dense samples")))
    return groups


def trace_bake(sc: BakeScene, settings: PrtSettings, progress: Progress | None = None, *,
               dense: DenseVertices | None = None, sets: int = 1, pick: PickFn | None = None,
               keep_gather: bool = False) -> tuple[Transfer, GatherBlocks | None]:
    """Bake ``sc`` once (module doc) by ``settings`` (its mode, degree, samples, bounces,
    seed, threads and limits; not its refinement) and return the [`Transfer`][shprobe.prt.Transfer]
    and, with ``keep_gather`` (an interreflected bake), the bounce gather matrix G as its blocks:
    bounce b+1 = ρ/π · G @ bounce b (`shprobe.prt.refine` reads where each vertex gathers from).

    ``sets`` > 1: each vertex traces one of that many rotated copies of the direction set
    (`rotated_direction_sets`). ``pick`` (an interreflected bake with dense
    vertices): once every vertex is traced, called as ``pick(direct, cumulative, blocks,
    albedo)`` with the layers (V, K, C) and the gather blocks; the vertices it returns are
    traced again as the dense ones are, their rows of T_0 and of the gather matrix replaced,
    before the bounces (the other vertices' rays are kept; `shprobe.prt.criteria.gather_picks`).

    Parameters
    ----------
    sc
        The scene ([`load_scene`][shprobe.prt.load_scene]).
    settings
        Mode, degree, samples, bounces, seed, threads and limits (its refinement unused).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter.
    dense
        Vertices traced with more directions (`DenseVertices`), or None.
    sets
        Rotated copies of the direction set (1: one set).
    pick
        The picks' callback (above), or None.
    keep_gather
        Return the gather blocks too (an interreflected bake).

    Returns
    -------
    tuple
        (the [`Transfer`][shprobe.prt.Transfer], the gather blocks or None).
    """
    mode, lmax, seed = settings.mode, settings.lmax, settings.seed
    nthreads = check_threads(settings.threads)
    sets = check_int(sets, 1, "direction sets")
    traced_mode = settings.traced
    samples = settings.samples if traced_mode else 0
    bounces = settings.bounces if mode == "interreflected" else 0
    groups = _groups(sc.n_vertices, samples, dense) if traced_mode else []
    adaptive_q = dense is not None and dense.quadrature == "adaptive"
    levels = int(dense.levels) if dense is not None else ADAPTIVE_LEVELS
    k = num_coeffs(lmax)
    channels = 3 if coloured(sc.albedo) else 1
    shape = (sc.n_vertices, k) + ((3,) if channels == 3 else ())
    counts = tuple(range(bounces + 1)) if traced_mode else ()
    # the adaptive quadrature's grids: int32 owner + int8 value per cell at its one-but-finest
    # level, for at least one vertex per thread; the picks' cumulative and bounce sums
    grids = (5.0 * (adaptive_grid(groups[1][1]) * 2 ** max(0, levels - 1)) ** 2 * nthreads
             if adaptive_q and len(groups) > 1 else 0.0)
    check_memory(bake_bytes(sc.n_vertices, lmax, samples, len(counts), channels, nthreads,
                            grids + 16.0 * np.prod(shape) * (pick is not None)
                            + 8.0 * max([0] + [g[1] for g in groups[1:]]) * k * nthreads),
                 f"a {mode} bake of {sc.n_vertices} vertices at lmax {lmax} with {samples} "
                 "samples", limits=settings.limits)
    traced = np.empty((len(counts), *shape), dtype=np.float32)
    adaptive = None
    picked = np.zeros(0, dtype=np.int64)
    blocks: GatherBlocks = []
    if traced_mode:
        names = ["tracing rays", "tracing the dense vertices' rays",
                 "tracing the extra dense vertices' rays"]
        with ThreadPoolExecutor(nthreads) as pool:
            pmap = pool.map if nthreads > 1 else map
            t0 = np.empty((sc.n_vertices, k), dtype=np.float64)
            caster = RayCaster(sc.vertices, sc.faces)  # one BVH for every sample group
            # front-face test of the gather's hits, once for every group
            fnormals = (sc.face_normals().astype(np.float32) if mode == "interreflected"
                        else None)
            rays = [0, 0]  # the adaptive quadrature's rays and vertices

            ctx = TraceContext(sc, caster, fnormals, pmap, lmax, seed, progress)

            def trace(rows: NDArray[np.int64], n_dirs: int, group: int, name: str):
                if group and adaptive_q:
                    t0_g, b_g, n_rays = trace_adaptive(
                        ctx, rows, ray_origins(sc, caster, rows)[1], adaptive_grid(n_dirs),
                        levels, f"{name} (adaptive)")
                    rays[0] += n_rays
                    rays[1] += len(rows)
                    return t0_g, b_g
                return trace_rows(ctx, rows, n_dirs, sets, name)

            for gi, (rows, n_dirs) in enumerate(groups):
                t0[rows], b_g = trace(rows, n_dirs, gi, names[gi])
                blocks += b_g
            rho = sc.albedo[:, None, :channels] / np.pi
            if pick is not None and bounces and len(groups) > 1:
                total = times_albedo(t0, sc.albedo)
                cum, prev = total.copy(), total
                for _ in range(bounces):
                    prev = gather(blocks, prev, pmap) * rho
                    cum += prev
                picked = np.setdiff1d(np.asarray(pick(total, cum, blocks, sc.albedo),
                                                 dtype=np.int64), groups[1][0])
                if picked.size:  # traced again as the dense ones, the other rays kept
                    t0[picked], b_p = trace(picked, groups[1][1], 1,
                                            "tracing the picked vertices' rays")
                    drop = np.zeros(sc.n_vertices, dtype=bool)
                    drop[picked] = True
                    blocks = without_rows(blocks, drop) + b_p
            if rays[1]:
                adaptive = {"grid": adaptive_grid(groups[1][1]), "levels": levels,
                            "rays_per_vertex": round(rays[0] / rays[1], 1)}
            # cumulative layers: traced[b] = shadowed + bounces 1..b, accumulated in float64
            total = times_albedo(t0, sc.albedo)  # (V, K, C), C = 1 or 3
            traced[0] = as_stored(total)
            prev = total
            for b in track(range(1, bounces + 1), progress, "bounces", bounces):
                prev = gather(blocks, prev, pmap) * rho
                total = total + prev
                traced[b] = as_stored(total)
    meta = {
        "mesh_hash": sc.mesh_hash, "mode": mode, "lmax": lmax, "samples": samples,
        "bounces": bounces, "seed": seed, "ground": sc.n_ground > 0,
        "albedo": {"min": sc.albedo.min(0).tolist(), "max": sc.albedo.max(0).tolist(),
                   "mean": sc.albedo.mean(0).tolist()},
        "directions": "spherical Fibonacci, seeded random rotation" if samples else "none",
        **({"dense_samples": groups[1][1], "dense_vertices": len(groups[1][0])}
           if len(groups) > 1 else {}),
        **({"dense_picked": int(picked.size)} if traced_mode and pick is not None else {}),
        **({"second_dense": {"vertices": len(groups[2][0]), "samples": groups[2][1]}}
           if len(groups) > 2 else {}),
        **({"direction_sets": int(sets)} if sets > 1 else {}),
        **({"dense_quadrature": {"adaptive": adaptive}} if adaptive else {}),
        "scale": "transfer . L = exit radiance rho/pi * int L V max(0, n.w) dw (+ bounces)",
    }
    t = Transfer(vertices=sc.vertices, normals=sc.normals, faces=sc.faces, albedo=sc.albedo,
                 lmax=lmax, traced=traced, bounce_counts=counts, metadata=meta)
    return t, (blocks if keep_gather and mode == "interreflected" else None)


def without_rows(blocks: GatherBlocks, drop: NDArray[np.bool_]) -> GatherBlocks:
    """The gather blocks without the rows of the vertices marked in ``drop`` (V,)."""
    out = []
    for rows, g in blocks:
        keep = np.flatnonzero(~drop[rows])
        if len(keep) == len(rows):
            out.append((rows, g))
        elif len(keep):
            out.append((rows[keep], g[keep]))
    return out


def gather(blocks: GatherBlocks, prev: NDArray[np.float64],
           pmap: Callable[..., Iterable[Any]]) -> NDArray[np.float64]:
    """One bounce: (gather matrix) @ previous bounce, one CSR block of rows (with the vertex
    index of each row) at a time, in parallel (scipy's sparse product releases the GIL)."""
    v, k, c = prev.shape
    flat = prev.reshape(v, k * c)
    out = np.empty_like(flat)

    def one(i: int) -> None:
        rows, g = blocks[i]
        out[rows] = g @ flat

    for _ in pmap(one, range(len(blocks))):
        pass
    return out.reshape(v, k, c)


def trace_rows(ctx: TraceContext, rows: NDArray[np.int64], samples: int, sets: int = 1,
               description: str = "tracing rays"
               ) -> tuple[NDArray[np.float64], GatherBlocks]:
    """For the vertices ``rows`` (rays cast by ``ctx.caster`` over ``ctx.sc``'s mesh,
    ``samples`` directions each): the visibility-weighted projection Σ V cos y 4π/N
    (len(rows), K), and the bounce gather matrix's rows as (vertex indices, CSR block) per
    span of ``rows`` (None without gather, i.e. when ``ctx.fnormals`` is None). ``sets`` > 1:
    each vertex traces one of that many rotated copies of the direction set
    (`rotated_direction_sets`)."""
    from scipy.sparse import coo_matrix

    from ._kernels import add_visible

    sc, caster, lmax, seed = ctx.sc, ctx.caster, ctx.lmax, ctx.seed
    fnormals, pmap, progress = ctx.fnormals, ctx.pmap, ctx.progress
    gather_wanted = fnormals is not None
    step = max(1, RAYS_PER_CHUNK // max(1, samples // 2))
    spans = [(i, min(i + step, len(rows))) for i in range(0, len(rows), step)]
    dirs, rots, sid, rays = ray_source(sc, caster, rows, samples, seed, sets)
    yw = sh_basis(dirs, lmax) * (4.0 * np.pi / samples)  # (N, K), in the base set's frame
    faces = sc.faces
    k = yw.shape[1]

    def work(span: tuple[int, int]):
        i0, i1 = span
        o, d, cw, vid, did = rays(i0, i1)
        proj = np.zeros((i1 - i0, k))
        if not gather_wanted:
            free = ~caster.occluded_local(o, d)
            add_visible(free, vid, did, cw, yw, proj)
            return proj, None
        prim, u, v = caster.first_hit_local(o, d)
        add_visible(prim < 0, vid, did, cw, yw, proj)
        hit = np.flatnonzero(prim >= 0)
        front = np.einsum("ij,ij->i", d[hit], fnormals[prim[hit]]) < 0
        sel = hit[front]
        ph = prim[sel]
        w = cw[sel] * np.float32(4.0 * np.pi / samples)
        uu, vv = u[sel], v[sel]
        rr = np.repeat(vid[sel], 3)
        cols = faces[ph].ravel()
        vals = (np.stack([1.0 - uu - vv, uu, vv], axis=1) * w[:, None]).ravel()
        # this block's rows of the gather matrix; CSR sums the many repeated (row, col) pairs
        g = coo_matrix((vals.astype(np.float64), (rr, cols)), shape=(i1 - i0, sc.n_vertices))
        return proj, g.tocsr()

    t0 = np.empty((len(rows), num_coeffs(lmax)), dtype=np.float64)
    blocks = []
    for (i0, i1), (proj, g) in zip(spans, track(pmap(work, spans), progress, description,
                                                len(spans)), strict=True):
        t0[i0:i1] = proj
        blocks.append((rows[i0:i1], g))
    if sets > 1:  # y(R ω) = D(R) y(ω): each row turned from its set's frame to the world's
        dm = wigner_d(rots, lmax)
        for s in range(sets):
            sel = np.flatnonzero(sid == s)
            t0[sel] = t0[sel] @ dm[s].T
    return t0, blocks
