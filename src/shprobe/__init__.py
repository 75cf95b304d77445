"""shprobe: spherical-harmonic lighting in Python.

Irradiance environment maps (Ramamoorthi & Hanrahan 2001), SH of any degree and Wigner rotation
(Lisle & Huang 2007), the H-basis (Habel & Wimmer 2010) and precomputed radiance transfer.

The public names below are imported lazily, so ``import shprobe`` stays fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

# public name -> module that defines it
_EXPORTS: dict[str, str] = {
    # SH basis (foundation)
    "sh_basis": "sh",
    "sh_index": "sh",
    "sh_lm": "sh",
    "num_coeffs": "sh",
    "lmax_of": "sh",
    # zonal functions
    "clamped_cosine_factors": "zonal",
    "zonal_coeffs": "zonal",
    "circular_window": "zonal",
    "convolve": "zonal",
    "clamped_cosine_H": "zonal",
    "legendre_moments": "zonal",
    "zonal_from_moments": "zonal",
    # rotation
    "wigner_d": "rotation",
    "rotate": "rotation",
    "from_quaternion": "rotation",
    "from_euler_zyz": "rotation",
    # errors
    "ShprobeError": "errors",
    # precomputed radiance transfer
    "bake": "prt",
    "relight": "prt",
    "load_transfer": "prt",
    # probes in, irradiance out
    "load_env": "prefilter",
    "project": "prefilter",
    "irradiance": "prefilter",
    "irradiance_matrix": "prefilter",
    "reference_irradiance": "prefilter",
    "project_samples": "prefilter",
    "irradiance_quadratic": "prefilter",
    "irradiance_from_matrix": "prefilter",
    "irradiance_map": "prefilter",
    "error_report": "prefilter",
    "read_coeffs_json": "prefilter",
    "get_preset": "presets",
    "PRESETS": "presets",
    "procedural_env": "environments",
    # H-basis (Habel & Wimmer 2010)
    "h_basis": "hbasis",
    "sh_to_h_matrix": "hbasis",
    "read_image": "images",
    "write_image": "images",
    # layouts (issue 3, part A)
    "Env": "layouts",
    "env_from_function": "layouts",
    "get_layout": "layouts",
    "detect_layout": "layouts",
    "write_env": "layouts",
    # rendering, lighting design, export
    "Camera": "render",
    "render_vertex_colors": "render",
    "load_mesh": "render",
    "min_irradiance": "design",
    "auto_window": "design",
    "window_factors": "design",
    "export_coeffs": "export",
    "import_coeffs": "export",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    mod = _EXPORTS.get(name)
    if mod is None:
        raise AttributeError(f"module 'shprobe' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{mod}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # pragma: no cover
    from .design import auto_window, min_irradiance, window_factors
    from .errors import ShprobeError
    from .export import export_coeffs, import_coeffs
    from .hbasis import h_basis, sh_to_h_matrix
    from .images import read_image, write_image
    from .layouts import Env, detect_layout, env_from_function, get_layout, write_env
    from .prefilter import irradiance, irradiance_matrix, load_env, project, reference_irradiance
    from .render import Camera, load_mesh, render_vertex_colors
    from .rotation import from_euler_zyz, from_quaternion, rotate, wigner_d
    from .sh import lmax_of, num_coeffs, sh_basis, sh_index, sh_lm
    from .zonal import (
        circular_window,
        clamped_cosine_factors,
        clamped_cosine_H,
        convolve,
        legendre_moments,
        zonal_coeffs,
        zonal_from_moments,
    )
