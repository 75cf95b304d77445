"""Baking per-vertex transfer vectors (Lisle & Huang 2007 §4; Sloan et al. 2002 §5): the public
entry, and its estimate of time and memory.

Three diffuse models, all with the radiance scale of `shprobe.prt.transfer`
(transfer · L = exit radiance): unshadowed (analytic, b_lm = Â_l y_lm(n) ρ/π, LH eq. 9–10),
shadowed and interreflected (ray traced, `shprobe.prt.trace`). A traced bake with a ground plane is
refined where the transfer varies fast (`shprobe.prt.refine`), by default with
[`QUICK`][shprobe.prt.QUICK]; [`ACCURATE`][shprobe.prt.ACCURATE] is the opt-in accurate contact.

One bake serves every model up to the one baked (run-time switching, LH §4): the unshadowed
transfer is analytic in the stored normals; an interreflected bake keeps its bounce-0 (shadowed)
transfer and the cumulative transfer after every bounce.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import ShprobeError
from ..limits import Cost
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

    scene: a mesh path, a trimesh object, a list of them, or a [`BakeScene`][shprobe.prt.BakeScene]
    ([`load_scene`][shprobe.prt.load_scene]: the way to a ground albedo or resolution of one's own).
    albedo: one value for every mesh (a number or r,g,b); mesh_albedo: one entry per mesh (number,
    r,g,b or per-vertex values); ground: add a ground plane
    ([`load_scene`][shprobe.prt.load_scene]). mode: 'unshadowed' | 'shadowed' | 'interreflected' —
    the most complete model baked: a shadowed bake also gives unshadowed, an interreflected bake
    also gives shadowed and any fewer bounces ([`Transfer.select`][shprobe.prt.Transfer.select]).
    lmax: degree baked (any lower degree can be used later). samples: ray directions per vertex over
    the whole sphere (about half are traced). bounces: interreflection bounces (interreflected
    only). seed: an integer >= 0, picks the random rotation of the direction set. threads: workers
    for ray casting, kernels and bounce products (default: all cores; `shprobe.prt.trace`).
    progress: a [`Progress`][shprobe.progress.Progress] reporter (stages "k/N: what", countable).

    refine: adaptive refinement of the scene where the transfer varies fast
    (`shprobe.prt.refine`): a [`Refinement`][shprobe.prt.Refinement] ([`QUICK`][shprobe.prt.QUICK],
    [`ACCURATE`][shprobe.prt.ACCURATE]) or its name, True (QUICK) or False. Default (None): QUICK
    for a traced bake with ``ground=True``, else none (a [`BakeScene`][shprobe.prt.BakeScene] that
    holds a ground is refined when asked: its ground is refined like every mesh).

    Returns a [`Transfer`][shprobe.prt.Transfer]; its ``transfer`` ((V, K) float32, or (V, K, 3)
    when the albedo is coloured) is the baked model, with transfer · L = exit radiance
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
class BakeEstimate(Cost):
    """What a bake is expected to cost on this machine
    ([`shprobe.limits.Cost`][shprobe.limits.Cost]: seconds and peak bytes) and the ``vertices`` of
    its final geometry."""

    vertices: int = 0

    @property
    def bytes(self) -> float:
        return self.nbytes


#: Seconds per (input vertex × sample) of a bake at lmax 2 on two threads, by mode and
#: refinement, and the final vertices as a multiple of the input's: measured on the bench scene
#: (bunny + ground, 6,728 vertices, 1024 samples, 2 bounces; bench/bench_prt.py,
#: bench/bench_prt_contact.py --timing) on the 2-core box.
COST = {("shadowed", None): (3.5e-8, 1.0), ("interreflected", None): (1.2e-7, 1.0),
        ("shadowed", "quick"): (7.0e-7, 1.6), ("interreflected", "quick"): (6.1e-6, 12.0),
        ("shadowed", "accurate"): (1.5e-6, 2.0), ("interreflected", "accurate"): (5.8e-5, 34.0)}
#: The time of a bake grows with the SH degree as (LMAX_COST + K) (K = (lmax + 1)²): the
#: quick interreflected bunny takes 42 s at lmax 2 and 94 s at lmax 6.
LMAX_COST = 23.0
#: Resident memory of the process besides the bake's arrays (Python, numpy, Embree's BVH).
BASE_BYTES = 3e8


def estimate_bake(scene: BakeScene, mode: str = "shadowed", lmax: int = 4,
                  samples: int = 1024, bounces: int = 2,
                  refine: Refinement | None = None, threads: int | None = None) -> BakeEstimate:
    """The time and peak memory of ``bake(scene, mode, lmax, samples, bounces, refine=...)``
    on this machine: time from the measured cost per input vertex and sample (`COST`,
    scaled by the degree and the threads), memory from the bake's own memory model
    (`shprobe.prt.trace.bake_bytes`, the one its memory check uses) at the final vertex count."""
    if mode not in MODES:
        raise ShprobeError(f"unknown PRT mode {mode!r}; choose one of {', '.join(MODES)}")
    lmax = check_lmax(lmax)
    nthreads = check_threads(threads)
    k = num_coeffs(lmax)
    if mode == "unshadowed":
        return BakeEstimate(2e-7 * scene.n_vertices * k,
                            BASE_BYTES + bake_bytes(scene.n_vertices, lmax, 0, 0),
                            scene.n_vertices)
    samples = check_int(samples, 16, "samples per vertex")
    bounces = check_int(bounces, 0, "bounces") if mode == "interreflected" else 0
    name = None if refine is None else ("accurate" if refine.post_jump is not None
                                        or refine.dense_factor > 8 else "quick")
    per, grow = COST[mode, name]
    n = int(scene.n_vertices * grow)
    seconds = (per * scene.n_vertices * samples * (LMAX_COST + k) / (LMAX_COST + 9)
               * (max(1, bounces) / 2 if mode == "interreflected" else 1) * 2 / nthreads)
    channels = 3 if coloured(scene.albedo) else 1
    nbytes = BASE_BYTES + bake_bytes(n, lmax, samples, bounces + 1, channels, nthreads)
    return BakeEstimate(seconds, nbytes, n)
