"""Final gather at chosen vertices of an interreflected bake (issue 17, run 6).

A bounce of :mod:`shprobe.prt.bake` gathers, along each blocked ray of vertex v, the previous
bounce's transfer *interpolated linearly* over the hit triangle from its corners' stored values:

    T_b(v) = ρ_v/π Σ_h w_h Σ_i β_hi T_{b−1}(c_hi),     w_h = max(0, n_v·ω_h) 4π/N,

(β_hi the barycentric weights of hit h on corners c_hi). Where T_{b−1} varies across a triangle
much faster than linearly — the underside of an object 0.4 mm above the ground, lit through the
slot between them — that interpolation is biased, and neither more directions nor (short of
several times the vertices) refinement remove it (docs/benchmarks.md, issue 17, runs 2–5).

The final gather evaluates the previous layer *at the hit point x_h itself*, by a second level
of M rays per hit, cosine-weighted about the hit's interpolated normal n_h (stratified √M × √M
when M is a square), each hit its own random directions (a generator per gathering vertex,
seeded by the bake's seed and the vertex's index, so a bake is reproducible and independent of
the thread count and of how the vertices are split into blocks), from the hit
point offset by the bake's one rule (:meth:`~shprobe.scene.raycast.RayCaster.offset_points`):

    Ê_0(x) = ρ(x)/M Σ_j V_j y(ω_j)                   (the shadowed transfer at x, LH §4),
    Ê_b(x) = ρ(x)/M Σ_j F_j Σ_i β_ji T_b(c_ji)        (b ≥ 1: bounce b+1's input at x),

with V_j = 1 where ray j escapes, F_j = 1 where it hits a front face (back faces block and send
nothing, as in the bake), ρ(x) the interpolated albedo; cosine-weighted sampling (pdf cos/π)
turns ρ/π ∫ V cos y dω into ρ/M Σ V y. Then

    T_1(v) = ρ_v/π Σ_h w_h Ê_0(x_h),      T_b(v) = ρ_v/π Σ_h w_h Ê_{b−2}'(x_h) (b ≥ 2),

where Ê'_{b−2} gathers the stored layer b−2 at the second-level hits: the first bounce at v has
no interpolation at all; bounce b ≥ 2 interpolates only at the third vertex of each path (the
classic final gather of photon mapping and irradiance caching, here on SH transfer vectors, so
the transfer stays linear in the lighting). Every estimate is unbiased given the stored layers;
its noise (M rays at each of the thousands of hits of a vertex) averages over the hits.

With ``near`` = r only the hits closer to the vertex than r × their triangle's longest edge
are gathered afresh — where the previous layer can vary across the triangle faster than the
vertex's footprint there (a slot under an object); farther hits read every layer interpolated,
as the bake does (their M-ray estimates would add noise and remove little bias).

The vertices' own rays are the bake's (:func:`shprobe.prt.bake._ray_source`: the same
directions, origins and rotations), so the final gather replaces exactly the bake's bounce
terms at those vertices. Cost: about (hits of those vertices) × M rays — 2,569 bunny contact
vertices × 8192 directions × ~½ upward × ~½ blocked × 16 ≈ 8e7.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..scene.raycast import RayCaster
from ..sh import sh_basis
from ..sh.rotation import frame_from_normal
from .scene import Scene

__all__ = ["cosine_directions", "final_gather_layers"]


def cosine_directions(normals: NDArray[np.float64], u: NDArray[np.float64]
                      ) -> NDArray[np.float64]:
    """(H, m, 3) unit directions about each of ``normals`` (H, 3), cosine-weighted (pdf
    cos θ/π, Malley's method: uniform points on the disc lifted to the hemisphere) from uniform
    samples ``u`` (H, m, 2) in [0, 1)²; stratified on a √m × √m grid of the unit square when m
    is a square (each sample in its own cell)."""
    m = u.shape[1]
    k = int(np.sqrt(m))
    u1, u2 = u[..., 0], u[..., 1]
    if k * k == m:
        i, j = np.divmod(np.arange(m), k)
        u1, u2 = (i[None] + u1) / k, (j[None] + u2) / k
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    x, y, z = r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))
    f = frame_from_normal(normals)  # columns (t, b, n)
    return x[..., None] * f[:, None, :, 0] + y[..., None] * f[:, None, :, 1] + (
        z[..., None] * f[:, None, :, 2])


def final_gather_layers(sc: Scene, caster: RayCaster, rows: NDArray[np.int64], samples: int,
                        seed: int, sets: int, lmax: int, bounces: int,
                        layers: list[NDArray[np.float64]], rays: int,
                        pmap: Callable[..., Iterable[Any]], wrap: Any, rays2: int = 0,
                        rng_seed: int | None = None, near: float | None = None
                        ) -> list[NDArray[np.float64]]:
    """The bounce increments 1..``bounces`` at the vertices ``rows`` by final gather (module
    doc), *without* the gathering vertex's own ρ_v/π: Σ_h w_h Ê_{b−1}(x_h), as (len(rows), K, C)
    arrays. ``samples``, ``seed``, ``sets``: the rows' own bake directions; ``layers``: the
    stored layer increments T_0 … T_{B−2} (V, K, C) (T_0 the shadowed transfer times ρ/π), read
    where the fresh levels stop (T_0 also fixes K and C); ``rays``: M per hit; ``rays2`` > 0:
    a third level, that many rays from every second-level hit, so that the second bounce
    reads no stored value either (bounce b ≥ 3 then reads T_{b−3} at the third-level hits);
    ``rng_seed``: of the fresh directions (default ``seed``; each vertex its own generator,
    seeded by it and its index); ``near``: final-gather only the hits closer than ``near`` ×
    their triangle's longest edge (module doc; None: every hit), the others interpolated
    (then ``layers`` holds T_0 … T_{B−1})."""
    from scipy.sparse import coo_matrix

    from .bake import RAYS_PER_CHUNK, _ray_source

    k = layers[0].shape[1]
    ch = layers[0].shape[2]
    _, _, _, eps, vertex_rays = _ray_source(sc, caster, rows, samples, seed, sets)
    fn = sc.face_normals()
    fn32 = fn.astype(np.float32)
    faces = sc.faces
    alb = sc.albedo[:, :ch]
    fv = sc.vertices[faces]
    edge = np.linalg.norm(fv - np.roll(fv, 1, axis=1), axis=2).max(1)
    counts = [rays] + ([rays2] if rays2 > 0 else [])  # rays per point of each fresh level
    # vertices per block: ~RAYS_PER_CHUNK fresh rays (about a quarter of the upward rays hit)
    per_vertex = samples // 8 * rays * (1 + (rays2 // 2 if rays2 > 0 else 0))
    step = max(1, RAYS_PER_CHUNK // max(1, per_vertex))
    spans = [(i, min(i + step, len(rows))) for i in range(0, len(rows), step)]

    def front(o, d, owner, w):
        """The rays' front-face hits as (owner, face, barycentrics, weight) (back faces block
        and send nothing)."""
        prim, u, v = caster.first_hit_local(o, d)
        h = np.flatnonzero(prim >= 0)
        h = h[np.einsum("ij,ij->i", d[h], fn32[prim[h]]) < 0]
        beta = np.stack([1.0 - u[h] - v[h], u[h], v[h]], 1).astype(np.float64)
        return owner[h], prim[h].astype(np.int64), beta, w[h], prim < 0

    def gather(n, hits, m, gens, need_hits):
        """One fresh level from the points ``hits``: m cosine-weighted rays from each, offset
        by the bake's rule; returns Σ w ρ(x)/m y(ω) over the rays that escape, per owner
        (n, K, C), and the front hits of the rays (weights w ρ(x)/m)."""
        owner, face, beta, w = hits
        corners = faces[face]
        x = np.einsum("hi,hij->hj", beta, sc.vertices[corners])
        nx = np.einsum("hi,hij->hj", beta, sc.normals[corners])
        nx /= np.linalg.norm(nx, axis=1, keepdims=True)
        wr = np.repeat(w * np.einsum("hi,hic->hc", beta, alb[corners]) / m, m, axis=0)
        origin = caster.local(caster.offset_points(x, nx, eps, face)[0])
        # each gathering vertex draws from its own generator, in the order of its hits, so
        # that the bake does not depend on how the vertices are split into blocks
        per = np.bincount(owner, minlength=n)
        u = np.concatenate([gens[i].random((c, m, 2)) for i, c in enumerate(per) if c])
        d = cosine_directions(nx, u).reshape(-1, 3)
        d32 = np.ascontiguousarray(d, dtype=np.float32)
        own = np.repeat(owner, m)
        nxt = front(np.repeat(origin, m, axis=0), d32, own, wr)
        esc = np.flatnonzero(nxt[4])
        direct = np.zeros((n, k, ch))
        if esc.size:
            y = sh_basis(d[esc], lmax)  # (E, K)
            for c in range(ch):
                a = coo_matrix((wr[esc, c], (own[esc], np.arange(esc.size))),
                               shape=(n, esc.size)).tocsr()
                direct[:, :, c] = a @ y
        return direct, (nxt[:4] if need_hits else None)

    def work(span: tuple[int, int]) -> list[NDArray[np.float64]]:
        i0, i1 = span
        n = i1 - i0
        s0 = seed if rng_seed is None else rng_seed
        gens = [np.random.default_rng([s0, 0x17F, int(r)]) for r in rows[i0:i1]]
        o, d, cw, vid, _ = vertex_rays(i0, i1)
        wcos = (cw.astype(np.float64) * (4.0 * np.pi / samples))[:, None]  # cos × solid angle
        hits = front(o, d, vid, wcos)[:4]
        out = [np.zeros((n, k, ch)) for _ in range(bounces)]
        if near is not None and len(hits[0]):
            # only hits closer than ``near`` × their triangle's longest edge are gathered
            # afresh; the others read every layer interpolated, as the bake does
            owner, face, beta, w = hits
            x = np.einsum("hi,hij->hj", beta, sc.vertices[faces[face]])
            org = o[np.searchsorted(vid, owner)]  # the vertex's origin (rays grouped by vertex)
            dist = np.linalg.norm(caster.local(x) - org, axis=1) / caster.scale
            close = dist < near * edge[face]
            fo = ~close
            if fo.any():
                r = np.repeat(owner[fo], 3)
                cols = faces[face[fo]].ravel()
                for c in range(ch):
                    g = coo_matrix(((beta[fo] * w[fo, c:c + 1]).ravel(), (r, cols)),
                                   shape=(n, sc.n_vertices)).tocsr()
                    for b in range(bounces):
                        out[b][:, :, c] += g @ layers[b][:, :, c]
            hits = (owner[close], face[close], beta[close], w[close])
        for lvl, m in enumerate(counts[:bounces]):  # bounce lvl+1: the direct light there
            if not len(hits[0]):
                return out
            part, hits = gather(n, hits, m, gens, need_hits=bounces > lvl + 1)
            out[lvl] += part
        if bounces > len(counts) and len(hits[0]):  # later bounces: stored layers, interpolated
            owner, face, beta, w = hits
            r = np.repeat(owner, 3)
            cols = faces[face].ravel()
            for c in range(ch):
                g = coo_matrix(((beta * w[:, c:c + 1]).ravel(), (r, cols)),
                               shape=(n, sc.n_vertices)).tocsr()
                for b in range(len(counts), bounces):
                    out[b][:, :, c] += g @ layers[b - len(counts)][:, :, c]
        return out

    res = [np.zeros((len(rows), k, ch)) for _ in range(bounces)]
    for (i0, i1), part in zip(spans, wrap(pmap(work, spans), "final gather", len(spans)),
                              strict=True):
        for b in range(bounces):
            res[b][i0:i1] = part[b]
    return res
