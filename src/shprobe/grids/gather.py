"""The final gather of a bounce (``GridSettings.gather``, default 2 rays): the irradiance of
each surface a probe ray meets, gathered by a few cosine-distributed rays from the surface
itself instead of read from the grid.

Reading a surface's irradiance from the grid (DDGI's recursion, ``gather=0``) lights the foot
of a wall as the nearest probe outside sees it — up to a cell away, with more sky. Gathering
from the surface gives it its own sky: E(x) = π · mean over G cosine rays of L, L the
environment where a ray leaves the scene, ρ/π·E' at the front of a surface it meets (E' from
the grid of one bounce fewer, with leak control), 0 at a back face. G is small (a few rays):
each probe projects thousands of such surfaces, which averages their noise.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..prt.directions import OFFSET_FRACTION
from ..sh.rotation import frame_from_normal
from .grid import ProbeGrid
from .rays import ProbeTracer

__all__ = ["cosine_directions", "gather_irradiance"]

#: Surface points per block of the gather (bounds its ray buffers).
_POINTS = 1 << 15


def cosine_directions(normals: NDArray[np.float64], count: int,
                      rng: np.random.Generator) -> NDArray[np.float64]:
    """(N, count, 3) directions, cosine-distributed about unit ``normals`` (N, 3) (Malley:
    uniform on the disc, lifted to the hemisphere)."""
    u1, u2 = rng.random((len(normals), count)), rng.random((len(normals), count))
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u1)], axis=-1)
    return np.einsum("nij,ncj->nci", frame_from_normal(normals), local)


def gather_irradiance(tracer: ProbeTracer, where, sky: Callable[[NDArray], NDArray],
                      previous: ProbeGrid | None, albedo_at, count: int,
                      rng: np.random.Generator, advance) -> NDArray[np.float64]:
    """Irradiance (M, 3) at the surface points of ``where`` = (points, normals, albedo, faces)
    by ``count`` cosine rays each (module doc); ``previous`` (None: surfaces met are black) is
    the grid the surfaces met are lit from, ``albedo_at(hits, rays)`` their albedo."""
    pts, nrm, _, faces = where
    eps = OFFSET_FRACTION * float(np.linalg.norm(np.ptp(tracer.vertices, axis=0)))
    out = np.zeros((len(pts), 3))
    for a in range(0, len(pts), _POINTS):
        s = slice(a, a + _POINTS)
        o, _ = tracer.caster.offset_points(pts[s], nrm[s], eps, faces[s])
        d = cosine_directions(nrm[s], count, rng)
        h = tracer.trace(o, d, distances=False)
        light = np.zeros((*h.face.shape, 3))
        miss = h.face < 0
        light[miss] = sky(d[miss])
        front = np.flatnonzero((~miss & ~h.back).ravel())
        if previous is not None and len(front):
            p2, n2, rho, _ = albedo_at(h, front)
            light.reshape(-1, 3)[front] = rho / np.pi * previous.irradiance(p2, n2)
        out[s] = np.pi * light.mean(axis=1)
        advance(len(o))
    return out
