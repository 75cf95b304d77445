"""Layer 3, lighting: the coefficient core (`shprobe.lighting.coeffs`, `shprobe.lighting.document`),
projection (R&H eq. 10, `shprobe.lighting.projection`), irradiance and the quadratic form (eq. 7,
11–13, `shprobe.lighting.irradiance`), the brute-force reference and
error report (`shprobe.lighting.reference`), lighting design (§3.3, `shprobe.lighting.design`) and
its one edit language (`shprobe.lighting.edits`), windows and the non-negativity certificate
(`shprobe.lighting.windows`), engine export / import (`shprobe.lighting.export`) and the one
lighting resolver (`shprobe.lighting.source`). Imports only ``probes``, ``sh`` and the base modules.
"""

from .coeffs import RH_CONSTANTS, RH_LABELS, as_coeffs, labels, pad_coeffs
from .document import coeffs_document, read_coeffs_json
from .edits import EditSpec
from .export import FORMATS, export_coeffs, import_coeffs
from .irradiance import (
    irradiance,
    irradiance_coeffs,
    irradiance_from_matrix,
    irradiance_map,
    irradiance_matrix,
    irradiance_quadratic,
    quadratic_form,
    shade_irradiance,
)
from .projection import project, project_samples, total_intensity
from .reference import ErrorReport, ErrorRow, error_report, reference_irradiance
from .windows import WINDOWS, apply_window, auto_window, min_irradiance, window_factors

__all__ = [
    "FORMATS",
    "RH_CONSTANTS",
    "RH_LABELS",
    "WINDOWS",
    "EditSpec",
    "ErrorReport",
    "ErrorRow",
    "apply_window",
    "as_coeffs",
    "auto_window",
    "coeffs_document",
    "error_report",
    "export_coeffs",
    "import_coeffs",
    "irradiance",
    "irradiance_coeffs",
    "irradiance_from_matrix",
    "irradiance_map",
    "irradiance_matrix",
    "irradiance_quadratic",
    "labels",
    "min_irradiance",
    "pad_coeffs",
    "project",
    "project_samples",
    "quadratic_form",
    "read_coeffs_json",
    "reference_irradiance",
    "shade_irradiance",
    "total_intensity",
    "window_factors",
]
