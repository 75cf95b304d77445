"""The settings of a PRT bake: [`PrtSettings`][shprobe.prt.PrtSettings] (what
[`shprobe.prt.bake`][shprobe.prt.bake] takes, its defaults the CLI's), and how a traced bake with a
ground refines its scene: one frozen type, [`Refinement`][shprobe.prt.Refinement], and its two named
instances.

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

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import ShprobeError
from ..limits import Limits
from ..sh import check_lmax
from .hemisphere import ADAPTIVE_LEVELS, MAX_ADAPTIVE_LEVELS, QUADRATURES
from .transfer import MODES, check_int

__all__ = ["ACCURATE", "DEFAULT_LMAX", "QUICK", "REFINEMENTS", "PrtSettings", "Refinement",
           "as_refinement"]

#: The SH degree a bake stores by default, in the library and the CLI alike: a quick
#: interreflected bake of the packaged bunny on a ground takes about a minute and a half on
#: two cores at lmax 6 and enough memory to run beside other work (docs/prt.md), and the
#: degrees 0..6 serve every model and lighting the tour shows; higher degrees are a named
#: choice (``lmax=10``).
DEFAULT_LMAX = 6


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


def _check_threads(threads: Any) -> int | None:
    return None if threads is None else check_int(threads, 1, "threads")


@dataclass(frozen=True)
class PrtSettings:
    """Settings of a PRT bake (Lisle & Huang 2007 §4): what [`shprobe.prt.bake`][shprobe.prt.bake]
    takes. The defaults are the CLI's (``shprobe prt bake``); accuracy is a named choice.

    Parameters
    ----------
    mode
        'unshadowed' | 'shadowed' | 'interreflected': the most complete model baked. A
        shadowed bake also gives unshadowed, an interreflected bake also gives shadowed and any
        fewer bounces.
    lmax
        SH degree baked (any lower degree can be used later);
        [`DEFAULT_LMAX`][shprobe.prt.DEFAULT_LMAX].
    samples
        Ray directions per vertex over the whole sphere (about half are traced); >= 16.
    bounces
        Interreflection bounces (interreflected only).
    seed
        An integer >= 0: picks the random rotation of the direction set.
    threads
        Workers for ray casting, kernels and bounce products (None: all cores).
    refine
        Adaptive refinement of the scene where the transfer varies fast: a
        [`Refinement`][shprobe.prt.Refinement] (QUICK, ACCURATE), its name, True (QUICK), False
        (none) or None (QUICK for a traced bake that adds a ground, ``bake(..., ground=True)``, else
        none: a [`BakeScene`][shprobe.prt.BakeScene] that holds a ground is refined when asked).
    limits
        The memory limit the bake is refused over
        ([`shprobe.limits.Limits`][shprobe.limits.Limits]).
    """

    mode: str = "shadowed"
    lmax: int = DEFAULT_LMAX
    samples: int = 1024
    bounces: int = 2
    seed: int = 0
    threads: int | None = None
    refine: Refinement | str | bool | None = None
    limits: Limits = field(default_factory=Limits, compare=False)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ShprobeError(f"unknown PRT mode {self.mode!r}; choose one of "
                               f"{', '.join(MODES)}")
        object.__setattr__(self, "lmax", check_lmax(self.lmax))
        object.__setattr__(self, "seed", check_int(self.seed, 0, "seed"))
        object.__setattr__(self, "threads", _check_threads(self.threads))
        if self.traced:
            object.__setattr__(self, "samples", check_int(self.samples, 16,
                                                          "samples per vertex"))
        if self.mode == "interreflected":
            object.__setattr__(self, "bounces", check_int(self.bounces, 0, "bounces"))
        if self.refine is not None and not isinstance(self.refine, bool | Refinement):
            object.__setattr__(self, "refine", as_refinement(self.refine))
        if not isinstance(self.limits, Limits):
            raise ShprobeError(f"limits must be a shprobe.limits.Limits, got {self.limits!r}")

    @property
    def traced(self) -> bool:
        """Whether the bake traces rays (shadowed or interreflected)."""
        return self.mode != "unshadowed"

    def refinement(self, ground: bool) -> Refinement | None:
        """The refinement this bake runs when it adds (or does not add) a ground.

        Parameters
        ----------
        ground
            Whether the bake adds a ground plane to its scene.

        Returns
        -------
        Refinement or None
            QUICK, ACCURATE or a custom refinement; None: no refinement.
        """
        if self.refine is None:
            return QUICK if self.traced and ground else None
        got = as_refinement(self.refine)
        if got is not None and not self.traced:
            raise ShprobeError("refinement needs a traced bake (mode shadowed or "
                               "interreflected)")
        return got

    def but(self, **changes: Any) -> PrtSettings:
        """A copy with some settings changed.

        Parameters
        ----------
        **changes
            Fields and their new values.

        Returns
        -------
        PrtSettings
            The changed copy.
        """
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field; a refinement by its name.
        """
        r = self.refine
        return {"mode": self.mode, "lmax": self.lmax, "samples": self.samples,
                "bounces": self.bounces, "seed": self.seed, "threads": self.threads,
                "refine": r.name if isinstance(r, Refinement) else r,
                "limits": self.limits.as_dict()}
