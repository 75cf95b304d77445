"""The coefficient document: the JSON of ``shprobe prefilter --format json``, written and read
in one place."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._version import __version__
from ..errors import ShprobeError
from ..files import read_text
from ..sh import lmax_of
from .coeffs import as_coeffs, as_rgb, labels
from .irradiance import irradiance_coeffs, irradiance_matrix

__all__ = ["coeffs_document", "coeffs_from_document", "parse_json", "read_coeffs_json"]


def coeffs_document(coeffs: ArrayLike, source: str | None = None, layout: str | None = None
                    ) -> dict[str, Any]:
    """The JSON document of ``shprobe prefilter --format json``.

    Keys: shprobe_version, source, layout, lmax, convention, labels, coefficients `[k][rgb]`,
    irradiance_coefficients `[k][rgb]` (Â_l L_lm) and, for lmax ≥ 2, M `[rgb][4][4]` (eq. 11–12).

    Parameters
    ----------
    coeffs
        (K, C) lighting coefficients.
    source
        What they came from.
    layout
        The source image's layout.

    Returns
    -------
    dict
        The JSON-able document.
    """
    c = as_coeffs(coeffs)
    if c.shape[1] == 1:
        c = as_rgb(c)
    lmax = lmax_of(c.shape[0])
    doc: dict[str, Any] = {
        "shprobe_version": __version__,
        "source": source,
        "layout": layout,
        "lmax": lmax,
        "convention": "real orthonormal SH, R&H 2001 signs (no Condon-Shortley phase), "
                      "k = l(l+1)+m, world +Y up; E(n) = sum_k irradiance_coefficients[k] y_k(n)",
        "labels": labels(lmax),
        "coefficients": c.tolist(),
        "irradiance_coefficients": irradiance_coeffs(c).tolist(),
    }
    if lmax >= 2:
        doc["M"] = irradiance_matrix(c).tolist()
    return doc


#: The ``format`` each other coefficient file names itself by (shprobe.lighting.export).
_OTHER_FORMATS = {"condon-shortley": "cs-phase", "three.SphericalHarmonics3": "three"}


def coeffs_from_document(doc: Any, where: Any = None) -> NDArray[np.float64]:
    """L_lm (K, C) of a parsed shprobe JSON document (any object with ``coefficients``
    `[k][channel]` in shprobe's convention)."""
    if not isinstance(doc, dict):
        raise ShprobeError("JSON coefficient file must hold an object", where)
    fmt = doc.get("format", "shprobe-coeffs")
    if fmt in _OTHER_FORMATS or "extensions" in doc or "object" in doc:
        other = _OTHER_FORMATS.get(fmt, "gltf" if "extensions" in doc else "three")
        raise ShprobeError(f"holds {other} coefficients, not a shprobe JSON document (read it "
                           "with shprobe.import_coeffs)", where)
    if "coefficients" not in doc:
        raise ShprobeError("JSON file holds no coefficients", where)
    return as_coeffs(doc["coefficients"], where)


def read_coeffs_json(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Coefficients (K, C) from a shprobe JSON document (``shprobe prefilter --format json``).

    Other formats (Condon–Shortley JSON, three.js, glTF, shaders, cmgen) are refused here:
    [`shprobe.import_coeffs`][shprobe.lighting.import_coeffs] reads every format and converts it.

    Parameters
    ----------
    path
        A shprobe JSON document.

    Returns
    -------
    ndarray of shape (K, C)
        The lighting coefficients it holds.
    """
    p = os.fspath(path)
    return coeffs_from_document(parse_json(read_text(p, "text file"), p), p)


def parse_json(text: str, where: Any = None) -> Any:
    """Strict JSON (no NaN / Infinity, bounded depth) or one line naming ``where``."""
    try:
        return json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as e:
        raise ShprobeError(f"not valid JSON: {e.msg} (line {e.lineno})", where) from None
    except ValueError as e:  # NaN / Infinity, or an integer too long to convert
        raise ShprobeError(f"not valid JSON: {e}", where) from None
    except RecursionError:
        raise ShprobeError("not valid JSON: nested too deeply", where) from None


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")
