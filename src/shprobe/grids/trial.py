"""A grid bake's trial trace, for its time estimate: a few hundred rays of the bake's own kinds
from a sample of its probes, telling what fraction of the probe rays meet a lit surface (each
such ray costs a bounce its gather rays or its grid lookup) and what fraction of the gather
rays go on to meet a surface (each costs a lookup in the previous bounce's grid).

A grid whose probes see mostly sky or back faces, or a scene of black surfaces, does little
bounce work whatever ``samples``, ``bounces`` and ``gather`` say; a room whose probes see
walls everywhere does all of it. The fractions are measured, not assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..prt.directions import OFFSET_FRACTION, sample_directions
from .gather import cosine_directions
from .rays import ProbeTracer

__all__ = ["TRIAL_FACES", "TrialFractions", "trial_fractions"]

#: Probes sampled, directions per probe, surface points gathered from and gather rays per
#: point (≤ 32·64 + 256·4 rays: a few milliseconds of tracing).
TRIAL_PROBES = 32
TRIAL_DIRECTIONS = 64
TRIAL_POINTS = 256
TRIAL_GATHER = 4
#: Largest scene traced for a trial (its ray caster is built for it: ~0.2 s at this size on
#: 2 cores); a larger scene's estimate assumes the fractions of `ASSUMED` (its preparation
#: alone takes seconds).
TRIAL_FACES = 150_000


@dataclass(frozen=True)
class TrialFractions:
    """``lit``: fraction of probe rays meeting the front of a surface of non-zero albedo
    (a bounce's work per probe ray); ``onward``: fraction of those surfaces' gather rays meeting
    the front of a surface (a grid lookup each, from the second bounce); ``rays``: traced."""

    lit: float
    onward: float
    rays: int


#: What a scene too large for a trial is assumed to do (the room and the bunny on its ground
#: measure 0.41 and 0.43 lit: a bake whose probes see lit surfaces everywhere is then within 2×).
ASSUMED = TrialFractions(lit=0.5, onward=0.5, rays=0)


def trial_fractions(vertices: NDArray[np.float64], faces: NDArray[np.int64],
                    albedo: NDArray[np.float64], bounds: NDArray[np.float64],
                    settings) -> TrialFractions:
    """Trace the trial (module doc) of a bake of ``settings`` over ``bounds`` (2, 3).

    Parameters
    ----------
    vertices, faces, albedo
        The scene: (V, 3) positions, (F, 3) vertex indices, (V, 3) albedo.
    bounds
        The grid's (2, 3) corners.
    settings
        The bake's `GridSettings` (resolution, inside_fraction, gather, bounces, seed).

    Returns
    -------
    TrialFractions
        The measured fractions.
    """
    tracer = ProbeTracer(vertices, faces)
    rng = np.random.default_rng([settings.seed, 71])
    res, n = settings.resolution, settings.n_probes
    # the sampled cells' centres only (a grid of 512³ cells is refused for its memory after this)
    pick = rng.choice(n, TRIAL_PROBES, replace=False) if n > TRIAL_PROBES else np.arange(n)
    b = np.asarray(bounds, np.float64)
    cell = np.stack(np.unravel_index(pick, res), axis=-1)
    centres = b[0] + (cell + 0.5) * (b[1] - b[0]) / np.asarray(res)
    dirs = sample_directions(TRIAL_DIRECTIONS, settings.seed)
    h = tracer.trace(centres, dirs, distances=False)
    rays = h.face.size
    # a probe inside geometry is moved to free space before the bake traces: judge by the rest
    outside = h.back.mean(axis=1) <= settings.inside_fraction
    if outside.any():
        h = type(h)(*(x[outside] for x in (h.face, h.u, h.v, h.dist, h.back)))
    front = np.flatnonzero(((h.face >= 0) & ~h.back).ravel())
    f = h.face.ravel()[front]
    rho = tracer.interpolate(albedo, f, h.u.ravel()[front], h.v.ravel()[front])
    lit = front[rho.max(axis=1) > 0]
    frac_lit = len(lit) / max(h.face.size, 1)
    onward = 0.0
    if settings.gather and settings.bounces >= 2 and len(lit):
        at = lit if len(lit) <= TRIAL_POINTS else rng.choice(lit, TRIAL_POINTS, replace=False)
        fp = h.face.ravel()[at]
        pts = tracer.points(fp, h.u.ravel()[at], h.v.ravel()[at])
        nrm = tracer.face_normals[fp]
        eps = OFFSET_FRACTION * float(np.linalg.norm(np.ptp(tracer.vertices, axis=0)))
        o, _ = tracer.caster.offset_points(pts, nrm, eps, fp)
        g = tracer.trace(o, cosine_directions(nrm, TRIAL_GATHER, rng), distances=False)
        onward = float(((g.face >= 0) & ~g.back).mean())
        rays += g.face.size
    return TrialFractions(lit=frac_lit, onward=onward, rays=rays)
