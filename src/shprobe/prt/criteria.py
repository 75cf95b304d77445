"""Refinement criteria: where a baked transfer needs more vertices or more directions.

Per-vertex transfer is interpolated linearly over each triangle, both when relighting and when
a bounce gathers the previous bounce at a ray's hit point (`shprobe.prt.trace`). Where it varies
within a triangle much faster than linearly (the contact of an object with the ground) the
interpolated light is wrong however many rays are traced. These measures say where:

- jumps (`transfer_jumps`): ‖T_b(a) − T_b(c)‖ / s_b across each edge, layer by layer
  (the shadowed transfer and each bounce increment), s_b the 90th percentile of ‖T_b‖;
- gather criterion (`gather_importance`, `gather_errors`): bounce b+1 at a vertex v
  is ρ_v/π Σ_c G[v, c] T_b(c) (LH §4), G holding each blocked ray's cosine-weighted solid angle
  times the barycentric weights of its hit. A vertex close to a surface leans on a few of its
  vertices, where a linear interpolant of a fast-varying transfer is far off although the jump
  is small on the scene's scale. The share of v's exit transfer that passes through vertex c is
  ρ_v/π G[v, c] / ‖T(v)‖ (‖T(v)‖ at least ``floor`` × the scene's median); an edge's error is
  its jump times the larger share of its ends, over the gathered layers; jumps below ``tol``
  of the edge's own level are the driving bake's noise, which the gather averages, and count
  zero. This is the irradiance-caching argument in matrix form: a triangle matters in
  proportion to the solid angle it fills as seen from its closest gatherer;
- picks (`gather_picks`): the vertices whose value carries more than a threshold of a
  contact vertex's exit radiance in a bounce, ρ_v/π G[v, c] ‖T_0(c)‖ / ‖T(v)‖, then (second
  round) of a contact vertex or a first-round pick by their cumulative transfer: their own
  quadrature error, shared and never averaged, would be the contact's;
- post-pass (`post_split_marks`): among the vertices the contact leans on, the edges
  where the final shadowed transfer jumps (the slot-lit ground's direct decays as about
  1/distance from the slot: convex, so a linear interpolant overestimates it on every
  triangle).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .subdivide import edge_table
from .trace import GatherBlocks
from .transfer import Transfer

__all__ = ["GATHER_FLOOR", "Gathered", "gather_errors", "gather_importance", "gather_picks",
           "post_split_marks", "transfer_jumps"]

#: Gathering vertices dimmer than this fraction of the scene's median ‖T‖ are judged as if that
#: bright (the relative error of a black vertex is meaningless).
GATHER_FLOOR = 0.02


def transfer_jumps(t: Transfer) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Per vertex pair (edge of ``t.faces``): the largest relative jump over the layers (shadowed
    and each bounce increment), ‖ΔT_b‖ / s_b, s_b the 90th percentile of ‖T_b‖ over the scene's
    vertices (so a bounce, a few per cent of the direct light, is judged on its own scale).
    Returns (edges (E, 2), jumps (E,))."""
    edges, _ = edge_table(np.asarray(t.faces, dtype=np.int64))
    tr = np.asarray(t.traced, dtype=np.float64)
    layers = [tr[0]] + [tr[i] - tr[i - 1] for i in range(1, tr.shape[0])]
    jump = np.zeros(len(edges))
    for lay in layers:
        flat = lay.reshape(lay.shape[0], -1)
        s = float(np.percentile(np.linalg.norm(flat, axis=1), 90))
        if s <= 0:
            continue
        d = np.linalg.norm(flat[edges[:, 0]] - flat[edges[:, 1]], axis=1) / s
        jump = np.maximum(jump, d)
    return edges, jump


def gather_importance(t: Transfer, blocks: GatherBlocks,
                      floor: float = GATHER_FLOOR) -> NDArray[np.float64]:
    """Per vertex c: the largest share of any gathering vertex's exit transfer that passes
    through c's barycentric weight in a bounce, max_v ρ_v/π G[v, c] / ‖T(v)‖ (module doc, gather
    criterion), with G the bake's gather matrix (``blocks``: `shprobe.prt.trace.trace_bake` with
    ``keep_gather``) and ‖T(v)‖ v's cumulative transfer, at least ``floor`` × its median over
    the scene (dimmer vertices are judged as if that bright)."""
    share = _exit_share(t.traced[-1], t.albedo, floor)
    return _leaned_on(share, blocks, np.ones(t.n_vertices, dtype=bool), None)


def _norms(x: Any) -> NDArray[np.float64]:
    """‖x[v]‖ over each vertex's coefficients (and channels)."""
    return np.linalg.norm(np.asarray(x, dtype=np.float64).reshape(len(x), -1), axis=1)


def _exit_share(cumulative: Any, albedo: Any, floor: float) -> NDArray[np.float64]:
    """Per gathering vertex v: ρ_v/π / ‖T(v)‖, the share of v's exit transfer per unit of
    G[v, c] T(c) (module doc, gather criterion), ‖T(v)‖ its cumulative transfer, at least
    ``floor`` × the median over the scene (0 where that is 0)."""
    level = _norms(cumulative)
    scale = np.maximum(level, floor * float(np.median(level)))
    rho = np.asarray(albedo, dtype=np.float64).max(axis=1) / np.pi
    return np.where(scale > 0, rho / np.where(scale > 0, scale, 1.0), 0.0)


def gather_errors(t: Transfer, edges: NDArray[np.int64], importance: NDArray[np.float64],
                  tol: float = 0.25) -> NDArray[np.float64]:
    """Per edge (a, c): the estimated relative error its linear interpolation brings to the
    next bounce of the vertex that leans on it most, max over the layers gathered (shadowed and
    each bounce increment but the last) of ‖T_b(a) − T_b(c)‖ · max(importance[a],
    importance[c]) (module doc, gather criterion); a jump below ``tol`` × the edge's brighter end's
    ‖T_b‖ counts zero (the driving bake's noise, not a shape)."""
    tr = np.asarray(t.traced, dtype=np.float64)
    layers = [tr[0]] + [tr[i] - tr[i - 1] for i in range(1, tr.shape[0] - 1)]
    imp = np.maximum(importance[edges[:, 0]], importance[edges[:, 1]])
    err = np.zeros(len(edges))
    for lay in layers:
        flat = lay.reshape(lay.shape[0], -1)
        norms = np.linalg.norm(flat, axis=1)
        d = np.linalg.norm(flat[edges[:, 0]] - flat[edges[:, 1]], axis=1)
        # only jumps beyond ``tol`` of the edge's own level: not the bake's noise
        big = d > tol * np.maximum(norms[edges[:, 0]], norms[edges[:, 1]])
        err = np.maximum(err, np.where(big, d * imp, 0.0))
    return err


def gather_picks(direct: NDArray[np.float64], cumulative: NDArray[np.float64],
                 blocks: GatherBlocks, albedo: NDArray[np.float64],
                 seeds: NDArray[np.bool_], thresholds: tuple[float, ...],
                 floor: float = GATHER_FLOOR) -> NDArray[np.int64]:
    """The vertices a bounce of the ``seeds`` (V,) leans on (module doc, picks): round r picks
    every vertex c, not yet picked, with max_v ρ_v/π G[v, c] ‖T(c)‖ / ‖T(v)‖ above
    ``thresholds[r]``, v over the seeds and the picks of the rounds before, T(c) c's
    ``direct`` layer in round 0 and its ``cumulative`` one after, ‖T(v)‖ v's cumulative
    transfer, at least ``floor`` × its median over the scene. Layers (V, K, C) with the albedo
    applied (ρ/π T); ``blocks``: the gather matrix G as `shprobe.prt.trace.trace_bake`'s
    (vertex indices, CSR rows). Returns the picked vertices (not the seeds), sorted."""
    share = _exit_share(cumulative, albedo, floor)
    chosen = np.asarray(seeds, dtype=bool).copy()
    for r, thr in enumerate(thresholds):
        # the gatherers: the seeds and every earlier pick
        chosen |= _leaned_on(share, blocks, chosen, _norms(direct if r == 0 else cumulative)) > thr
    return np.flatnonzero(chosen & ~np.asarray(seeds, dtype=bool))


def _leaned_on(share: NDArray[np.float64], blocks: GatherBlocks,
               gatherers: NDArray[np.bool_], level: NDArray[np.float64] | None
               ) -> NDArray[np.float64]:
    """Per vertex c: max over the ``gatherers`` v of share[v] G[v, c] level[c] (the share of v's
    exit transfer that c's value carries in a bounce; `gather_picks`; ``level`` None:
    1, `gather_importance`)."""
    from scipy.sparse import diags

    imp = np.zeros(len(gatherers))
    for rows, g in blocks:
        sel = np.flatnonzero(gatherers[rows])
        if sel.size:
            w = diags(share[rows[sel]]) @ (g if sel.size == len(rows) else g[sel])
            if level is not None:
                w = w @ diags(level)
            imp = np.maximum(imp, w.max(axis=0).toarray().ravel())
    return imp


class Gathered(NamedTuple):
    """What a final bake's gather saw (`gather_picks`' inputs): the shadowed and the
    cumulative layers (V, K, C), the gather blocks and the albedo."""

    direct: NDArray[np.float64]
    cumulative: NDArray[np.float64]
    blocks: GatherBlocks
    albedo: NDArray[np.float64]


def post_split_marks(traced0: NDArray[np.float64], edges: NDArray[np.int64],
                     gathered: Gathered, gatherers: NDArray[np.bool_], jump: float,
                     share_tol: float = 2e-4, floor: float = GATHER_FLOOR
                     ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """The post-pass's edges (module doc, post-pass): an edge is marked where both ends carry more
    than ``share_tol`` of a gatherer's exit transfer (`gather_picks`' measure, with
    max(‖T_0(c)‖, ‖T(c)‖) as c's level; ``gatherers``: the contact's dense vertices and the
    picks) and the final bake's shadowed transfer ``traced0`` (V, K, C) jumps across it by more
    than ``jump`` of its brighter end (ends dimmer than 2 % of the median ‖T_0‖ count no jump).
    ``gathered``: `gather_picks`' inputs from the final bake. Returns (marked edges
    (E,), the vertices that qualify (V,))."""
    direct, cumulative, blocks, albedo = gathered
    share = _exit_share(cumulative, albedo, floor)
    hit = _leaned_on(share, blocks, gatherers,
                     np.maximum(_norms(direct), _norms(cumulative))) > share_tol
    nrm = _norms(traced0)
    d = np.linalg.norm((traced0[edges[:, 0]] - traced0[edges[:, 1]]).reshape(len(edges), -1),
                       axis=1)
    big = np.maximum(nrm[edges[:, 0]], nrm[edges[:, 1]])
    rel = np.where(big > 0.02 * np.median(nrm), d / np.maximum(big, 1e-30), 0.0)
    return hit[edges].all(1) & (rel > jump), hit
