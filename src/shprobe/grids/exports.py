"""Probe grids for engines: three.js ``LightProbeGridWebGL``, Unity ``SphericalHarmonicsL2``
probes and a Godot 4 text resource; docs/grid-exports.md shows how each is loaded.

Every format holds the 9 RGB coefficients of each probe (lmax 1 grids are zero-padded) and
the volume; what differs is the basis scaling (a convention of `shprobe.sh.registry`)
and the frame, turned here at the edge:

========= ===================================================================================
format    content
========= ===================================================================================
three     JSON: ``bounds``, ``resolution``, ``coefficients`` — per probe, X fastest then Y then
          Z (the order of three.js's 3D texture), the 27 floats c0.rgb … c8.rgb of three.js's
          shader: radiance L_lm, R&H constants and signs (convention ``three``), world +Y up,
          probes at cell centres (three.js's own layout). The loader in the docs packs them
          into the 7-sub-volume atlas ``LightProbeGridWebGL`` samples.
unity     JSON: per probe its position and the 27 floats ``sh[rgb, k]`` (flat rgb·9 + k) of a
          ``SphericalHarmonicsL2`` (convention ``unity-l2``: (Â_l/π) K_k L_lm), in Unity's
          left-handed frame: world (x, y, z) → (x, y, −z), the z-odd coefficients negated.
          ``SphericalHarmonicsL2.Evaluate`` / ``ShadeSH9`` then return E/π at Unity normals.
godot     Godot 4 ``.tres`` text resource (a plain ``Resource`` with metadata): AABB, probe
          count per axis, probe positions and a ``PackedColorArray`` of 9 colours per probe,
          ``LightmapGIData``'s probe convention (``godot``: L_lm/π, R&H basis; Godot's
          frame is shprobe's, right-handed +Y up); the forward shader's polynomial gives E/π.
========= ===================================================================================
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._version import __version__
from ..errors import ShprobeError
from ..files import write_text
from ..limits import check_memory
from ..sh.registry import convert
from ..sh.rotation import z_mirror_signs
from .grid import ProbeGrid

__all__ = ["FORMATS", "SUFFIX", "estimate_export", "export_grid", "export_text", "grid_coeffs9"]

#: Format of each export document (the ``format`` field / Godot metadata).
THREE_FORMAT = "shprobe-grid-three"
UNITY_FORMAT = "shprobe-grid-unity"
GODOT_FORMAT = "shprobe-grid-godot"
EXPORT_VERSION = 1


def grid_coeffs9(grid: ProbeGrid) -> NDArray[np.float64]:
    """(NX, NY, NZ, 9, 3) float64 coefficients (an lmax 1 grid zero-padded to l ≤ 2)."""
    c = np.asarray(grid.coeffs, dtype=np.float64)
    out = np.zeros((*c.shape[:3], 9, 3))
    out[..., : c.shape[3], :] = c
    return out


def _texture_order(a: NDArray) -> NDArray:
    """(NX, NY, NZ, ...) → (NZ, NY, NX, ...): X fastest in memory, as a 3D texture."""
    return np.ascontiguousarray(np.transpose(a, (2, 1, 0, *range(3, a.ndim))))


def _floats(a: NDArray) -> list[float]:
    """Finite floats for a document, refused otherwise (never write a non-finite number)."""
    flat = np.asarray(a, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(flat)):
        raise ShprobeError("grid holds non-finite values; nothing written")
    return [float(format(v, ".9g")) for v in flat]


def _common(grid: ProbeGrid) -> dict[str, Any]:
    nx, ny, nz = grid.resolution
    return {"generator": f"shprobe {__version__}", "resolution": [nx, ny, nz],
            "probes": nx * ny * nz, "lmax_baked": grid.lmax}


def _three(grid: ProbeGrid, source: str | None) -> str:
    c = _texture_order(convert(grid_coeffs9(grid), to="three"))
    doc = {"format": THREE_FORMAT, "version": EXPORT_VERSION, **_common(grid),
           "target": "three.js LightProbeGridWebGL / LightProbeGrid (r187): probes at cell "
                     "centres of bounds, one per cell",
           "convention": "three.js SphericalHarmonics3: R&H basis constants and signs, "
                         "c0..c8 = k = l(l+1)+m, world frame +Y up",
           "quantity": "radiance coefficients L_lm (three.js's shader applies A_l; the "
                       "Lambert BRDF divides by pi)",
           "layout": "coefficients[(((iz*ny + iy)*nx + ix)*9 + k)*3 + rgb]",
           "bounds": _floats(grid.bounds), "coefficients": _floats(c)}
    if source:
        doc["source"] = source
    return json.dumps(doc, separators=(",", ":")) + "\n"


def unity_frame(points: NDArray) -> NDArray[np.float64]:
    """World points or directions (..., 3) in Unity's left-handed frame: (x, y, −z)."""
    return np.asarray(points, dtype=np.float64) * np.array([1.0, 1.0, -1.0])


def _unity(grid: ProbeGrid, source: str | None) -> str:
    sh = convert(grid_coeffs9(grid), to="unity-l2") * z_mirror_signs(2)[:, None]
    sh = np.swapaxes(sh, -1, -2)  # (..., rgb, k): SphericalHarmonicsL2's sh[rgb, k]
    pos = unity_frame(grid.centres())  # where the lookup places each probe's SH
    lo, hi = unity_frame(grid.bounds)
    doc = {"format": UNITY_FORMAT, "version": EXPORT_VERSION, **_common(grid),
           "target": "UnityEngine.Rendering.SphericalHarmonicsL2 per probe "
                     "(LightProbes.bakedProbes, or a custom-provided probe per renderer)",
           "frame": "Unity world, left-handed +Y up: shprobe's (x, y, z) is (x, y, -z) here; "
                    "coefficients odd in z negated",
           "convention": "SphericalHarmonicsL2 sh[rgb, k], k = l(l+1)+m: (A_l/pi) K_k L_lm "
                         "(kNormalizationConstants; the CS signs of basis and constants "
                         "cancel). ShadeSH9 / Evaluate give E/pi: the outgoing radiance of a "
                         "white Lambertian surface",
           "layout": "probes in grid order ix, iy, iz with iz fastest (shprobe's index "
                     "(ix*ny + iy)*nz + iz); positions[i] (3 floats: the cell centre, "
                     "where the interpolation places the probe, even if it was baked at a "
                     "relocated point), coefficients[i] (27 floats, index rgb*9 + k)",
           "bounds": _floats(np.stack([np.minimum(lo, hi), np.maximum(lo, hi)])),
           "positions": _floats(pos.reshape(-1, 3)),
           "coefficients": _floats(sh.reshape(-1, 27))}
    if source:
        doc["source"] = source
    return json.dumps(doc, separators=(",", ":")) + "\n"


def _godot_floats(a: NDArray) -> str:
    return ", ".join(format(v, ".9g") for v in _floats(a))


def _godot(grid: ProbeGrid, source: str | None) -> str:
    sh = convert(grid_coeffs9(grid), to="godot").reshape(-1, 9, 3)
    rgba = np.concatenate([sh, np.ones((*sh.shape[:2], 1))], axis=-1)
    lo, hi = grid.bounds
    nx, ny, nz = grid.resolution
    src = re.sub(r'[\x00-\x1f"\\]', "_", source or "")  # one line, no escapes
    lines = [
        '[gd_resource type="Resource" format=3]',
        "",
        "[resource]",
        f'metadata/format = "{GODOT_FORMAT}"',
        f"metadata/version = {EXPORT_VERSION}",
        f'metadata/generator = "shprobe {__version__}"',
        f'metadata/source = "{src}"',
        'metadata/convention = "LightmapGIData probe SH: 9 colours per probe, L_lm/pi, R&H '
        "basis (k = l(l+1)+m), world frame +Y up; E/pi = the forward shader's lightmap-capture "
        'polynomial of the trilinear blend"',
        'metadata/layout = "probe (ix, iy, iz) at index (ix*ny + iy)*nz + iz, centre of its '
        'cell of bounds; sh[index*9 + k]"',
        f"metadata/bounds = AABB({_godot_floats(np.concatenate([lo, hi - lo]))})",
        f"metadata/resolution = Vector3i({nx}, {ny}, {nz})",
        f"metadata/points = PackedVector3Array({_godot_floats(grid.centres())})",
        f"metadata/sh = PackedColorArray({_godot_floats(rgba)})",
        "",
    ]
    return "\n".join(lines)


_WRITERS: dict[str, Callable[[ProbeGrid, str | None], str]] = {
    "three": _three, "unity": _unity, "godot": _godot}

#: Export formats and the suffix each file gets by default.
FORMATS = tuple(_WRITERS)
SUFFIX = {"three": ".three.json", "unity": ".unity.json", "godot": ".tres"}


#: Bytes of memory an export needs per probe, by format, and a fixed part (measured peaks of
#: bench/bench_estimates.py, fitted): the float64 copies made on the way, a Python float per
#: number (24 bytes and a list slot), the text (27 + 3 numbers of up to 16 characters) and,
#: for Godot, the formatted strings joined.
BYTES_PER_PROBE = {"three": 1900, "unity": 2150, "godot": 4050}
EXPORT_BASE_BYTES = 20e6


def estimate_export(grid: ProbeGrid, fmt: str) -> float:
    """Peak bytes of `export_text` of ``grid`` in format ``fmt``.

    Parameters
    ----------
    grid : ProbeGrid
        The grid to export.
    fmt : str
        One of `FORMATS`.

    Returns
    -------
    float
        The estimate checked against the memory limit.
    """
    return EXPORT_BASE_BYTES + float(np.prod(grid.resolution)) * BYTES_PER_PROBE[fmt]


def export_text(grid: ProbeGrid, fmt: str, source: str | None = None) -> str:
    """The text of ``grid`` in format ``fmt``; refused first when it would not fit in
    memory (`estimate_export`) or its values would overflow the conversion.

    Parameters
    ----------
    grid : ProbeGrid
        The grid.
    fmt : str
        One of `FORMATS`.
    source : str, optional
        The grid file's name, recorded in the export.

    Returns
    -------
    str
        The export's text.
    """
    if fmt not in _WRITERS:
        raise ShprobeError(f"unknown grid export format {fmt!r}; choose from "
                           f"{', '.join(FORMATS)}")
    check_memory(estimate_export(grid, fmt), f"the {fmt} export")
    _check_values(grid)
    return _WRITERS[fmt](grid, source)


def _check_values(grid: ProbeGrid) -> None:
    """Refuse, before converting, values whose conversion would overflow (a grid made in
    memory; [`shprobe.grids.load_grid`][shprobe.grids.load_grid] refuses them in files)."""
    from .io import MAX_COEFFICIENT
    from .settings import MAX_COORDINATE

    c = np.asarray(grid.coeffs)
    if not np.all(np.isfinite(c)) or not np.all(np.isfinite(grid.bounds)):
        raise ShprobeError("grid holds non-finite values; nothing written")
    if np.abs(c).max() > MAX_COEFFICIENT or np.abs(grid.bounds).max() > MAX_COORDINATE:
        raise ShprobeError(f"grid holds coefficients beyond ±{MAX_COEFFICIENT:g} or bounds "
                           f"beyond ±{MAX_COORDINATE:g}; nothing written")


def export_grid(grid: ProbeGrid, fmt: str, path: str | os.PathLike[str],
                overwrite: bool = False, source: str | None = None) -> Path:
    """Write ``grid`` to ``path`` in format ``fmt`` atomically (nothing replaced unless
    ``overwrite``); the text is built before the file is opened."""
    text = export_text(grid, fmt, source)
    return write_text(path, text, overwrite)
