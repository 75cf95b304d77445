"""The hemispherical bases Habel & Wimmer 2010 compare against (§2, Fig. 3), one interface.

Every basis is a [`HemiBasis`][shprobe.hbasis.HemiBasis]: ``name``, ``n_coeffs``,
``evaluate(normals)`` (..., n) for tangent-frame normals (z = surface normal), ``project(f)``
(coefficients of a function), and ``sh_matrix(lmax)`` (the fixed (n, K) matrix taking a signal's SH
coefficients to the basis coefficients — what the Fig. 3 study applies to all signals at once).

Projection is the L2(Ω+, dω) least-squares fit: c = G⁻¹ ∫_Ω+ f B dω with G the Gram matrix
∫_Ω+ B Bᵀ dω; for the orthonormal bases G = I and this is the plain inner product. The one
exception is quadratic SH ("SH9"), which like the paper keeps the signal's own full-sphere SH
coefficients (l ≤ 2) and is evaluated on Ω+; "SH9 (LSQ)" is its hemispherical least-squares
variant. All integrals are by [`hemisphere_quadrature`][shprobe.hbasis.hemisphere_quadrature] (exact
for the polynomial bases).

Definitions (φ from +x towards +y, θ from +z, z = cos θ):

* **H4, H6** — [`shprobe.hbasis.basis.h_basis`][shprobe.hbasis.h_basis] (H&W eq. 8–13).
* **HL2** — Half-Life 2 basis, √(3/2π) n·h_i with the three h_i of H&W eq. 1 (orthonormal).
* **HSH2, HSH3** — hemispherical harmonics (Gautron et al. 2004): √2 · y_lm(θ', φ) with
  cos θ' = 2 cos θ − 1, i.e. SH of the shifted direction (2x√(z/(1+z)), 2y√(z/(1+z)), 2z − 1),
  bands l ≤ 1 (4) and l ≤ 2 (9); orthonormal on Ω+.
* **Makhotkin2, Makhotkin3** — shifted Jacobi polynomials (Makhotkin 1996) with the SH band
  structure, bands n ≤ 1 (4) and n ≤ 2 (9): N · trig(mφ) · (sin θ′)^|m| ·
  P^(|m|,|m|)_{n−|m|}(2z − 1) with sin θ′ = 2√(z(1−z)) (cos θ′ = 2z − 1: the shift of H&W
  §2.2). With x = 2z − 1 the hemisphere measure is ½ dx dφ and (sin θ′)^{2|m|} = (1 − x²)^|m|
  is the Jacobi weight of P^(|m|,|m|), so these are orthonormal on Ω+ — "hemispherically
  orthonormal", zero (m ≠ 0) or constant (m = 0) on the border, as H&W §2.2 describe — with
  the closed-form Jacobi norms. Since P^(m,m)_{l−m} ∝ d^m P_l/dx^m, they coincide function by
  function with HSH (tested): the paper's two "shifted" bases are the same functions, written
  once through shifted SH and once through shifted Jacobi polynomials. The seed paper does not
  print Makhotkin's formulas; an earlier reconstruction, orthonormal for the cosine-weighted
  measure z dω of radiative transfer, is kept as `makhotkin_cosine` (not in the study).
* **Zernike3, Zernike6** — Zernike polynomials on the hemisphere (Koenderink et al. 1996) with
  ρ = √2 sin(θ/2) = √(1 − z) (area-preserving map, dω = 2ρ dρ dφ): N R_n^|m|(ρ) trig(mφ) for
  n ≤ 1 (3) and n ≤ 2 (6); N = √((n+1)/π), or √((n+1)/2π) for m = 0. Z_2^0 = −H³.
* **SH4 (LSQ)** — linear SH y_00, y_1m fitted by least squares on Ω+ (spans 1, x, y, z = H4).
* **SH9** and **SH9 (LSQ)** — quadratic SH, see above.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import num_coeffs, sh_basis
from .basis import h_basis, hemisphere_quadrature

#: default quadrature for Gram / projection matrices of non-polynomial bases
QUAD = (64, 128)


def _dirs(normals: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(normals, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != 3:
        raise ShprobeError(f"normals must have shape (..., 3), got {d.shape}")
    return d


def _trig(m: int, x: NDArray, y: NDArray, r: NDArray) -> NDArray:
    """cos(mφ) (m > 0), sin(|m|φ) (m < 0) or 1 (m = 0) from x, y and r = sin θ."""
    if m == 0:
        return np.ones_like(x)
    c = np.ones_like(x)
    s = np.zeros_like(x)
    safe = np.where(r > 1e-300, r, 1.0)
    cx, sy = np.where(r > 1e-300, x / safe, 1.0), np.where(r > 1e-300, y / safe, 0.0)
    for _ in range(abs(m)):
        c, s = c * cx - s * sy, c * sy + s * cx
    return c if m > 0 else s


@dataclass(frozen=True)
class HemiBasis:
    """A finite function set on the upper hemisphere with least-squares projection.

    Parameters
    ----------
    name
        The basis's name in the study.
    n_coeffs
        Its number of functions n.
    _eval
        Maps (N, 3) tangent-frame directions to (N, n) function values.
    fit
        How coefficients are fitted: "hemisphere" (least squares over the upper hemisphere),
        "cosine" or "sphere".
    orthonormal
        Whether its functions are orthonormal over the hemisphere.
    description
        One line about it.
    """

    name: str
    n_coeffs: int
    _eval: Callable[[NDArray], NDArray] = field(repr=False)
    #: "hemisphere": L2(Ω+) least squares; "sphere": keep full-sphere SH coefficients (SH9);
    #: "cosine": the inner product ∫ f B z dω the basis is orthonormal for (Makhotkin)
    fit: str = "hemisphere"
    orthonormal: bool = True
    description: str = ""

    def evaluate(self, normals: ArrayLike) -> NDArray[np.float64]:
        """Basis functions at tangent-frame unit normals (..., 3) → (..., n).

        Parameters
        ----------
        normals
            (..., 3) tangent-frame unit normals.

        Returns
        -------
        ndarray of shape (..., n)
            The basis functions.
        """
        return self._eval(_dirs(normals))

    def gram(self, quad: tuple[int, int] = QUAD) -> NDArray[np.float64]:
        """G = ∫_Ω+ B Bᵀ dω by quadrature (identity for an orthonormal basis).

        Parameters
        ----------
        quad
            (n_z, n_phi) of the hemisphere quadrature.

        Returns
        -------
        ndarray of shape (n, n)
            G = ∫_Ω+ B Bᵀ dω.
        """
        nodes, w = hemisphere_quadrature(*quad)
        b = self.evaluate(nodes)
        return (b * w[:, None]).T @ b

    def projection_matrix(self, quad: tuple[int, int] = QUAD) -> NDArray[np.float64]:
        """P (n, N): coefficients = P @ samples at the nodes of ``hemisphere_quadrature(*quad)``.

        Parameters
        ----------
        quad
            (n_z, n_phi) of the hemisphere quadrature.

        Returns
        -------
        ndarray of shape (n, N)
            P with coefficients = P @ samples at the nodes.
        """
        return _projection_matrix(self, quad)

    def project(self, f: Callable[[NDArray], ArrayLike] | ArrayLike,
                quad: tuple[int, int] = QUAD) -> NDArray[np.float64]:
        """Coefficients (n,) or (n, C) of ``f``: a callable on (N, 3) directions or samples at
        the nodes of ``hemisphere_quadrature(*quad)``. SH9 needs a callable (it integrates
        over the whole sphere).

        Parameters
        ----------
        f
            A callable on (N, 3) directions, or samples at the quadrature's nodes.
        quad
            (n_z, n_phi) of the hemisphere quadrature.

        Returns
        -------
        ndarray of shape (n,) or (n, C)
            The coefficients.
        """
        if self.fit == "sphere":
            if not callable(f):
                raise ShprobeError(f"{self.name} projects over the whole sphere: pass a function")
            nodes, w = _sphere_quadrature(quad)
            vals = np.asarray(f(np.array(nodes)), dtype=np.float64)
            return (self.evaluate(nodes) * w[:, None]).T @ vals
        nodes, _ = hemisphere_quadrature(*quad)
        vals = np.asarray(f(np.array(nodes)) if callable(f) else f, dtype=np.float64)
        if vals.shape[0] != nodes.shape[0]:
            raise ShprobeError(f"need {nodes.shape[0]} samples, got shape {vals.shape}")
        return self.projection_matrix(quad) @ vals

    def sh_matrix(self, lmax: int, quad: tuple[int, int] = QUAD) -> NDArray[np.float64]:
        """M (n, K): basis coefficients of a signal with SH coefficients s (K = (lmax+1)²) are
        M @ s. For SH9 this is the truncation to l ≤ 2.

        Parameters
        ----------
        lmax
            The SH degree of the signal.
        quad
            (n_z, n_phi) of the hemisphere quadrature.

        Returns
        -------
        ndarray of shape (n, K)
            M with basis coefficients = M @ s.
        """
        if self.fit == "sphere":
            k = min(self.n_coeffs, num_coeffs(lmax))
            m = np.zeros((self.n_coeffs, num_coeffs(lmax)))
            m[:k, :k] = np.eye(k)
            return m
        return self.projection_matrix(quad) @ sh_at_nodes(lmax, quad)


@lru_cache(maxsize=64)
def _projection_matrix(basis: HemiBasis, quad: tuple[int, int]) -> NDArray[np.float64]:
    nodes, w = hemisphere_quadrature(*quad)
    b = basis.evaluate(nodes)
    bw = (b * w[:, None]).T
    if basis.fit == "cosine":
        return np.ascontiguousarray((b * (w * nodes[:, 2])[:, None]).T)
    p = bw if basis.orthonormal else np.linalg.solve(bw @ b, bw)
    p.flags.writeable = False
    return p


@lru_cache(maxsize=8)
def sh_at_nodes(lmax: int, quad: tuple[int, int] = QUAD) -> NDArray[np.float64]:
    """sh_basis at the nodes of ``hemisphere_quadrature(*quad)`` (cached, read-only)."""
    nodes, _ = hemisphere_quadrature(*quad)
    y = sh_basis(nodes, lmax)
    y.flags.writeable = False
    return y


@lru_cache(maxsize=4)
def _sphere_quadrature(quad: tuple[int, int]) -> tuple[NDArray, NDArray]:
    up, w = hemisphere_quadrature(*quad)
    down = up * np.array([1.0, 1.0, -1.0])
    return np.concatenate([up, down]), np.concatenate([w, w])


# --- the bases --------------------------------------------------------------------------

#: H&W eq. 1, the Half-Life 2 basis directions
HL2_DIRECTIONS = np.array(
    [
        [-1 / np.sqrt(6), -1 / np.sqrt(2), 1 / np.sqrt(3)],
        [-1 / np.sqrt(6), 1 / np.sqrt(2), 1 / np.sqrt(3)],
        [np.sqrt(2 / 3), 0.0, 1 / np.sqrt(3)],
    ]
)


def _hl2(d: NDArray) -> NDArray:
    return np.sqrt(3 / (2 * np.pi)) * (d @ HL2_DIRECTIONS.T)


def _shifted(d: NDArray) -> NDArray:
    """(x', y', z') = (2x√(z/(1+z)), 2y√(z/(1+z)), 2z − 1): cos θ' = 2 cos θ − 1, same φ."""
    x, y, z = d[..., 0], d[..., 1], np.clip(d[..., 2], 0.0, 1.0)
    f = 2.0 * np.sqrt(z / (1.0 + z))
    return np.stack([x * f, y * f, 2.0 * z - 1.0], axis=-1)


def _hsh(lmax: int) -> Callable[[NDArray], NDArray]:
    def ev(d: NDArray) -> NDArray:
        return np.sqrt(2.0) * sh_basis(_shifted(d), lmax)

    return ev


def _band_lm(nmax: int) -> list[tuple[int, int]]:
    return [(n, m) for n in range(nmax + 1) for m in range(-n, n + 1)]


def _jacobi_norm2(k: int, a: int, b: int) -> float:
    """∫_{-1}^{1} (1−x)^a (1+x)^b P_k^{(a,b)}(x)² dx (DLMF 18.3.1 / Szegő (4.3.3))."""
    return (2.0 ** (a + b + 1) / (2 * k + a + b + 1) * math.gamma(k + a + 1)
            * math.gamma(k + b + 1) / (math.gamma(k + a + b + 1) * math.factorial(k)))


def _makhotkin(nmax: int) -> Callable[[NDArray], NDArray]:
    """Hemispherically orthonormal shifted Jacobi basis, bands n ≤ nmax (see the module doc):
    N · trig(mφ) · (sin θ′)^|m| · P^{(|m|,|m|)}_{n−|m|}(2z − 1), sin θ′ = 2√(z(1 − z)).

    With x = 2z − 1 the measure dω = dz dφ becomes ½ dx dφ and the weight (sin θ′)^{2|m|} =
    (1 − x²)^{|m|} is exactly the Jacobi weight of P^{(|m|,|m|)}: N² · ½ h_k · ∫trig² dφ = 1
    with h_k the Jacobi norm (`_jacobi_norm2`)."""
    from scipy.special import eval_jacobi

    norms = {}
    for n, m in _band_lm(nmax):
        a = abs(m)
        norms[n, m] = 1.0 / math.sqrt(0.5 * _jacobi_norm2(n - a, a, a)
                                      * (2 * math.pi if m == 0 else math.pi))

    def ev(d: NDArray) -> NDArray:
        z = np.clip(d[..., 2], 0.0, 1.0)
        x = 2.0 * z - 1.0
        sin_t = 2.0 * np.sqrt(z * (1.0 - z))  # sin θ′
        r = np.sqrt(np.maximum(0.0, 1 - d[..., 2] ** 2))
        out = np.empty((*d.shape[:-1], len(norms)))
        for i, (n, m) in enumerate(norms):
            a = abs(m)
            out[..., i] = (norms[n, m] * sin_t**a * eval_jacobi(n - a, a, a, x)
                           * _trig(m, d[..., 0], d[..., 1], r))
        return out

    return ev


def _makhotkin_cosine(nmax: int) -> Callable[[NDArray], NDArray]:
    """The earlier reconstruction, orthonormal for the cosine-weighted measure z dω:
    N · trig(mφ) · (sin θ′)^|m| · P^{(|m|,|m|+1)}_{n−|m|}(2z − 1)."""
    from scipy.special import eval_jacobi

    norms = {}
    for n, m in _band_lm(nmax):
        a = abs(m)
        # ∫_0^1 z (4z(1−z))^a P² dz = ¼ ∫ (1−x)^a (1+x)^{a+1} P² dx (x = 2z − 1)
        radial = 0.25 * _jacobi_norm2(n - a, a, a + 1)
        norms[n, m] = 1.0 / math.sqrt(radial * (2 * math.pi if m == 0 else math.pi))

    def ev(d: NDArray) -> NDArray:
        z = np.clip(d[..., 2], 0.0, 1.0)
        sin_t = 2.0 * np.sqrt(z * (1.0 - z))
        r = np.sqrt(np.maximum(0.0, 1 - d[..., 2] ** 2))
        out = np.empty((*d.shape[:-1], len(norms)))
        for i, (n, m) in enumerate(norms):
            a = abs(m)
            out[..., i] = (norms[n, m] * sin_t**a * eval_jacobi(n - a, a, a + 1, 2 * z - 1)
                           * _trig(m, d[..., 0], d[..., 1], r))
        return out

    return ev


def makhotkin_cosine(nmax: int) -> HemiBasis:
    """The cosine-weighted shifted Jacobi variant (orthonormal for z dω, projected with that
    inner product), bands n ≤ ``nmax``; not part of [`all_bases`][shprobe.hbasis.all_bases]
    (docs/hbasis.md §3)."""
    if nmax not in (1, 2):
        raise ShprobeError(f"makhotkin_cosine has bands n ≤ 1 or 2, got {nmax!r}")
    return HemiBasis(f"Makhotkin{nmax + 1} (z dω)", (nmax + 1) ** 2, _makhotkin_cosine(nmax),
                     fit="cosine", orthonormal=False,
                     description="shifted Jacobi P^(m,m+1), orthonormal for z dω")


def _zernike_nm(nmax: int) -> list[tuple[int, int]]:
    return [(n, m) for n in range(nmax + 1) for m in range(-n, n + 1, 2)]


def _zernike_radial(n: int, m: int, rho: NDArray) -> NDArray:
    from math import factorial

    out = np.zeros_like(rho)
    for k in range((n - m) // 2 + 1):
        c = ((-1) ** k * factorial(n - k)
             / (factorial(k) * factorial((n + m) // 2 - k) * factorial((n - m) // 2 - k)))
        out = out + c * rho ** (n - 2 * k)
    return out


def _zernike(nmax: int) -> Callable[[NDArray], NDArray]:
    nm = _zernike_nm(nmax)

    def ev(d: NDArray) -> NDArray:
        z = np.clip(d[..., 2], -1.0, 1.0)
        rho = np.sqrt(np.maximum(0.0, 1.0 - z))  # √2 sin(θ/2)
        r = np.sqrt(np.maximum(0.0, 1 - z * z))
        out = np.empty((*d.shape[:-1], len(nm)))
        for i, (n, m) in enumerate(nm):
            norm = np.sqrt((n + 1) / (2 * np.pi if m == 0 else np.pi))
            out[..., i] = norm * _zernike_radial(n, abs(m), rho) * _trig(m, d[..., 0], d[..., 1], r)
        return out

    return ev


@lru_cache(maxsize=1)
def all_bases() -> dict[str, HemiBasis]:
    """Every basis of the Fig. 3 study, by name, in the study's order.

    Returns
    -------
    dict of str to HemiBasis
        Every basis of the study, in its order.
    """
    bases = [
        HemiBasis("HL2", 3, _hl2, description="Half-Life 2 basis (H&W eq. 1-2)"),
        HemiBasis("Zernike3", 3, _zernike(1), description="Zernike n<=1 (Koenderink 1996)"),
        HemiBasis("H4", 4, lambda d: h_basis(d, 4), description="H-basis, H1..H4"),
        HemiBasis("SH4 (LSQ)", 4, lambda d: sh_basis(d, 1), orthonormal=False,
                  description="linear SH, least squares on the hemisphere"),
        HemiBasis("HSH2", 4, _hsh(1), description="hemispherical harmonics l<=1 (Gautron 2004)"),
        HemiBasis("Makhotkin2", 4, _makhotkin(1),
                  description="shifted Jacobi (Makhotkin 1996) n<=1, orthonormal on Ω+"),
        HemiBasis("H6", 6, lambda d: h_basis(d, 6), description="H-basis, H1..H6"),
        HemiBasis("Zernike6", 6, _zernike(2), description="Zernike n<=2 (Koenderink 1996)"),
        HemiBasis("SH9", 9, lambda d: sh_basis(d, 2), fit="sphere", orthonormal=False,
                  description="quadratic SH, the signal's own l<=2 coefficients"),
        HemiBasis("SH9 (LSQ)", 9, lambda d: sh_basis(d, 2), orthonormal=False,
                  description="quadratic SH, least squares on the hemisphere"),
        HemiBasis("HSH3", 9, _hsh(2), description="hemispherical harmonics l<=2 (Gautron 2004)"),
        HemiBasis("Makhotkin3", 9, _makhotkin(2),
                  description="shifted Jacobi (Makhotkin 1996) n<=2, orthonormal on Ω+"),
    ]
    return {b.name: b for b in bases}


def get_basis(name: str) -> HemiBasis:
    """A basis of [`all_bases`][shprobe.hbasis.all_bases] by name (case-insensitive).

    Parameters
    ----------
    name
        A basis's name (case-insensitive).

    Returns
    -------
    HemiBasis
        The basis.
    """
    for k, b in all_bases().items():
        if k.lower() == name.lower():
            return b
    raise ShprobeError(f"unknown basis {name!r}; known: {', '.join(all_bases())}")
