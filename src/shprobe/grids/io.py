"""Grid files: a ``.npz`` with the arrays of [`ProbeGrid`][shprobe.grids.ProbeGrid] and its
bake settings as JSON, read back with every array checked before use."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import ShprobeError
from ..files import load_npz, npz_headers, save_npz
from .grid import GRID_FORMAT, GRID_VERSION, ProbeGrid
from .settings import MAX_COORDINATE

__all__ = ["load_grid", "save_grid"]

_OPTIONAL = ("positions", "validity", "depth")


def save_grid(path: str | os.PathLike[str], grid: ProbeGrid, overwrite: bool = False) -> Path:
    """Write ``grid`` to ``path`` (``*.npz``) atomically; non-finite values are refused.

    Parameters
    ----------
    path
        The output file (``*.npz``).
    grid
        The grid.
    overwrite
        Replace an existing file.

    Returns
    -------
    Path
        The file written.
    """
    arrays = {"coeffs": np.asarray(grid.coeffs, dtype=np.float32),
              "bounds": np.asarray(grid.bounds, dtype=np.float64)}
    for name in _OPTIONAL:
        a = getattr(grid, name)
        if a is not None:
            arrays[name] = np.asarray(a, dtype=np.float64 if name == "positions" else np.float32)
    head = {"format": GRID_FORMAT, "version": GRID_VERSION, **dict(grid.meta)}
    arrays["meta"] = np.frombuffer(json.dumps(head).encode(), dtype=np.uint8)
    return save_npz(path, overwrite=overwrite, **arrays)


#: The meta keys a bake writes and what each must be: (kind, lowest, highest).
_META = {"lmax": (int, 1, 2), "bounces": (int, 0, 16), "samples": (int, 1, 1 << 20),
         "depth_resolution": (int, 1, 64), "normal_bias": (float, 0.0, 0.5),
         "gather": (int, 0, 256), "moved": (int, 0, 1 << 27), "invalid": (int, 0, 1 << 27),
         "seconds": (float, 0.0, 1e9)}
#: Nesting of the meta JSON accepted (a bake writes a flat object).
_META_DEPTH = 4
#: Largest magnitude of a coefficient: shading sums a few dozen of them in float32.
MAX_COEFFICIENT = 1e30


def _depth(x: object) -> int:
    """Nesting depth of a parsed JSON value, without recursion."""
    deepest, stack = 0, [(x, 1)]
    while stack:
        v, d = stack.pop()
        deepest = max(deepest, d)
        if d > _META_DEPTH:
            break
        if isinstance(v, dict):
            stack.extend((w, d + 1) for w in v.values())
        elif isinstance(v, list):
            stack.extend((w, d + 1) for w in v)
    return deepest


def _check_meta(meta: object, p: str) -> dict:
    """The meta object of a grid file, its format, version and bake settings checked."""
    if not isinstance(meta, dict) or meta.get("format") != GRID_FORMAT:
        raise ShprobeError("not a shprobe grid file", p)
    version = meta.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise ShprobeError(f"grid file version {str(version)[:40]!r} is not a positive "
                           "integer", p)
    if version > GRID_VERSION:
        raise ShprobeError(f"grid file version {version} is newer than this shprobe reads "
                           f"({GRID_VERSION})", p)
    if _depth(meta) > _META_DEPTH:
        raise ShprobeError(f"grid file's meta is nested deeper than {_META_DEPTH} levels", p)
    for key, (kind, lo, hi) in _META.items():
        if key not in meta:
            continue
        v = meta[key]
        ok = (isinstance(v, int | float) and not isinstance(v, bool)
              and (kind is float or isinstance(v, int)) and math.isfinite(v) and lo <= v <= hi)
        if not ok:
            what = "an integer" if kind is int else "a number"
            raise ShprobeError(f"grid file's meta {key!r} is {str(v)[:40]!r}, not {what} in "
                               f"{lo}..{hi}", p)
    return meta


def _check_arrays(d: dict, p: str) -> None:
    """Types, shapes and ranges of a grid file's arrays (before a
    [`ProbeGrid`][shprobe.grids.ProbeGrid])."""
    for k, a in d.items():
        if k != "meta" and (a.dtype.kind not in "fiu" or not np.all(np.isfinite(a))):
            raise ShprobeError(f"grid array {k!r} is not finite numbers", p)
    limits = {"coeffs": MAX_COEFFICIENT, "bounds": MAX_COORDINATE,
              "positions": MAX_COORDINATE, "depth": MAX_COORDINATE, "validity": 1.0}
    for k, top in limits.items():
        if k in d and d[k].size and float(np.abs(d[k]).max()) > top:
            raise ShprobeError(f"grid array {k!r} holds {float(np.abs(d[k]).max()):.3g}, "
                               f"beyond ±{top:g}", p)
    if "validity" in d and d["validity"].size and float(d["validity"].min()) < 0:
        raise ShprobeError("grid array 'validity' is not in [0, 1]", p)
    if "depth" in d:
        s = d["depth"].shape
        if len(s) != 6 or s[3] != s[4] or s[5] != 2 or not 1 <= s[3] <= 64 \
                or float(d["depth"].min(initial=0.0)) < 0:
            raise ShprobeError(f"grid array 'depth' has shape {s}: expected (NX, NY, NZ, D, D, "
                               "2) non-negative moments, D ≤ 64", p)


def load_grid(path: str | os.PathLike[str]) -> ProbeGrid:
    """Read a grid written by [`save_grid`][shprobe.grids.save_grid] (``shprobe grid bake``); one
    line naming the file on anything else: the meta JSON (strict, bounded nesting, format, version
    and bake settings of their types and ranges) and every array (type, shape, finite, within
    `MAX_COORDINATE` / `MAX_COEFFICIENT`) are checked before use.

    Parameters
    ----------
    path : str or os.PathLike
        The grid file (``.npz``).

    Returns
    -------
    ProbeGrid
        The grid, its meta without ``format`` and ``version``.
    """
    from ..lighting.document import parse_json

    p = os.fspath(path)
    heads = npz_headers(p, "shprobe grid file")
    if "meta" not in heads or "coeffs" not in heads or "bounds" not in heads:
        raise ShprobeError("not a shprobe grid file (no meta/coeffs/bounds arrays)", p)
    d = load_npz(p, ["meta", "coeffs", "bounds", *_OPTIONAL], "shprobe grid file")
    if d["meta"].ndim != 1 or d["meta"].dtype.kind not in "iu":
        raise ShprobeError("grid file's meta is not JSON", p)
    try:
        text = d["meta"].astype(np.uint8).tobytes().decode()
    except UnicodeDecodeError:
        raise ShprobeError("grid file's meta is not JSON", p) from None
    meta = _check_meta(parse_json(text, p), p)
    _check_arrays(d, p)
    try:
        return ProbeGrid(coeffs=d["coeffs"].astype(np.float32), bounds=d["bounds"],
                         positions=d.get("positions"), validity=d.get("validity"),
                         depth=d.get("depth"),
                         meta={k: v for k, v in meta.items() if k not in ("format", "version")})
    except ShprobeError as e:
        raise ShprobeError(e.message, p) from None
