"""Baking per-vertex transfer vectors (Lisle & Huang 2007 §4; Sloan et al. 2002 §5): the public
entry, and its estimate of time and memory.

Three diffuse models, all with the radiance scale of :mod:`shprobe.prt.transfer`
(transfer · L = exit radiance): unshadowed (analytic, b_lm = Â_l y_lm(n) ρ/π, LH eq. 9–10),
shadowed and interreflected (ray traced, :mod:`.trace`). A traced bake with a ground plane is
refined where the transfer varies fast (:mod:`.refine`), by default with
:data:`~.settings.QUICK`; :data:`~.settings.ACCURATE` is the opt-in accurate contact.

One bake serves every model up to the one baked (run-time switching, LH §4): the unshadowed
transfer is analytic in the stored normals; an interreflected bake keeps its bounce-0 (shadowed)
transfer and the cumulative transfer after every bounce.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import ShprobeError
from ..progress import Progress
from ..sh import check_lmax, num_coeffs
from .geometry import BakeScene, load_scene
from .refine import bake_refined, stage_progress
from .settings import QUICK, Refinement, as_refinement
from .trace import bake_bytes, check_threads, trace_bake
from .transfer import MODES, Transfer, check_int, coloured

__all__ = ["BakeEstimate", "bake", "estimate_bake"]


def bake(scene: Any, mode: str = "shadowed", lmax: int = 4, samples: int = 1024,
         bounces: int = 2, albedo: Any = None, seed: int = 0, ground: bool = False,
         threads: int | None = None, progress: Progress | None = None, *,
         mesh_albedo: Any = None, refine: Refinement | str | bool | None = None) -> Transfer:
    """Bake per-vertex transfer vectors (Lisle & Huang 2007 §4).

    scene: a mesh path, a trimesh object, a list of them, or a :class:`BakeScene`
    (:func:`load_scene`: the way to a ground albedo or resolution of one's own). albedo: one
    value for every mesh (a number or r,g,b); mesh_albedo: one entry per mesh (number, r,g,b or
    per-vertex values); ground: add a ground plane (:func:`load_scene`). mode: 'unshadowed' |
    'shadowed' | 'interreflected' — the most complete model baked: a shadowed bake also gives
    unshadowed, an interreflected bake also gives shadowed and any fewer bounces
    (:meth:`Transfer.select`). lmax: degree baked (any lower degree can be used later).
    samples: ray directions per vertex over the whole sphere (about half are traced).
    bounces: interreflection bounces (interreflected only). seed: an integer >= 0, picks the
    random rotation of the direction set. threads: workers for ray casting, kernels and bounce
    products (default: all cores; :mod:`.trace`). progress: a
    :class:`~shprobe.progress.Progress` reporter (stages "k/N: what", countable).

    refine: adaptive refinement of the scene where the transfer varies fast
    (:mod:`.refine`): a :class:`~.settings.Refinement` (:data:`~.settings.QUICK`,
    :data:`~.settings.ACCURATE`) or its name, True (QUICK) or False. Default (None): QUICK
    for a traced bake with ``ground=True``, else none (a :class:`BakeScene` that holds a
    ground is refined when asked: its ground is refined like every mesh).

    Returns a :class:`Transfer`; its ``transfer`` ((V, K) float32, or (V, K, 3) when the albedo
    is coloured) is the baked model, with transfer · L = exit radiance
    ρ/π ∫ L V max(0, n·ω) dω (+ bounces).
    """
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    settings = as_refinement(refine)
    sc = load_scene(scene, albedo=albedo, ground=ground, mesh_albedo=mesh_albedo)
    if refine is None and mode != "unshadowed" and ground:
        settings = QUICK
    if settings is not None:
        return bake_refined(sc, settings, mode, lmax, samples, bounces, seed, threads, progress)
    return trace_bake(sc, mode, lmax, samples, bounces, seed, threads,
                      stage_progress(progress, 1, 1, f"{mode} bake, {sc.n_vertices:,} vertices"))[0]


@dataclass(frozen=True)
class BakeEstimate:
    """What a bake is expected to cost on this machine: ``seconds``, peak ``bytes`` and the
    ``vertices`` of its final geometry."""

    seconds: float
    bytes: float
    vertices: int

    def __str__(self) -> str:
        from ..limits import format_bytes

        s = self.seconds
        when = (f"{s:.0f} s" if s < 90 else f"{s / 60:.1f} min" if s < 5400
                else f"{s / 3600:.1f} h")
        return f"about {when} and {format_bytes(self.bytes)}"


#: Seconds per traced ray and thread, with its share of the SH projection and the gather
#: matrix (calibrated on the bench scene: bench/bench_prt.py).
SECONDS_PER_RAY = 1.0e-6
#: Stored gather-matrix bytes per traced ray of an interreflected bake (CSR value + index for
#: the three corners of the hits that survive the merging of repeated entries).
GATHER_BYTES_PER_RAY = 9.0
#: A refined bake's final vertices and total traced rays, as multiples of an unrefined bake's
#: of the input (measured on the bunny with a ground, docs/prt.md).
REFINED_GROWTH = {"quick": (2.3, 4.0), "accurate": (6.0, 40.0)}


def estimate_bake(scene: BakeScene, mode: str = "shadowed", lmax: int = 4,
                  samples: int = 1024, bounces: int = 2,
                  refine: Refinement | None = None, threads: int | None = None) -> BakeEstimate:
    """The time and peak memory of ``bake(scene, mode, lmax, samples, bounces, refine=...)``
    on this machine, from the cost model of the bake's memory check (:func:`.trace.bake_bytes`)
    and the rays it traces (about half the samples per vertex, times the refinement's growth)."""
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    lmax = check_lmax(lmax)
    nthreads = check_threads(threads)
    samples = check_int(samples, 16, "samples per vertex")
    bounces = check_int(bounces, 0, "bounces") if mode == "interreflected" else 0
    if mode == "unshadowed":
        return BakeEstimate(1e-7 * scene.n_vertices * num_coeffs(lmax),
                            bake_bytes(scene.n_vertices, lmax, 0, 0), scene.n_vertices)
    grow, work = REFINED_GROWTH.get(refine.name, REFINED_GROWTH["accurate"]) if refine else (
        1.0, 1.0)
    n = int(scene.n_vertices * grow)
    rays = 0.5 * samples * scene.n_vertices * work
    channels = 3 if coloured(scene.albedo) else 1
    nbytes = bake_bytes(n, lmax, samples * (refine.dense_factor if refine else 1), bounces + 1,
                        channels, nthreads)
    seconds = rays * SECONDS_PER_RAY * num_coeffs(lmax) ** 0.25 / nthreads
    if mode == "interreflected":
        nbytes += GATHER_BYTES_PER_RAY * 0.5 * samples * n
        seconds += 2e-9 * 0.5 * samples * n * num_coeffs(lmax) * channels * bounces
    return BakeEstimate(seconds, nbytes, n)
