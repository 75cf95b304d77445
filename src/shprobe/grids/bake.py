"""Baking a probe grid: per probe, the environment as it is seen past the scene plus the
diffuse light of the scene's surfaces, to N bounces, with the depth moments of leak control.

Per probe (at its cell centre, or moved out of geometry: `shprobe.grids.placement`), ``samples``
spherical-Fibonacci directions are traced once. A ray that leaves the scene brings the SH
moments of the probe image over the direction's own cell of the sphere (each image pixel goes
to its nearest direction, so the cells tile the image: an unoccluded probe holds the image's
projection pixel for pixel, and occlusion is resolved per cell without aliasing the image's
bright spots), or 4π/D · L(ω) y(ω) from the lighting's SH where there is no image. A ray that
meets the front of a surface sees ρ/π·E, E the surface's irradiance from the previous
bounce's grid through the leak-controlled interpolation (DDGI's recursive bounce, Majercik
et al. 2019 §5) or, with ``gather`` > 0, gathered from the surface itself (`shprobe.grids.gather`),
ρ the albedo there, projected with weight 4π/D (R&H 2001 eq. 6 by quadrature); a back face is
black.

Each probe's octahedral depth map (mean and mean-square distance to the first hit over
``depth_samples``² rays per texel, distances capped at twice the cell diagonal) feeds the
Chebyshev test of `shprobe.grids.visibility`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..limits import Cost, check_memory, cores
from ..progress import Progress, Steps
from ..prt.directions import sample_directions
from ..prt.geometry import BakeScene, albedo_keywords, load_scene
from ..sh.basis import sh_basis
from ..sh.indexing import lmax_of, num_coeffs
from .grid import ProbeGrid, cell_centres
from .octahedral import texel_directions
from .placement import TEST_RAYS, dilate, place_probes
from .rays import ProbeTracer
from .settings import GridSettings, check_bounds

__all__ = ["bake_grid", "estimate_grid_bake", "grid_bounds", "grid_scene"]

#: Rays per second and core of the probe tracer (probe, placement and depth rays: Embree
#: spreads them over the cores).
RAYS_PER_CORE_SECOND = 1.5e6
#: Work per second of a bounce, which runs mostly in one thread (process CPU seconds on the
#: room, bench/bench_grid_estimate.py): gather rays (their cosine directions, offsets, trace and
#: sky), grid lookups with leak control (each lit surface point under the DDGI recursion, each
#: gather ray meeting a surface from the second bounce), probe rays projected per bounce. A
#: trial trace (`shprobe.grids.trial`) says how much of this work the scene really makes.
GATHER_RAYS_PER_SECOND = 1.7e6
LOOKUPS_PER_SECOND = 6e5
PROJECTIONS_PER_SECOND = 2e7
#: Fixed seconds of a bake (compiled kernels loaded, the sky's moments).
BAKE_BASE_SECONDS = 0.5
#: Scene triangles prepared per second and core (the ray caster's BVH, face normals, the
#: scene's hash: 29 s for 5.2 million triangles on the 2-core box), so that a large scene's
#: bake is announced even with few probes.
FACES_PER_CORE_SECOND = 1e5
#: Peak memory of a bake (measured in fresh processes by bench/bench_estimates.py on the
#: reference room and bunny scenes, fitted): a fixed part (compiled kernels, the ray buffers
#: of one Embree call, one block of depth rays and of bounce lookups), per probe ray (its hit,
#: radiance and, for the rays that meet a surface, that surface's point, normal and albedo),
#: per probe (its depth map, its coefficients per bounce) and per probe again when a bounce
#: reads the previous bounce's grid. Placement and depth rays are traced in blocks.
BAKE_BASE_BYTES = 135e6
BYTES_PER_RAY = 107.0
BYTES_PER_PROBE = 0.0
BOUNCE_BYTES_PER_PROBE = 20e3

#: Depth-map rays traced at once (their hits, distances and temporaries: ~120 bytes a ray).
DEPTH_RAYS_PER_BLOCK = 1 << 18


def grid_bounds(scene: BakeScene, settings: GridSettings) -> NDArray[np.float64]:
    """The bake volume: ``settings.bounds``, or the scene's bounding box (a flat box grown to
    a tenth of its largest side); refused when it lies wholly outside the bounding box of the
    scene's triangles."""
    v = scene.vertices
    if settings.bounds is None:
        lo, hi = v.min(axis=0), v.max(axis=0)
        pad = np.where(hi - lo > 0, 0.0, 0.05 * max(float((hi - lo).max()), 1.0))
        b = check_bounds([lo - pad, hi + pad])
    else:
        b = check_bounds(settings.bounds)
    lo, hi = v[scene.faces].reshape(-1, 3).min(axis=0), v[scene.faces].reshape(-1, 3).max(axis=0)
    if np.any(lo > b[1]) or np.any(hi < b[0]):  # a grid inside an enclosing room is fine
        raise ShprobeError(f"grid bounds {_fmt(b[0])}..{_fmt(b[1])} contain no geometry of the "
                           f"scene (it spans {_fmt(lo)}..{_fmt(hi)})")
    return b


def grid_scene(scene: Sequence[str | os.PathLike[str] | Any], settings: GridSettings,
               albedo: Sequence[Any] = ()) -> tuple[BakeScene, GridSettings]:
    """The scene of a grid bake and its settings with the bounds filled in.

    Parameters
    ----------
    scene
        Mesh paths or objects, or the name of a reference scene (``room``,
        ``bunny-on-ground``: `shprobe.grids.scenes.named_scene`, with its own bounds).
    settings
        The bake's settings; ``bounds`` None: the reference scene's bounds, else the scene's
        bounding box (`grid_bounds`).
    albedo
        Albedo values: none (each mesh's own), one (every mesh) or one per mesh in order.

    Returns
    -------
    tuple
        (the [`BakeScene`][shprobe.prt.BakeScene], the settings with their bounds).
    """
    from .scenes import named_scene

    scene = list(scene)
    where = os.fspath(scene[0]) if len(scene) == 1 and isinstance(
        scene[0], str | os.PathLike) else None
    named = [named_scene(s) if isinstance(s, str | os.PathLike) else None for s in scene]
    if settings.bounds is None and len(scene) == 1 and named[0] is not None:
        settings = replace(settings, bounds=named[0][1])
    try:
        sc = load_scene([s if n is None else n[0] for s, n in zip(scene, named, strict=True)],
                        **albedo_keywords(albedo, len(scene)))
    except ShprobeError as e:
        raise ShprobeError(e.message, e.path or where) from None
    if len(sc.faces) == 0:
        raise ShprobeError("the scene has no faces", where)
    return sc, replace(settings, bounds=grid_bounds(sc, settings))


def _fmt(x: NDArray) -> str:
    return "(" + ", ".join(f"{float(a):.4g}" for a in x) + ")"


def estimate_grid_bake(n_faces: int, settings: GridSettings,
                       scene: BakeScene | None = None) -> Cost:
    """Seconds and peak bytes of [`bake_grid`][shprobe.grids.bake_grid] on this machine, from the
    arguments and, given the scene, a trial trace of it.

    Parameters
    ----------
    n_faces : int
        Triangles of the scene.
    settings : GridSettings
        The bake's settings.
    scene : BakeScene, optional
        The scene: a trial trace (`shprobe.grids.trial`, a few milliseconds, for scenes up to
        `shprobe.grids.trial.TRIAL_FACES` triangles) measures how many probe rays meet a lit
        surface and how many gather rays go on to meet another, so that a bake whose probes see
        mostly sky or back faces is not announced as long. Without it (or for a larger scene)
        most rays are assumed to.

    Returns
    -------
    Cost
        Seconds (probe rays and the scene's preparation over this machine's cores, then the
        bounces' gather rays, grid lookups and projections, which run mostly in one thread)
        and peak bytes (fitted to measured peaks: bench/bench_estimates.py),
        the figure checked against the memory limit.
    """
    from .trial import ASSUMED, TRIAL_FACES, trial_fractions

    fr = ASSUMED
    if scene is not None and settings.bounces and n_faces <= TRIAL_FACES:
        bounds = settings.bounds if settings.bounds is not None else grid_bounds(scene, settings)
        fr = trial_fractions(scene.vertices, scene.faces, scene.albedo, bounds, settings)
    p, d = settings.n_probes, settings.samples
    rays = p * (TEST_RAYS + d + settings.depth_rays)
    points = p * d * fr.lit  # surface points each bounce lights
    if settings.gather:
        gathered = settings.bounces * points * settings.gather
        lookups = max(settings.bounces - 1, 0) * points * settings.gather * fr.onward
    else:
        gathered, lookups = 0.0, settings.bounces * points
    seconds = (BAKE_BASE_SECONDS
               + (rays / RAYS_PER_CORE_SECOND + n_faces / FACES_PER_CORE_SECOND) / cores()
               + gathered / GATHER_RAYS_PER_SECOND + lookups / LOOKUPS_PER_SECOND
               + settings.bounces * p * d / PROJECTIONS_PER_SECOND)
    seconds *= 1.0 + 0.05 * np.log2(max(n_faces, 2)) / 10  # deeper BVH
    per_probe = (BYTES_PER_PROBE + 8 * settings.depth_resolution ** 2
                 + num_coeffs(settings.lmax) * 3 * 8 * (2 + settings.bounces)
                 + (BOUNCE_BYTES_PER_PROBE if settings.bounces and not settings.gather else 0))
    nbytes = BAKE_BASE_BYTES + p * (per_probe + d * BYTES_PER_RAY)
    return Cost(float(seconds), float(nbytes))


def bake_grid(scene: Any, lighting: Any, settings: GridSettings,
              progress: Progress | None = None) -> ProbeGrid:
    """Bake an irradiance volume (module doc).

    Parameters
    ----------
    scene
        Anything [`shprobe.prt.load_scene`][shprobe.prt.load_scene] takes: a mesh path, trimesh,
        BakeScene or list of them (its per-vertex albedo as the renderer reads it); `grid_scene`
        also resolves the reference scenes' names.
    lighting
        A `shprobe.lighting.source.Lighting` (a probe image is then used directly) or
        SH coefficients (K, 3).
    settings
        The bake's [`GridSettings`][shprobe.grids.GridSettings] (its limits apply to everything the
        bake does).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter.

    Returns
    -------
    ProbeGrid
        The grid; ``as_dict()`` summarises it.
    """
    if not isinstance(settings, GridSettings):
        raise ShprobeError("bake_grid needs a GridSettings")
    with settings.limits.applied():
        return _bake_grid(scene, lighting, settings, progress)


def _bake_grid(scene: Any, lighting: Any, settings: GridSettings,
               progress: Progress | None) -> ProbeGrid:
    t0 = time.monotonic()
    sc = scene if isinstance(scene, BakeScene) else load_scene(scene)
    if len(sc.faces) == 0:
        raise ShprobeError("the scene has no faces")
    coeffs, env, source = _lighting_parts(lighting)
    bounds = grid_bounds(sc, settings)
    cost = estimate_grid_bake(len(sc.faces), settings)
    check_memory(cost.nbytes, f"a {'x'.join(map(str, settings.resolution))} grid bake with "
                 f"{settings.samples} rays per probe")
    res, lmax = settings.resolution, settings.lmax
    spacing = (bounds[1] - bounds[0]) / np.asarray(res, dtype=np.float64)
    tracer = ProbeTracer(sc.vertices, sc.faces)
    dirs = sample_directions(settings.samples, settings.seed)
    y = sh_basis(dirs, lmax)  # (D, K)
    with Steps(progress, 4 + settings.bounces) as step:
        step("finding probes inside geometry")
        pos, valid, moved = place_probes(tracer, cell_centres(bounds, res), spacing,
                                         settings.inside_fraction, settings.seed)
        bar = step(f"tracing {settings.samples} rays from each of {len(pos)} probes",
                   total=len(pos))
        hits = tracer.trace(pos, dirs, on_block=bar.advance, distances=False)
        bar = step("depth maps (leak control)", total=len(pos))
        depth = _depth_moments(tracer, pos, settings, float(np.linalg.norm(spacing)),
                               bar.advance)
        step("environment seen by the probes")
        sky = _miss_moments(coeffs, env, dirs, y)  # (D, K, 3)
        miss = (hits.face < 0).astype(np.float32)
        radiance = np.zeros((*miss.shape, 3), np.float32)  # of the surfaces hit
        front = np.flatnonzero((hits.face >= 0).ravel() & ~hits.back.ravel())
        where = _hit_geometry(tracer, sc, hits, front)
        meta = {"lmax": lmax, "bounces": settings.bounces, "samples": settings.samples,
                "depth_resolution": settings.depth_resolution,
                "normal_bias": settings.normal_bias, "gather": settings.gather,
                "lighting": source,
                "scene": sc.mesh_hash, "moved": int(moved.sum()),
                "invalid": int((valid == 0).sum())}
        shape = (*res, num_coeffs(lmax), 3)

        def project() -> ProbeGrid:
            c = _project(miss, sky, radiance, y, valid, shape)
            return _grid(c, bounds, pos, valid, depth, meta)

        grids = [project()]  # grids[k]: light reflected up to k times
        rng = np.random.default_rng([settings.seed, 37])
        sky_fn = _sky_function(coeffs, env)
        for k in range(1, settings.bounces + 1):
            bar = step(f"bounce {k} of {settings.bounces}", total=len(front))
            if settings.gather:
                e = _gathered(tracer, sc, where, sky_fn, grids[k - 2] if k >= 2 else None,
                              settings, rng, lambda n: None)
            else:
                e = _from_grid(grids[k - 1], where)
            radiance.reshape(-1, 3)[front] = _bounce_radiance(e, where, bar.advance)
            grids.append(project())
        grid = grids[-1]
    meta["seconds"] = round(time.monotonic() - t0, 3)
    return grid


def _grid(coeffs, bounds, pos, valid, depth, meta) -> ProbeGrid:
    res = coeffs.shape[:3]
    return ProbeGrid(coeffs=coeffs.astype(np.float32), bounds=bounds,
                     positions=pos.reshape(*res, 3), validity=valid.reshape(res),
                     depth=depth.reshape(*res, *depth.shape[1:]), meta=meta)


def _project(miss: NDArray, sky: NDArray, radiance: NDArray, y: NDArray, valid: NDArray,
             shape: tuple) -> NDArray:
    """L_lm per probe: the environment's moments over the directions that leave the scene
    plus 4π/D Σ_d L(ω_d) y_lm(ω_d) over the surfaces hit (R&H eq. 6 by quadrature); invalid
    probes filled from their neighbours."""
    p, d = miss.shape
    k = y.shape[1]
    # two GEMMs: (P, D)·(D, K·3) and (P·3, D)·(D, K)
    c = (miss @ sky.reshape(d, k * 3).astype(np.float32)).reshape(p, k, 3).astype(np.float64)
    r = np.ascontiguousarray(radiance.transpose(0, 2, 1)).reshape(p * 3, d)
    c += (4.0 * np.pi / d) * (r @ y.astype(np.float32)).reshape(p, 3, k).transpose(0, 2, 1)
    return dilate(c.reshape(shape), valid.reshape(shape[:3]))


def _hit_geometry(tracer: ProbeTracer, sc: BakeScene, hits, rays: NDArray[np.int64]):
    """Points, face normals, albedo (RGB) and faces of the front hits ``rays`` (flat ray
    indices)."""
    f = hits.face.ravel()[rays]
    u, v = hits.u.ravel()[rays], hits.v.ravel()[rays]
    return (tracer.points(f, u, v), tracer.face_normals[f],
            tracer.interpolate(sc.albedo, f, u, v), f)


def _bounce_radiance(irradiance, where, advance, block: int = 1 << 17) -> NDArray:
    """ρ/π·E at the front hits, E = ``irradiance(index array)`` (0 where albedo is 0)."""
    albedo = where[2]
    out = np.zeros((len(albedo), 3), np.float32)
    lit = np.flatnonzero(albedo.max(axis=1) > 0)
    for a in range(0, len(lit), block):
        i = lit[a:a + block]
        out[i] = albedo[i] / np.pi * irradiance(i)
        advance(len(i))
    return out


def _from_grid(grid: ProbeGrid, where):
    """E at the hits ``i`` read from ``grid`` with leak control (DDGI's recursion)."""
    return lambda i: grid.irradiance(where[0][i], where[1][i], leak_control=True)


def _gathered(tracer, sc, where, sky, previous, settings, rng, advance):
    """E at the hits ``i`` by the final gather of `shprobe.grids.gather`."""
    from .gather import gather_irradiance

    def albedo_at(h, rays):
        return _hit_geometry(tracer, sc, h, rays)

    def irradiance(i):
        sub = tuple(x[i] for x in where)
        return gather_irradiance(tracer, sub, sky, previous, albedo_at, settings.gather, rng,
                                 advance)

    return irradiance


def _sky_function(coeffs: NDArray, env: Any):
    """Radiance in directions (..., 3): the probe image (bilinear), else the lighting's SH."""
    if env is not None:
        return lambda d: np.asarray(env.sample(d), dtype=np.float64)
    lmax = lmax_of(coeffs.shape[0])
    return lambda d: sh_basis(np.asarray(d, dtype=np.float64), lmax) @ coeffs


def _depth_moments(tracer: ProbeTracer, pos: NDArray, settings: GridSettings, cap: float,
                   advance) -> NDArray[np.float32]:
    """(P, n, n, 2) mean and mean-square distance per texel of each probe's octahedral map,
    distances capped at ``cap`` (misses count as the cap)."""
    n, s = settings.depth_resolution, settings.depth_samples
    td = texel_directions(n, s).reshape(-1, 3)  # (n·n·s², 3)
    out = np.empty((len(pos), n, n, 2), np.float32)
    # a block of probes at a time: the hits of all depth rays at once held ~100 bytes a ray
    step = max(1, DEPTH_RAYS_PER_BLOCK // len(td))
    for a in range(0, len(pos), step):
        h = tracer.trace(pos[a:a + step], td, on_block=advance)
        d = np.minimum(h.dist.astype(np.float64), 2.0 * cap).reshape(-1, n, n, s * s)
        out[a:a + step, ..., 0] = d.mean(axis=-1)
        out[a:a + step, ..., 1] = (d * d).mean(axis=-1)
    return out


def _lighting_parts(lighting: Any) -> tuple[NDArray[np.float64], Any, str]:
    """(coefficients (K, 3), the probe image or None, a name) of a Lighting or an array."""
    from ..lighting.coeffs import as_rgb

    env = getattr(lighting, "env", None)
    source = str(getattr(lighting, "source", "coefficients"))
    c = getattr(lighting, "coeffs", lighting)
    try:
        c = as_rgb(np.asarray(c, dtype=np.float64))
    except (TypeError, ValueError):
        raise ShprobeError("grid lighting must be a Lighting or SH coefficients (K, 3)") from None
    if not np.all(np.isfinite(c)):
        raise ShprobeError("grid lighting coefficients must be finite")
    lmax_of(c.shape[0])
    return c, env, source


def _miss_moments(coeffs: NDArray, env: Any, dirs: NDArray, y: NDArray
                  ) -> NDArray[np.float64]:
    """SH moments (D, K, 3) of the light a ray leaving the scene in each direction stands
    for: Σ L y_lm dω over the probe image's pixels nearest to that direction (its cell), so
    that the unoccluded sum is the image's own projection pixel for pixel; without an image,
    4π/D · L(ω) y_lm(ω) with L the lighting's SH."""
    if env is None:
        sky = _sky_function(coeffs, None)(dirs)  # (D, 3)
        return (4.0 * np.pi / len(dirs)) * y[:, :, None] * sky[:, None, :]
    from scipy.spatial import cKDTree

    pd, rad, dw = env.samples()
    _, near = cKDTree(dirs).query(pd, workers=-1)
    k = y.shape[1]
    yp = sh_basis(pd, lmax_of(k)) * dw[:, None]  # (S, K)
    out = np.zeros((len(dirs), k, 3))
    for c in range(3):
        w = yp * rad[:, c, None].astype(np.float64)
        for j in range(k):
            out[:, j, c] = np.bincount(near, weights=w[:, j], minlength=len(dirs))
    return out
