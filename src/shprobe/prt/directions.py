"""Where a bake's rays start and where they go: the seeded spherical-Fibonacci direction set,
its rotated copies (one per vertex, by a hash of its index), and the ray origins offset from
each vertex along its normal by the one rule of `shprobe.scene.raycast`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..scene.raycast import RayCaster
from ..sh.rotation import from_quaternion
from .geometry import BakeScene
from .transfer import check_int, vertex_hash

__all__ = ["OFFSET_FRACTION", "RAYS_PER_CHUNK", "RaySource", "random_rotation", "ray_origins",
           "ray_source", "rotated_direction_sets", "sample_directions"]

#: Rays traced per work item (a block of vertices × their upper-hemisphere directions).
RAYS_PER_CHUNK = 1 << 17
#: Ray origins are moved this fraction of the scene's bounding-box diagonal along the normal.
OFFSET_FRACTION = 1e-4

#: ``rays(i0, i1)`` → (origins, directions (float32, the caster's frame), cosines, row − i0,
#: direction index) of rows[i0:i1] over their upper hemispheres (:func:`ray_source`).
RaySource = Callable[[int, int], tuple[Any, Any, Any, Any, Any]]


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


def rotated_direction_sets(rows: NDArray[np.int64], sets: int, seed: int
                           ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The rotations (S, 3, 3) of ``sets`` copies of the direction set and the copy each vertex
    of ``rows`` traces (len(rows),): one set (the identity) for ``sets`` = 1; otherwise random
    rotations drawn from ``seed`` and a copy picked by a hash of the vertex index, so that
    neighbouring vertices (consecutive or not) trace different directions and a bake stays
    reproducible. Neighbours with nearly the same normal that look past the same horizon through
    the same few directions make one shared quadrature error that no gather of theirs averages;
    with their own rotations the errors are independent. The SH rows are projected in the
    copy's frame and turned to the world's by the Wigner matrix D(R) (y(Rω) = D(R) y(ω)), so
    one table of y over the base set serves every copy."""
    if sets <= 1:
        return np.eye(3)[None], np.zeros(len(rows), dtype=np.int64)
    rng = np.random.default_rng([seed, 17])
    rots = from_quaternion(rng.normal(size=(sets, 4)))
    return rots, ((vertex_hash(rows, seed) >> np.uint64(33)) % np.uint64(sets)).astype(np.int64)


def ray_origins(sc: BakeScene, caster: RayCaster, rows: NDArray[np.int64]
                ) -> tuple[float, NDArray[np.float32]]:
    """The ray-origin offset ε and the origins of the vertices ``rows`` (float32, the caster's
    frame; row i belongs to vertex rows[i]), offset by the one rule
    ([`offset_points`][shprobe.scene.RayCaster.offset_points]: a step that would cross another
    surface, as at a vertex touching the ground, is put back)."""
    diag = float(np.linalg.norm(np.ptp(sc.vertices, axis=0)))
    eps = OFFSET_FRACTION * max(diag, 1e-12)
    on = np.full(sc.n_vertices, -1, dtype=np.int64)  # a face of each vertex
    on[sc.faces.ravel()] = np.repeat(np.arange(len(sc.faces)), 3)
    return eps, caster.local(caster.offset_points(sc.vertices[rows], sc.normals[rows], eps,
                                                  on[rows])[0])


def ray_source(sc: BakeScene, caster: RayCaster, rows: NDArray[np.int64], samples: int,
               seed: int, sets: int = 1
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64], RaySource]:
    """The vertex rays of a bake for the vertices ``rows``: returns the direction set (N, 3),
    the rotations and set of each row (`rotated_direction_sets`) and the
    `RaySource` ``rays(i0, i1)`` of rows[i0:i1] (only directions with n·ω > 0)."""
    dirs = sample_directions(samples, seed)
    rots, sid = rotated_direction_sets(rows, sets, seed)
    dirs32 = np.ascontiguousarray((dirs @ rots.transpose(0, 2, 1)).astype(np.float32))
    _, p32 = ray_origins(sc, caster, rows)
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

    return dirs, rots, sid, rays
