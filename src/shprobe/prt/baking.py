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

import numpy as np

from ..errors import ShprobeError
from ..limits import Cost
from ..progress import Progress
from ..sh import num_coeffs
from .geometry import BakeScene, load_scene
from .refine import bake_refined, stage_progress
from .settings import PrtSettings
from .trace import bake_bytes, check_threads, trace_bake
from .transfer import Transfer, coloured

__all__ = ["BakeEstimate", "bake", "estimate_bake"]


def bake(scene: Any, settings: PrtSettings | None = None, progress: Progress | None = None,
         *, albedo: Any = None, ground: bool = False, mesh_albedo: Any = None,
         **changes: Any) -> Transfer:
    """Bake per-vertex transfer vectors (Lisle & Huang 2007 §4).

    Parameters
    ----------
    scene
        A mesh path, a trimesh object, a list of them, or a [`BakeScene`][shprobe.prt.BakeScene]
        ([`load_scene`][shprobe.prt.load_scene]: the way to a ground albedo or resolution of one's
        own).
    settings
        The bake's [`PrtSettings`][shprobe.prt.PrtSettings] (default: its defaults, the CLI's).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter (stages "k/N: what",
        countable).
    albedo
        One value for every mesh (a number or r,g,b), when ``scene`` is not a BakeScene.
    ground
        Add a ground plane ([`load_scene`][shprobe.prt.load_scene]), when ``scene`` is not a
        BakeScene.
    mesh_albedo
        One entry per mesh (number, r,g,b or per-vertex values).
    **changes
        Fields of [`PrtSettings`][shprobe.prt.PrtSettings] changed from ``settings``
        (``mode="interreflected", lmax=2``).

    Returns
    -------
    Transfer
        Its ``transfer`` ((V, K) float32, or (V, K, 3) when the albedo is coloured) is the
        baked model, with transfer · L = exit radiance ρ/π ∫ L V max(0, n·ω) dω (+ bounces);
        ``as_dict()`` summarises it. A traced bake that adds a ground is refined by default
        (`PrtSettings.refine`).
    """
    settings = settings if settings is not None else PrtSettings()
    if not isinstance(settings, PrtSettings):
        raise ShprobeError(f"settings must be a PrtSettings, got {type(settings).__name__}")
    if changes:
        settings = settings.but(**changes)
    with settings.limits.applied():
        sc = load_scene(scene, albedo=albedo, ground=ground, mesh_albedo=mesh_albedo)
        refinement = settings.refinement(ground)
        if refinement is not None:
            return bake_refined(sc, refinement, settings, progress)
        return trace_bake(sc, settings, stage_progress(
            progress, 1, 1, f"{settings.mode} bake, {sc.n_vertices:,} vertices"))[0]


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
#: refinement, and the final vertices as a multiple of the input's at lmax 2: measured on the
#: bench scene (bunny + ground, 6,728 vertices, 1024 samples, 2 bounces; bench/bench_prt.py,
#: bench/bench_prt_contact.py --timing) on the 2-core box.
COST = {("shadowed", None): (3.5e-8, 1.0), ("interreflected", None): (1.2e-7, 1.0),
        ("shadowed", "quick"): (7.0e-7, 1.6), ("interreflected", "quick"): (6.1e-6, 12.0),
        ("shadowed", "accurate"): (1.5e-6, 2.0), ("interreflected", "accurate"): (5.8e-5, 34.0)}
#: The final vertices of a quick refinement as a multiple of the input's, by degree: a higher
#: degree sees sharper jumps in the transfer and splits more (bunny + ground, 1024 samples,
#: bench/bench_prt_memory.py); read linearly between the degrees, flat beyond them.
GROWTH = {("shadowed", "quick"): ((2, 1.59), (6, 2.17), (10, 2.81), (16, 5.57)),
          ("interreflected", "quick"): ((2, 12.2), (6, 15.6), (10, 18.1), (16, 22.5))}
#: The time of a bake grows with the SH degree as (LMAX_COST + K) (K = (lmax + 1)²): the
#: quick interreflected bunny takes 42 s at lmax 2 and 94 s at lmax 6.
LMAX_COST = 23.0
#: Resident memory of the process besides the bake's arrays (Python, numpy, trimesh, the
#: scene): an unshadowed bake of the bunny peaks at 115 MB.
BASE_BYTES = 1.15e8
#: What a traced bake adds to it besides its arrays: Embree's BVH, the compiled kernels and
#: the workers' ray chunks (a shadowed bake of the bunny at lmax 2 peaks at 240 MB).
TRACE_BYTES = 1.25e8


#: A refined bake's peak memory beyond the bases, by mode: bytes per cell (final vertex ×
#: coefficient × channel) and per final vertex at 1024 samples (its rays, the gather of an
#: interreflected bake, the mesh's tables), least-squares fits to the peak resident memory of
#: the quick bakes of the bunny + ground at lmax 2, 6, 10 and 16 (bench/bench_prt_memory.py).
REFINED_BYTES = {"shadowed": (54.2, 2790.0), "interreflected": (97.8, 5357.0)}


def growth(mode: str, refinement: str | None, lmax: int) -> float:
    """The final vertices of a bake as a multiple of its input's (`GROWTH`, else the
    lmax-2 figure of `COST`).

    Parameters
    ----------
    mode
        The bake's mode.
    refinement
        None, 'quick' or 'accurate'.
    lmax
        The degree baked.

    Returns
    -------
    float
        The factor.
    """
    table = GROWTH.get((mode, refinement))
    if table is None:
        return COST[mode, refinement][1]
    degrees = [d for d, _ in table]
    return float(np.interp(lmax, degrees, [g for _, g in table]))


def estimate_bake(scene: BakeScene, settings: PrtSettings | None = None) -> BakeEstimate:
    """The time and peak memory of ``bake(scene, settings)`` on this machine.

    Time from the measured cost per input vertex and sample (`COST`, scaled by the
    degree and the threads), memory from the bake's own memory model
    (`shprobe.prt.trace.bake_bytes`, the one its memory check uses) at the final vertex count.

    Parameters
    ----------
    scene
        The scene to bake ([`load_scene`][shprobe.prt.load_scene]).
    settings
        The bake's settings (default: [`PrtSettings`][shprobe.prt.PrtSettings]'s defaults).

    Returns
    -------
    BakeEstimate
        Seconds, peak bytes and the final vertex count.
    """
    settings = settings if settings is not None else PrtSettings()
    mode, lmax = settings.mode, settings.lmax
    nthreads = check_threads(settings.threads)
    k = num_coeffs(lmax)
    if mode == "unshadowed":
        return BakeEstimate(2e-7 * scene.n_vertices * k,
                            BASE_BYTES + bake_bytes(scene.n_vertices, lmax, 0, 0),
                            scene.n_vertices)
    samples = settings.samples
    bounces = settings.bounces if mode == "interreflected" else 0
    refine = settings.refinement(False)  # a BakeScene is refined when asked
    name = None if refine is None else ("accurate" if refine.post_jump is not None
                                        or refine.dense_factor > 8 else "quick")
    per = COST[mode, name][0]
    n = int(scene.n_vertices * growth(mode, name, lmax))
    seconds = (per * scene.n_vertices * samples * (LMAX_COST + k) / (LMAX_COST + 9)
               * (max(1, bounces) / 2 if mode == "interreflected" else 1) * 2 / nthreads)
    channels = 3 if coloured(scene.albedo) else 1
    layers = bounces + 1
    if refine is None:
        nbytes = (BASE_BYTES + TRACE_BYTES
                  + bake_bytes(n, lmax, samples, layers, channels, nthreads))
    else:
        # the final geometry's cells and vertices at the rates fitted to the refined bakes
        # (they hold a round's arrays while the next bakes, the rounds' criteria and edge
        # tables, the final bake's groups), and the contact's SH rows dense_factor× longer
        per_cell, per_vertex = REFINED_BYTES[mode]
        nbytes = (BASE_BYTES + TRACE_BYTES + per_cell * n * k * channels
                  + per_vertex * n * samples / 1024.0
                  + 8.0 * refine.dense_factor * samples * k * nthreads)
    return BakeEstimate(seconds, nbytes, n)
