"""The encodings a stored lightmap implies: what the viewer and the figures can show from one
``SHPROBE_lightmap`` file.

A .glb holds one encoding (`shprobe.lightmaps.format`). Others follow from it exactly where the
format's
definitions allow:

* every encoding gives ``plain`` — its own E at the unperturbed normal n = (0, 0, 1), i.e.
  the lightmap with the normal map ignored (H&W Fig. 1, left);
* ``h6`` gives ``h4`` (its first four coefficients: the H-basis is hierarchical, H&W §4.1);
* ``sh9`` gives ``sh4`` (bands l ≤ 1) and, through the radiance SH it was made from
  (E_lm = Â_l L_lm), ``hl2``, ``h4`` and ``h6`` as the bake derives them
  (`shprobe.lightmaps.encode.encodings_from_sh`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from . import format as fmt

#: the unperturbed tangent-frame normal
UP = np.array([0.0, 0.0, 1.0])


def implied_encodings(encoding: str, coeffs: NDArray) -> dict[str, NDArray[np.float64]]:
    """Every encoding the stored one determines, with its coefficients.

    Parameters
    ----------
    encoding : str
        The stored encoding (one of
        [`shprobe.lightmaps.format.ENCODINGS`][shprobe.lightmaps.ENCODINGS]).
    coeffs : ndarray, shape (..., n, 3)
        Its coefficients (already multiplied by the file's scale).

    Returns
    -------
    dict
        Encoding name → coefficients (..., n', 3), in
        [`shprobe.lightmaps.format.ENCODINGS`][shprobe.lightmaps.ENCODINGS] order; the stored
        encoding's own coefficients are the input, unchanged.
    """
    e = fmt.check_encoding(encoding)
    c = np.asarray(coeffs, dtype=np.float64)
    out = {e: c}
    plain = fmt.evaluate(e, c, UP)
    if e != "plain":
        out["plain"] = plain[..., None, :]
    if e == "h6":
        out["h4"] = c[..., :4, :]
    if e == "sh9":
        from .encode import A_HAT, encodings_from_sh

        derived = encodings_from_sh(c / np.asarray(A_HAT)[:, None], plain)
        for k in ("hl2", "sh4", "h4", "h6"):
            out[k] = derived[k]
    return {k: out[k] for k in fmt.ENCODINGS if k in out}


__all__ = ["implied_encodings"]
