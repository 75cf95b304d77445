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
    "clamped_cosine_factors": "sh.zonal",
    "zonal_coeffs": "sh.zonal",
    "circular_window": "sh.zonal",
    "convolve": "sh.zonal",
    "clamped_cosine_H": "sh.zonal",
    "legendre_moments": "sh.zonal",
    "zonal_from_moments": "sh.zonal",
    # rotation
    "wigner_d": "sh.rotation",
    "rotate": "sh.rotation",
    "from_quaternion": "sh.rotation",
    "from_euler_zyz": "sh.rotation",
    # errors and limits
    "ShprobeError": "errors",
    "Limits": "limits",
    # precomputed radiance transfer
    "bake": "prt",
    "PrtSettings": "prt",
    "relight": "prt",
    "load_transfer": "prt",
    # probes in, irradiance out
    "load_env": "probes.env",
    "project": "lighting.projection",
    "irradiance": "lighting.irradiance",
    "irradiance_matrix": "lighting.irradiance",
    "reference_irradiance": "lighting.reference",
    "project_samples": "lighting.projection",
    "irradiance_quadratic": "lighting.irradiance",
    "irradiance_from_matrix": "lighting.irradiance",
    "irradiance_map": "lighting.irradiance",
    "error_report": "lighting.reference",
    "read_coeffs_json": "lighting.document",
    "get_preset": "probes.presets",
    "PRESETS": "probes.presets",
    "procedural_env": "probes.environments",
    # H-basis (Habel & Wimmer 2010)
    "h_basis": "hbasis",
    "HBasisSettings": "hbasis",
    "bake_hbasis": "hbasis",
    "sh_to_h_matrix": "hbasis",
    "read_image": "probes.images",
    "write_image": "probes.images",
    # layouts
    "Env": "probes.env",
    "env_from_function": "probes.env",
    "get_layout": "probes.layouts",
    "detect_layout": "probes.layouts",
    "write_env": "probes.env",
    # rendering, lighting design, export
    "Camera": "scene.camera",
    "render_vertex_colors": "scene.render",
    "load_mesh": "scene.mesh",
    "packaged_bunny": "scene.mesh",
    "min_irradiance": "lighting.windows",
    "auto_window": "lighting.windows",
    "window_factors": "lighting.windows",
    "export_coeffs": "lighting.export",
    "import_coeffs": "lighting.export",
    # conventions, images ↔ coefficients on NumPy and tensors
    "convert": "sh.registry",
    "project_latlong": "lighting.maps",
    "project_cube": "lighting.maps",
    "latlong_radiance": "lighting.maps",
    "latlong_irradiance": "lighting.maps",
    # probe grids (irradiance volumes)
    "load_grid": "grids",
    "ProbeGrid": "grids",
    "bake_grid": "grids",
    "GridSettings": "grids",
    # directional lightmaps (H-basis and rivals on a second UV set)
    "bake_lightmap": "lightmaps",
    "LightmapSettings": "lightmaps",
    "Lightmap": "lightmaps",
    "load_lightmap": "lightmaps",
    # the workflows' settings (the CLI's defaults)
    "PrefilterSettings": "lighting.workflow",
    "IrradianceSettings": "lighting.workflow",
    "FitSettings": "fitting.settings",
    "ReportSettings": "report.probe",
    "RenderSettings": "scene.workflow",
    "render_image": "scene.workflow",
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
    from .errors import ShprobeError
    from .fitting.settings import FitSettings
    from .hbasis import HBasisSettings, bake_hbasis, h_basis, sh_to_h_matrix
    from .lighting.document import read_coeffs_json
    from .lighting.export import export_coeffs, import_coeffs
    from .lighting.irradiance import (
        irradiance,
        irradiance_from_matrix,
        irradiance_map,
        irradiance_matrix,
        irradiance_quadratic,
    )
    from .lighting.projection import project, project_samples
    from .lighting.reference import error_report, reference_irradiance
    from .lighting.windows import auto_window, min_irradiance, window_factors
    from .lighting.workflow import IrradianceSettings, PrefilterSettings
    from .limits import Limits
    from .probes.env import Env, env_from_function, load_env, write_env
    from .probes.environments import procedural_env
    from .probes.images import read_image, write_image
    from .probes.layouts import detect_layout, get_layout
    from .probes.presets import PRESETS, get_preset
    from .prt import PrtSettings, bake, load_transfer, relight
    from .report.probe import ReportSettings
    from .scene.camera import Camera
    from .scene.mesh import load_mesh, packaged_bunny
    from .scene.render import render_vertex_colors
    from .scene.workflow import RenderSettings, render_image
    from .sh import lmax_of, num_coeffs, sh_basis, sh_index, sh_lm
    from .sh.rotation import from_euler_zyz, from_quaternion, rotate, wigner_d
    from .sh.zonal import (
        circular_window,
        clamped_cosine_factors,
        clamped_cosine_H,
        convolve,
        legendre_moments,
        zonal_coeffs,
        zonal_from_moments,
    )
