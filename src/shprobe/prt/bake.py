"""Baking per-vertex transfer vectors (Lisle & Huang 2007 §4; Sloan et al. 2002 §5).

Three diffuse models, all with the radiance scale of :mod:`shprobe.prt.transfer`
(transfer · L = exit radiance):

- unshadowed: analytic, b_lm = π H_l y_lm(n) = Â_l y_lm(n) (LH eq. 9–10), times ρ/π;
- shadowed: ρ/π Σ_j V(ω_j) max(0, n·ω_j) y(ω_j) 4π/N over N seeded spherical-Fibonacci
  directions, visibility V by Embree occlusion rays from the vertex offset along its normal
  (only directions with n·ω > 0 are traced);
- interreflected: the shadowed term plus k bounces; bounce b gathers, along every blocked ray
  that hits a front face, the previous bounce's transfer interpolated barycentrically over the
  hit triangle: T_b(v) = ρ_v/π Σ_j max(0, n·ω_j) T_{b−1}(hit_j) 4π/N. Back-face hits block
  light but send none.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..sh import check_lmax, degrees, num_coeffs, sh_basis
from ..zonal import clamped_cosine_factors
from .scene import Scene, load_scene
from .transfer import MODES, Transfer

#: Rays traced per work item (a block of vertices × their upper-hemisphere directions).
RAYS_PER_CHUNK = 1 << 17
#: Ray origins are moved this fraction of the scene's bounding-box diagonal along the normal.
OFFSET_FRACTION = 1e-4

ProgressFn = Callable[..., Iterable[Any]]


def random_rotation(rng: np.random.Generator) -> NDArray[np.float64]:
    """A uniformly distributed rotation matrix (unit quaternion from 4 normals)."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def sample_directions(n: int, seed: int = 0) -> NDArray[np.float64]:
    """N spherical-Fibonacci unit vectors turned by a random rotation drawn from ``seed``.

    Each point carries the solid angle 4π/N; the same seed gives the same directions.
    """
    if n < 1:
        raise ShprobeError(f"need at least 1 sample direction, got {n}")
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * ((i * (np.sqrt(5.0) - 1.0) / 2.0) % 1.0)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    return d @ random_rotation(np.random.default_rng(seed)).T


def unshadowed_transfer(normals: NDArray[np.floating], lmax: int) -> NDArray[np.float64]:
    """Â_l y_lm(n) for each normal, (V, K): the SH of max(0, n·ω) (LH eq. 9, π H_l = Â_l)."""
    a = clamped_cosine_factors(lmax)[degrees(lmax)]
    return sh_basis(np.asarray(normals, dtype=np.float64), lmax) * a


class RayCaster:
    """Embree (embreex) scene over a :class:`Scene`'s triangles."""

    def __init__(self, scene: Scene) -> None:
        from embreex import mesh_construction, rtcore_scene

        self._scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self._scene, scene.vertices.astype(np.float32),
                                       scene.faces.astype(np.int32))

    def occluded(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]) -> NDArray:
        """True where the ray hits anything (any-hit query)."""
        return self._scene.run(origins, dirs, query="OCCLUDED") != -1

    def intersect(self, origins: NDArray[np.float32], dirs: NDArray[np.float32]):
        """Closest hit: (primitive id or −1, u, v) with hit = (1−u−v)p0 + u p1 + v p2."""
        r = self._scene.run(origins, dirs, output=1)
        return r["primID"], r["u"], r["v"]


@lru_cache(maxsize=1)
def _kernels():
    """Numba kernels (compiled once, cached on disk): hemisphere ray set, visibility sum."""
    import numba

    @numba.njit(cache=True, nogil=True)
    def hemisphere_rays(p, n, dirs, o, d, cw, vid, did):
        m = 0
        for v in range(p.shape[0]):
            for j in range(dirs.shape[0]):
                c = n[v, 0] * dirs[j, 0] + n[v, 1] * dirs[j, 1] + n[v, 2] * dirs[j, 2]
                if c > 0:
                    for a in range(3):
                        o[m, a] = p[v, a]
                        d[m, a] = dirs[j, a]
                    cw[m] = c
                    vid[m] = v
                    did[m] = j
                    m += 1
        return m

    @numba.njit(cache=True, nogil=True)
    def add_visible(free, vid, did, cw, yw, out):
        for r in range(free.shape[0]):
            if free[r]:
                v, j, c = vid[r], did[r], cw[r]
                for k in range(yw.shape[1]):
                    out[v, k] += c * yw[j, k]

    return hemisphere_rays, add_visible


def _chunks(n_vertices: int, samples: int) -> list[tuple[int, int]]:
    step = max(1, RAYS_PER_CHUNK // max(1, samples // 2))
    return [(i, min(i + step, n_vertices)) for i in range(0, n_vertices, step)]


def _quiet(items: Iterable[Any], description: str = "", total: int | None = None) -> Iterator:
    yield from items


def bake(scene: Any, mode: str = "shadowed", lmax: int = 4, samples: int = 1024,
         bounces: int = 2, albedo: Any = None, seed: int = 0, ground: bool = False,
         threads: int | None = None, progress: ProgressFn | None = None) -> Transfer:
    """Bake per-vertex transfer vectors (Lisle & Huang 2007 §4).

    scene: a mesh path, a trimesh object, a list of them, or a :class:`Scene`; albedo and ground
    as in :func:`load_scene`. mode: 'unshadowed' | 'shadowed' | 'interreflected'. lmax: degree
    baked (any lower degree can be used later). samples: ray directions per vertex over the whole
    sphere (about half are traced). bounces: interreflection bounces (interreflected only).
    seed: picks the random rotation of the direction set. threads: Embree/numpy workers
    (default: all cores). progress: a wrapper ``progress(items, description, total)`` that
    yields ``items`` (e.g. :func:`shprobe.cli.common.progress`).

    Returns a :class:`Transfer`: (V, K) float32, or (V, K, 3) when the albedo is coloured, with
    transfer · L = exit radiance ρ/π ∫ L V max(0, n·ω) dω (+ bounces).
    """
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    lmax = check_lmax(lmax)
    sc = load_scene(scene, albedo=albedo, ground=ground)
    samples = int(samples) if mode != "unshadowed" else 0
    bounces = int(bounces) if mode == "interreflected" else 0
    if mode != "unshadowed" and samples < 16:
        raise ShprobeError(f"need at least 16 samples per vertex, got {samples}")
    if bounces < 0:
        raise ShprobeError(f"bounces must be >= 0, got {bounces}")
    wrap = progress or _quiet
    rho = sc.albedo / np.pi  # (V, 3)
    channels = 3 if sc.coloured else 1
    if mode == "unshadowed":
        t0 = unshadowed_transfer(sc.normals, lmax)
        total = t0[:, :, None] * rho[:, None, :channels]
    else:
        t0, gather = _trace(sc, lmax, samples, seed, mode == "interreflected", threads, wrap)
        t_prev = t0[:, :, None] * rho[:, None, :channels]
        total = t_prev.copy()
        k = num_coeffs(lmax)
        for _ in wrap(range(bounces), "bounces", bounces):
            g = (gather @ t_prev.reshape(sc.n_vertices, k * channels)).reshape(t_prev.shape)
            t_prev = g * rho[:, None, :channels]
            total += t_prev
    transfer = (total[:, :, 0] if channels == 1 else total).astype(np.float32)
    meta = {
        "mesh_hash": sc.mesh_hash, "mode": mode, "lmax": lmax, "samples": samples,
        "bounces": bounces, "seed": int(seed), "ground": bool(ground),
        "albedo": {"min": sc.albedo.min(0).tolist(), "max": sc.albedo.max(0).tolist(),
                   "mean": sc.albedo.mean(0).tolist()},
        "directions": "spherical Fibonacci, seeded random rotation" if samples else "none",
        "scale": "transfer . L = exit radiance rho/pi * int L V max(0, n.w) dw (+ bounces)",
    }
    return Transfer(transfer, sc.vertices, sc.normals, sc.faces, sc.albedo, meta)


def _trace(sc: Scene, lmax: int, samples: int, seed: int, gather: bool,
           threads: int | None, wrap: ProgressFn):
    """Visibility-weighted projection Σ V cos y 4π/N (V, K), and the bounce gather matrix."""
    dirs = sample_directions(samples, seed)
    dirs32 = dirs.astype(np.float32)
    yw = sh_basis(dirs, lmax) * (4.0 * np.pi / samples)  # (N, K)
    caster = RayCaster(sc)
    diag = float(np.linalg.norm(np.ptp(sc.vertices, axis=0)))
    eps = OFFSET_FRACTION * max(diag, 1e-12)
    p32 = (sc.vertices + eps * sc.normals).astype(np.float32)
    n32 = sc.normals.astype(np.float32)
    fnormals = sc.face_normals().astype(np.float32) if gather else None
    faces = sc.faces

    from scipy.sparse import coo_matrix
    from scipy.sparse import vstack as sparse_vstack

    kernels = _kernels()
    k = yw.shape[1]

    def work(span: tuple[int, int]):
        i0, i1 = span
        cap = (i1 - i0) * samples
        o = np.empty((cap, 3), np.float32)
        d = np.empty((cap, 3), np.float32)
        cw = np.empty(cap, np.float32)
        vid = np.empty(cap, np.int64)
        did = np.empty(cap, np.int64)
        m = kernels[0](p32[i0:i1], n32[i0:i1], dirs32, o, d, cw, vid, did)
        o, d, cw, vid, did = o[:m], d[:m], cw[:m], vid[:m], did[:m]
        proj = np.zeros((i1 - i0, k))
        if not gather:
            free = ~caster.occluded(o, d)
            kernels[1](free, vid, did, cw, yw, proj)
            return proj, None
        prim, u, v = caster.intersect(o, d)
        kernels[1](prim < 0, vid, did, cw, yw, proj)
        hit = np.flatnonzero(prim >= 0)
        front = np.einsum("ij,ij->i", d[hit], fnormals[prim[hit]]) < 0
        sel = hit[front]
        ph = prim[sel]
        w = cw[sel] * np.float32(4.0 * np.pi / samples)
        uu, vv = u[sel], v[sel]
        rows = np.repeat(vid[sel], 3)
        cols = faces[ph].ravel()
        vals = (np.stack([1.0 - uu - vv, uu, vv], axis=1) * w[:, None]).ravel()
        # this block's rows of the gather matrix; CSR sums the many repeated (row, col) pairs
        g = coo_matrix((vals.astype(np.float64), (rows, cols)), shape=(i1 - i0, sc.n_vertices))
        return proj, g.tocsr()

    spans = _chunks(sc.n_vertices, samples)
    nthreads = max(1, int(threads or os.cpu_count() or 1))
    t0 = np.empty((sc.n_vertices, num_coeffs(lmax)), dtype=np.float64)
    parts = []
    with ThreadPoolExecutor(nthreads) as ex:
        results = ex.map(work, spans) if nthreads > 1 else map(work, spans)
        for (i0, i1), (proj, g) in zip(spans, wrap(results, "tracing rays", len(spans)),
                                       strict=True):
            t0[i0:i1] = proj
            if g is not None:
                parts.append(g)
    gmat = sparse_vstack(parts, format="csr") if gather else None
    return t0, gmat
