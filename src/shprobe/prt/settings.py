"""How a traced bake with a ground refines its scene: one frozen settings type,
[`Refinement`][shprobe.prt.Refinement], and its two named instances.

- [`QUICK`][shprobe.prt.QUICK]: the default of every traced bake with a ground. The scene is split
  where the transfer jumps or where a close gatherer leans on a coarse triangle, and the contact's
  vertices trace 8× the directions.
- [`ACCURATE`][shprobe.prt.ACCURATE]: opt-in (``shprobe prt bake --accurate-contact``). The contact
  traced on the adaptive hemisphere grid (32×), the vertices its bounces lean on picked and traced
  so too, a post-pass that splits among them once more, and 256 rotated direction sets. It brings
  the contact's worst error from 2.4–17× to 1.2–2.8× the open vertices' noise on the bunny, at
  about 10× the bake time (docs/prt.md, "why these defaults").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import ShprobeError
from .hemisphere import ADAPTIVE_LEVELS
from .trace import MAX_ADAPTIVE_LEVELS, QUADRATURES

__all__ = ["ACCURATE", "QUICK", "REFINEMENTS", "Refinement", "as_refinement"]


@dataclass(frozen=True)
class Refinement:
    """Settings of a refined bake (`shprobe.prt.refine.bake_refined`).

    Splitting: ``tol`` on the relative jump of a transfer layer across an edge
    (`transfer_jumps`); ``gather_tol`` on an edge's estimated share of a
    gathering vertex's exit transfer that its interpolation gets wrong, with jumps below
    ``gather_gate`` of the edge's level counted as noise and gatherers dimmer than
    ``gather_floor`` × the median judged as if that bright (`gather_errors`;
    interreflected bakes with bounces); edges shorter than ``min_edge_fraction`` × the scene's
    diagonal are not split; at most ``max_rounds`` re-bakes and ``max_vertices`` vertices.

    Final bake: the input vertices the refinement touched trace ``dense_factor`` × the samples
    on ``dense_quadrature`` (``"fibonacci"`` or ``"adaptive"``, refined ``adaptive_levels``
    times); ``direction_sets`` rotated copies of the direction set, one per vertex by a hash;
    ``dense_picks``: the thresholds of `gather_picks`, one per round (empty:
    no picks); ``post_jump`` (None: no post-pass) and ``post_share``: the post-pass of
    `post_split_marks`, its new vertices between two leaned-on ones traced
    at ``post_dense`` × the samples.
    """

    name: str = "custom"
    tol: float = 0.25
    gather_tol: float = 0.03
    gather_gate: float = 0.25
    gather_floor: float = 0.02
    min_edge_fraction: float = 2e-4
    max_rounds: int = 8
    max_vertices: int = 2_000_000
    dense_factor: int = 8
    dense_quadrature: str = "fibonacci"
    adaptive_levels: int = ADAPTIVE_LEVELS
    direction_sets: int = 1
    dense_picks: tuple[float, ...] = ()
    post_jump: float | None = None
    post_share: float = 2e-4
    post_dense: int = 8

    def __post_init__(self) -> None:
        for name in ("tol", "gather_tol", "min_edge_fraction", "post_share"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise ShprobeError(f"refinement {name} must be a finite number > 0, got {v!r}")
        for name in ("gather_gate", "gather_floor"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v >= 0):
                raise ShprobeError(f"refinement {name} must be a finite number >= 0, got {v!r}")
        for name, low in (("max_rounds", 0), ("max_vertices", 1), ("dense_factor", 1),
                          ("adaptive_levels", 0), ("direction_sets", 1), ("post_dense", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < low:
                raise ShprobeError(f"refinement {name} must be an integer >= {low}, got {v!r}")
        if self.adaptive_levels > MAX_ADAPTIVE_LEVELS:
            raise ShprobeError(f"refinement adaptive_levels must be at most "
                               f"{MAX_ADAPTIVE_LEVELS}, got {self.adaptive_levels}")
        if self.dense_quadrature not in QUADRATURES:
            raise ShprobeError(f"refinement dense_quadrature must be one of "
                               f"{', '.join(QUADRATURES)}, got {self.dense_quadrature!r}")
        picks = self.dense_picks
        if (not isinstance(picks, tuple) or len(picks) > 8
                or not all(isinstance(x, int | float) and np.isfinite(x) and x > 0
                           for x in picks)):
            raise ShprobeError(f"refinement dense_picks must be a tuple of up to 8 thresholds "
                               f"> 0, got {picks!r}")
        if self.post_jump is not None:
            if not (isinstance(self.post_jump, int | float) and np.isfinite(self.post_jump)
                    and self.post_jump > 0):
                raise ShprobeError(f"refinement post_jump must be > 0 (or None), got "
                                   f"{self.post_jump!r}")
            if not picks:
                raise ShprobeError("the post-pass splits among the vertices the contact leans "
                                   "on: it needs dense_picks")

    def but(self, **changes: Any) -> Refinement:
        """A copy with some settings changed (named ``custom`` unless ``name`` is given)."""
        return replace(self, **{"name": "custom", **changes})


#: The default refinement of every traced bake with a ground.
QUICK = Refinement(name="quick")
#: The accurate contact: opt-in, about 10× the quick bake's time (module doc).
ACCURATE = Refinement(name="accurate", gather_gate=0.1, dense_factor=32,
                      dense_quadrature="adaptive", direction_sets=256,
                      dense_picks=(0.01, 0.01), post_jump=0.1)
#: The named refinements, for the API edge and the CLI.
REFINEMENTS = {r.name: r for r in (QUICK, ACCURATE)}


def as_refinement(value: Any, default: Refinement = QUICK) -> Refinement | None:
    """``refine`` as given to [`shprobe.prt.bake`][shprobe.prt.bake]: a
    [`Refinement`][shprobe.prt.Refinement], a name of [`REFINEMENTS`][shprobe.prt.REFINEMENTS], True
    (``default``) or False / None (none)."""
    if isinstance(value, Refinement):
        return value
    if value is None or value is False or value is np.False_:
        return None
    if value is True or value is np.True_:
        return default
    if isinstance(value, str) and value in REFINEMENTS:
        return REFINEMENTS[value]
    raise ShprobeError(f"refine must be a Refinement, True, False, None or one of "
                       f"{', '.join(map(repr, REFINEMENTS))}, got {value!r}")
