"""The one registry of SH coefficient conventions: [`convert`][shprobe.sh.registry.convert] between
any two, on NumPy arrays and on array-API arrays (torch, JAX: differentiable, same kind back).

Every convention is a linear map T from shprobe's coefficients (real orthonormal SH, R&H
signs, k = l(l+1)+m, see `shprobe.sh.conventions`) to its own: a per-coefficient factor
(``diagonal``) or a block matrix (``matrix``, e.g. a relabelling of the axes).
``convert(c, from_=a, to=b)`` applies T_b T_a⁻¹ along the K axis of (..., K, C) or (K,)
coefficients. The registry converts the *basis* (signs, scale, axis order, baked-in
constants); where a format also fixes a frame (glTF's cube frame, a left-handed engine),
the exporter turns the frame first. docs/conventions.md has the table.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from . import _xp
from .indexing import degrees, lmax_of, num_coeffs, sh_lm

__all__ = ["CONVENTIONS", "Convention", "convention", "convention_matrix", "convert"]


@dataclass(frozen=True)
class Convention:
    """One entry: ``name``, who uses it (``users``), what it stores (``doc``), its largest
    degree (``lmax``, None for any) and the map from shprobe's coefficients: ``diagonal(lmax)``
    → (K,) factors, or ``matrix(lmax)`` → (K, K).

    Parameters
    ----------
    name
        The convention's name in ``CONVENTIONS``.
    users
        Who stores coefficients this way.
    doc
        What it stores.
    lmax
        Its largest degree (None for any).
    diagonal
        lmax → (K,) factors, for a per-coefficient map.
    matrix
        lmax → (K, K), for a block map.
    """

    name: str
    users: str
    doc: str
    lmax: int | None = None
    diagonal: Callable[[int], NDArray[np.float64]] | None = None
    matrix: Callable[[int], NDArray[np.float64]] | None = None

    def __repr__(self) -> str:
        return f"Convention({self.name}: {self.users})"


def cs_signs(lmax: int) -> NDArray[np.float64]:
    """(−1)^|m| for every flat index up to ``lmax``: the Condon–Shortley phase."""
    _, m = sh_lm(np.arange(num_coeffs(lmax)))
    return np.where(np.abs(m) % 2 == 1, -1.0, 1.0)


def _identity(lmax: int) -> NDArray[np.float64]:
    return np.ones(num_coeffs(lmax))


def _four_pi(cs: bool) -> Callable[[int], NDArray[np.float64]]:
    def f(lmax: int) -> NDArray[np.float64]:
        s = np.full(num_coeffs(lmax), 1.0 / math.sqrt(4.0 * math.pi))
        return s * cs_signs(lmax) if cs else s

    return f


def _e3nn(lmax: int) -> NDArray[np.float64]:
    """e3nn's Y_l(v) = y_l(Qv), Q v = (z, x, y) (its l = 1 harmonics are (x, y, z), pole +Y):
    coefficients b = D(Q) a, the Wigner matrix of Q."""
    from .rotation import wigner_d

    q = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return wigner_d(q, lmax)


def _ahat_over_pi(lmax: int) -> NDArray[np.float64]:
    from .zonal import clamped_cosine_factors

    return clamped_cosine_factors(lmax)[degrees(lmax)] / math.pi


def basis_constants(lmax: int = 2) -> NDArray[np.float64]:
    """K_k of the R&H basis polynomials for k < 9 (y_k = K_k · poly_k, R&H eq. 3), exact."""
    p = math.pi
    k1, k2 = math.sqrt(3 / (4 * p)), math.sqrt(15 / (4 * p))
    full = np.array([0.5 / math.sqrt(p), k1, k1, k1, k2, k2, math.sqrt(5 / (16 * p)), k2,
                     math.sqrt(15 / (16 * p))])
    return full[: num_coeffs(lmax)]


def _filament(lmax: int) -> NDArray[np.float64]:
    """Filament cmgen ``sh.txt`` "irradiance, pre-scaled base": c_k = (Â_l/π) K_k L_lm."""
    return _ahat_over_pi(lmax) * basis_constants(lmax)


def _unity(lmax: int) -> NDArray[np.float64]:
    """Unity's shader constants (``unity_SHAr/g/b``, ``SHBr/g/b``, ``SHC``) per channel, in
    the order (A.x, A.y, A.z, A.w, B.x, B.y, B.z, B.w, C): E(n)/π = A·(x, y, z, 1) +
    B·(xy, yz, z², xz) + C (x² − y²) (``ShadeSH9``)."""
    if lmax != 2:
        raise ShprobeError("the unity convention holds exactly lmax 2 (9 coefficients)")
    s = _ahat_over_pi(2) * basis_constants(2)
    M = np.zeros((9, 9))
    M[0, 3], M[1, 1], M[2, 2] = s[3], s[1], s[2]  # x, y, z ← L11, L1−1, L10
    M[3, 0], M[3, 6] = s[0], -s[6]  # constant ← L00 and −L20 (3z² − 1)
    M[4, 4], M[5, 5], M[6, 6], M[7, 7] = s[4], s[5], 3.0 * s[6], s[7]  # xy, yz, z², xz
    M[8, 8] = s[8]  # x² − y²
    return M


def _godot(lmax: int) -> NDArray[np.float64]:
    """Godot 4 ``LightmapGIData`` probe SH (lightmapper_rd ``MODE_LIGHT_PROBES``: Σ L y_k ·
    4/N over N uniform rays = L_lm/π, R&H basis constants and signs), evaluated by the forward
    shaders' R&H eq. 13 polynomial, which then gives E(n)/π."""
    return np.full(num_coeffs(lmax), 1.0 / math.pi)


_CS_DOC = "real orthonormal SH with the Condon–Shortley phase: a_lm (−1)^m"

CONVENTIONS: dict[str, Convention] = {c.name: c for c in (
    Convention("shprobe", "shprobe, R&H 2001, three.js SphericalHarmonics3 (l ≤ 2)",
               "real orthonormal, no CS phase, k = l(l+1)+m", diagonal=_identity),
    Convention("three", "three.js SphericalHarmonics3 / LightProbe.sh",
               "R&H constants and signs (getAt: 0.488603·y for k = 1): shprobe's, l ≤ 2",
               lmax=2, diagonal=_identity),
    Convention("cs", "google/spherical-harmonics, DirectXMath XMSHEval, cmft, Filament's basis",
               _CS_DOC, diagonal=cs_signs),
    Convention("3dgs", "3D Gaussian splatting (SH_C0..C3 of its eval_sh; colour = eval + 0.5)",
               _CS_DOC + " (the +0.5 colour offset is the caller's)", diagonal=cs_signs),
    Convention("gltf", "glTF EXT_lights_image_based irradianceCoefficients (Babylon.js)",
               _CS_DOC + " (the exporter adds Â_l and the cube frame's z flip)",
               diagonal=cs_signs),
    Convention("kaolin", "NVIDIA kaolin sh9 (render.lighting)", _CS_DOC, diagonal=cs_signs),
    Convention("e3nn", "e3nn o3.spherical_harmonics (normalization='integral')",
               "orthonormal, axis order (y, z, x) → its l = 1 is (x, y, z), pole +Y: b = D(Q) a",
               lmax=256, matrix=_e3nn),
    Convention("4pi", "pyshtools '4pi' (geodesy), csphase=1",
               "4π-normalised: a / √(4π)", diagonal=_four_pi(False)),
    Convention("4pi-cs", "pyshtools '4pi', csphase=-1", "a (−1)^m / √(4π)",
               diagonal=_four_pi(True)),
    Convention("filament", "Filament cmgen sh.txt (irradiance, pre-scaled base)",
               "c_k = (Â_l/π) K_k L_lm: E(n)/π = Σ c_k poly_k(n)", lmax=2, diagonal=_filament),
    Convention("unity", "Unity shader constants unity_SHA*/SHB*/SHC (ShadeSH9)",
               "pre-multiplied polynomial of E(n)/π: (A.xyzw, B.xyzw, C) per channel",
               lmax=2, matrix=_unity),
    # Unity's SphericalHarmonicsL2 holds the canonical Condon–Shortley L_lm times
    # kNormalizationConstants = (Â_l/π) × the CS-signed basis constants (HDRP
    # SphericalHarmonicMath.UndoCosineRescaling divides by them): the signs cancel, leaving
    # Filament's pre-scaled base, the terms ShadeSH9 sums after the unity_SH* packing. Unity's
    # left-handed frame (z mirrored) is the exporter's.
    Convention("unity-l2", "Unity SphericalHarmonicsL2 (LightProbes.bakedProbes, ambientProbe)",
               "s_k = (Â_l/π) K_k L_lm, sh[rgb, k], k = l(l+1)+m (CS signs of the basis and of "
               "kNormalizationConstants cancel)", lmax=2, diagonal=_filament),
    Convention("godot", "Godot 4 LightmapGIData probe SH (lightmap captures)",
               "L_lm/π, R&H constants and signs, k = l(l+1)+m", lmax=2, diagonal=_godot),
)}


def convention(name: str) -> Convention:
    """The registry entry ``name`` (one line listing the names for an unknown one).

    Parameters
    ----------
    name
        A name of ``CONVENTIONS``.

    Returns
    -------
    Convention
        The registry's entry.
    """
    try:
        return CONVENTIONS[name]
    except (KeyError, TypeError):
        raise ShprobeError(f"unknown SH convention {name!r}; choose from "
                           f"{', '.join(CONVENTIONS)}") from None


@lru_cache(maxsize=128)
def _map(name: str, lmax: int, inverse: bool) -> tuple[bool, NDArray[np.float64]]:
    conv = convention(name)
    if conv.lmax is not None and lmax > conv.lmax:
        raise ShprobeError(f"convention {name!r} holds l ≤ {conv.lmax}, got lmax {lmax}")
    if conv.diagonal is not None:
        f = conv.diagonal(lmax)
        out = 1.0 / f if inverse else f
        diag = True
    else:
        M = conv.matrix(lmax)  # type: ignore[misc]
        out = np.linalg.inv(M) if inverse else M
        diag = False
    out = np.ascontiguousarray(out)
    out.flags.writeable = False
    return diag, out


def convention_matrix(name: str, lmax: int) -> NDArray[np.float64]:
    """The (K, K) matrix T of convention ``name`` (from shprobe's coefficients to its own).

    Parameters
    ----------
    name
        A name of ``CONVENTIONS``.
    lmax
        The highest degree.

    Returns
    -------
    ndarray of shape (K, K)
        T, from shprobe's coefficients to the convention's.
    """
    diag, t = _map(name, lmax, False)
    return np.diag(t) if diag else t.copy()


def convert(coeffs: Any, from_: str = "shprobe", to: str = "shprobe") -> Any:
    """Coefficients in convention ``from_`` → convention ``to``.

    Parameters
    ----------
    coeffs : array_like
        (..., K, C) or (K,) coefficients, NumPy, torch or JAX. NaN or infinity is refused
        (one ``ShprobeError``).
    from_, to : str
        Convention names (the keys of ``CONVENTIONS``).

    Returns
    -------
    array
        NumPy in: float64 out (float32 stays float32); torch / JAX in: the same kind, device
        and dtype, differentiable.
    """
    xp = _xp.namespace(coeffs)
    if xp is None:
        c = np.asarray(coeffs)
        if c.dtype not in (np.float32, np.float64):
            try:
                c = np.asarray(c, dtype=np.float64)
            except (TypeError, ValueError):
                raise ShprobeError("coefficients must be real numbers") from None
    else:
        c = _xp.asarray(xp, coeffs, _xp.float_dtype(xp, coeffs), coeffs)
    if c.ndim == 0:
        raise ShprobeError("coefficients must have shape (..., K, C) or (K,)")
    lmax = lmax_of(c.shape[-1] if c.ndim == 1 else c.shape[-2])
    if xp is None:
        if not np.isfinite(c).all():
            raise ShprobeError("coefficients contain NaN or infinity")
    else:
        _xp.check_finite(xp, c, "coefficients")
    for name, inverse in ((from_, True), (to, False)):
        if name == "shprobe":
            continue
        diag, t = _map(name, lmax, inverse)
        if xp is None:
            t = t.astype(c.dtype)
        else:
            t = _xp.constant(xp, t, c)
        if diag:
            c = c * (t if c.ndim == 1 else t[:, None])
        elif c.ndim == 1:
            c = (t @ c[:, None])[:, 0] if xp is None else xp.matmul(t, c[:, None])[:, 0]
        else:
            c = t @ c if xp is None else xp.matmul(t, c)
    return c
