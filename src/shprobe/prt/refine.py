"""Adaptive refinement of a PRT scene where the baked transfer varies fast (issue 17).

Per-vertex transfer is interpolated linearly over each triangle, both when relighting and when a
bounce gathers the previous bounce at a ray's hit point (:mod:`shprobe.prt.bake`). Where the
transfer varies within a triangle much faster than linearly — at the contact of an object with
the ground, where a ground vertex under the object sees nothing and its neighbour a hand-width
away sees half the sky — the interpolated bounce light is wrong by tens of per cent, however many
rays are traced. A uniform ground fine enough everywhere costs vertices everywhere; this module
puts them where the transfer says they are needed:

1. bake the scene (:func:`shprobe.prt.bake.bake`, public API) with a quarter of the samples
   (enough to see where the transfer jumps);
2. for every edge of a refinable triangle (the ground's; every mesh's too with
   ``refine_mesh=True``) compare its endpoints' transfer, layer by layer — the shadowed transfer
   and each bounce *increment* — as ‖T_b(a) − T_b(c)‖ / s_b, with s_b the 90th percentile of
   ‖T_b‖ over the scene's vertices (so a bounce, a few per cent of the direct light, is judged
   on its own scale); mark the edges where some layer exceeds ``tol`` and that are longer than
   ``min_edge``;

   2b. ... and mark as well the edges whose interpolation matters to the vertices that gather
   from them (``gather_tol``): bounce b+1 at a vertex v is ρ_v/π Σ_c G[v, c] T_b(c) (LH §4:
   the interreflected transfer gathers the previous bounce's transfer along the blocked rays;
   G holds each ray's cosine-weighted solid angle times the barycentric weights of its hit).
   A vertex close to a surface — the ground under the belly, 0.4 mm below 2 mm triangles of the
   underside — leans on a few of that surface's vertices, where a linear interpolant of a
   transfer that varies 4× across a triangle is tens of per cent off, although the jump is
   small on the *scene's* scale s_b. The share of v's exit transfer that passes through vertex
   c is ρ_v/π G[v, c] / ‖T(v)‖ (:func:`gather_importance`, the largest over v; ‖T(v)‖ the
   cumulative transfer, at least ``gather_floor`` × the scene's median); an edge's estimated
   error is its jump ‖T_b(a) − T_b(c)‖ times the larger share of its ends, over the layers that
   are gathered (:func:`gather_errors`). Jumps below ``gather_gate`` (0.25) of the edge's own
   level are left out: that is the driving bake's quadrature noise, which the gather averages,
   not a shape the interpolant misses. (At 0.25 the bunny's crevice vertices gather over
   unsplit triangles of the crevice's wall where the direct varies 15–20 % across a
   triangle, and read −0.26 % from its linear interpolation alone: issue 17 run 11;
   :data:`ADAPTIVE_CONTACT` gates at 0.1.) This is the irradiance-caching argument in matrix
   form:
   a triangle matters in proportion to the solid angle it fills as seen from its closest
   gatherer;
3. split the marked edges at their midpoints (a triangle with two marked edges gets its third
   marked as well, repeated to closure; then 3 marked → 4 triangles, 1 marked → 2), new
   vertices get the mean of their endpoints' albedo and the input surface's shading normal
   there: the barycentric interpolation of the input triangle's vertex normals, normalised,
   as a renderer (and the independent gather of the tests) shades the input mesh — kept
   exact through the rounds by carrying the unnormalised interpolants (the mean of the
   ends' *unit* normals, normalised, drifts by up to a degree or more after a few levels,
   enough to move the light under the bunny's belly, lit through a 0.4 mm slot at grazing
   angles, by 0.4 %: issue 17, run 6a);
4. re-bake the refined scene and repeat until no edge is marked or ``max_rounds`` is reached;
   the final geometry is baked with the full samples;
5. ... and with ``dense_factor`` (8) times as many at the *input scene's* vertices that the
   refinement touched (an edge of theirs split in round ``dense_depth`` (0) or later) — the
   contact, where visibility is intricate and the light dim, so that the bake's quadrature
   noise *relative to the radiance there* falls below the open vertices' (the error there
   must be at the level of the noise elsewhere). The new vertices keep ``samples``: they
   support the interpolation, and the gathers that read them average their noise over many
   rays; ``dense_new=True`` gives them the dense directions as well (as before issue 17's
   third run: factor 4, depth 3), at several times the bake time. The dense vertices trace
   ``dense_quadrature``: Fibonacci directions, or ``"adaptive"`` (:mod:`shprobe.prt.hemisphere`,
   a 128² grid at factor 32, refined where visibility changes, which finds the slivers of sky
   that light the ground under the bunny's belly through a 0.4 mm slot);
6. ... and with ``dense_picks`` so do the vertices that the contact's bounces lean on (
   :func:`gather_picks`): once the final geometry is traced, the vertices c whose value carries
   more than a threshold of some contact vertex v's exit radiance in a bounce,
   ρ_v/π G[v, c] ‖T_0(c)‖ / ‖T(v)‖ > 0.01, are picked; then, in a second round, those whose
   cumulative transfer carries as much of a contact vertex or of one picked in the first (the
   contact's second bounce reads its sources' first; the bunny's flat base, black in its own
   direct, carries most of the slot-lit ground vertex's second bounce). Only they are traced
   again (their rows of T_0 and G replaced, every other ray kept) before the bounces are
   gathered. A contact vertex's bounce reads the slot-lit underside and the crevice's walls
   at a few vertices each, so their own quadrature error, shared and never averaged, would
   be the contact's: on the bunny about 9.2–9.7k of 86–90k vertices are picked;
7. ... and with ``post_jump`` a post-pass on the final bake (:func:`post_split_marks`): the
   vertices the contact leans on — those whose value carries more than ``post_share`` of the
   exit transfer of a dense vertex or a pick, by :func:`gather_picks`' measure — have the
   edges between them split where the final shadowed transfer jumps by more than
   ``post_jump``, and the scene baked once more (its picks again those of the contact's dense
   vertices: seeded by the new vertices too, they were 28–30k, not 3.4k, and the bake twice
   as long for no gain, run 13). The error it removes is the linear interpolation over a few
   hundred triangles per gatherer, each below step 2b's per-edge tolerance (the slot-lit
   ground's direct decays as about 1/distance from the slot's mouth: convex, so a linear
   interpolant overestimates it on every triangle). The bake the post-pass reads only
   screens: its picks are found but not traced (``post_first_picks=True`` traces them, as
   run 13 did); and the new vertices between two leaned-on ones are traced on an adaptive
   grid of their own at ``post_dense`` (8) × ``samples`` (G 64), not the picks' 32 (run
   13's; with the ``samples`` alone, ``post_dense=0``, a crevice vertex that gathers them was
   +0.15 % off in its first bounce: their quadrature errors, though independent with
   ``direction_sets``, do not average away; run 12 had found the same with one shared set).
   On the bunny this is ~330 s a bake, not ~600 s (docs/benchmarks.md, issue 17 run 14).

Meshes are refined too by default (``refine_mesh``): a mesh vertex that touches the ground has
its ray origin pushed along its (downward) normal below the ground, so it sees the open sky from
below — light that leaks into the contact through every triangle around it; splitting those
triangles shrinks the leak with the triangles. The original vertices keep their indices (new
vertices are appended), so per-vertex data of the input mesh still lines up with the first
vertices of the result.

The result is an ordinary :class:`~shprobe.prt.transfer.Transfer` over the refined geometry;
its metadata records the refinement (tolerance, rounds, vertices per round, the hash of the
unrefined scene). Because every round is a full bake with the same seed, the result is
deterministic.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .bake import ADAPTIVE_DENSE_FACTOR, FIBONACCI_DENSE_FACTOR, _bake, _check_quadrature, bake
from .hemisphere import ADAPTIVE_LEVELS
from .scene import Scene, load_scene, mesh_hash
from .transfer import MODES, Transfer, check_int

__all__ = ["ADAPTIVE_CONTACT", "FINE_CONTACT", "GATHER_TOL", "POST_DENSE", "POST_SHARE",
           "QUICK_CONTACT", "REFINE_TOL", "RefineRound", "bake_refined", "gather_errors",
           "gather_importance", "gather_picks", "post_split_marks", "split_edges",
           "transfer_jumps"]

#: Default tolerance on the relative jump of a transfer layer across an edge.
REFINE_TOL = 0.25
#: The input scene's vertices that the refinement touches in this round or later get
#: DENSE_FACTOR × the samples in the final bake (module doc, step 5).
DENSE_DEPTH = 0
DENSE_FACTOR = FIBONACCI_DENSE_FACTOR
#: Default noise gate of the gather criterion (module doc, step 2b; :func:`gather_errors`'
#: ``tol``).
GATHER_GATE = 0.25
#: Default ``floor`` of :func:`transfer_jumps`: 1, jumps judged on the scene's scale only. A
#: floor of 0.2 brings the bunny's dimmest contact vertex from 14 % to 1.9 % (2 bounces) but
#: at 4× the vertices (84k) — docs/benchmarks.md, issue 17 run 2.
FLOOR = 1.0
#: Default smallest edge that is still split, as a fraction of the scene's bounding diagonal.
MIN_EDGE_FRACTION = 2e-4
#: Default tolerance on an edge's estimated share of a gathering vertex's exit transfer that its
#: interpolation gets wrong (module doc, step 2b); None turns that criterion off. 0.03 (with
#: dense directions at the input's contact vertices) brings the bunny's worst contact vertex to
#: 0.15 % / 0.49 % (1 / 2 bounces; run 2: 0.77 % / 14.5 %) at 3.8× the vertices and 2.8× the
#: time of ``None`` (docs/benchmarks.md, issue 17 run 3); 0.05 leaves 0.42 % / 0.68 % at 2.6×
#: the vertices; 0.02 gives 0.19 % / 0.37 % at 4.9×.
GATHER_TOL = 0.03
#: Gathering vertices dimmer than this fraction of the scene's median ‖T‖ are judged as if that
#: bright (the relative error of a black vertex is meaningless; the bench scores vertices above
#: 2 % of the far vertices' median).
GATHER_FLOOR = 0.02
#: Settings of ``bake(..., refine="fine")`` (``shprobe prt bake --fine-contact``): a noise gate
#: of 0.05, gather tolerance 0.01, edges down to 1e-4 of the diagonal, up to 10 rounds, and the
#: dense directions at the new contact vertices too (the slot-lit underside's shared
#: quadrature error, read twice by the crevice, goes with them). On the bunny, seeds 0 / 1:
#: the crevice within ±0.1 % with 2 bounces (default −0.1 … −0.37 %); worst contact error
#: 0.75× / 2.8× the open vertices' median with 1 bounce (default 2.5× / 4.3×), 3.3× / 13×
#: with 2 (default 5.2× / 5.6×: the dim ground vertex under the belly — its own direct through
#: the slot, and the slot-lit underside's shared quadrature error that it gathers, run 9), at
#: 3–4× the vertices and 13–17× the bake time (docs/benchmarks.md, issue 17 runs 8–9).
FINE_CONTACT: Mapping[str, Any] = MappingProxyType({
    "gather_gate": 0.05, "gather_tol": 0.01, "min_edge_fraction": 1e-4, "max_rounds": 10,
    "dense_new": True, "dense_factor": DENSE_FACTOR, "dense_quadrature": "fibonacci",
    "dense_picks": None})
#: Settings of ``bake(..., refine="quick")`` (``shprobe prt bake --quick-contact``, and a
#: shadowed bake's default): :func:`bake_refined`'s own defaults. On the bunny with 2 bounces
#: the contact stays 2.4–4.2× (1 bounce) and 4.4–17× (2 bounces) the open vertices' error
#: (docs/benchmarks.md, issue 17 runs 13–14), at about a tenth of the default's time.
QUICK_CONTACT: Mapping[str, Any] = MappingProxyType({})
#: Default ``post_share`` of the post-pass (module doc, step 7): a vertex is one the contact
#: leans on when its value carries more than this share of a gatherer's exit transfer.
POST_SHARE = 2e-4
#: Default ``post_dense``: the post-pass's new vertices between two the contact leans on are
#: traced on the adaptive grid at this factor × ``samples`` (8: G 64), below the picks' 32.
POST_DENSE = 8
#: ``post_jump`` of :data:`ADAPTIVE_CONTACT`.
POST_JUMP = 0.1
#: Settings of ``bake(..., refine="adaptive")`` (``shprobe prt bake --adaptive-contact``; the
#: default refinement of an interreflected bake with bounces): the gather criterion's noise
#: gate at 0.1, the contact's dense vertices on the adaptive grid (factor 32: 128² at 1024
#: samples), the vertices its bounces lean on picked (module doc, step 6, thresholds 0.01,
#: 0.01) and traced so too, the post-pass (step 7; its new vertices at factor 8) and 256
#: direction sets in the final bakes. On the bunny (issue 17 run 14; worst contact error over
#: the open vertices' median, 1 / 2 bounces): seeds 0 / 1 / 2 / 3 1.95× / 2.79×, 1.42× /
#: 1.18×, 1.99× / 2.20×, 1.82× / 2.58× (the quick refinement: 2.4–4.2× / 4.4–17×), at
#: 2.8–2.9× its vertices and about 10× its bake time (319–335 s on two cores; run 13's
#: version, the post-pass's vertices as the picks, 573–627 s). Without the post-pass and the
#: direction sets (run 11) the slot-lit ground vertex under the belly was +0.5 % with 2
#: bounces in every seed (7.8–8.2×).
ADAPTIVE_CONTACT: Mapping[str, Any] = MappingProxyType({
    "gather_gate": 0.1, "dense_factor": ADAPTIVE_DENSE_FACTOR, "dense_quadrature": "adaptive",
    "dense_picks": (0.01, 0.01), "post_jump": POST_JUMP, "post_share": POST_SHARE,
    "post_dense": POST_DENSE, "post_first_picks": False, "direction_sets": 256})


@dataclass(frozen=True)
class RefineRound:
    """One bake of the refinement: vertices baked, edges split after it, bake seconds."""

    vertices: int
    split: int
    seconds: float


def _edges(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Unique undirected edges (E, 2) and, per face, the index of its edges (F, 3) in the order
    (v0v1, v1v2, v2v0)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    uniq, inv = np.unique(e, axis=0, return_inverse=True)
    return uniq, inv.reshape(3, -1).T


def transfer_jumps(t: Transfer, floor: float = FLOOR) -> NDArray[np.float64]:
    """Per vertex pair (edge of ``t.faces``): the largest relative jump over the layers (shadowed
    and each bounce increment), ‖ΔT_b‖ / scale, the scale being s_b, the 90th percentile of
    ‖T_b‖ (module doc) — or, with ``floor`` < 1, the edge's brighter end's ‖T_b‖ clipped to
    [floor·s_b, s_b], so that dim regions are judged on their own level (up to 1/floor times
    stricter). Returns (edges (E, 2), jumps (E,))."""
    edges, _ = _edges(np.asarray(t.faces, dtype=np.int64))
    tr = np.asarray(t.traced, dtype=np.float64)
    layers = [tr[0]] + [tr[i] - tr[i - 1] for i in range(1, tr.shape[0])]
    jump = np.zeros(len(edges))
    for lay in layers:
        flat = lay.reshape(lay.shape[0], -1)
        norms = np.linalg.norm(flat, axis=1)
        s = float(np.percentile(norms, 90))
        if s <= 0:
            continue
        # the scale of an edge: its brighter end's ‖T_b‖, clipped to [floor·s_b, s_b]
        local = np.maximum(norms[edges[:, 0]], norms[edges[:, 1]])
        scale = np.clip(local, floor * s, s)
        d = np.linalg.norm(flat[edges[:, 0]] - flat[edges[:, 1]], axis=1) / scale
        jump = np.maximum(jump, d)
    return edges, jump


def gather_importance(t: Transfer, blocks: list[tuple[NDArray[np.int64], Any]],
                      floor: float = GATHER_FLOOR) -> NDArray[np.float64]:
    """Per vertex c: the largest share of any gathering vertex's exit transfer that passes
    through c's barycentric weight in a bounce, max_v ρ_v/π G[v, c] / ‖T(v)‖ (module doc, step
    2b), with G the bake's gather matrix (``blocks``: :func:`shprobe.prt.bake._bake` with
    ``keep_gather``) and ‖T(v)‖ v's cumulative transfer, at least ``floor`` × its median over
    the scene (dimmer vertices are judged as if that bright)."""
    share = _exit_share(t.traced[-1], t.albedo, floor)
    return _leaned_on(share, blocks, np.ones(t.n_vertices, dtype=bool), None)


def _norms(x: Any) -> NDArray[np.float64]:
    """‖x[v]‖ over each vertex's coefficients (and channels)."""
    return np.linalg.norm(np.asarray(x, dtype=np.float64).reshape(len(x), -1), axis=1)


def _exit_share(cumulative: Any, albedo: Any, floor: float) -> NDArray[np.float64]:
    """Per gathering vertex v: ρ_v/π / ‖T(v)‖, the share of v's exit transfer per unit of
    G[v, c] T(c) (module doc, step 2b), ‖T(v)‖ its cumulative transfer, at least ``floor`` ×
    the median over the scene (0 where that is 0)."""
    level = _norms(cumulative)
    scale = np.maximum(level, floor * float(np.median(level)))
    rho = np.asarray(albedo, dtype=np.float64).max(axis=1) / np.pi
    return np.where(scale > 0, rho / np.where(scale > 0, scale, 1.0), 0.0)


def gather_errors(t: Transfer, edges: NDArray[np.int64], importance: NDArray[np.float64],
                  tol: float = REFINE_TOL) -> NDArray[np.float64]:
    """Per edge (a, c): the estimated relative error its linear interpolation brings to the
    next bounce of the vertex that leans on it most, max over the layers gathered (shadowed and
    each bounce increment but the last) of ‖T_b(a) − T_b(c)‖ · max(importance[a],
    importance[c]) (module doc, step 2b); a jump below ``tol`` × the edge's brighter end's
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


def split_edges(scene: Scene, marked: NDArray[np.bool_], edges: NDArray[np.int64],
                face_edges: NDArray[np.int64]) -> Scene:
    """Split the ``marked`` edges (closure: a face with 2 marked edges gets its 3rd marked) at
    their midpoints; faces with 3 marked → 4, with 1 → 2 (module doc, step 3)."""
    return _split(scene, _closure_edges(marked, face_edges), edges, face_edges)[0]


def _split(scene: Scene, sel: NDArray[np.int64], edges: NDArray[np.int64],
           face_edges: NDArray[np.int64], raw: NDArray[np.float64] | None = None
           ) -> tuple[Scene, NDArray[np.float64]]:
    """:func:`split_edges` of the closed edge set ``sel`` (:func:`_closure_edges`), and the
    unnormalised normals of the result: ``raw`` (default: the scene's normals) holds, for
    every vertex, the barycentric interpolation of its input triangle's vertex normals (an
    input vertex: its own), so a midpoint's is the mean of its ends' and the scene's normal
    is that normalised (module doc, step 3)."""
    nv = scene.n_vertices
    mid = np.full(len(edges), -1, dtype=np.int64)
    mid[sel] = nv + np.arange(len(sel))
    a, b = edges[sel, 0], edges[sel, 1]
    v = np.concatenate([scene.vertices, 0.5 * (scene.vertices[a] + scene.vertices[b])])
    raw = scene.normals if raw is None else raw
    rn = 0.5 * (raw[a] + raw[b])
    ln = np.linalg.norm(rn, axis=1, keepdims=True)
    n = np.where(ln > 1e-12, rn / np.where(ln > 1e-12, ln, 1.0), scene.normals[a])
    nrm = np.concatenate([scene.normals, n])
    alb = np.concatenate([scene.albedo, 0.5 * (scene.albedo[a] + scene.albedo[b])])
    f = scene.faces
    m = mid[face_edges]  # (F, 3): midpoint of (v0v1, v1v2, v2v0) or −1
    cnt = (m >= 0).sum(1)
    out = [f[cnt == 0]]
    full = cnt == 3
    if full.any():
        ff, mm = f[full], m[full]
        out += [np.stack([ff[:, 0], mm[:, 0], mm[:, 2]], 1),
                np.stack([mm[:, 0], ff[:, 1], mm[:, 1]], 1),
                np.stack([mm[:, 2], mm[:, 1], ff[:, 2]], 1),
                np.stack([mm[:, 0], mm[:, 1], mm[:, 2]], 1)]
    one = cnt == 1
    if one.any():
        ff, mm = f[one], m[one]
        k = np.argmax(mm >= 0, axis=1)  # which edge: (v_k, v_{k+1}) split at its midpoint
        r = np.arange(len(ff))
        p0, p1, p2 = ff[r, k], ff[r, (k + 1) % 3], ff[r, (k + 2) % 3]
        q = mm[r, k]
        out += [np.stack([p0, q, p2], 1), np.stack([q, p1, p2], 1)]
    faces = np.concatenate(out).astype(np.int64)
    return Scene(v, nrm, faces, alb, mesh_hash(v, faces)), np.concatenate([raw, rn])


def bake_refined(scene: Any, mode: str = "interreflected", lmax: int = 4, samples: int = 1024,
                 bounces: int = 2, albedo: Any = None, seed: int = 0, ground: bool = True,
                 threads: int | None = None, progress: Any = None, *, tol: float = REFINE_TOL,
                 max_rounds: int = 8, refine_mesh: bool = True,
                 driver_samples: int | None = None,
                 min_edge: float | None = None, ground_resolution: int = 64,
                 max_vertices: int = 2_000_000, mesh_albedo: Any = None,
                 ground_albedo: Any = None, dense_factor: int = DENSE_FACTOR,
                 dense_depth: int = DENSE_DEPTH, floor: float = FLOOR,
                 gather_tol: float | None = GATHER_TOL,
                 gather_floor: float = GATHER_FLOOR, gather_gate: float = GATHER_GATE,
                 dense_new: bool = False, direction_sets: int = 1,
                 final_gather: int = 0, final_gather_inner: int = 0,
                 final_gather_near: float | None = None,
                 min_edge_fraction: float = MIN_EDGE_FRACTION,
                 dense_quadrature: str = "fibonacci",
                 adaptive_levels: int = ADAPTIVE_LEVELS,
                 dense_picks: tuple[float, ...] | None = None,
                 post_jump: float | None = None, post_share: float = POST_SHARE,
                 post_dense: int = POST_DENSE, post_first_picks: bool = False) -> Transfer:
    """:func:`~shprobe.prt.bake.bake` with adaptive refinement of the ground (and of the meshes
    with ``refine_mesh``) where the baked transfer jumps by more than ``tol`` across an edge
    (module doc). Other arguments as :func:`~shprobe.prt.bake.bake`; ``min_edge`` (default
    ``min_edge_fraction`` (2e-4) × the scene's diagonal; the gap under the bunny's belly is
    ~8e-4 of it) stops splitting; ``max_rounds`` bounds the re-bakes; ``max_vertices``
    refuses to grow past it; ``driver_samples`` (default ``samples``/4, at
    least 64): directions of the bakes that only decide where to split — the final geometry is
    baked once more with ``samples``, except the input scene's vertices that the refinement
    touched (the ends of an edge split in round ``dense_depth`` or later: the contact; with
    ``dense_new`` the new vertices made in those rounds too), which get ``dense_factor`` ×
    ``samples`` directions (module doc, step 5; ``dense_factor=1``: none); ``floor``: see
    :func:`transfer_jumps`; ``gather_tol``, ``gather_floor``, ``gather_gate``: the gather
    criterion (module doc, step 2b; ``gather_gate`` is :func:`gather_errors`' ``tol``;
    ``gather_tol=None``: off, as before issue 17's third run); ``direction_sets``: of the final
    bake (:func:`~shprobe.prt.bake.bake`; the driving bakes keep one set); ``final_gather``: M
    >= 1 rays per hit of a final gather at the dense vertices in the final bake
    (:mod:`shprobe.prt.final_gather`; 0: none), ``final_gather_inner`` its third level and
    ``final_gather_near`` the hits it takes (:func:`~shprobe.prt.bake.bake`);
    ``dense_quadrature``, ``adaptive_levels``: of the dense vertices in the final bake
    (:func:`~shprobe.prt.bake.bake`); ``dense_picks``: the thresholds of :func:`gather_picks`,
    one per round (module doc, step 6; None or empty: no picks; an interreflected bake with
    dense vertices and no final gather only); ``post_jump``, ``post_share``: the post-pass
    (module doc, step 7; :func:`post_split_marks`; None: none; needs ``dense_picks``);
    ``post_dense``: its new vertices between two leaned-on ones traced on the dense
    quadrature at ``post_dense`` × ``samples`` (0: not; ``dense_factor`` or more: as the
    picks, run 13's); ``post_first_picks``: the picks traced in the bake it reads too (run
    13's; by default that bake only screens). The
    returned
    transfer's
    ``metadata['refine']`` holds the rounds (:class:`RefineRound` as dicts)."""
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    if mode == "unshadowed":
        raise ShprobeError("refinement needs a traced bake (shadowed or interreflected)")
    if not (np.isfinite(tol) and tol > 0):
        raise ShprobeError(f"refinement tolerance must be > 0, got {tol}")
    if not (np.isfinite(floor) and 0 < floor <= 1):
        raise ShprobeError(f"refinement floor must be in (0, 1], got {floor}")
    base = load_scene(scene, albedo=albedo, ground=ground, ground_albedo=ground_albedo,
                      ground_resolution=ground_resolution, mesh_albedo=mesh_albedo)
    n_mesh = (load_scene(scene, albedo=albedo, mesh_albedo=mesh_albedo).n_vertices if ground
              else base.n_vertices)
    sc = base
    raw = base.normals  # the input surface's interpolated normals, unnormalised (_split)
    diag = float(np.linalg.norm(np.ptp(sc.vertices, axis=0)))
    if not (np.isfinite(min_edge_fraction) and min_edge_fraction > 0):
        raise ShprobeError(f"min_edge_fraction must be > 0, got {min_edge_fraction}")
    min_len = float(min_edge_fraction) * diag if min_edge is None else float(min_edge)
    is_ground = np.arange(sc.n_vertices) >= n_mesh
    rounds: list[RefineRound] = []
    stage = [""]  # what the bake under way is, before each of its progress bars

    def staged(items: Any, description: str, total: int | None = None) -> Any:
        return progress(items, f"{stage[0]}: {description}", total)

    prog = staged if progress is not None else None
    kw = dict(mode=mode, lmax=lmax, bounces=bounces, seed=seed, threads=threads,
              progress=prog)
    drive = max(64, int(samples) // 4) if driver_samples is None else int(driver_samples)
    deep = np.zeros(sc.n_vertices, dtype=bool)  # touched at depth >= dense_depth
    factor = check_int(dense_factor, 1, "dense_factor")
    gathered = gather_tol is not None and mode == "interreflected" and int(bounces) > 0
    gtol = float(gather_tol) if gather_tol is not None else np.inf
    if gathered and not (np.isfinite(gtol) and gtol > 0):
        raise ShprobeError(f"refinement gather tolerance must be > 0, got {gather_tol}")
    if not (np.isfinite(gather_floor) and np.isfinite(gather_gate) and gather_floor >= 0
            and gather_gate >= 0):
        raise ShprobeError(f"gather_floor and gather_gate must be >= 0, got {gather_floor} and "
                           f"{gather_gate}")

    def dense_mask() -> NDArray[np.bool_]:
        return deep if dense_new else deep & (np.arange(len(deep)) < base.n_vertices)

    fg = check_int(final_gather, 0, "final_gather")
    _check_quadrature(dense_quadrature, fg, adaptive_levels)
    fg_inner = check_int(final_gather_inner, 0, "final_gather_inner")
    picks = _check_picks(dense_picks)
    if picks and fg:
        raise ShprobeError("dense_picks and final_gather do not go together (the final gather "
                           "reads only the contact's vertices); pass dense_picks=None")
    if post_jump is not None:
        if not (np.isfinite(post_jump) and post_jump > 0 and np.isfinite(post_share)
                and post_share > 0):
            raise ShprobeError(f"post_jump and post_share must be > 0, got {post_jump} and "
                               f"{post_share}")
        if not picks:
            raise ShprobeError("post_jump splits among the vertices the contact leans on: it "
                               "needs dense_picks")
    pdense = check_int(post_dense, 0, "post_dense")
    picks = picks if mode == "interreflected" and int(bounces) > 0 and factor > 1 else ()
    n_picked = [0]
    held: dict[str, Any] = {}  # the last final bake's layers and gather, for the post-pass

    def final(sc: Scene, extra: NDArray[np.bool_] | None = None) -> Transfer:
        keep = post_jump is not None and extra is None  # the bake the post-pass reads
        # the post-pass's new vertices: as the picks, or on their own grid (post_dense)
        own = extra is not None and 0 < pdense < factor
        mask = dense_mask() if extra is None or own else dense_mask() | extra
        screen = keep and bool(picks) and bool(mask.any()) and not post_first_picks
        stage[0] = f"{'screening' if screen else 'final'} bake, {sc.n_vertices:,} vertices"
        held.clear()
        if picks and mask.any():

            def pick(direct: Any, cum: Any, blocks: Any, alb: Any) -> NDArray[np.int64]:
                # what the contact leans on: seeded by its dense vertices, not the post-pass's
                got = gather_picks(direct, cum, blocks, alb, dense_mask(), picks, gather_floor)
                if keep:
                    held.update(direct=direct, cumulative=cum, albedo=alb, picked=got)
                    if not post_first_picks:  # this bake only screens: no picks traced
                        return got[:0]
                return got

            t, blocks = _bake(sc, mode, lmax, samples, bounces, None, seed, False, threads,
                              prog, None, None, mask, factor * int(samples),
                              sets=check_int(direction_sets, 1, "direction_sets"),
                              quadrature=dense_quadrature, levels=int(adaptive_levels),
                              pick=pick, keep_gather=keep,
                              second=(extra, pdense * int(samples)) if own else None)
            if keep:
                held.update(blocks=blocks, mask=mask)
            n_picked[0] = int(t.metadata.get("dense_picked", 0))
            return t
        if (factor > 1 or fg) and mask.any():
            return bake(sc, samples=samples, refine=False, dense=mask,
                        dense_samples=factor * int(samples), direction_sets=direction_sets,
                        final_gather=fg, final_gather_inner=fg_inner,
                        final_gather_near=final_gather_near,
                        dense_quadrature=dense_quadrature, adaptive_levels=adaptive_levels,
                        **kw)
        return bake(sc, samples=samples, refine=False, direction_sets=direction_sets, **kw)

    def splittable(sc: Scene, edges: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Edges longer than min_edge, on the ground unless refine_mesh."""
        length = np.linalg.norm(sc.vertices[edges[:, 0]] - sc.vertices[edges[:, 1]], axis=1)
        return (length > min_len) & (is_ground[edges].all(1) if not refine_mesh else True)

    for r in range(int(max_rounds) + 1):
        t0 = time.perf_counter()
        last = r == int(max_rounds)
        if last:
            t = final(sc)
            rounds.append(RefineRound(sc.n_vertices, 0, time.perf_counter() - t0))
            break
        stage[0] = f"refinement round {r + 1}, {sc.n_vertices:,} vertices"
        t, blocks = _bake(sc, mode, lmax, min(drive, samples), bounces, None, seed, False,
                          threads, prog, None, None, None, None, keep_gather=gathered)
        secs = time.perf_counter() - t0
        edges, face_edges = _edges(sc.faces)
        _, jump = transfer_jumps(t, floor)
        over = jump > tol
        if gathered and blocks is not None:
            imp = gather_importance(t, blocks, gather_floor)
            over |= gather_errors(t, edges, imp, gather_gate) > gtol
        marked = over & splittable(sc, edges)
        rounds.append(RefineRound(sc.n_vertices, int(marked.sum()), secs))
        if not marked.any():
            if drive < samples or ((factor > 1 or fg) and dense_mask().any()):
                # the geometry is final: bake it with the full samples, the crevice dense
                t0 = time.perf_counter()
                t = final(sc)
                rounds.append(RefineRound(sc.n_vertices, 0, time.perf_counter() - t0))
            break
        mids = _closure_edges(marked, face_edges)  # the edges split, in _split's order
        new, raw = _split(sc, mids, edges, face_edges, raw)
        if new.n_vertices > max_vertices:
            raise ShprobeError(f"refinement would grow the scene past {max_vertices} vertices; "
                               "raise tol or min_edge")
        # new vertices on ground edges are ground; with refine_mesh a mesh edge gives mesh
        added = new.n_vertices - sc.n_vertices
        deep = np.concatenate([deep, np.full(added, r >= dense_depth)])
        if r >= dense_depth:
            deep[edges[mids].ravel()] = True
        is_ground = np.concatenate([is_ground, np.zeros(added, dtype=bool)])
        is_ground[sc.n_vertices:] = is_ground[edges[mids, 0]] & is_ground[edges[mids, 1]]
        sc = new
    post: dict[str, Any] = {}
    if "blocks" in held:  # the post-pass (module doc, step 7)
        edges, face_edges = _edges(sc.faces)
        gatherers = held["mask"].copy()
        gatherers[held["picked"]] = True
        marked, hit = post_split_marks(
            np.asarray(t.traced[0], dtype=np.float64), edges, held["direct"],
            held["cumulative"], held["blocks"], held["albedo"], gatherers, float(post_jump),
            float(post_share), gather_floor)
        held.clear()
        marked &= splittable(sc, edges)
        rounds[-1] = RefineRound(rounds[-1].vertices, int(marked.sum()), rounds[-1].seconds)
        post = {"post_jump": float(post_jump), "post_share": float(post_share),
                "post_first_picks": bool(post_first_picks), "post_dense_factor": pdense,
                "post_leaned_on": int(hit.sum()), "post_split": int(marked.sum()),
                "post_dense": 0}
        if marked.any():
            t0 = time.perf_counter()
            mids = _closure_edges(marked, face_edges)
            new, raw = _split(sc, mids, edges, face_edges, raw)
            if new.n_vertices > max_vertices:
                raise ShprobeError(f"refinement would grow the scene past {max_vertices} "
                                   "vertices; raise post_jump or min_edge")
            added = new.n_vertices - sc.n_vertices
            deep = np.concatenate([deep, np.zeros(added, dtype=bool)])
            # the new vertices between two the contact leans on: traced at post_dense
            extra = np.zeros(new.n_vertices, dtype=bool)
            extra[sc.n_vertices:] = gatherers[edges[mids]].all(1) & (pdense > 0)
            post["post_dense"] = int(extra.sum())
            sc = new
            t = final(sc, extra)
            rounds.append(RefineRound(sc.n_vertices, 0, time.perf_counter() - t0))
        elif not post_first_picks:  # nothing to split: bake again, the picks traced
            t0 = time.perf_counter()
            t = final(sc, np.zeros(sc.n_vertices, dtype=bool))
            rounds.append(RefineRound(sc.n_vertices, 0, time.perf_counter() - t0))
    meta = dict(t.metadata)
    meta["refine"] = {
        "tol": float(tol), "min_edge": min_len, "max_rounds": int(max_rounds),
        "gather_gate": float(gather_gate), "refine_mesh": bool(refine_mesh),
        "ground_resolution": int(ground_resolution), "base_mesh_hash": base.mesh_hash,
        "dense_factor": factor, "dense_depth": int(dense_depth), "floor": float(floor),
        "dense_new": bool(dense_new), "final_gather": fg, "final_gather_inner": fg_inner,
        "final_gather_near": final_gather_near,
        # what the final bake ran (no dense vertices: Fibonacci everywhere)
        "dense_quadrature": "adaptive" if "dense_quadrature" in t.metadata else "fibonacci",
        "dense_vertices": int(dense_mask().sum()) if factor > 1 else 0,
        "dense_picks": list(picks), "dense_picked": n_picked[0], **post,
        "gather_tol": gtol if gathered else None, "gather_floor": float(gather_floor),
        "rounds": [{"vertices": x.vertices, "split": x.split, "seconds": round(x.seconds, 3)}
                   for x in rounds],
    }
    meta["ground"] = bool(ground)
    from dataclasses import replace

    return replace(t, metadata=meta)


def _check_picks(picks: Any) -> tuple[float, ...]:
    """``dense_picks`` as a tuple of thresholds > 0 (None: none)."""
    if picks is None:
        return ()
    try:
        out = tuple(float(x) for x in picks)
    except (TypeError, ValueError):
        out = (float("nan"),)
    if not all(np.isfinite(x) and x > 0 for x in out) or len(out) > 8:
        raise ShprobeError(f"dense_picks must be up to 8 thresholds > 0 (or None), got {picks!r}")
    return out


def gather_picks(direct: NDArray[np.float64], cumulative: NDArray[np.float64],
                 blocks: list[tuple[NDArray[np.int64], Any]], albedo: NDArray[np.float64],
                 seeds: NDArray[np.bool_], thresholds: tuple[float, ...],
                 floor: float = GATHER_FLOOR) -> NDArray[np.int64]:
    """The vertices a bounce of the ``seeds`` (V,) leans on (module doc, step 6): round r picks
    every vertex c, not yet picked, with max_v ρ_v/π G[v, c] ‖T(c)‖ / ‖T(v)‖ above
    ``thresholds[r]``, v over the seeds and the picks of the rounds before, T(c) c's
    ``direct`` layer in round 0 and its ``cumulative`` one after, ‖T(v)‖ v's cumulative
    transfer, at least ``floor`` × its median over the scene. Layers (V, K, C) with the albedo
    applied (ρ/π T); ``blocks``: the gather matrix G as :func:`shprobe.prt.bake._bake`'s
    (vertex indices, CSR rows). Returns the picked vertices (not the seeds), sorted."""
    share = _exit_share(cumulative, albedo, floor)
    chosen = np.asarray(seeds, dtype=bool).copy()
    for r, thr in enumerate(thresholds):
        # the gatherers: the seeds and every earlier pick
        chosen |= _leaned_on(share, blocks, chosen, _norms(direct if r == 0 else cumulative)) > thr
    return np.flatnonzero(chosen & ~np.asarray(seeds, dtype=bool))


def _leaned_on(share: NDArray[np.float64], blocks: list[tuple[NDArray[np.int64], Any]],
               gatherers: NDArray[np.bool_], level: NDArray[np.float64] | None
               ) -> NDArray[np.float64]:
    """Per vertex c: max over the ``gatherers`` v of share[v] G[v, c] level[c] (the share of v's
    exit transfer that c's value carries in a bounce; :func:`gather_picks`; ``level`` None:
    1, :func:`gather_importance`)."""
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


def post_split_marks(traced0: NDArray[np.float64], edges: NDArray[np.int64],
                     direct: NDArray[np.float64], cumulative: NDArray[np.float64],
                     blocks: list[tuple[NDArray[np.int64], Any]], albedo: NDArray[np.float64],
                     gatherers: NDArray[np.bool_], jump: float, share_tol: float = POST_SHARE,
                     floor: float = GATHER_FLOOR) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """The post-pass's edges (module doc, step 7): an edge is marked where both ends carry more
    than ``share_tol`` of a gatherer's exit transfer (:func:`gather_picks`' measure, with
    max(‖T_0(c)‖, ‖T(c)‖) as c's level; ``gatherers``: the contact's dense vertices and the
    picks) and the final bake's shadowed transfer ``traced0`` (V, K, C) jumps across it by more
    than ``jump`` of its brighter end (ends dimmer than 2 % of the median ‖T_0‖ count no jump).
    ``direct``, ``cumulative``, ``blocks``, ``albedo``: as :func:`gather_picks`' from the final
    bake. Returns (marked edges (E,), the vertices that qualify (V,))."""
    share = _exit_share(cumulative, albedo, floor)
    hit = _leaned_on(share, blocks, gatherers,
                     np.maximum(_norms(direct), _norms(cumulative))) > share_tol
    nrm = _norms(traced0)
    d = np.linalg.norm((traced0[edges[:, 0]] - traced0[edges[:, 1]]).reshape(len(edges), -1),
                       axis=1)
    big = np.maximum(nrm[edges[:, 0]], nrm[edges[:, 1]])
    rel = np.where(big > 0.02 * np.median(nrm), d / np.maximum(big, 1e-30), 0.0)
    return hit[edges].all(1) & (rel > jump), hit


def _closure_edges(marked: NDArray[np.bool_], face_edges: NDArray[np.int64]) -> NDArray:
    """The edge indices :func:`split_edges` splits (marked, closed), in its order."""
    m = marked.copy()
    while True:
        cnt = m[face_edges].sum(1)
        two = cnt == 2
        if not two.any():
            break
        m[face_edges[two].ravel()] = True
    return np.flatnonzero(m)
