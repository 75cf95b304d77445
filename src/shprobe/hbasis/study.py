"""The error study of Habel & Wimmer 2010, Fig. 3: IMSE (eq. 16) of every hemispherical basis,
averaged over random irradiance signals, grouped by coefficient count.

Signal generator (:func:`random_irradiance`, all in the tangent frame, z = normal; RGB):

1. Background: a random low-frequency radiance with SH coefficients up to l = 2,
   L_00 = B c √(4π) (a constant radiance B c) and L_lm = B · g · 0.5^l · √(4π) for l = 1, 2,
   with B ~ log-uniform[0.05, 1], c ~ U[0.3, 1]³ and g ~ N(0, 1) per channel.
2. Lights: k ~ U{1..4} smooth bright lobes, each a normalised von Mises–Fisher lobe
   h(t) = κ e^{κ(t−1)} / (2π(1 − e^{−2κ})) (t = cos of the angle to its axis, ∫h dω = 1), axis
   uniform on the sphere (so lights below the tangent plane still light tilted normals),
   sharpness κ ~ log-uniform[4, 64], power P ~ log-uniform[0.1, 100] (dynamic range 10³, and
   up to 2000× the background), colour ~ U[0.2, 1]³. Its SH coefficients are h_l y_lm(axis)
   with the Legendre moments h_l = 2π ∫ h P_l, computed by 96-point Gauss–Legendre.
3. Irradiance E_lm = Â_l L_lm (R&H eq. 7) up to ``lmax`` = 16. This *is* the exact irradiance
   of the band-limited lighting (and the IMSE is computed exactly against it); compared with
   the irradiance of the un-truncated lobes it differs by a relative L2 amount ≤ 3.2e-4 for
   the sharpest lone lobe (κ = 64), 2e-7 at κ = 16 (see docs/hbasis.md).

IMSE_b(E) = ∫_Ω+ (Σ c_i B_i − E)² dω with c = M_b e (each basis' fixed SH → coefficient matrix),
i.e. the quadratic form eᵀ Q_b e with Q_b = R_bᵀ W R_b, R_b = B M_b − Y on the hemisphere
quadrature nodes: one matrix per basis applied to every signal and channel at once.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..sh import num_coeffs, sh_basis
from ..zonal import clamped_cosine_factors, convolve
from .basis import hemisphere_quadrature
from .rivals import QUAD, HemiBasis, all_bases, sh_at_nodes

LMAX_SIGNAL = 16


def _legendre_table(lmax: int, t: NDArray) -> NDArray:
    p = np.empty((lmax + 1, t.size))
    p[0] = 1.0
    if lmax >= 1:
        p[1] = t
    for l in range(2, lmax + 1):
        p[l] = ((2 * l - 1) * t * p[l - 1] - (l - 1) * p[l - 2]) / l
    return p


def vmf_moments(kappa: NDArray, lmax: int) -> NDArray[np.float64]:
    """h_l = 2π ∫_{-1}^{1} h(t) P_l(t) dt of the normalised vMF lobe, shape (..., lmax+1)."""
    kappa = np.asarray(kappa, dtype=np.float64)
    t, w = np.polynomial.legendre.leggauss(96)
    norm = kappa / (2 * np.pi * (-np.expm1(-2 * kappa)))
    h = norm[..., None] * np.exp(kappa[..., None] * (t - 1.0))  # (..., 96)
    return 2 * np.pi * np.einsum("...t,lt->...l", h * w, _legendre_table(lmax, t))


def random_lighting(n_signals: int, seed: int = 0, lmax: int = LMAX_SIGNAL) -> NDArray:
    """Radiance SH coefficients L_lm (S, K, 3) of the documented random generator."""
    rng = np.random.default_rng(seed)
    s = int(n_signals)
    k = num_coeffs(lmax)
    out = np.zeros((s, k, 3))
    b = np.exp(rng.uniform(np.log(0.05), np.log(1.0), s))
    c = rng.uniform(0.3, 1.0, (s, 3))
    sq4pi = np.sqrt(4 * np.pi)
    out[:, 0, :] = b[:, None] * c * sq4pi
    for l in (1, 2):
        if l <= lmax:
            sl = slice(l * l, (l + 1) ** 2)
            out[:, sl, :] = b[:, None, None] * rng.normal(size=(s, 2 * l + 1, 3)) * 0.5**l * sq4pi
    nl = rng.integers(1, 5, s)
    idx = np.repeat(np.arange(s), nl)  # signal of each light
    m = idx.size
    axis = rng.normal(size=(m, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    kappa = np.exp(rng.uniform(np.log(4.0), np.log(64.0), m))
    power = np.exp(rng.uniform(np.log(0.1), np.log(100.0), m))
    col = rng.uniform(0.2, 1.0, (m, 3))
    from ..sh import degrees

    hl = vmf_moments(kappa, lmax)[:, degrees(lmax)]  # (m, K)
    lobe = hl * sh_basis(axis, lmax)  # (m, K)
    np.add.at(out, idx, lobe[:, :, None] * (power[:, None] * col)[:, None, :])
    return out


def random_irradiance(n_signals: int, seed: int = 0, lmax: int = LMAX_SIGNAL) -> NDArray:
    """Exact irradiance SH coefficients E_lm = Â_l L_lm (S, K, 3) of :func:`random_lighting`."""
    return convolve(random_lighting(n_signals, seed, lmax), clamped_cosine_factors(lmax))


def _terms(basis: HemiBasis, lmax: int, quad: tuple[int, int]) -> tuple[NDArray, ...]:
    """M (n, K), G = ∫ B Bᵀ (n, n) and C = ∫ B yᵀ (n, K) over Ω+."""
    nodes, w = hemisphere_quadrature(*quad)
    bw = (basis.evaluate(nodes) * w[:, None]).T
    return basis.sh_matrix(lmax, quad), bw @ basis.evaluate(nodes), bw @ sh_at_nodes(lmax, quad)


def imse_matrix(basis: HemiBasis | None, lmax: int, quad: tuple[int, int] = QUAD) -> NDArray:
    """Q (K, K) with IMSE = eᵀ Q e for a signal of SH coefficients e; ``None``: Q = ∫_Ω+ y yᵀ
    (so eᵀ Q e = ∫_Ω+ E²). Q = Q0 − MᵀC − CᵀM + MᵀGM (expanding ∫ (B M e − yᵀe)²)."""
    _, w = hemisphere_quadrature(*quad)
    y = sh_at_nodes(lmax, quad)
    q0 = (y * w[:, None]).T @ y
    if basis is None:
        return q0
    m, g, c = _terms(basis, lmax, quad)
    return q0 - m.T @ c - c.T @ m + m.T @ g @ m


def imse(basis: HemiBasis, sh_coeffs: NDArray, quad: tuple[int, int] = QUAD) -> NDArray:
    """IMSE (H&W eq. 16) of ``basis`` for signals with SH coefficients (..., K, C) → (..., C)."""
    from ..sh import lmax_of

    e = np.asarray(sh_coeffs, dtype=np.float64)
    q = imse_matrix(basis, lmax_of(e.shape[-2]), quad)
    return np.einsum("...kc,kj,...jc->...c", e, q, e)


@dataclass
class StudyResult:
    """Per-basis IMSE statistics over all signals and channels."""

    names: list[str]
    n_coeffs: list[int]
    mean_imse: NDArray
    median_imse: NDArray
    mean_rel: NDArray  # mean of IMSE / ∫_Ω+ E²
    n_signals: int
    seed: int

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


def run_study(n_signals: int = 10000, seed: int = 0, lmax: int = LMAX_SIGNAL,
              bases: list[HemiBasis] | None = None,
              quad: tuple[int, int] = QUAD) -> StudyResult:
    """IMSE of every basis over ``n_signals`` random irradiance signals (vectorised)."""
    e = random_irradiance(n_signals, seed, lmax)  # (S, K, 3)
    flat = e.transpose(1, 0, 2).reshape(num_coeffs(lmax), -1)  # (K, S*3)
    total = np.einsum("ks,ks->s", flat, imse_matrix(None, lmax, quad) @ flat)  # ∫_Ω+ E²
    bases = list(all_bases().values()) if bases is None else bases
    means, medians, rels = [], [], []
    for b in bases:
        # IMSE = ∫E² − 2 cᵀ(C e) + cᵀ G c with c = M e: O(n K S) per basis
        m, g, cm = _terms(b, lmax, quad)
        c = m @ flat
        v = total - 2 * np.einsum("is,is->s", c, cm @ flat) + np.einsum("is,is->s", c, g @ c)
        means.append(v.mean())
        medians.append(np.median(v))
        rels.append(np.mean(v / total))
    return StudyResult([b.name for b in bases], [b.n_coeffs for b in bases], np.array(means),
                       np.array(medians), np.array(rels), int(n_signals), int(seed))
