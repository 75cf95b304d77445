"""The lighting workflows in the one shape (settings, one entry, a result with ``as_dict``):
prefiltering a probe into SH coefficients (`PrefilterSettings`, `prefilter`;
R&H 2001 eq. 10) and writing an irradiance environment map (`IrradianceSettings`,
`write_irradiance_map`; R&H 2001 §3.1). ``shprobe prefilter`` and ``shprobe
irradiance`` read their defaults here."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ShprobeError
from ..limits import Cost, Limits
from ..progress import Progress
from .source import Lighting, resolve_lighting

__all__ = ["IRRADIANCE_METHODS", "OUT_LAYOUTS", "IrradianceResult", "IrradianceSettings",
           "PrefilterSettings", "irradiance_map_cost", "lighting_document", "prefilter",
           "write_irradiance_map"]

#: How an irradiance map is computed: from the SH coefficients (eq. 7) or by brute force.
IRRADIANCE_METHODS = ("sh", "brute")
#: Layouts of an irradiance map ('same': the probe's, lat-long without one).
OUT_LAYOUTS = ("same", "latlong", "angular", "mirrorball", "cube")


@dataclass(frozen=True)
class PrefilterSettings:
    """Settings of a prefilter (`prefilter`); the defaults are ``shprobe prefilter``'s.

    Parameters
    ----------
    lmax
        Highest SH degree of the coefficients.
    layout
        The probe's layout ('auto': detected).
    clamp
        Set NaN, infinite and negative pixels to 0 instead of refusing the image.
    limits
        The memory limit ([`shprobe.limits.Limits`][shprobe.limits.Limits]).
    """

    lmax: int = 2
    layout: str = "auto"
    clamp: bool = False
    limits: Limits = field(default_factory=Limits, compare=False)

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            lmax, layout, clamp, limits.
        """
        return {"lmax": self.lmax, "layout": self.layout, "clamp": self.clamp,
                "limits": self.limits.as_dict()}


def prefilter(probe: Any = None, settings: PrefilterSettings | None = None, *,
              preset: str | None = None, coeffs: Any = None) -> Lighting:
    """SH lighting coefficients L_lm of one source (R&H 2001 eq. 10).

    Parameters
    ----------
    probe
        A probe image path (or six cube-face paths).
    settings
        The prefilter's `PrefilterSettings` (default: its defaults).
    preset
        An R&H 2001 Fig. 2 table's name, instead of a probe.
    coeffs
        A coefficient file, instead of a probe.

    Returns
    -------
    Lighting
        The coefficients (K, 3), the source's name and layout (`lighting_document`
        gives its JSON document).
    """
    s = settings if settings is not None else PrefilterSettings()
    with s.limits.applied():
        return resolve_lighting(probe, preset, coeffs, None, s.layout, s.lmax, s.clamp)


def lighting_document(lighting: Lighting) -> dict[str, Any]:
    """The JSON document of prefiltered lighting (``shprobe prefilter --format json``).

    Parameters
    ----------
    lighting
        The lighting (`prefilter`).

    Returns
    -------
    dict
        [`shprobe.lighting.document.coeffs_document`][shprobe.lighting.coeffs_document] of its
        coefficients.
    """
    return lighting.as_dict()


@dataclass(frozen=True)
class IrradianceSettings:
    """Settings of an irradiance map (`write_irradiance_map`); the defaults are
    ``shprobe irradiance``'s.

    Parameters
    ----------
    method
        'sh' (eq. 7 from L_lm) or 'brute' (the hemispherical integral per pixel; needs the
        probe image).
    out_layout
        Layout of the map (`OUT_LAYOUTS`; 'same': the probe's, lat-long for presets).
    size
        The layout's size argument (None: 256x128 lat-long, 64 a cube face, 256 the discs).
    exposure
        PNG only: exposure in stops of E/π (None: automatic, the 99th percentile at white).
    limits
        The memory limit ([`shprobe.limits.Limits`][shprobe.limits.Limits]).
    """

    method: str = "sh"
    out_layout: str = "same"
    size: Any = None
    exposure: float | None = None
    limits: Limits = field(default_factory=Limits, compare=False)

    def __post_init__(self) -> None:
        if self.method not in IRRADIANCE_METHODS:
            raise ShprobeError(f"method must be one of {', '.join(IRRADIANCE_METHODS)}, got "
                               f"{self.method!r}")
        if self.out_layout not in OUT_LAYOUTS:
            raise ShprobeError(f"out_layout must be one of {', '.join(OUT_LAYOUTS)}, got "
                               f"{self.out_layout!r}")
        if self.exposure is not None and not math.isfinite(self.exposure):
            raise ShprobeError(f"exposure must be a finite number, got {self.exposure!r}")

    def layout_for(self, lighting: Lighting) -> Any:
        """The map's layout object for ``lighting`` and its size argument.

        Parameters
        ----------
        lighting
            The lighting mapped.

        Returns
        -------
        tuple
            (layout, size argument).
        """
        from ..probes.layouts import get_layout

        name = self.out_layout if self.out_layout != "same" else (lighting.layout or "latlong")
        lay = get_layout(name)
        size = self.size
        if size is None:
            size = {"latlong": (256, 128), "cube": 64}.get(lay.name, 256)
        return lay, size


@dataclass(frozen=True)
class IrradianceResult:
    """What `write_irradiance_map` wrote: the file, its layout and grid (rows, columns),
    the method, the degree and the exposure applied (stops; 0 for a linear file)."""

    path: Path
    layout: str
    grid: tuple[int, ...]
    method: str
    lmax: int
    exposure: float
    auto_exposure: bool

    def as_dict(self) -> dict[str, Any]:
        """The result as JSON-able values.

        Returns
        -------
        dict
            path, layout, grid, method, lmax, exposure, auto_exposure.
        """
        return {"path": str(self.path), "layout": self.layout, "grid": list(self.grid),
                "method": self.method, "lmax": int(self.lmax), "exposure": float(self.exposure),
                "auto_exposure": self.auto_exposure}


def irradiance_map_cost(lighting: Lighting, settings: IrradianceSettings) -> Cost | None:
    """The brute-force map's time and memory on this machine (None for the SH method).

    Parameters
    ----------
    lighting
        The lighting, with its probe image.
    settings
        The map's settings.

    Returns
    -------
    Cost or None
        The estimate.
    """
    if settings.method != "brute":
        return None
    from .reference import MAP_CHUNK, reference_cost

    lay, size = settings.layout_for(lighting)
    grid = lay.grid_shape(size)
    return reference_cost(lighting.env, int(lay.valid_mask(grid).sum()), chunk=MAP_CHUNK)


def write_irradiance_map(lighting: Lighting, output: str | os.PathLike[str],
                         settings: IrradianceSettings | None = None,
                         progress: Progress | None = None, *,
                         overwrite: bool = False) -> IrradianceResult:
    """Write an irradiance environment map E(n) of ``lighting`` (R&H 2001 §3.1).

    Linear files (.exr .hdr .pfm .tif) hold E; a .png shows E/π (the radiance a white diffuse
    surface reflects), tone-mapped at ``settings.exposure`` (automatic when None).

    Parameters
    ----------
    lighting
        Its coefficients (and, for the brute-force method, its probe image).
    output
        The map's file.
    settings
        The map's `IrradianceSettings` (default: its defaults).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter (the brute-force stage).
    overwrite
        Replace an existing file.

    Returns
    -------
    IrradianceResult
        The file, layout, grid, method, degree and exposure.
    """
    from ..lighting.irradiance import irradiance_map
    from ..lighting.reference import reference_irradiance_map
    from ..probes.env import Env, write_env
    from ..probes.figures import exposure_for
    from ..probes.images import check_image_output
    from ..sh import lmax_of

    s = settings if settings is not None else IrradianceSettings()
    check_image_output(output, overwrite)
    if s.method == "brute" and lighting.env is None:
        raise ShprobeError("the brute-force map needs a probe image")
    lay, size = s.layout_for(lighting)
    with s.limits.applied():
        if s.method == "sh":
            emap = irradiance_map(lighting.coeffs, lay, size)
        else:
            emap = reference_irradiance_map(lighting.env, lay, size, progress=progress)
        shown, stops = emap, 0.0
        png = Path(output).suffix.lower() == ".png"
        if png:  # the one rule: an LDR picture shows E/π
            shown = Env(emap.radiance / np.pi, emap.layout)
            stops = (exposure_for(shown.radiance, mask=lay.valid_mask(emap.grid))
                     if s.exposure is None else s.exposure)  # pixels outside a disc: out
        write_env(output, shown, overwrite=overwrite, exposure=stops)
    return IrradianceResult(Path(output), lay.name, tuple(emap.grid), s.method,
                            lmax_of(np.asarray(lighting.coeffs).shape[0]), float(stops),
                            png and s.exposure is None)
