"""The refined bake: a driver of named stages over `shprobe.prt.trace`, `shprobe.prt.criteria` and
`shprobe.prt.subdivide`, set by one [`Refinement`][shprobe.prt.Refinement].

1. **subdivision rounds**: bake the scene with a quarter of the samples (at least 64; enough
   to see where the transfer jumps), mark the edges where `transfer_jumps`
   exceeds ``tol`` or (interreflected, with bounces) `gather_errors` exceeds
   ``gather_tol``, longer than ``min_edge_fraction`` of the diagonal; split them
   (`shprobe.prt.subdivide`) and repeat until none is marked or ``max_rounds`` is reached;
2. **final bake** of the final geometry with the full samples, the input scene's vertices that
   the refinement touched (the contact, where visibility is intricate and the light dim)
   traced with ``dense_factor`` × the samples on ``dense_quadrature``; with ``dense_picks``
   the vertices the contact's bounces lean on (`gather_picks`) traced so
   too. The new vertices keep the samples: they support the interpolation, and the gathers
   that read them average their noise over many rays;
3. **post-pass** (``post_jump``): the final bake only screens (its picks found, not traced);
   among the vertices the contact leans on, the edges where the shadowed transfer jumps by
   more than ``post_jump`` are split (`post_split_marks`) and the scene is
   baked once more, the picks traced, the new vertices between two leaned-on ones on their own
   adaptive grid at ``post_dense`` × the samples.

Every bake has the same seed, so the result is deterministic. The result is an ordinary
[`Transfer`][shprobe.prt.Transfer] over the refined geometry (input vertices first); its metadata
records the refinement (settings, rounds, the hash of the unrefined scene).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..progress import Progress, numbered, prefixed
from .criteria import (
    Gathered,
    gather_errors,
    gather_importance,
    gather_picks,
    post_split_marks,
    transfer_jumps,
)
from .geometry import BakeScene
from .settings import PrtSettings, Refinement
from .subdivide import closed_edges, edge_table, split_closed
from .trace import DenseVertices, GatherBlocks, trace_bake
from .transfer import Transfer

__all__ = ["RefineRound", "bake_count", "bake_refined"]


@dataclass(frozen=True)
class RefineRound:
    """One bake of the refinement: vertices baked, edges split after it, bake seconds."""

    vertices: int
    split: int
    seconds: float


def _bounced(settings: PrtSettings) -> bool:
    """An interreflected bake with bounces: the gather criteria apply."""
    return settings.mode == "interreflected" and settings.bounces > 0


def _picks(settings: PrtSettings, refinement: Refinement) -> tuple[float, ...]:
    """The pick thresholds the final bake uses (none unless bounced with dense vertices)."""
    r = refinement
    return r.dense_picks if _bounced(settings) and r.dense_factor > 1 else ()


@dataclass
class _Geometry:
    """The scene as the rounds leave it: ``raw`` its unnormalised interpolated normals
    (`split_closed`), ``touched`` (V,) the vertices of split edges;
    ``n_input`` the vertices of the unrefined scene, ``min_edge`` the length edges must exceed
    to be split."""

    scene: BakeScene
    raw: NDArray[np.float64]
    touched: NDArray[np.bool_]
    rounds: list[RefineRound]
    n_input: int
    min_edge: float

    def dense(self) -> NDArray[np.bool_]:
        """The contact: the input vertices the refinement touched."""
        return self.touched & (np.arange(len(self.touched)) < self.n_input)

    def split(self, sel: NDArray[np.int64], edges: NDArray[np.int64],
              face_edges: NDArray[np.int64], max_vertices: int, touch: bool) -> int:
        """Split the closed edge set ``sel``; returns the vertices added."""
        new, self.raw = split_closed(self.scene, sel, edges, face_edges, self.raw)
        if new.n_vertices > max_vertices:
            raise ShprobeError(f"refinement would grow the scene past {max_vertices} vertices; "
                               "raise its tolerances or min_edge_fraction")
        added = new.n_vertices - self.scene.n_vertices
        self.touched = np.concatenate([self.touched, np.full(added, touch)])
        if touch:
            self.touched[edges[sel].ravel()] = True
        self.scene = new
        return added


class _Picker:
    """The ``pick`` of a final bake (`gather_picks` seeded by the contact)
    and what it saw, which the post-pass reads. ``trace`` False: the bake only screens."""

    def __init__(self, seeds: NDArray[np.bool_], thresholds: tuple[float, ...], floor: float,
                 trace: bool) -> None:
        self.seeds, self.thresholds, self.floor, self.trace = seeds, thresholds, floor, trace
        self.seen: dict[str, Any] = {}

    def __call__(self, direct: Any, cumulative: Any, blocks: GatherBlocks, albedo: Any
                 ) -> NDArray[np.int64]:
        got = gather_picks(direct, cumulative, blocks, albedo, self.seeds, self.thresholds,
                           self.floor)
        self.seen = {"direct": direct, "cumulative": cumulative, "albedo": albedo,
                     "picked": got}
        return got if self.trace else got[:0]


def stage_progress(progress: Progress | None, index: int, count: int, what: str
                   ) -> Progress | None:
    """Progress of one bake among several: its stages read 'k/N: <bake>: <stage>'."""
    return prefixed(numbered(progress, index, count), what)


def bake_count(refinement: Refinement) -> int:
    """The most bakes a refined bake runs: the rounds, the final bake, the post-pass's."""
    return refinement.max_rounds + 1 + (refinement.post_jump is not None)


def bake_refined(scene: BakeScene, refinement: Refinement, settings: PrtSettings,
                 progress: Progress | None = None) -> Transfer:
    """Bake ``scene`` with adaptive refinement (module doc).

    Parameters
    ----------
    scene
        The scene ([`load_scene`][shprobe.prt.load_scene]; its ground plane, if any, is refined like
        every mesh).
    refinement
        How the scene is refined ([`QUICK`][shprobe.prt.QUICK], [`ACCURATE`][shprobe.prt.ACCURATE]).
    settings
        The bake's [`PrtSettings`][shprobe.prt.PrtSettings] (a traced mode).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter (stages "k/N: <bake>:
        <stage>").

    Returns
    -------
    Transfer
        Over the refined geometry (input vertices first); ``metadata['refine']`` holds the
        refinement and the rounds (`RefineRound` as dicts).
    """
    if not settings.traced:
        raise ShprobeError(f"refinement needs a traced bake (shadowed or interreflected), not "
                           f"{settings.mode!r}")
    diag = float(np.linalg.norm(np.ptp(scene.vertices, axis=0)))
    geo = _Geometry(scene, scene.normals, np.zeros(scene.n_vertices, dtype=bool), [],
                    scene.n_vertices, refinement.min_edge_fraction * diag)
    count = bake_count(refinement)
    t = _subdivide(settings, refinement, geo, progress, count)
    picker, blocks = None, None
    if t is None:
        t0 = time.perf_counter()
        screen = refinement.post_jump is not None
        t, blocks, picker = _final_bake(settings, refinement, geo, None, screen,
                                        stage_progress(progress, count - screen, count,
                                               f"{'screening' if screen else 'final'} bake, "
                                               f"{geo.scene.n_vertices:,} vertices"))
        geo.rounds.append(RefineRound(geo.scene.n_vertices, 0, time.perf_counter() - t0))
    post: dict[str, Any] = {}
    if picker is not None and picker.seen and blocks is not None:
        t, post = _post_pass(settings, refinement, geo, (t, blocks, picker),
                             (progress, count))
    meta = dict(t.metadata)
    s = refinement
    dense = geo.dense()
    meta["refine"] = {
        "settings": s.name, "tol": s.tol, "min_edge_fraction": s.min_edge_fraction,
        "max_rounds": s.max_rounds, "gather_tol": s.gather_tol if _bounced(settings) else None,
        "gather_gate": s.gather_gate, "gather_floor": s.gather_floor,
        "base_mesh_hash": scene.mesh_hash, "dense_factor": s.dense_factor,
        # what the final bake ran (no dense vertices: Fibonacci everywhere)
        "dense_quadrature": "adaptive" if "dense_quadrature" in t.metadata else "fibonacci",
        "dense_vertices": int(dense.sum()) if s.dense_factor > 1 else 0,
        "dense_picks": list(_picks(settings, refinement)),
        "dense_picked": int(t.metadata.get("dense_picked", 0)),
        **post,
        "rounds": [{"vertices": x.vertices, "split": x.split, "seconds": round(x.seconds, 3)}
                   for x in geo.rounds],
    }
    meta["ground"] = scene.n_ground > 0
    return replace(t, metadata=meta)


def _subdivide(settings: PrtSettings, refinement: Refinement, geo: _Geometry,
               progress: Progress | None, count: int) -> Transfer | None:
    """Stage 1 (module doc): the rounds, splitting ``geo`` in place. Returns the last
    driving bake when it is already the final one (full samples, no dense vertices), else
    None (the final bake is still to run)."""
    s = refinement
    drive = max(64, settings.samples // 4)
    driving = settings.but(samples=min(drive, settings.samples))
    for r in range(s.max_rounds):
        t0 = time.perf_counter()
        sc = geo.scene
        t, blocks = trace_bake(sc, driving,
                               stage_progress(progress, r + 1, count,
                                              f"refinement round {r + 1}, "
                                              f"{sc.n_vertices:,} vertices"),
                               keep_gather=_bounced(settings))
        secs = time.perf_counter() - t0
        edges, face_edges = edge_table(sc.faces)
        over = transfer_jumps(t)[1] > s.tol
        if _bounced(settings) and blocks is not None:
            imp = gather_importance(t, blocks, s.gather_floor)
            over |= gather_errors(t, edges, imp, s.gather_gate) > s.gather_tol
        length = np.linalg.norm(sc.vertices[edges[:, 0]] - sc.vertices[edges[:, 1]], axis=1)
        marked = over & (length > geo.min_edge)
        geo.rounds.append(RefineRound(sc.n_vertices, int(marked.sum()), secs))
        if not marked.any():
            final = drive >= settings.samples and not (s.dense_factor > 1
                                                   and geo.dense().any())
            return t if final else None
        geo.split(closed_edges(marked, face_edges), edges, face_edges, s.max_vertices, True)
    return None


def _final_bake(settings: PrtSettings, refinement: Refinement, geo: _Geometry,
                extra: NDArray[np.bool_] | None, screen: bool, progress: Progress | None
                ) -> tuple[Transfer, GatherBlocks | None, _Picker | None]:
    """Stage 2 (module doc): the final geometry with the full samples, the contact dense;
    ``extra``: the post-pass's new vertices traced on their own grid; ``screen``: the bake the
    post-pass reads (its picks found, not traced; the gather kept)."""
    s = refinement
    samples = settings.samples
    contact = geo.dense()
    own = extra is not None and 0 < s.post_dense < s.dense_factor
    mask = contact if extra is None or own else contact | extra
    dense = None
    if s.dense_factor > 1 and mask.any():
        dense = DenseVertices(mask, s.dense_factor * samples, s.dense_quadrature,
                              s.adaptive_levels, extra if own else None,
                              s.post_dense * samples)
    picker = None
    picks = _picks(settings, refinement)
    if picks and mask.any():
        picker = _Picker(contact, picks, s.gather_floor, trace=not screen)
    t, blocks = trace_bake(geo.scene, settings, progress, dense=dense, sets=s.direction_sets,
                           pick=picker, keep_gather=screen and picker is not None)
    return t, blocks, picker


def _post_pass(settings: PrtSettings, refinement: Refinement, geo: _Geometry,
               screened: tuple[Transfer, GatherBlocks, _Picker],
               where: tuple[Progress | None, int]) -> tuple[Transfer, dict[str, Any]]:
    """Stage 3 (module doc): split among what the contact leans on where the screening bake's
    (``screened``: its transfer, gather blocks and picker) shadowed transfer jumps, and bake
    again with the picks traced; ``where``: the progress and the count of bakes."""
    t, blocks, picker = screened
    progress, count = where
    s = refinement
    sc = geo.scene
    edges, face_edges = edge_table(sc.faces)
    gatherers = geo.dense()
    gatherers[picker.seen["picked"]] = True
    seen = picker.seen
    marked, hit = post_split_marks(
        np.asarray(t.traced[0], dtype=np.float64), edges,
        Gathered(seen["direct"], seen["cumulative"], blocks, seen["albedo"]), gatherers,
        float(s.post_jump), float(s.post_share), s.gather_floor)
    length = np.linalg.norm(sc.vertices[edges[:, 0]] - sc.vertices[edges[:, 1]], axis=1)
    marked &= length > geo.min_edge
    last = geo.rounds[-1]
    geo.rounds[-1] = RefineRound(last.vertices, int(marked.sum()), last.seconds)
    post = {"post_jump": float(s.post_jump), "post_share": float(s.post_share),
            "post_dense_factor": s.post_dense, "post_leaned_on": int(hit.sum()),
            "post_split": int(marked.sum()), "post_dense": 0}
    t0 = time.perf_counter()
    extra = np.zeros(sc.n_vertices, dtype=bool)
    if marked.any():
        sel = closed_edges(marked, face_edges)
        geo.split(sel, edges, face_edges, s.max_vertices, False)
        # the new vertices between two the contact leans on: traced at post_dense
        extra = np.zeros(geo.scene.n_vertices, dtype=bool)
        extra[sc.n_vertices:] = gatherers[edges[sel]].all(1) & (s.post_dense > 0)
        post["post_dense"] = int(extra.sum())
    t, _, _ = _final_bake(settings, refinement, geo, extra, False,
                          stage_progress(progress, count, count,
                                 f"final bake, {geo.scene.n_vertices:,} vertices"))
    geo.rounds.append(RefineRound(geo.scene.n_vertices, 0, time.perf_counter() - t0))
    return t, post
