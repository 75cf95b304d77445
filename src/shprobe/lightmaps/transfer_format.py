"""The ``transfer`` object of the ``SHPROBE_lightmap`` extension (specified in
`shprobe.lightmaps.format`): per texel, the matrices from the sky's SH (lmax 2) to the
coefficients."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .format import EXTENSION, N_COEFFS, add_textures, choose_scale, read_lightmap

__all__ = ["add_transfer", "read_transfer"]


def add_transfer(doc: dict, binary: bytearray, transfer: ArrayLike,
                 sky: ArrayLike | None = None) -> dict:
    """Add the transfer of a lightmap already added by `add_lightmap` (module doc).

    Parameters
    ----------
    doc : dict
        The glTF JSON holding the extension object.
    binary : bytearray
        The BIN chunk, extended in place.
    transfer : array_like, shape (H, W, n, 9, 3)
        Per texel, coefficient i of colour c under sky SH j: [..., i, j, c].
    sky : array_like (9, 3), optional
        The sky SH the lightmap was baked under, stored as ``"sky"`` (a viewer turns it).

    Returns
    -------
    dict
        The ``transfer`` object written.
    """
    ext = doc["extensions"][EXTENSION]
    e = ext["encoding"]
    t = np.asarray(transfer, dtype=np.float64)
    if t.shape != (ext["height"], ext["width"], N_COEFFS[e], 9, 3):
        raise ShprobeError(f"transfer must be (H, W, {N_COEFFS[e]}, 9, 3), got {t.shape}")
    scale = choose_scale(t)
    sets = [{"textures": add_textures(doc, binary, e, t[:, :, :, j], scale)}
            for j in range(9)]
    ext["transfer"] = {"sky_lmax": 2, "scale": scale, "sets": sets}
    if sky is not None:
        k = np.asarray(sky, dtype=np.float64)
        if k.shape != (9, 3) or not np.isfinite(k).all():
            raise ShprobeError(f"the transfer's sky must be finite (9, 3), got {k.shape}")
        ext["transfer"]["sky"] = k.tolist()
    return ext["transfer"]


def read_transfer(doc: dict, binary: bytes, where: Any = None) -> NDArray[np.float32] | None:
    """The transfer (H, W, n, 9, 3) of a lightmap document, or None (module docstring).

    Parameters
    ----------
    doc : dict
        The glTF JSON.
    binary : bytes
        The BIN chunk.
    where : str, optional
        The file, for error messages.

    Returns
    -------
    ndarray or None
        Per texel, coefficient i of colour c under sky SH j: [..., i, j, c].
    """
    ext = doc.get("extensions", {}).get(EXTENSION, {})
    tr = ext.get("transfer")
    if tr is None:
        return None
    try:
        sets = [dict(ext, textures=st["textures"], scale=tr["scale"]) for st in tr["sets"]]
    except (KeyError, TypeError):
        raise ShprobeError(f"its {EXTENSION} transfer is malformed", where) from None
    if len(sets) != 9:
        raise ShprobeError(f"its {EXTENSION} transfer needs 9 sets, has {len(sets)}", where)
    parts = [read_lightmap({"extensions": {EXTENSION: st}, "bufferViews": doc["bufferViews"]},
                           binary, where).coeffs for st in sets]
    return np.stack(parts, axis=3)
