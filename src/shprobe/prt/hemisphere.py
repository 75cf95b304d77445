"""Adaptive hemisphere quadrature at chosen vertices of a PRT bake.

A vertex lit through a slot — the ground under an object's belly — sees the sky in a thin band,
and the error of a fixed direction set there is the error at the band's edges: v4612 under the
bunny needs about half a million Fibonacci directions for 0.1 % (docs/prt.md, "why these
defaults"). Here the directions are the cells of a quadtree on the unit square, mapped to the
hemisphere about the vertex's normal by an equal-area map (`equal_area_hemisphere`:
every cell of level l holds 2π / (G·2^l)² sr), and rays are spent where visibility changes:

1. level 0: the G × G cell centres, each vertex the grid turned by its own angle about its
   normal (a hash of its index and the seed), so that neighbours' errors are independent;
2. level l + 1: the four children of every cell of level l (traced or not) whose visibility
   (escapes / blocked) differs from one of its eight neighbours;
3. every finest cell takes the value of the deepest traced cell that covers it; a traced
   cell's weight is its finest cells' solid angle times its own cos θ (the midpoint rule).

The transfer's rows are then the bake's sums (LH §4) over these weighted directions:
T_0 = Σ_escaping w y(ω) and the gather matrix Σ_front-hits w β (`shprobe.prt.trace`).
Cell centres, not jittered points: the midpoint rule over the smooth rest (cos θ y(ω) on a cell)
is exact to O(1/G²), where a jittered point adds noise of O(1/G). A feature thinner than a
level-0 cell that no centre hits is missed (a sky sliver below the grid's resolution): G sets
the smallest feature found, the levels how finely its edges are resolved.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..progress import Progress, track
from ..scene.raycast import RayCaster
from ..sh import num_coeffs, sh_basis
from ..sh.rotation import frame_from_normal
from .directions import RAYS_PER_CHUNK
from .geometry import BakeScene
from .transfer import vertex_hash


@dataclass(frozen=True)
class TraceContext:
    """What every ray-tracing pass of one bake reads: the scene, its ray caster, the face
    normals (float32) when the bounce gather is wanted (else None), the map that runs the
    workers, the degree, the seed and the progress reporter."""

    sc: BakeScene
    caster: RayCaster
    fnormals: NDArray[np.float32] | None
    pmap: Callable[..., Iterable[Any]]
    lmax: int
    seed: int
    progress: Progress | None = None


#: Quadratures of the dense vertices.
QUADRATURES = ("fibonacci", "adaptive")
#: The most levels of the adaptive refinement (each halves the finest cell).
MAX_ADAPTIVE_LEVELS = 8

__all__ = ["ADAPTIVE_LEVELS", "adaptive_grid", "equal_area_hemisphere", "trace_adaptive"]

#: Default levels of visibility refinement below the level-0 grid.
ADAPTIVE_LEVELS = 3

_NEIGHBOURS = [(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1) if a or b]


def adaptive_grid(samples: int) -> int:
    """G, the level-0 cells per side, for a budget of ``samples`` directions over the sphere
    (``samples``/2 over the hemisphere, as a Fibonacci set of that size traces): √(samples/2)."""
    return max(2, round(float(np.sqrt(samples / 2.0))))


def equal_area_hemisphere(u: NDArray[np.float64], v: NDArray[np.float64]
                          ) -> NDArray[np.float64]:
    """Points (u, v) of the unit square → unit vectors (..., 3) of the upper hemisphere about
    +z: Shirley & Chiu's concentric map to the unit disc (area-preserving) and Lambert's
    azimuthal equal-area lift (z = 1 − r², sin θ = r √(2 − r²)), so that a region of the square
    of area a holds 2πa sr. Solid angle, not cos θ dω, is spread evenly: near the horizon a cell
    spans about 2/G rad of elevation, where a cosine-weighted lift (Malley) spans ~√(2/G) rad —
    too coarse for a sky seen through a slot at grazing angles."""
    a, b = 2.0 * np.asarray(u, dtype=np.float64) - 1.0, 2.0 * np.asarray(v, dtype=np.float64) - 1.0
    first = np.abs(a) > np.abs(b)
    r = np.where(first, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(first, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    phi = np.where(r == 0, 0.0, phi)
    r2 = r * r
    s = r * np.sqrt(np.maximum(0.0, 2.0 - r2))  # ± sin θ: a negative r turns φ by π
    return np.stack([s * np.cos(phi), s * np.sin(phi), 1.0 - r2], axis=-1)


def _edge_cells(val: NDArray[np.int8]) -> NDArray[np.bool_]:
    """Cells of the (n, R, R) grids whose value differs from one of their eight neighbours
    (the square's border is the horizon: no neighbour there)."""
    r = val.shape[1]
    p = np.pad(val, ((0, 0), (1, 1), (1, 1)), mode="edge")
    out = np.zeros(val.shape, dtype=bool)
    for a, b in _NEIGHBOURS:
        out |= p[:, 1 + a:1 + a + r, 1 + b:1 + b + r] != val
    return out


def _turned_frames(normals: NDArray[np.float64], rows: NDArray[np.int64], seed: int
                   ) -> NDArray[np.float64]:
    """Frames (n, 3, 3), columns (t, b, n), each turned about its normal by an angle hashed
    from the vertex index and the seed (reproducible; independent of how rows are split)."""
    ang = (vertex_hash(rows, seed) >> np.uint64(11)).astype(np.float64) * (2.0 * np.pi / 2.0**53)
    f = frame_from_normal(normals)
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    t, b = f[:, :, 0], f[:, :, 1]
    return np.stack([c * t + s * b, c * b - s * t, f[:, :, 2]], axis=-1)


def trace_adaptive(ctx: TraceContext, rows: NDArray[np.int64], origins: NDArray[np.float32],
                   grid: int, levels: int = ADAPTIVE_LEVELS,
                   description: str = "tracing rays (adaptive)"
                   ) -> tuple[NDArray[np.float64], list[tuple[NDArray[np.int64], Any]], int]:
    """The unscaled shadowed rows Σ_escaping w y(ω) (len(rows), K) of the vertices ``rows`` by
    the adaptive quadrature of the module doc (``grid`` G cells per side, ``levels`` of
    refinement), their gather matrix's CSR blocks (vertex indices, (n, V) rows of Σ w β over
    front-face hits; [] without gather, i.e. ``ctx.fnormals`` None) as
    `shprobe.prt.trace.trace_rows` returns them, and the number of rays traced.
    ``origins``: the rows' ray origins (float32, the caster's frame)."""
    sc, caster, lmax, seed = ctx.sc, ctx.caster, ctx.lmax, ctx.seed
    fnormals, pmap, progress = ctx.fnormals, ctx.pmap, ctx.progress
    gather = fnormals is not None
    from scipy.sparse import coo_matrix

    n_all = len(rows)
    frames = _turned_frames(sc.normals[rows].astype(np.float64), rows, seed)
    finest = (grid * 2 ** max(0, int(levels) - 1)) ** 2  # cells of the deepest grids kept
    step = max(1, min(RAYS_PER_CHUNK // (grid * grid), (1 << 24) // finest))
    spans = [(i, min(i + step, n_all)) for i in range(0, n_all, step)]
    c0, c1 = np.meshgrid(np.arange(grid), np.arange(grid), indexing="ij")
    loc0 = equal_area_hemisphere((c0.ravel() + 0.5) / grid, (c1.ravel() + 0.5) / grid)

    def work(span: tuple[int, int]):
        i0, i1 = span
        n, res = i1 - i0, grid
        fr = frames[i0:i1]
        traced: list[tuple] = []  # per batch: (vertex, direction, blocked, prim, u, v)
        areas: list[NDArray[np.float64]] = []  # the solid angle each traced cell keeps
        owner = np.empty((n, res, res), dtype=np.int32)  # the traced cell covering each cell
        val = np.empty((n, res, res), dtype=np.int8)
        count = 0

        def trace(vi, ci, cj, res, record=True, d=None):
            nonlocal count
            areas.append(np.full(len(vi), 2.0 * np.pi / res**2))
            if d is None:
                loc = equal_area_hemisphere((ci + 0.5) / res, (cj + 0.5) / res)
                d = np.einsum("nij,nj->ni", fr[vi], loc)
            d32 = np.ascontiguousarray(d, dtype=np.float32)
            if gather:
                prim, u, v = caster.first_hit_local(origins[i0 + vi], d32)
                blocked = prim >= 0
            else:
                blocked, prim, u, v = caster.occluded_local(origins[i0 + vi], d32), None, None, None
            traced.append((vi, d, blocked, prim, u, v))
            if record:
                owner[vi, ci, cj] = np.arange(count, count + len(vi))
                val[vi, ci, cj] = blocked
            count += len(vi)

        vi, ci, cj = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(res),
                                                   np.arange(res), indexing="ij"))
        # level 0: one grid of local directions turned into every vertex's frame
        trace(vi, ci, cj, res, d=np.matmul(loc0, fr.transpose(0, 2, 1)).reshape(-1, 3))
        for level in range(int(levels)):
            vi, ci, cj = np.nonzero(_edge_cells(val))
            if not len(vi):
                break
            # the split cells' solid angle passes from the traced cells covering them to
            # their four children
            area = np.concatenate(areas)
            area -= np.bincount(owner[vi, ci, cj], minlength=count) * (2.0 * np.pi / res**2)
            areas[:] = [area]
            if level + 1 < int(levels):  # the grids the next level's edges are found on
                owner = owner.repeat(2, 1).repeat(2, 2)
                val = val.repeat(2, 1).repeat(2, 2)
            res *= 2
            vi = np.repeat(vi, 4)
            ci = 2 * np.repeat(ci, 4) + np.tile([0, 0, 1, 1], len(ci))
            cj = 2 * np.repeat(cj, 4) + np.tile([0, 1, 0, 1], len(cj))
            trace(vi, ci, cj, res, record=level + 1 < int(levels))
        vi = np.concatenate([x[0] for x in traced])
        d = np.concatenate([x[1] for x in traced])
        blocked = np.concatenate([x[2] for x in traced])
        cos = np.maximum(0.0, np.einsum("ij,ij->i", d, fr[vi, :, 2]))
        w = np.concatenate(areas) * cos
        esc = np.flatnonzero(~blocked & (w > 0))
        proj = coo_matrix((w[esc], (vi[esc], np.arange(esc.size))),
                          shape=(n, esc.size)).tocsr() @ sh_basis(d[esc], lmax)
        if not gather:
            return proj, None, count
        prim = np.concatenate([x[3] for x in traced])
        uu = np.concatenate([x[4] for x in traced])
        vv = np.concatenate([x[5] for x in traced])
        hit = np.flatnonzero(blocked & (w > 0))
        sel = hit[np.einsum("ij,ij->i", d[hit], fnormals[prim[hit]]) < 0]  # front faces send
        beta = np.stack([1.0 - uu[sel] - vv[sel], uu[sel], vv[sel]], axis=1)
        g = coo_matrix(((beta * w[sel, None]).ravel(),
                        (np.repeat(vi[sel], 3), sc.faces[prim[sel]].ravel())),
                       shape=(n, sc.n_vertices))
        return proj, g.tocsr(), count

    t0 = np.empty((n_all, num_coeffs(lmax)), dtype=np.float64)
    blocks = []
    total = 0
    for (i0, i1), (proj, g, c) in zip(spans, track(pmap(work, spans), progress, description,
                                                   len(spans)), strict=True):
        t0[i0:i1] = proj
        total += c
        if gather:
            blocks.append((rows[i0:i1], g))
    return t0, blocks, total
