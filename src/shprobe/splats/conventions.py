"""The SH convention of Gaussian-splat files, and converters to shprobe's.

The 3DGS reference renderer (Kerbl et al. 2023, ``computeColorFromSH`` in
diff-gaussian-rasterization) evaluates, per splat and colour channel,

    c(d) = max(0, Σ_k sh_k Y^CS_k(d) + 0.5),   d = normalize(splat_position − camera_position)

with real SH constants that carry the Condon–Shortley phase (``-C1·y·sh[1] + C1·z·sh[2] −
C1·x·sh[3]``, C1 = 0.4886025119029199, …): Y^CS_lm = (−1)^|m| y_lm in shprobe's basis (R&H
signs, `shprobe.sh.conventions`). So a file's coefficients convert to shprobe's by the
same sign flip, a_lm = (−1)^|m| sh_lm, through the one registry
(`shprobe.sh.conventions.from_condon_shortley`). The DC term is ``f_dc``; the +0.5 is a
bias of the renderer, not a coefficient: the coefficient of the constant 0.5 would be
0.5 / C0. SPZ and glTF ``KHR_gaussian_splatting`` store the same coefficients.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh.conventions import from_condon_shortley, to_condon_shortley

#: Y_00 = 1 / (2√π), the renderer's C0.
SH_C0 = 0.28209479177387814
#: The renderer adds this to the SH sum before clamping at 0.
DC_BIAS = 0.5
#: Largest SH degree of the 3DGS renderer (16 coefficients per channel).
MAX_DEGREE = 3

__all__ = ["DC_BIAS", "MAX_DEGREE", "SH_C0", "check_degree", "colour_to_dc", "dc_to_colour",
           "from_shprobe", "to_shprobe", "view_colour"]


def check_degree(degree: int, what: str, where: Any = None) -> int:
    """The one check of a splat SH degree: 0 to `MAX_DEGREE`, what the 3DGS renderer evaluates.

    Parameters
    ----------
    degree
        The degree to check.
    what
        What holds it, named in the refusal ("sh_degree", "SPZ holds SH degree", ...).
    where
        The file concerned, if any.

    Returns
    -------
    int
        ``degree``.
    """
    if not 0 <= degree <= MAX_DEGREE:
        raise ShprobeError(f"{what} {degree}: the 3DGS renderer evaluates SH degree "
                           f"0–{MAX_DEGREE}", where)
    return degree


def to_shprobe(sh: ArrayLike) -> NDArray[np.floating]:
    """Splat-file SH (..., K, C) (CS phase, as the renderer evaluates them) → shprobe's
    coefficients of the same function without the bias: a_lm = (−1)^|m| sh_lm.

    Parameters
    ----------
    sh
        (..., K, C) SH as a splat file stores them.

    Returns
    -------
    ndarray of shape (..., K, C)
        shprobe's coefficients, a_lm = (−1)^|m| sh_lm.
    """
    return from_condon_shortley(sh)


def from_shprobe(coeffs: ArrayLike) -> NDArray[np.floating]:
    """shprobe coefficients (..., K, C) → splat-file SH (the same involution).

    Parameters
    ----------
    coeffs
        (..., K, C) shprobe coefficients.

    Returns
    -------
    ndarray of shape (..., K, C)
        The splat file's SH (Condon–Shortley phase).
    """
    return to_condon_shortley(coeffs)


def dc_to_colour(dc: ArrayLike) -> NDArray[np.floating]:
    """The view-independent colour of ``f_dc``: C0·dc + 0.5 (before the renderer's clamp).

    Parameters
    ----------
    dc
        (..., 3) ``f_dc`` values.

    Returns
    -------
    ndarray of shape (..., 3)
        C0·dc + 0.5.
    """
    return np.asarray(dc) * SH_C0 + DC_BIAS


def colour_to_dc(colour: ArrayLike) -> NDArray[np.floating]:
    """``f_dc`` of a view-independent colour (the inverse of
    [`dc_to_colour`][shprobe.splats.dc_to_colour]).

    Parameters
    ----------
    colour
        (..., 3) view-independent colours.

    Returns
    -------
    ndarray of shape (..., 3)
        ``f_dc`` = (colour − 0.5) / C0.
    """
    return (np.asarray(colour) - DC_BIAS) / SH_C0


def view_colour(sh: ArrayLike, directions: ArrayLike) -> NDArray[np.float64]:
    """The renderer's colour max(0, Σ sh_k Y^CS_k(d) + 0.5) of splats with SH ``sh`` (N, K, C)
    seen along unit ``directions`` (N, 3), camera → splat; evaluated with shprobe's basis.

    Parameters
    ----------
    sh
        (N, K, C) the splats' SH.
    directions
        (N, 3) unit directions, camera → splat.

    Returns
    -------
    ndarray of shape (N, C)
        The colour the renderer shows.
    """
    from ..sh.basis import sh_basis_numpy
    from ..sh.indexing import lmax_of

    c = to_shprobe(np.asarray(sh, dtype=np.float64))
    y = sh_basis_numpy(np.asarray(directions, dtype=np.float64), lmax_of(c.shape[-2]))
    return np.maximum(0.0, np.einsum("nk,nkc->nc", y, c) + DC_BIAS)
