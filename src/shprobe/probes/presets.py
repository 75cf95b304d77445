"""Lighting presets: the R&H 2001 Fig. 2 coefficient tables.

Ramamoorthi & Hanrahan 2001, Fig. 2: RGB lighting coefficients L_lm (l ≤ 2) of three of
Debevec's light probes, printed to two decimals. Transcribed from the seed text and checked
against the second OCR copy and thesis ch. 4 (identical). Rows in shprobe's flat order
k = l(l+1)+m (L00, L1-1, L10, L11, L2-2, L2-1, L20, L21, L22), which is also the paper's row
order; the signs are the paper's, which are shprobe's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

_TABLES: dict[str, tuple[tuple[float, float, float], ...]] = {
    "grace": (  # Grace Cathedral
        (0.79, 0.44, 0.54),
        (0.39, 0.35, 0.60),
        (-0.34, -0.18, -0.27),
        (-0.29, -0.06, 0.01),
        (-0.11, -0.05, -0.12),
        (-0.26, -0.22, -0.47),
        (-0.16, -0.09, -0.15),
        (0.56, 0.21, 0.14),
        (0.21, -0.05, -0.30),
    ),
    "eucalyptus": (  # Eucalyptus Grove
        (0.38, 0.43, 0.45),
        (0.29, 0.36, 0.41),
        (0.04, 0.03, 0.01),
        (-0.10, -0.10, -0.09),
        (-0.06, -0.06, -0.04),
        (0.01, -0.01, -0.05),
        (-0.09, -0.13, -0.15),
        (-0.06, -0.05, -0.04),
        (0.02, -0.00, -0.05),
    ),
    "stpeters": (  # St. Peter's Basilica
        (0.36, 0.26, 0.23),
        (0.18, 0.14, 0.13),
        (-0.02, -0.01, -0.00),
        (0.03, 0.02, 0.01),
        (0.02, 0.01, 0.00),
        (-0.05, -0.03, -0.01),
        (-0.09, -0.08, -0.07),
        (0.01, 0.00, 0.00),
        (-0.08, -0.06, 0.00),
    ),
}

#: Preset name → long name.
PRESETS: dict[str, str] = {
    "grace": "Grace Cathedral (R&H 2001 Fig. 2)",
    "eucalyptus": "Eucalyptus Grove (R&H 2001 Fig. 2)",
    "stpeters": "St. Peters Basilica (R&H 2001 Fig. 2)",
}

_ALIASES = {"gracecathedral": "grace", "eucalyptusgrove": "eucalyptus", "stpeter": "stpeters",
            "stpetersbasilica": "stpeters"}


def get_preset(name: str) -> NDArray[np.float64]:
    """The (9, 3) lighting coefficients L_lm of an R&H Fig. 2 environment (a fresh copy).

    Parameters
    ----------
    name
        An R&H Fig. 2 environment's name (``PRESETS``).

    Returns
    -------
    ndarray of shape (9, 3)
        Its lighting coefficients L_lm (a fresh copy).
    """
    key = "".join(ch for ch in str(name).lower() if ch.isalnum())
    key = _ALIASES.get(key, key)
    if key not in _TABLES:
        raise ShprobeError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
    return np.array(_TABLES[key], dtype=np.float64)


__all__ = ["PRESETS", "get_preset"]
