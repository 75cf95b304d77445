"""The brute-force reference and R&H's error report.

- [`reference_irradiance`][shprobe.lighting.reference_irradiance] — Σ_pixels L max(0, n·ω) dω,
  O(T·S), numba, chunked.
- `reference_irradiance_map` — the same on the grid of any layout.
- [`error_report`][shprobe.lighting.error_report] — R&H's metric (§3.1): |E_SH − E_ref| as a
  fraction of ∫L dω.

Pixels as samples and the error report's tables of E_ref live in `shprobe.lighting.exact`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import PAIRS_PER_CORE_SECOND, Cost, check_memory, check_pairs, cores
from ..probes.env import Env
from ..probes.layouts import LatLong, Layout, get_layout
from ..progress import Progress, stage
from ..sh import check_lmax, num_coeffs
from .exact import _Exact, _sample_chunks
from .irradiance import irradiance, unit_normals
from .projection import project, total_intensity

__all__ = [
    "ErrorReport",
    "ErrorRow",
    "error_report",
    "reference_cost",
    "reference_irradiance",
    "reference_irradiance_map",
    "reference_pairs",
]

#: Samples per chunk of :func:`reference_irradiance_map` (its many normals: smaller chunks).
MAP_CHUNK = 1 << 16


def reference_cost(env: Env, n_normals: int, subdivide: int = 1,
                   chunk: int = 1 << 18) -> Cost:
    """What [`reference_irradiance`][shprobe.lighting.reference_irradiance] of ``n_normals`` normals
    costs: the time from the number of normal–sample products, the bytes from its tables (the
    normals and the result, one chunk of samples, and for layouts other than lat-long the k²-times
    larger pixel tables its memory check refuses on)."""
    k = int(subdivide)
    pixels = int(np.prod(env.grid))
    pairs = reference_pairs(env, n_normals, k)
    nbytes = 2 * 24.0 * n_normals + 2 * 48.0 * min(chunk, pixels * k * k)
    if env.layout.name != "latlong":
        nbytes += pixels * k * k * 8.0 * 8
    return Cost(pairs / (PAIRS_PER_CORE_SECOND * cores()), nbytes)


#: Work of generating one (sub-)sample of the brute force, in normal × sample products
#: (measured: a subdivided lat-long sub-pixel costs about as much as 64 products).
SAMPLE_COST = 64


def check_env(env: Any, what: str = "env") -> Env:
    if not isinstance(env, Env):
        raise ShprobeError(f"{what} must be an Env (shprobe.load_env(path), or "
                           f"Env(radiance, layout) for an array), got {type(env).__name__}")
    return env


def reference_pairs(env: Env, normals: int, subdivide: int = 1) -> float:
    """Normal × sample products of [`reference_irradiance`][shprobe.lighting.reference_irradiance]
    at ``normals`` normals: the (sub-)samples times the normals, plus the making of each sample."""
    samples = float(np.prod(env.grid, dtype=np.float64)) * float(subdivide) ** 2
    return samples * (float(normals) + SAMPLE_COST)


def reference_irradiance(env: Env, normals: ArrayLike, chunk: int = 1 << 18,
                         subdivide: int = 1, progress: Progress | None = None
                         ) -> NDArray[np.float64]:
    """Brute-force irradiance Σ_pixels L(ω) max(0, n·ω) dω for any normals (..., 3) → (..., 3).

    O(T·S); a numba kernel parallel over normals, fed ``chunk`` samples at a time so memory
    stays bounded. ``subdivide=k`` splits every pixel into k×k sub-pixels (exact sub-solid
    angles, constant radiance) to check convergence; lat-long builds them chunk by chunk, the
    other layouts build their k²-times larger pixel tables whole (memory O(k²·S)).
    ``progress`` gets one stage counting the normal–sample pairs, advanced every ~2²³ pairs
    (`shprobe.progress`); `reference_cost` estimates the time and memory. Normals
    follow `shprobe.lighting.irradiance`'s policy (normalised; zero
    or non-finite refused).

    Parameters
    ----------
    env
        The environment map.
    normals
        (..., 3) normals.
    chunk
        Samples fed to the kernel at a time (bounds memory).
    subdivide
        k: every pixel split into k×k sub-pixels.
    progress
        Told about the normal–sample pairs done.

    Returns
    -------
    ndarray of shape (..., 3)
        The exact irradiance Σ_pixels L(ω) max(0, n·ω) dω.
    """
    from ._kernels import brute_kernel as kern  # numba, imported lazily

    check_env(env)
    n = unit_normals(normals)
    k = subdivide
    if isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 1:
        raise ShprobeError(f"subdivide must be an integer >= 1, got {subdivide!r}")
    pixels = int(np.prod(env.grid))
    if env.layout.name != "latlong":  # the k²-times larger pixel tables are built whole
        check_memory(pixels * int(k) ** 2 * 8.0 * 8, f"subdivide={k} on a {env.layout.name} "
                     f"map of {pixels} pixels", env.path)
    check_pairs(reference_pairs(env, int(np.prod(n.shape[:-1])), int(k)),
                f"the brute-force irradiance of {int(np.prod(n.shape[:-1]))} normals over "
                f"{pixels} pixels{f' x {int(k)}x{int(k)} sub-pixels' if k > 1 else ''}",
                env.path, "use fewer normals, a smaller subdivide or a smaller probe")
    flat = np.ascontiguousarray(n.reshape(-1, 3))
    t = flat.shape[0]
    out = np.zeros((t, 3))
    total = t * int(np.prod(env.grid)) * int(subdivide) ** 2
    with stage(progress, f"exact irradiance at {t:,} normals (brute force)", total) as bar:
        for d, lw in _sample_chunks(env, subdivide, int(chunk)):
            dT, lwT = np.ascontiguousarray(d.T), np.ascontiguousarray(lw.T)
            block = max(256, (1 << 23) // max(1, d.shape[0]))  # normals per call
            for i in range(0, t, block):
                kern(flat[i:i + block], dT, lwT, out[i:i + block])
                bar.advance(min(block, t - i) * d.shape[0])
    return out.reshape(*n.shape[:-1], 3)


# ----------------------------------------------------------------------------- error report


@dataclass(frozen=True)
class ErrorRow:
    """Errors of the order-lmax SH irradiance against the brute-force reference.

    ``mean_frac`` / ``max_frac``: mean and max |E_SH − E_ref| / ∫L dω (R&H's metric; per
    channel, mean weighted by the normals' solid angles, max over normals and channels);
    ``mean_rel``: mean |ΔE| / E_ref over normals with E_ref > 0; ``smape``: mean
    2|ΔE| / (|E_SH| + |E_ref|).

    The max is the worst case on the sphere, found by refinement
    ([`error_report`][shprobe.lighting.error_report]): ``max_normal`` / ``max_channel`` where it
    occurs, ``max_tol`` the stated tolerance (the last refinement level changed it by ``max_change``
    < ``max_tol``), ``grid_max_frac`` the plain sample max over the grid. Both are attained values
    (the exact error at a normal), so both are lower bounds of the true worst case; the refined one
    is never below the grid's, and no finer sampling near it is expected to beat it by more than
    ``max_tol`` (a numerical statement, checked against dense brute-force patches, not a proof). A
    finer grid's max is no substitute: a grid straddles any ridge narrower than its spacing,
    whatever the spacing. ``mean_change``: |mean(N) − mean(N/2)| of the quadrature over the 2N×N and
    N×N/2 grids (NaN for given normals): the mean's stated accuracy.

    Attributes
    ----------
    lmax
        The SH order measured.
    mean_frac, max_frac
        Mean and max |E_SH − E_ref| / ∫L dω.
    mean_rel
        Mean |ΔE| / E_ref over normals with E_ref > 0.
    smape
        Mean 2|ΔE| / (|E_SH| + |E_ref|).
    max_normal, max_channel
        Where the max occurs.
    max_tol
        The max's stated tolerance.
    max_change
        The last refinement level's change of the max.
    grid_max_frac
        The plain sample max over the grid.
    mean_change
        |mean(N) − mean(N/2)|: the mean's stated accuracy (NaN for given normals).
    """

    lmax: int
    mean_frac: float
    max_frac: float
    mean_rel: float
    smape: float
    max_normal: NDArray[np.float64] = field(default_factory=lambda: np.full(3, np.nan))
    max_channel: int = -1
    max_tol: float = float("nan")
    max_change: float = float("nan")
    grid_max_frac: float = float("nan")
    mean_change: float = float("nan")

    def as_dict(self, refined: bool = False) -> dict[str, Any]:
        """The row as JSON-able values; the entries that are not finite numbers (a quantity
        not measured) are left out: a non-finite number is never written.

        Parameters
        ----------
        refined
            Whether the report refined its maxima (adds ``max_converged``).

        Returns
        -------
        dict
            lmax, mean_frac, max_frac, mean_rel, smape and, when measured, max_normal,
            max_channel, max_tol, max_change, grid_max_frac, mean_change.
        """
        return {"lmax": self.lmax, "mean_frac": self.mean_frac, "max_frac": self.max_frac,
                "mean_rel": self.mean_rel, "smape": self.smape,
                **_finite({"max_normal": [float(x) for x in self.max_normal],
                           "max_channel": self.max_channel, "max_tol": self.max_tol,
                           "max_change": self.max_change, "grid_max_frac": self.grid_max_frac,
                           "mean_change": self.mean_change}),
                **({"max_converged": bool(self.max_change < self.max_tol)} if refined else {})}

    def __repr__(self) -> str:
        n = ", ".join(f"{x:+.3f}" for x in self.max_normal)
        tol = (f"tol {100 * self.max_tol:.1g}" if not self.max_change >= self.max_tol else
               f"NOT converged: last change {100 * self.max_change:.1g} ≥ tol "
               f"{100 * self.max_tol:.1g}")
        return (f"ErrorRow(lmax={self.lmax}, mean {100 * self.mean_frac:.3f} % "
                f"(±{100 * self.mean_change:.1g}), max {100 * self.max_frac:.3f} % "
                f"({tol}) at ({n}) ch {self.max_channel})")


@dataclass(frozen=True)
class ErrorReport:
    """Per-lmax error rows, the total intensity ∫L dω (3,) and the number of grid normals.

    Attributes
    ----------
    rows
        One [`ErrorRow`][shprobe.lighting.ErrorRow] per lmax.
    total_intensity
        (3,) ∫L dω per channel.
    n_normals
        The normals measured at.
    refined
        Whether the max was refined on the whole sphere.
    """

    rows: tuple[ErrorRow, ...]
    total_intensity: NDArray[np.float64]
    n_normals: int
    refined: bool = False

    def row(self, lmax: int) -> ErrorRow:
        for r in self.rows:
            if r.lmax == lmax:
                return r
        raise KeyError(lmax)

    def as_dict(self, source: str | None = None) -> dict[str, Any]:
        """The error report's one document (``shprobe error --format json``, the viewer's
        error view and the batch table read it).

        Parameters
        ----------
        source
            What the lighting came from, for people (a path, a preset name), or None.

        Returns
        -------
        dict
            shprobe_version, source, n_normals, total_intensity, refined and one row per
            degree ([`ErrorRow.as_dict`][shprobe.lighting.ErrorRow.as_dict]).
        """
        from .._version import __version__

        return {"shprobe_version": __version__, "source": source,
                "n_normals": int(self.n_normals),
                "total_intensity": np.asarray(self.total_intensity, float).tolist(),
                "refined": bool(self.refined),
                "rows": [r.as_dict(self.refined) for r in self.rows]}


def _finite(d: dict[str, Any]) -> dict[str, Any]:
    """The entries that are finite numbers (or lists of them), or not numbers at all."""
    import math

    def ok(v: Any) -> bool:
        if isinstance(v, list):
            return all(ok(x) for x in v)
        return not isinstance(v, float) or math.isfinite(v)

    return {k: v for k, v in d.items() if ok(v)}


def _normal_grid(h: int = 32) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lay = LatLong()
    grid = (h, 2 * h)
    return lay.pixel_directions(grid).reshape(-1, 3), lay.solid_angles(grid).reshape(-1)


#: Default tolerance of the refined maximum, as a fraction of ∫L dω (0.001 percentage points).
MAX_TOL = 1e-5


def _frac_rows(coeffs, lm, nrm, ref, tot, wts):
    e = irradiance(coeffs[: num_coeffs(lm)], nrm)
    err = np.abs(e - ref)
    frac = err / tot
    pos = ref > 0
    rel = np.where(pos, err / np.where(pos, ref, 1.0), 0.0)
    denom = np.abs(e) + np.abs(ref)
    sm = np.where(denom > 0, 2.0 * err / np.where(denom > 0, denom, 1.0), 0.0)
    wpos = wts[:, None] * pos
    return (frac, float((wts[:, None] * frac).sum() / 3.0),
            float((wpos * rel).sum() / max(wpos.sum(), 1e-300)),
            float((wts[:, None] * sm).sum() / 3.0))


def error_report(env: Env, lmax_values: tuple[int, ...] = (1, 2, 3, 4),
                 normals: ArrayLike | None = None, reference: ArrayLike | None = None,
                 progress: Progress | None = None, normal_grid: int = 32,
                 refine: bool | None = None,
                 tol: float = MAX_TOL) -> ErrorReport:
    """R&H's error metric (§3.1) for each lmax: SH irradiance vs
    [`reference_irradiance`][shprobe.lighting.reference_irradiance].

    ``normals`` default: the pixel centres of a (2N)×N lat-long grid, N = ``normal_grid``,
    weighted by their solid angles (given normals are weighted equally). ``reference`` may
    pass a precomputed E_ref (of the given or grid normals).

    ``refine`` (default: True for the grid, False for given normals): the max is the worst case
    on the whole sphere, not over the samples — from the grid's 4 worst, well-separated normals,
    a compass search of max_c |E_SH − E_ref|(n) / ∫L_c with the exact E_ref at every
    candidate (`shprobe.lighting.sphere_search.refine_max`), until a halving of the step
    changes the max by less than ``tol`` (a fraction of ∫L dω). The mean stays the grid
    quadrature; with the default grid its accuracy is reported as |mean(N) − mean(N/2)|.

    E_ref here is the sum of [`reference_irradiance`][shprobe.lighting.reference_irradiance] (the
    same pixels, re-associated) taken per row of a lat-long map from prefix sums (`_Exact`: O(H) per
    normal, so the refinement's thousands of evaluations cost tens of milliseconds); other layouts
    sum pixel by pixel.

    Parameters
    ----------
    env
        The environment map.
    lmax_values
        The degrees to report.
    normals
        (N, 3) normals to measure at (weighted equally); default the lat-long grid.
    reference
        A precomputed E_ref at those normals.
    progress
        Told about each step (`shprobe.progress`).
    normal_grid
        N of the default (2N)×N grid of normals.
    refine
        Refine the max on the whole sphere (default: for the grid, not for given normals).
    tol
        The refinement's tolerance, a fraction of ∫L dω.

    Returns
    -------
    ErrorReport
        One row per lmax: mean and max |ΔE| / ∫L dω, mean relative error, sMAPE.
    """
    from .sphere_search import refine_max

    check_env(env)
    if normals is None:
        nrm, wts = _normal_grid(normal_grid)
    else:
        nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        wts = np.ones(nrm.shape[0])
    refine = normals is None if refine is None else bool(refine)
    if not (np.isfinite(tol) and tol > 0):
        raise ShprobeError(f"tolerance must be > 0, got {tol}")
    wts = wts / wts.sum()
    latlong = env.layout.name == "latlong"
    tables: list[_Exact] = []

    def exact() -> _Exact:  # the tables, built on first need only
        if not tables:
            tables.append(_Exact(env))
        return tables[0]

    if reference is None and latlong:
        ref = exact()(unit_normals(nrm))  # milliseconds: no stage to report
    elif reference is None:  # pixel by pixel: the parallel kernel, with progress
        ref = reference_irradiance(env, nrm, progress=progress)
    else:
        ref = np.asarray(reference, dtype=np.float64).reshape(-1, 3)
    tot = total_intensity(env)
    if not np.all(tot > 0):
        raise ShprobeError("the environment has a channel with zero total intensity", env.path)
    lmax_values = tuple(check_lmax(int(x)) for x in lmax_values)
    coeffs = project(env, max(lmax_values))
    half = None
    if normals is None and normal_grid >= 4:
        hn, hw = _normal_grid(normal_grid // 2)
        half = (hn, hw / hw.sum(),
                exact()(hn) if latlong else reference_irradiance(env, hn))
    step = np.pi / max(2, int(normal_grid)) if normals is None else _spacing(nrm)
    rows = []
    done: dict[int, tuple] = {}  # effective degree → refined max (odd l ≥ 3 adds nothing: Â_l = 0)
    for lm in lmax_values:
        frac, mean_frac, mean_rel, smape = _frac_rows(coeffs, lm, nrm, ref, tot, wts)
        grid_max = float(frac.max())
        mean_change = float("nan")
        if half is not None:
            mean_change = abs(mean_frac - _frac_rows(coeffs, lm, half[0], half[2], tot,
                                                     half[1])[1])
        if refine:
            eff = lm - 1 if (lm >= 3 and lm % 2 == 1) else lm
            if eff not in done:
                err = exact().error_fn(coeffs[: num_coeffs(eff)], tot)
                sm = refine_max(lambda n, err=err: err(n)[0], nrm, frac.max(axis=1),
                                step=step, tol=tol)
                done[eff] = (sm, int(err(sm.direction[None])[1][0]))
            sm, chan = done[eff]
            rows.append(ErrorRow(lm, mean_frac, sm.value, mean_rel, smape, sm.direction, chan,
                                 tol, sm.change, grid_max, mean_change))
        else:
            i, chan = np.unravel_index(int(np.argmax(frac)), frac.shape)
            rows.append(ErrorRow(lm, mean_frac, grid_max, mean_rel, smape, nrm[i].copy(),
                                 int(chan), float("nan"), float("nan"), grid_max, mean_change))
    return ErrorReport(tuple(rows), tot, nrm.shape[0], refine)


def _spacing(n: NDArray[np.float64]) -> float:
    """A typical angular spacing of given normals: the area per point, √(4π/N), capped."""
    return float(min(0.5, np.sqrt(4.0 * np.pi / max(1, n.shape[0]))))


def reference_irradiance_map(env: Env, layout: str | Layout = "latlong",
                             size: int | tuple[int, int] = 128,
                             progress: Progress | None = None) -> Env:
    """The brute-force irradiance map:
    [`reference_irradiance`][shprobe.lighting.reference_irradiance] at every pixel of a grid of any
    layout (``size`` as in
    [`shprobe.lighting.irradiance.irradiance_map`][shprobe.lighting.irradiance_map]) → Env; pixels
    outside a disc layout are 0."""
    check_env(env)
    lay = get_layout(layout)
    grid = lay.grid_shape(size)
    dirs = lay.pixel_directions(grid)
    valid = lay.valid_mask(grid)
    e = np.zeros((*grid, 3), dtype=np.float32)
    e[valid] = reference_irradiance(env, dirs[valid], chunk=MAP_CHUNK, progress=progress)
    return Env(e, lay)
