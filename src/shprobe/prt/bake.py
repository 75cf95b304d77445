"""Baking per-vertex transfer vectors (Lisle & Huang 2007 §4; Sloan et al. 2002 §5).

Three diffuse models, all with the radiance scale of :mod:`shprobe.prt.transfer`
(transfer · L = exit radiance):

- unshadowed: analytic, b_lm = π H_l y_lm(n) = Â_l y_lm(n) (LH eq. 9–10), times ρ/π;
- shadowed: ρ/π Σ_j V(ω_j) max(0, n·ω_j) y(ω_j) 4π/N over N seeded spherical-Fibonacci
  directions, visibility V by Embree occlusion rays from the vertex offset along its normal
  (:meth:`~shprobe.scene.raycast.RayCaster.offset_points`: a step that would cross another
  surface, as at a vertex touching the ground, is put back; only directions with n·ω > 0 are
  traced);
- interreflected: the shadowed term plus k bounces; bounce b gathers, along every blocked ray
  that hits a front face, the previous bounce's transfer interpolated barycentrically over the
  hit triangle: T_b(v) = ρ_v/π Σ_j max(0, n·ω_j) T_{b−1}(hit_j) 4π/N. Back-face hits block
  light but send none.

One bake serves every model up to the one baked (run-time switching, LH §4): the unshadowed
transfer is analytic in the stored normals; an interreflected bake keeps its bounce-0 (shadowed)
transfer and the cumulative transfer after every bounce.

Threads: ``threads`` workers run the ray casting (Embree queries from embreex, which releases the
GIL), the numba ray-set and visibility kernels (``nogil``) and the sparse bounce products (scipy,
GIL released) on blocks of vertices. No kernel here is numba-``parallel`` and the bake does no
BLAS work of note; Embree's BVH build (milliseconds) uses Embree's own threads, which embreex
does not let us set.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import check_memory
from ..scene.raycast import RayCaster
from ..sh import check_lmax, num_coeffs, sh_basis
from ..sh.rotation import from_quaternion, wigner_d
from .hemisphere import ADAPTIVE_LEVELS, adaptive_grid, trace_adaptive
from .scene import Scene, load_scene
from .transfer import (
    MODES,
    Transfer,
    as_stored,
    check_int,
    coloured,
    times_albedo,
    unshadowed_transfer,
    vertex_hash,
)

__all__ = ["bake", "default_refinement", "random_rotation", "rotated_direction_sets",
           "sample_directions", "unshadowed_transfer"]

#: Rays traced per work item (a block of vertices × their upper-hemisphere directions).
RAYS_PER_CHUNK = 1 << 17
#: Ray origins are moved this fraction of the scene's bounding-box diagonal along the normal.
OFFSET_FRACTION = 1e-4
#: Quadratures of the dense vertices (:func:`bake`'s ``dense_quadrature``).
QUADRATURES = ("fibonacci", "adaptive")
#: ``dense_factor`` of a refined bake with ``dense_quadrature="adaptive"``: a 128² grid at 1024
#: samples; with ``"fibonacci"``: 8192 directions at 1024 samples.
ADAPTIVE_DENSE_FACTOR = 32
FIBONACCI_DENSE_FACTOR = 8
#: ``bake``'s named refinements (:data:`shprobe.prt.refine.ADAPTIVE_CONTACT`, ``FINE_CONTACT``).
PRESETS = {"adaptive": "ADAPTIVE_CONTACT", "fine": "FINE_CONTACT", "quick": "QUICK_CONTACT"}
#: The most levels of :mod:`.hemisphere`'s refinement (each halves the finest cell).
MAX_ADAPTIVE_LEVELS = 8

ProgressFn = Callable[..., Iterable[Any]]
#: ``pick(direct, cumulative, blocks, albedo)`` → vertex indices (:func:`_bake`'s ``pick``).
PickFn = Callable[..., NDArray[np.int64]]


def random_rotation(rng: np.random.Generator) -> NDArray[np.float64]:
    """A uniformly distributed rotation matrix (a unit quaternion from 4 normals)."""
    return from_quaternion(rng.normal(size=4))


def sample_directions(n: int, seed: int = 0) -> NDArray[np.float64]:
    """N spherical-Fibonacci unit vectors turned by a random rotation drawn from ``seed``.

    Each point carries the solid angle 4π/N; the same seed (an integer >= 0) gives the same
    directions.
    """
    n = check_int(n, 1, "the number of sample directions")
    seed = check_int(seed, 0, "seed")
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * ((i * (np.sqrt(5.0) - 1.0) / 2.0) % 1.0)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    return d @ random_rotation(np.random.default_rng(seed)).T


def check_threads(threads: Any) -> int:
    """None → all cores; otherwise an integer >= 1."""
    if threads is None:
        return max(1, os.cpu_count() or 1)
    return check_int(threads, 1, "threads")


def _chunks(n_vertices: int, samples: int) -> list[tuple[int, int]]:
    step = max(1, RAYS_PER_CHUNK // max(1, samples // 2))
    return [(i, min(i + step, n_vertices)) for i in range(0, n_vertices, step)]


def _quiet(items: Iterable[Any], description: str = "", total: int | None = None) -> Iterator:
    yield from items


def bake(scene: Any, mode: str = "shadowed", lmax: int = 4, samples: int = 1024,
         bounces: int = 2, albedo: Any = None, seed: int = 0, ground: bool = False,
         threads: int | None = None, progress: ProgressFn | None = None, *,
         mesh_albedo: Any = None, ground_albedo: Any = None,
         refine: bool | str | None = None, dense: Any = None,
         dense_samples: int | None = None, direction_sets: int | None = None,
         final_gather: int = 0, final_gather_inner: int = 0,
         final_gather_near: float | None = None, dense_quadrature: str | None = None,
         adaptive_levels: int = ADAPTIVE_LEVELS) -> Transfer:
    """Bake per-vertex transfer vectors (Lisle & Huang 2007 §4).

    scene: a mesh path, a trimesh object, a list of them, or a :class:`Scene`. albedo: one value
    for every mesh (a number or r,g,b); mesh_albedo: one entry per mesh (number, r,g,b or
    per-vertex values); ground, ground_albedo: see :func:`load_scene`. mode: 'unshadowed' |
    'shadowed' | 'interreflected' — the most complete model baked: a shadowed bake also gives
    unshadowed, an interreflected bake also gives shadowed and any fewer bounces
    (:meth:`Transfer.select`). lmax: degree baked (any lower degree can be used later).
    samples: ray directions per vertex over the whole sphere (about half are traced).
    bounces: interreflection bounces (interreflected only). seed: an integer >= 0, picks the
    random rotation of the direction set. threads: workers for ray casting, kernels and bounce
    products (default: all cores; see the module docstring). progress: a wrapper
    ``progress(items, description, total)`` that yields ``items`` (e.g.
    :func:`shprobe.cli.common.progress`).

    refine: adaptive refinement of the scene where the transfer varies fast
    (:func:`shprobe.prt.refine.bake_refined`); default (None): on for traced bakes with a
    ground; True (and that default): :func:`default_refinement` — ``"adaptive"`` for an
    interreflected bake with bounces, else ``"quick"``. ``"adaptive"``: with
    :data:`shprobe.prt.refine.ADAPTIVE_CONTACT` (the contact and what its bounces lean on
    traced on the adaptive grid, a post-pass, 256 direction sets: on the bunny the contact
    within 3× the open vertices' error with 1 and 2 bounces, at about 10× the quick one's
    time: docs/benchmarks.md, issue 17 runs 11, 13 and 14); ``"quick"``: with
    :data:`shprobe.prt.refine.QUICK_CONTACT` (bake_refined's own defaults: the contact 2.4–17×
    the open vertices' error); ``"fine"``: with :data:`shprobe.prt.refine.FINE_CONTACT` (run
    8); False: none.
    dense, dense_samples: vertex indices (or a (V,) mask) traced with ``dense_samples``
    directions instead of ``samples`` (their own seeded Fibonacci set) — where visibility is
    intricate and the light is dim, as in a crevice, so that the quadrature noise relative to
    the vertex's radiance stays at the level of the rest (the refinement passes the vertices
    it touched).
    dense_quadrature: ``"fibonacci"`` (default) or ``"adaptive"``: the dense vertices trace an
    equal-area grid of √(dense_samples/2) cells per side over their hemisphere and refine it
    ``adaptive_levels`` (0–8) times where visibility changes (:mod:`shprobe.prt.hemisphere`):
    on the bunny's slot-lit ground vertex within 0.04 % at ~38k rays, where 524,288 Fibonacci
    directions leave 0.11 % (docs/benchmarks.md, issue 17 run 10). The refinement's dense
    vertices get 32 × ``samples`` (G = 128 at 1024 samples; G = 64 misses slivers of that
    vertex's sky), 8 × as Fibonacci directions.
    direction_sets: 1 (default; ``refine="adaptive"``, and so an interreflected bake's
    default refinement: 256): every vertex traces the same
    directions; N > 1: N rotated copies of the set, each vertex one of them by a hash of its
    index (:func:`rotated_direction_sets`), so that neighbours' quadrature errors are
    independent rather than shared (docs/benchmarks.md, issue 17 run 5: on the bunny it lowers
    the open vertices' error but not the contact's, so it is not the default; run 13: with
    the post-pass it lowers the error of the contact's second bounce, which gathers many
    vertices traced with the shared directions).
    final_gather: M >= 1 (interreflected, with ``dense``): the dense vertices' bounces read the
    previous layer at each hit point by M fresh cosine-weighted rays instead of interpolating
    it over the hit triangle (:mod:`shprobe.prt.final_gather`); final_gather_inner: M' rays of
    a third level (the second bounce interpolates nothing either); final_gather_near: r, only
    the hits closer than r × their triangle's longest edge are gathered so (None: all). Opt-in:
    on the bunny it does not lower the worst contact error (docs/benchmarks.md, issue 17 run 7).

    Returns a :class:`Transfer`; its ``transfer`` ((V, K) float32, or (V, K, 3) when the albedo
    is coloured) is the baked model, with transfer · L = exit radiance
    ρ/π ∫ L V max(0, n·ω) dω (+ bounces).
    """
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    if final_gather_near is not None:
        try:
            final_gather_near = float(final_gather_near)
        except (TypeError, ValueError):
            final_gather_near = float("nan")
        if not (np.isfinite(final_gather_near) and final_gather_near >= 0):
            raise ShprobeError("final_gather_near must be a finite number >= 0 (or None)")
    if refine is None:
        refine = bool(ground) and mode != "unshadowed"
    if isinstance(refine, np.bool_):
        refine = bool(refine)
    if not (isinstance(refine, bool) or (isinstance(refine, str) and refine in PRESETS)):
        raise ShprobeError(f"refine must be True, False, None, {', '.join(map(repr, PRESETS))}"
                           f", got {refine!r}")
    if refine is True:  # the default refinement: the contact at the noise level (issue 17)
        refine = default_refinement(mode, bounces)
    if refine:
        from . import refine as _refine
        from .refine import bake_refined

        if dense is not None:
            raise ShprobeError("dense vertices are chosen by the refinement; pass refine=False")
        preset = dict(getattr(_refine, PRESETS[refine])) if refine in PRESETS else {}
        own_sets = preset.pop("direction_sets", 1)
        return bake_refined(scene, mode, lmax, samples, bounces, albedo, seed, ground, threads,
                            progress, mesh_albedo=mesh_albedo, ground_albedo=ground_albedo,
                            direction_sets=own_sets if direction_sets is None else direction_sets,
                            final_gather=final_gather,
                            final_gather_inner=final_gather_inner,
                            final_gather_near=final_gather_near,
                            **{**preset,
                               **({} if dense_quadrature is None else {
                                   "dense_quadrature": dense_quadrature,
                                   "adaptive_levels": adaptive_levels,
                                   "dense_factor": (ADAPTIVE_DENSE_FACTOR
                                                    if dense_quadrature == "adaptive"
                                                    else FIBONACCI_DENSE_FACTOR)})})
    return _bake(scene, mode, lmax, samples, bounces, albedo, seed, ground, threads, progress,
                 mesh_albedo, ground_albedo, dense, dense_samples,
                 sets=check_int(1 if direction_sets is None else direction_sets, 1,
                                "direction_sets"),
                 final_gather=check_int(final_gather, 0, "final_gather"),
                 final_gather_inner=check_int(final_gather_inner, 0, "final_gather_inner"),
                 final_gather_near=final_gather_near,
                 quadrature=_check_quadrature(dense_quadrature or "fibonacci", final_gather,
                                              adaptive_levels),
                 levels=int(adaptive_levels))[0]


def default_refinement(mode: str, bounces: Any) -> str:
    """The preset ``bake(refine=True)`` (and a traced bake with a ground) refines with:
    ``"adaptive"`` for an interreflected bake with bounces — the one that brings the contact's
    error to the open vertices' noise level (docs/benchmarks.md, issue 17 run 14) — else
    ``"quick"`` (the adaptive preset's picks and post-pass serve the bounces' gathers, which a
    shadowed bake has none of)."""
    return ("adaptive" if mode == "interreflected" and check_int(bounces, 0, "bounces") > 0
            else "quick")


def _check_quadrature(quadrature: Any, final_gather: Any, levels: Any) -> str:
    """:func:`bake`'s ``dense_quadrature`` and ``adaptive_levels``, checked."""
    if check_int(levels, 0, "adaptive_levels") > MAX_ADAPTIVE_LEVELS:
        raise ShprobeError(f"adaptive_levels must be at most {MAX_ADAPTIVE_LEVELS}, got {levels}")
    if not (isinstance(quadrature, str) and quadrature in QUADRATURES):
        raise ShprobeError(f"dense_quadrature must be one of {', '.join(QUADRATURES)}, got "
                           f"{quadrature!r}")
    if quadrature == "adaptive" and final_gather:
        raise ShprobeError("the final gather traces the Fibonacci directions; it does not go "
                           "with dense_quadrature='adaptive'")
    return quadrature


def _bake(scene: Any, mode: str, lmax: int, samples: int, bounces: int, albedo: Any, seed: int,
          ground: bool, threads: int | None, progress: ProgressFn | None, mesh_albedo: Any,
          ground_albedo: Any, dense: Any, dense_samples: int | None, keep_gather: bool = False,
          sets: int = 1, final_gather: int = 0, final_gather_inner: int = 0,
          final_gather_near: float | None = None, quadrature: str = "fibonacci",
          levels: int = ADAPTIVE_LEVELS, pick: PickFn | None = None,
          second: tuple[NDArray[np.bool_], int] | None = None
          ) -> tuple[Transfer, list[tuple[NDArray[np.int64], Any]] | None]:
    """:func:`bake` without refinement; with ``keep_gather`` (an interreflected bake) also the
    bounce gather matrix G as its blocks (vertex indices, CSR rows (n, V)): bounce b+1 =
    ρ/π · G @ bounce b (:mod:`shprobe.prt.refine` reads where each vertex gathers from).
    ``sets``, ``final_gather``, ``final_gather_inner``: :func:`bake`'s ``direction_sets``,
    ``final_gather`` and ``final_gather_inner`` (the kept G stays the interpolating one);
    ``quadrature``, ``levels``: :func:`bake`'s ``dense_quadrature`` and ``adaptive_levels``.
    ``pick`` (an interreflected bake with dense vertices): once every vertex is traced, called
    as ``pick(direct, cumulative, blocks, albedo)`` with the layers (V, K, C) and the gather
    blocks; the vertices it returns are traced again as the dense ones are, their rows of
    T_0 and of the gather matrix replaced, before the bounces (the other vertices' rays are
    kept; :func:`shprobe.prt.refine.gather_picks`). ``second``: (mask (V,), directions) of more
    vertices traced on the dense vertices' quadrature with their own number of directions
    (those of ``dense`` keep theirs; not with ``final_gather``)."""
    lmax = check_lmax(lmax)
    seed = check_int(seed, 0, "seed")  # numpy's seeding refuses negatives
    nthreads = check_threads(threads)
    traced_mode = mode != "unshadowed"
    samples = check_int(samples, 16, "samples per vertex") if traced_mode else 0
    bounces = check_int(bounces, 0, "bounces") if mode == "interreflected" else 0
    sc = load_scene(scene, albedo=albedo, ground=ground, ground_albedo=ground_albedo,
                    mesh_albedo=mesh_albedo)
    wrap = progress or _quiet
    groups = _sample_groups(sc.n_vertices, samples, dense, dense_samples) if traced_mode else []
    if second is not None and len(groups) > 1 and np.any(second[0]):
        if final_gather:
            raise ShprobeError("a second dense group does not go with the final gather")
        more = np.asarray(second[0], dtype=bool).copy()
        more[groups[1][0]] = False
        groups[0] = (groups[0][0][~more[groups[0][0]]], groups[0][1])
        groups.append((np.flatnonzero(more), check_int(second[1], 16, "second dense samples")))
    k = num_coeffs(lmax)
    shape = (sc.n_vertices, k) + ((3,) if coloured(sc.albedo) else ())
    counts = tuple(range(bounces + 1)) if traced_mode else ()
    # the layers (float32), the float64 running sums, one worker block of SH rows per thread
    # the adaptive quadrature's grids: int32 owner + int8 value per cell at its one-but-finest
    # level, for at least one vertex per thread
    grids = (5.0 * (adaptive_grid(groups[1][1]) * 2 ** max(0, int(levels) - 1)) ** 2 * nthreads
             if quadrature == "adaptive" and len(groups) > 1 else 0.0)
    # (the picks' cumulative and bounce sums: two more float64 layers)
    check_memory(4.0 * np.prod(shape) * len(counts)
                 + 16.0 * np.prod(shape) * (bool(counts) + (pick is not None))
                 + 8.0 * max([samples] + [g[1] for g in groups]) * k * nthreads + grids,
                 f"a {mode} bake of {sc.n_vertices} vertices at lmax {lmax} with {samples} "
                 "samples")
    traced = np.empty((len(counts), *shape), dtype=np.float32)
    adaptive = None
    if traced_mode:
        with ThreadPoolExecutor(nthreads) as pool:
            pmap = pool.map if nthreads > 1 else map
            t0 = np.empty((sc.n_vertices, k), dtype=np.float64)
            blocks: list[tuple[NDArray[np.int64], Any]] = []
            caster = RayCaster(sc.vertices, sc.faces)  # one BVH for every sample group
            # front-face test of the gather's hits, once for every group
            fnormals = (sc.face_normals().astype(np.float32) if mode == "interreflected"
                        else None)
            rays = [0, 0]  # the adaptive quadrature's rays and vertices

            def trace(rows: NDArray[np.int64], n_dirs: int, dense: bool):
                if dense and quadrature == "adaptive":
                    t0_g, b_g, n_rays = trace_adaptive(
                        sc, caster, rows, _origins(sc, caster, rows)[1], lmax, seed,
                        fnormals, pmap, wrap, adaptive_grid(n_dirs), levels, RAYS_PER_CHUNK)
                    rays[0] += n_rays
                    rays[1] += len(rows)
                    return t0_g, b_g
                return _trace(sc, caster, lmax, n_dirs, seed, fnormals, rows, pmap, wrap, sets)

            for gi, (rows, n_dirs) in enumerate(groups):
                t0[rows], b_g = trace(rows, n_dirs, gi >= 1)  # groups 1, 2: dense, second
                blocks += b_g
            rho = sc.albedo[:, None, : 3 if coloured(sc.albedo) else 1] / np.pi
            picked = np.zeros(0, dtype=np.int64)
            if pick is not None and bounces and len(groups) > 1:
                total = times_albedo(t0, sc.albedo)
                cum, prev = total.copy(), total
                for _ in range(bounces):
                    prev = _gather(blocks, prev, pmap) * rho
                    cum += prev
                picked = np.setdiff1d(np.asarray(pick(total, cum, blocks, sc.albedo),
                                                 dtype=np.int64), groups[1][0])
                if picked.size:  # traced again as the dense ones, the other rays kept
                    t0[picked], b_p = trace(picked, groups[1][1], True)
                    drop = np.zeros(sc.n_vertices, dtype=bool)
                    drop[picked] = True
                    blocks = _without_rows(blocks, drop) + b_p
            if rays[1]:
                adaptive = {"grid": adaptive_grid(groups[1][1]), "levels": int(levels),
                            "rays_per_vertex": round(rays[0] / rays[1], 1)}
            # cumulative layers: traced[b] = shadowed + bounces 1..b, accumulated in float64
            total = times_albedo(t0, sc.albedo)  # (V, K, C), C = 1 or 3
            traced[0] = as_stored(total)
            prev = total
            fg = None
            if final_gather and bounces:
                from .final_gather import final_gather_layers

                # the layers read at the final gather's second-level hits: T_0 … T_{B−2}
                layers = [total]
                for _ in range(bounces - (2 if final_gather_near is None else 1)):
                    layers.append(_gather(blocks, layers[-1], pmap) * rho)
                fg_rows, fg_dirs = groups[-1]
                fg = final_gather_layers(sc, caster, fg_rows, fg_dirs, seed, sets, lmax,
                                         bounces, layers, final_gather, pmap, wrap,
                                         rays2=final_gather_inner, near=final_gather_near)
            for b in wrap(range(1, bounces + 1), "bounces", bounces):
                prev = _gather(blocks, prev, pmap) * rho
                if fg is not None:  # the final gather's bounces at its vertices
                    prev[fg_rows] = fg[b - 1] * rho[fg_rows]
                total = total + prev
                traced[b] = as_stored(total)
    meta = {
        "mesh_hash": sc.mesh_hash, "mode": mode, "lmax": lmax, "samples": samples,
        "bounces": bounces, "seed": seed, "ground": bool(ground),
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
        **({"final_gather": {"rays": int(final_gather), "inner": int(final_gather_inner),
                             "near": final_gather_near, "vertices": len(groups[-1][0])}}
           if final_gather and bounces else {}),
        "scale": "transfer . L = exit radiance rho/pi * int L V max(0, n.w) dw (+ bounces)",
    }
    t = Transfer(vertices=sc.vertices, normals=sc.normals, faces=sc.faces, albedo=sc.albedo,
                 lmax=lmax, traced=traced, bounce_counts=counts, metadata=meta)
    return t, (blocks if keep_gather and mode == "interreflected" else None)


def _without_rows(blocks: list[tuple[NDArray[np.int64], Any]], drop: NDArray[np.bool_]
                  ) -> list[tuple[NDArray[np.int64], Any]]:
    """The gather blocks without the rows of the vertices marked in ``drop`` (V,)."""
    out = []
    for rows, g in blocks:
        keep = np.flatnonzero(~drop[rows])
        if len(keep) == len(rows):
            out.append((rows, g))
        elif len(keep):
            out.append((rows[keep], g[keep]))
    return out


def _gather(blocks: list[tuple[NDArray[np.int64], Any]], prev: NDArray[np.float64],
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


def _sample_groups(n_vertices: int, samples: int, dense: Any, dense_samples: int | None
                   ) -> list[tuple[NDArray[np.int64], int]]:
    """(vertex indices, directions) of each group: every vertex at ``samples``, or the
    ``dense`` ones at ``dense_samples`` and the rest at ``samples``."""
    if dense is None:
        return [(np.arange(n_vertices), samples)]
    d = np.asarray(dense)
    if d.dtype == bool:
        if d.shape != (n_vertices,):
            raise ShprobeError(f"dense mask has shape {d.shape}, not ({n_vertices},)")
        d = np.flatnonzero(d)
    elif d.dtype.kind not in "iu" or d.ndim != 1 or (d.size and (d.min() < 0
                                                                 or d.max() >= n_vertices)):
        raise ShprobeError(f"dense must be vertex indices in 0..{n_vertices - 1} or a mask")
    ns = check_int(dense_samples, 16, "dense samples per vertex")
    mask = np.zeros(n_vertices, dtype=bool)
    mask[d] = True
    return [(np.flatnonzero(~mask), samples), (np.flatnonzero(mask), ns)]


def rotated_direction_sets(rows: NDArray[np.int64], sets: int, seed: int
                           ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The rotations (S, 3, 3) of ``sets`` copies of the direction set and the copy each vertex
    of ``rows`` traces (len(rows),): one set (the identity) for ``sets`` = 1; otherwise random
    rotations drawn from ``seed`` and a copy picked by a hash of the vertex index, so that
    neighbouring vertices (consecutive or not) trace different directions and a bake stays
    reproducible. Neighbours with nearly the same normal that look past the same horizon through
    the same few directions make one shared quadrature error that no gather of theirs averages
    (issue 17, runs 4–5); with their own rotations the errors are independent. The SH rows are
    projected in the copy's frame and turned to the world's by the Wigner matrix D(R) (y(Rω) =
    D(R) y(ω)), so one table of y over the base set serves every copy."""
    if sets <= 1:
        return np.eye(3)[None], np.zeros(len(rows), dtype=np.int64)
    rng = np.random.default_rng([seed, 17])
    rots = from_quaternion(rng.normal(size=(sets, 4)))
    return rots, ((vertex_hash(rows, seed) >> np.uint64(33)) % np.uint64(sets)).astype(np.int64)


def _origins(sc: Scene, caster: RayCaster, rows: NDArray[np.int64]
             ) -> tuple[float, NDArray[np.float32]]:
    """The ray-origin offset ε and the origins of the vertices ``rows`` (float32, the caster's
    frame; row i belongs to vertex rows[i]), offset by the one rule
    (:meth:`~shprobe.scene.raycast.RayCaster.offset_points`)."""
    diag = float(np.linalg.norm(np.ptp(sc.vertices, axis=0)))
    eps = OFFSET_FRACTION * max(diag, 1e-12)
    on = np.full(sc.n_vertices, -1, dtype=np.int64)  # a face of each vertex
    on[sc.faces.ravel()] = np.repeat(np.arange(len(sc.faces)), 3)
    return eps, caster.local(caster.offset_points(sc.vertices[rows], sc.normals[rows], eps,
                                                  on[rows])[0])


def _ray_source(sc: Scene, caster: RayCaster, rows: NDArray[np.int64], samples: int,
                seed: int, sets: int = 1):
    """The vertex rays of a bake for the vertices ``rows``: returns the direction set (N, 3),
    the rotations and set of each row (:func:`rotated_direction_sets`), the ray-origin offset
    ε and ``rays(i0, i1)`` → (origins, directions (float32, the caster's frame), cosines,
    row − i0, direction index) of rows[i0:i1] over their upper hemispheres, origins offset by
    the one rule (:meth:`~shprobe.scene.raycast.RayCaster.offset_points`)."""
    dirs = sample_directions(samples, seed)
    rots, sid = rotated_direction_sets(rows, sets, seed)
    dirs32 = np.ascontiguousarray((dirs @ rots.transpose(0, 2, 1)).astype(np.float32))
    eps, p32 = _origins(sc, caster, rows)
    n32 = sc.normals[rows].astype(np.float32)

    from ._kernels import hemisphere_rays

    def rays(i0: int, i1: int):
        cap = (i1 - i0) * samples
        o = np.empty((cap, 3), np.float32)
        d = np.empty((cap, 3), np.float32)
        cw = np.empty(cap, np.float32)
        vid = np.empty(cap, np.int64)
        did = np.empty(cap, np.int64)
        m = hemisphere_rays(p32[i0:i1], n32[i0:i1], dirs32, sid[i0:i1], o, d, cw, vid, did)
        return o[:m], d[:m], cw[:m], vid[:m], did[:m]

    return dirs, rots, sid, eps, rays


def _trace(sc: Scene, caster: RayCaster, lmax: int, samples: int, seed: int,
           fnormals: NDArray[np.float32] | None, rows: NDArray[np.int64],
           pmap: Callable[..., Iterable[Any]], wrap: ProgressFn, sets: int = 1):
    """For the vertices ``rows`` (rays cast by ``caster``, over ``sc``'s mesh): the
    visibility-weighted projection Σ V cos y 4π/N (len(rows), K), and the bounce gather
    matrix's rows as (vertex indices, CSR block) per span of ``rows`` (None without gather).
    ``fnormals``: the scene's face normals (float32) when the gather is wanted (its hits on
    front faces), else None. ``sets`` > 1: each vertex traces one of that many rotated copies of
    the direction set (:func:`rotated_direction_sets`)."""
    gather = fnormals is not None
    spans = _chunks(len(rows), samples)
    dirs, rots, sid, _, rays = _ray_source(sc, caster, rows, samples, seed, sets)
    yw = sh_basis(dirs, lmax) * (4.0 * np.pi / samples)  # (N, K), in the base set's frame
    faces = sc.faces

    from scipy.sparse import coo_matrix

    from ._kernels import add_visible

    k = yw.shape[1]

    def work(span: tuple[int, int]):
        i0, i1 = span
        o, d, cw, vid, did = rays(i0, i1)
        proj = np.zeros((i1 - i0, k))
        if not gather:
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
    for (i0, i1), (proj, g) in zip(spans, wrap(pmap(work, spans), "tracing rays", len(spans)),
                                   strict=True):
        t0[i0:i1] = proj
        blocks.append((rows[i0:i1], g))
    if sets > 1:  # y(R ω) = D(R) y(ω): each row turned from its set's frame to the world's
        dm = wigner_d(rots, lmax)
        for s in range(sets):
            sel = np.flatnonzero(sid == s)
            t0[sel] = t0[sel] @ dm[s].T
    return t0, blocks
