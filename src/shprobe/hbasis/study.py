"""The error study of Habel & Wimmer 2010, Fig. 3: IMSE (eq. 16) of every hemispherical basis,
averaged over random irradiance signals, grouped by coefficient count.

**Signal generator** (`random_signals`; everything in the tangent frame, z = the surface
normal; RGB). Each signal is a physically valid radiance distribution — non-negative
everywhere — made of normalised von Mises–Fisher (vMF) lobes

    v_κ(ω; a) = κ e^{κ(a·ω − 1)} / (2π (1 − e^{−2κ})) > 0,   ∫_S² v_κ dω = 1,

and its irradiance is obtained by convolving with the clamped cosine exactly:

1. **Ambient**: a constant radiance a · c, level a ~ log-U[0.01, 1], colour c ~ U[0.2, 1]³.
2. **Broad lobes** (sky, bounce light, a window): k ~ U{1, 2, 3} vMF lobes with κ ~
   log-U[0.5, 8], flux P ~ log-U[0.1, 10], colour U[0.2, 1]³.
3. **Small bright lights**: k ~ U{1, 2, 3} vMF lobes with κ ~ log-U[32, 128] (angular radius
   1/√κ ≈ 5°–10°), flux P ~ log-U[0.1, 100], colour U[0.2, 1]³.

Every lobe axis is uniform on the whole sphere (light from below the tangent plane still reaches
tilted normals). Each channel is a sum of non-negative terms, so radiance is ≥ 0 and so is the
exact irradiance; the dynamic range is large (peak radiance up to ~2·10³ against an ambient
as low as 0.01; a light's flux up to 10⁴ × the ambient's). SH coefficients are exact closed
forms: the constant has L_00 = a c √(4π), a lobe has L_lm = P c h_l(κ) y_lm(a) with the vMF
Legendre moments h_l(κ) = 2π∫ v_κ P_l = I_{l+½}(κ) / I_{½}(κ) (ratio of modified Bessel
functions; `vmf_moments`). The irradiance is E_lm = Â_l L_lm (Funk–Hecke; R&H 2001 eq. 7) for
l ≤ ``lmax`` (default `LMAX_SIGNAL` = 32), the study's E. The exact irradiance differs
from it only by the bands above ``lmax``; `Signals.truncation_bound` bounds that
remainder per signal in L2(S²) (Σ_i |P_i c_i| (Σ_{l>lmax} Â_l² h_l(κ_i)² (2l+1)/4π)^½), and
for every basis |√IMSE(E) − √IMSE(E_lmax)| ≤ that bound (the fit is an orthogonal
projection, or for SH9 does not see bands > 2). The pointwise version of that bound is below
π a for every signal this generator draws (κ ≤ 128 at lmax = 32), so the band-limited E is
provably positive in every direction (`Signals.min_irradiance_certificate`; sharper
lights would need far more bands for that). `Signals.irradiance_exact` evaluates the
exact irradiance pointwise by a 1-D integral per lobe (for tests).

**IMSE** (H&W eq. 16) of basis b for a signal with SH coefficients e: ∫_Ω+ (Σ c_i B_i − E)² dω
with c = M_b e (each basis' fixed SH → coefficient matrix), i.e. ∫E² − 2 cᵀ(C e) + cᵀ G c with
C = ∫_Ω+ B yᵀ and G = ∫_Ω+ B Bᵀ (the Gram matrix) on the hemisphere quadrature: one matrix per
basis applied to every signal and channel at once.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..limits import Cost, check_memory
from ..progress import Progress, Steps
from ..sh import degrees, num_coeffs, sh_basis
from ..sh.zonal import clamped_cosine_factors, convolve
from .basis import hemisphere_quadrature
from .rivals import QUAD, HemiBasis, all_bases, sh_at_nodes

#: SH degree of the study's signals (the irradiance is exact up to this band)
LMAX_SIGNAL = 32
#: largest vMF concentration the generator draws (angular radius 1/√κ ≈ 5°)
KAPPA_MAX = 128.0


def vmf_moments(kappa: ArrayLike, lmax: int) -> NDArray[np.float64]:
    """Legendre moments h_l = 2π ∫_{-1}^{1} v_κ(t) P_l(t) dt = I_{l+½}(κ) / I_{½}(κ) of the
    normalised vMF lobe (h_0 = 1, h_1 = coth κ − 1/κ), shape (..., lmax+1), κ > 0.

    The ratios r_l = h_l / h_{l−1} = I_{l+½}/I_{l−½} obey 1/r_l = (2l+1)/κ + r_{l+1} (the
    Bessel recurrence); they are computed downwards (Miller's algorithm: stable, started at
    r = 0 sixty bands above max(lmax, κ), where the start error has decayed below 2^-100) and
    h_l = r_1 ⋯ r_l. Tested against scipy's ``ive`` and the closed forms of h_1, h_2.
    """
    k = np.asarray(kappa, dtype=np.float64)
    if np.any(~(k > 0)) or np.any(~np.isfinite(k)):
        raise ShprobeError("vMF concentrations must be positive and finite")
    lmax = int(lmax)
    start = int(max(lmax, float(k.max()) if k.size else 0.0)) + 60
    r = np.zeros(k.shape)
    ratios = np.empty((lmax + 1, *k.shape))
    for l in range(start, 0, -1):
        r = 1.0 / ((2 * l + 1) / k + r)
        if l <= lmax:
            ratios[l] = r
    ratios[0] = 1.0
    return np.moveaxis(np.cumprod(ratios, axis=0), 0, -1)


def vmf_radiance(kappa: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """v_κ(t) = κ e^{κ(t−1)} / (2π(1 − e^{−2κ})), t = cos of the angle to the axis (≥ 0)."""
    k = np.asarray(kappa, dtype=np.float64)
    return k * np.exp(k * (np.asarray(t) - 1.0)) / (2 * np.pi * -np.expm1(-2 * k))


def _ring_integral(t: NDArray, cg: float, sg: float) -> NDArray:
    """∫_0^{2π} max(0, n·ω) dψ over the ring of directions at cos t from the axis, for a normal
    at angle γ (cos γ = cg, sin γ = sg) from it: α = t cos γ, β = √(1−t²) sin γ and the
    integral is 2πα (α ≥ β), 0 (α ≤ −β), else 2(α acos(−α/β) + √(β² − α²))."""
    a = t * cg
    b = np.sqrt(np.maximum(0.0, 1.0 - t * t)) * sg
    with np.errstate(invalid="ignore", divide="ignore"):
        mid = 2 * (a * np.arccos(np.clip(-a / np.where(b > 0, b, 1.0), -1, 1))
                   + np.sqrt(np.maximum(0.0, b * b - a * a)))
    return np.where(a >= b, 2 * np.pi * a, np.where(a <= -b, 0.0, mid))


def vmf_irradiance(kappa: float, cos_gamma: float) -> float:
    """Exact irradiance ∫ v_κ(a·ω) max(0, n·ω) dω of a unit-flux vMF lobe at a normal making
    angle γ with its axis: a 1-D integral over t = a·ω of v_κ(t) times the closed-form ring
    integral (`_ring_integral`), by adaptive quadrature with the kinks t = ±sin γ and the
    lobe's width as break points."""
    from scipy.integrate import quad

    cg = float(np.clip(cos_gamma, -1.0, 1.0))
    sg = math.sqrt(max(0.0, 1.0 - cg * cg))
    lo = max(-1.0, 1.0 - 80.0 / kappa)  # v_κ < e^{-80} v_κ(1) below
    pts = sorted({p for p in (sg, -sg, 1 - 1 / kappa, 1 - 4 / kappa, 1 - 16 / kappa)
                  if lo < p < 1})
    f = lambda t: float(vmf_radiance(kappa, t) * _ring_integral(np.array(t), cg, sg))  # noqa: E731
    val, _ = quad(f, lo, 1.0, points=pts or None, limit=400, epsabs=0.0, epsrel=1e-12)
    return val


@dataclass
class Signals:
    """Parameters of S random lighting environments (see the module docstring).

    ``ambient`` (S, 3) constant radiance per channel; lobes (M in all): ``lobe_signal`` (M,)
    the signal each belongs to, ``lobe_axis`` (M, 3) unit axes, ``lobe_kappa`` (M,)
    concentrations, ``lobe_flux`` (M, 3) flux per channel (P × colour), ``lobe_small`` (M,)
    True for the small bright lights.
    """

    ambient: NDArray[np.float64]
    lobe_signal: NDArray[np.int64]
    lobe_axis: NDArray[np.float64]
    lobe_kappa: NDArray[np.float64]
    lobe_flux: NDArray[np.float64]
    lobe_small: NDArray[np.bool_]
    seed: int = 0
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_signals(self) -> int:
        return int(self.ambient.shape[0])

    def radiance(self, dirs: ArrayLike, signal: int) -> NDArray[np.float64]:
        """Radiance (N, 3) of signal ``signal`` at unit directions (N, 3), from the closed form
        of its lobes (no SH truncation)."""
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        out = np.broadcast_to(self.ambient[signal], (len(d), 3)).copy()
        for j in np.flatnonzero(self.lobe_signal == signal):
            v = vmf_radiance(self.lobe_kappa[j], d @ self.lobe_axis[j])
            out += v[:, None] * self.lobe_flux[j]
        return out

    def sh(self, lmax: int = LMAX_SIGNAL) -> NDArray[np.float64]:
        """Radiance SH coefficients L_lm (S, K, 3), l ≤ ``lmax`` (exact closed forms; cached,
        read-only)."""
        key = ("sh", int(lmax))
        if key not in self._cache:
            from scipy.sparse import csr_matrix

            k = num_coeffs(lmax)
            out = np.zeros((self.n_signals, k, 3))
            out[:, 0, :] = self.ambient * np.sqrt(4 * np.pi)
            deg = degrees(lmax)
            m = len(self.lobe_kappa)
            for lo in range(0, m, 8192):  # lobes in chunks: (chunk, K) at a time
                sl = slice(lo, min(m, lo + 8192))
                lobe = vmf_moments(self.lobe_kappa[sl], lmax)[:, deg] * sh_basis(
                    self.lobe_axis[sl], lmax)
                rows, cols = self.lobe_signal[sl], np.arange(sl.stop - sl.start)
                for c in range(3):
                    w = csr_matrix((self.lobe_flux[sl, c], (rows, cols)),
                                   shape=(self.n_signals, len(cols)))
                    out[:, :, c] += w @ lobe
            out.flags.writeable = False
            self._cache[key] = out
        return self._cache[key]

    def irradiance_sh(self, lmax: int = LMAX_SIGNAL) -> NDArray[np.float64]:
        """Irradiance SH coefficients E_lm = Â_l L_lm (S, K, 3), l ≤ ``lmax``."""
        return convolve(self.sh(lmax), clamped_cosine_factors(lmax))

    def irradiance_exact(self, normals: ArrayLike, signal: int) -> NDArray[np.float64]:
        """Exact irradiance (N, 3) of signal ``signal`` at unit normals (N, 3): π × ambient plus
        every lobe's `vmf_irradiance` (slow; for checks)."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        out = np.broadcast_to(np.pi * self.ambient[signal], (len(n), 3)).copy()
        for j in np.flatnonzero(self.lobe_signal == signal):
            e = np.array([vmf_irradiance(self.lobe_kappa[j], c) for c in n @ self.lobe_axis[j]])
            out += e[:, None] * self.lobe_flux[j]
        return out

    def truncation_bound(self, lmax: int = LMAX_SIGNAL, pointwise: bool = False
                         ) -> NDArray[np.float64]:
        """Upper bound (S, 3) of the irradiance the bands above ``lmax`` carry: in L2(S²)
        ‖E − E_lmax‖ ≤ Σ_i |Φ_i| (Σ_{l>lmax} Â_l² h_l(κ_i)² (2l+1)/4π)^½ (triangle inequality
        over the lobes, addition theorem per lobe; Φ_i the lobe's flux per channel); with
        ``pointwise`` the sup-norm bound Σ_i |Φ_i| Σ_{l>lmax} |Â_l| h_l(κ_i) (2l+1)/4π
        (|P_l| ≤ 1). The sums run to l = lmax + 12√κ_max, where h_l < e^{−70}."""
        key = ("tail", int(lmax), bool(pointwise))
        if key not in self._cache:
            kmax = float(self.lobe_kappa.max()) if len(self.lobe_kappa) else 1.0
            if kmax > KAPPA_MAX:
                raise ShprobeError(f"truncation bound is computed for κ ≤ {KAPPA_MAX:g}, "
                                   f"got {kmax:g}")
            ltail = lmax + 1 + int(12 * math.sqrt(kmax)) + 8
            a = clamped_cosine_factors(ltail)[lmax + 1:]
            l = np.arange(lmax + 1, ltail + 1)
            h = vmf_moments(self.lobe_kappa, ltail)[:, lmax + 1:]  # (M, L)
            w = (2 * l + 1) / (4 * np.pi)
            if pointwise:
                self._cache[key] = (np.abs(a) * h * w).sum(-1)
            else:
                self._cache[key] = np.sqrt((a * a * h * h * w).sum(-1))
        per_lobe = self._cache[key]
        out = np.zeros((self.n_signals, 3))
        np.add.at(out, self.lobe_signal, per_lobe[:, None] * np.abs(self.lobe_flux))
        return out

    def min_irradiance_certificate(self, lmax: int = LMAX_SIGNAL) -> NDArray[np.float64]:
        """A lower bound (S, 3) of the study's irradiance E_lmax over *all* directions:
        E_lmax ≥ E − ‖E − E_lmax‖_∞ ≥ π a − (pointwise truncation bound), since the exact E is
        at least the ambient's π a (every lobe adds a non-negative amount). Where it is > 0
        the band-limited irradiance is provably positive everywhere."""
        return np.pi * self.ambient - self.truncation_bound(lmax, pointwise=True)


def random_signals(n_signals: int, seed: int = 0) -> Signals:
    """``n_signals`` random lighting environments from the documented generator (module
    docstring); deterministic for a given ``seed``."""
    s = int(n_signals)
    if s < 1:
        raise ShprobeError(f"need at least one signal, got {n_signals!r}")
    rng = np.random.default_rng(seed)

    def logu(lo: float, hi: float, size) -> NDArray:
        return np.exp(rng.uniform(np.log(lo), np.log(hi), size))

    ambient = logu(0.01, 1.0, s)[:, None] * rng.uniform(0.2, 1.0, (s, 3))
    nb = rng.integers(1, 4, s)  # broad lobes per signal
    ns = rng.integers(1, 4, s)  # small lights per signal
    sig = np.concatenate([np.repeat(np.arange(s), nb), np.repeat(np.arange(s), ns)])
    small = np.concatenate([np.zeros(nb.sum(), bool), np.ones(ns.sum(), bool)])
    m = sig.size
    axis = rng.normal(size=(m, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    kappa = np.where(small, logu(32.0, KAPPA_MAX, m), logu(0.5, 8.0, m))
    power = np.where(small, logu(0.1, 100.0, m), logu(0.1, 10.0, m))
    flux = power[:, None] * rng.uniform(0.2, 1.0, (m, 3))
    order = np.argsort(sig, kind="stable")
    return Signals(ambient, sig[order], axis[order], kappa[order], flux[order], small[order],
                   int(seed))


def random_irradiance(n_signals: int, seed: int = 0, lmax: int = LMAX_SIGNAL) -> NDArray:
    """Irradiance SH coefficients E_lm = Â_l L_lm (S, K, 3) of `random_signals`."""
    return random_signals(n_signals, seed).irradiance_sh(lmax)


def _terms(basis: HemiBasis, lmax: int, quad: tuple[int, int]) -> tuple[NDArray, ...]:
    """M (n, K), G = ∫ B Bᵀ (n, n) and C = ∫ B yᵀ (n, K) over Ω+."""
    nodes, w = hemisphere_quadrature(*quad)
    bw = (basis.evaluate(nodes) * w[:, None]).T
    return basis.sh_matrix(lmax, quad), bw @ basis.evaluate(nodes), bw @ sh_at_nodes(lmax, quad)


@lru_cache(maxsize=8)
def _q0(lmax: int, quad: tuple[int, int]) -> NDArray[np.float64]:
    _, w = hemisphere_quadrature(*quad)
    y = sh_at_nodes(lmax, quad)
    q = (y * w[:, None]).T @ y
    q.flags.writeable = False
    return q


def imse_matrix(basis: HemiBasis | None, lmax: int, quad: tuple[int, int] = QUAD) -> NDArray:
    """Q (K, K) with IMSE = eᵀ Q e for a signal of SH coefficients e; ``None``: Q = ∫_Ω+ y yᵀ
    (so eᵀ Q e = ∫_Ω+ E²). Q = Q0 − MᵀC − CᵀM + MᵀGM (expanding ∫ (B M e − yᵀe)²)."""
    q0 = _q0(lmax, quad)
    if basis is None:
        return q0
    m, g, c = _terms(basis, lmax, quad)
    return q0 - m.T @ c - c.T @ m + m.T @ g @ m


def imse(basis: HemiBasis, sh_coeffs: NDArray, quad: tuple[int, int] = QUAD) -> NDArray:
    """IMSE (H&W eq. 16) of ``basis`` for signals with SH coefficients (..., K, C) → (..., C)."""
    from ..sh import lmax_of

    e = np.asarray(sh_coeffs, dtype=np.float64)
    q = imse_matrix(basis, lmax_of(e.shape[-2]), quad)
    return np.sum(e * np.matmul(q, e), axis=-2)


@dataclass
class GramReport:
    """G = ∫_Ω+ B Bᵀ dω of one basis by quadrature, with its deviation from the identity,
    extreme eigenvalues and condition number."""

    name: str
    matrix: NDArray[np.float64]
    max_dev: float  # max |G − I|
    eig_min: float
    eig_max: float

    @property
    def cond(self) -> float:
        return self.eig_max / self.eig_min

    @property
    def orthonormal(self) -> bool:
        return self.max_dev < 1e-8


def gram_report(basis: HemiBasis, quad: tuple[int, int] = QUAD) -> GramReport:
    """`GramReport` of ``basis`` on the ``hemisphere_quadrature(*quad)`` rule."""
    g = basis.gram(quad)
    ev = np.linalg.eigvalsh(g)
    return GramReport(basis.name, g, float(np.abs(g - np.eye(len(g))).max()), float(ev[0]),
                      float(ev[-1]))


def _fmt_matrix(m: NDArray, labels: list[str]) -> list[str]:
    lines = ["| | " + " | ".join(labels) + " |", "| --- |" + " ---: |" * len(labels)]
    for lab, row in zip(labels, m, strict=True):
        cells = ["0" if abs(v) < 5e-13 else f"{v:.6f}" for v in row]
        lines.append(f"| {lab} | " + " | ".join(cells) + " |")
    return lines


@dataclass
class StudyResult:
    """Per-basis IMSE statistics over all signals and channels, the Gram matrices, and the
    bound on what the SH truncation of the signals could change."""

    names: list[str]
    n_coeffs: list[int]
    mean_imse: NDArray
    median_imse: NDArray
    mean_rel: NDArray  # mean of IMSE / ∫_Ω+ E²
    n_signals: int
    seed: int
    grams: list[GramReport] = field(default_factory=list)
    lmax: int = LMAX_SIGNAL
    trunc_rel_max: float = float("nan")  # max over signals/channels of bound / ‖E‖_{S²}
    trunc_rel_mean: float = float("nan")

    def rows(self) -> list[dict]:
        order = sorted(range(len(self.names)),
                       key=lambda i: (self.n_coeffs[i], self.mean_imse[i]))
        return [dict(basis=self.names[i], coefficients=self.n_coeffs[i],
                     mean_imse=float(self.mean_imse[i]), median_imse=float(self.median_imse[i]),
                     mean_relative=float(self.mean_rel[i])) for i in order]

    def markdown(self) -> str:
        lines = [f"IMSE (H&W eq. 16) over {self.n_signals} random irradiance signals × 3 "
                 f"channels (seed {self.seed}), grouped by coefficient count.", "",
                 "| coefficients | basis | mean IMSE | median IMSE | mean IMSE / ∫E² |",
                 "| ---: | --- | ---: | ---: | ---: |"]
        for r in self.rows():
            lines.append(f"| {r['coefficients']} | {r['basis']} | {r['mean_imse']:.4g} | "
                         f"{r['median_imse']:.4g} | {r['mean_relative']:.3e} |")
        lines += ["", f"Signals: non-negative radiance (ambient + broad vMF lobes + small bright "
                      f"vMF lights), irradiance exact to SH degree {self.lmax}; the bands above "
                      f"carry at most {self.trunc_rel_max:.2e} (mean {self.trunc_rel_mean:.2e}) "
                      f"of ‖E‖ in L2(S²), which bounds the change of √IMSE."]
        if self.grams:
            lines += ["", "Gram matrices G = ∫_Ω+ B Bᵀ dω by quadrature (Gauss–Legendre in z × "
                          "uniform in φ):", "",
                      "| basis | n | max abs(G − I) | eigenvalues of G | cond(G) |",
                      "| --- | ---: | ---: | --- | ---: |"]
            for g in self.grams:
                lines.append(f"| {g.name} | {len(g.matrix)} | {g.max_dev:.1e} | "
                             f"{g.eig_min:.4g} … {g.eig_max:.4g} | {g.cond:.4g} |")
            shown: list[tuple[int, ...]] = []
            for g in self.grams:
                if g.orthonormal:
                    continue
                key = tuple(np.round(g.matrix, 12).ravel())
                same = [h.name for h in self.grams if not h.orthonormal and h is not g
                        and tuple(np.round(h.matrix, 12).ravel()) == key]
                if key in shown:
                    continue
                shown.append(key)
                k = len(g.matrix)
                labels = ([f"y{l}{m:+d}".replace("+0", "0") for l in range(3)
                           for m in range(-l, l + 1)][:k] if k in (4, 9) and "SH" in g.name
                          else [str(i + 1) for i in range(k)])
                title = " = ".join([g.name, *same])
                lines += ["", f"Gram matrix of {title}:", "", *_fmt_matrix(g.matrix, labels)]
        return "\n".join(lines) + "\n"

    def csv(self) -> str:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(self.rows()[0]))
        w.writeheader()
        w.writerows(self.rows())
        return buf.getvalue()

    def plot(self, path) -> None:
        """Bar chart (log scale) of mean IMSE grouped by coefficient count (matplotlib Agg)."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        rows = self.rows()
        fig, ax = plt.subplots(figsize=(10, 4.5), dpi=110)
        colours = {3: "#8c564b", 4: "#1f77b4", 6: "#d62728", 9: "#2ca02c"}
        x = np.arange(len(rows))
        ax.bar(x, [r["mean_imse"] for r in rows],
               color=[colours.get(r["coefficients"], "grey") for r in rows])
        ax.set_xticks(x, [f"{r['basis']}\n({r['coefficients']})" for r in rows], fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel("mean IMSE over signals")
        ax.set_title(f"H&W 2010 Fig. 3 study: {self.n_signals} random irradiance signals")
        fig.tight_layout()
        fig.savefig(path, format="png")
        plt.close(fig)


#: Seconds of the study's fixed part (quadrature, the bases' matrices) and per signal (the
#: documented "about 1 s per 2000 signals on one core").
STUDY_SECONDS = (3.0, 1 / 2000)


def study_cost(n_signals: int, lmax: int = LMAX_SIGNAL) -> Cost:
    """What `run_study` costs: per signal its radiance SH (K × 3 float64, K = (lmax+1)²)
    and two copies of its non-zero irradiance coefficients (even l and l = 1)."""
    k = num_coeffs(lmax)
    nonzero = 3 + sum(2 * l + 1 for l in range(0, lmax + 1, 2))
    per_signal = 8.0 * 3 * (k + 2 * nonzero)
    return Cost(STUDY_SECONDS[0] + STUDY_SECONDS[1] * n_signals, per_signal * n_signals)


def run_study(n_signals: int = 10000, seed: int = 0, lmax: int = LMAX_SIGNAL,
              bases: list[HemiBasis] | None = None,
              quad: tuple[int, int] = QUAD, progress: Progress | None = None) -> StudyResult:
    """IMSE of every basis over ``n_signals`` random irradiance signals (vectorised);
    ``progress`` gets its four stages "k/4: …", the bases counted one by one."""
    bases = list(all_bases().values()) if bases is None else bases
    check_memory(study_cost(n_signals, lmax).nbytes, f"the study of {n_signals} signals")
    with Steps(progress, 4) as step:
        step(f"{n_signals:,} random signals and their irradiance SH")
        sig = random_signals(n_signals, seed)
        a = clamped_cosine_factors(lmax)[degrees(lmax)]
        nz = np.flatnonzero(a != 0)  # Â_l = 0 for odd l ≥ 3: those E_lm vanish
        e = sig.sh(lmax)[:, nz, :] * a[nz, None]  # (S, K', 3) irradiance coefficients
        flat = np.ascontiguousarray(e.transpose(1, 0, 2)).reshape(len(nz), -1)  # (K', S*3)
        del e
        step("∫E² over the hemisphere (quadrature)")
        q0 = imse_matrix(None, lmax, quad)[np.ix_(nz, nz)]
        total = np.einsum("ks,ks->s", flat, q0 @ flat)  # ∫_Ω+ E²
        means, medians, rels = [], [], []
        bar = step(f"the IMSE of {len(bases)} bases", total=len(bases))
        for b in bases:
            # IMSE = ∫E² − 2 cᵀ(C e) + cᵀ G c with c = M e: O(n K S) per basis
            m, g, cm = _terms(b, lmax, quad)
            c = m[:, nz] @ flat
            v = total - 2 * np.einsum("is,is->s", c, cm[:, nz] @ flat) + np.einsum(
                "is,is->s", c, g @ c)
            means.append(v.mean())
            medians.append(np.median(v))
            rels.append(np.mean(v / total))
            bar.advance()
        step("truncation bound and Gram matrices")
        bound = sig.truncation_bound(lmax).reshape(-1)
        rel = bound / np.sqrt(np.einsum("ks,ks->s", flat, flat))
        grams = [gram_report(b, quad) for b in bases]
    return StudyResult([b.name for b in bases], [b.n_coeffs for b in bases], np.array(means),
                       np.array(medians), np.array(rels), int(n_signals), int(seed),
                       grams, int(lmax), float(rel.max()), float(rel.mean()))
