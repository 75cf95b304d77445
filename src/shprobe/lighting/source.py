"""Where the lighting comes from: one resolver for a probe image (or six cube faces), an R&H
preset, a coefficient file in any export format, or an analytic cone light. Every command, the
viewer and the batch call `resolve_lighting`."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..probes.env import Env, load_env
from ..probes.presets import get_preset
from ..sh import check_lmax, lmax_of, num_coeffs
from ..sh.rotation import unit_vectors
from ..sh.zonal import circular_window
from .coeffs import as_rgb
from .document import coeffs_document
from .export import import_coeffs
from .projection import project, project_file

__all__ = ["STREAM_ABOVE_BYTES", "Lighting", "SourceChoiceError", "blend_lighting",
           "read_coeff_file", "resolve_lighting"]


class SourceChoiceError(ShprobeError):
    """The lighting source was not given as `resolve_lighting` needs it: ``given`` lists
    what was given ('a probe', 'a preset', ...); ``need_env`` is True when a probe image was
    needed and something else was given. Commands reword it with their option names."""

    def __init__(self, message: str, given: Sequence[str], need_env: bool = False) -> None:
        super().__init__(message)
        self.given, self.need_env = tuple(given), need_env

ProbeArg = str | os.PathLike[str] | Sequence[str | os.PathLike[str]]


@dataclass(frozen=True)
class Lighting:
    """Resolved lighting: ``coeffs`` (K, 3) L_lm; ``source`` a name for people and documents;
    ``layout`` the probe's layout name (None without a probe); ``env`` the probe (or None)."""

    coeffs: NDArray[np.float64]
    source: str
    layout: str | None = None
    env: Env | None = None

    def as_dict(self) -> dict[str, Any]:
        """The JSON document of the coefficients (``shprobe prefilter --format json``).

        Returns
        -------
        dict
            [`coeffs_document`][shprobe.lighting.coeffs_document] of the coefficients, their
            source and layout (JSON-able).
        """
        return coeffs_document(self.coeffs, self.source, self.layout)

    def __repr__(self) -> str:
        return (f"Lighting({self.source!r}, lmax={lmax_of(self.coeffs.shape[0])}"
                + (f", layout={self.layout!r}" if self.layout else "") + ")")


#: Probes whose decoded float32 RGB would exceed this are streamed (when the image itself is
#: not needed).
STREAM_ABOVE_BYTES = 256 << 20


def _streamed(probe: str | os.PathLike[str], layout: str | None, lmax: int | None,
              clamp: bool) -> Lighting | None:
    from ..probes.streaming import image_size

    if layout in ("angular", "mirrorball") or not os.path.isfile(probe):
        return None
    w, h = image_size(probe)
    if 12 * w * h <= STREAM_ABOVE_BYTES:
        return None
    fp = project_file(probe, 2 if lmax is None else lmax, layout, clamp)
    return Lighting(fp.coeffs, os.fspath(probe), fp.layout)


def resolve_lighting(probe: ProbeArg | None = None, preset: str | None = None,
                     coeffs: str | os.PathLike[str] | None = None,
                     cone: tuple[Any, float] | None = None, layout: str | None = None,
                     lmax: int | None = 2, clamp: bool = False,
                     need_env: bool = False) -> Lighting:
    """Exactly one of ``probe`` / ``preset`` / ``coeffs`` (a file) / ``cone`` → coefficients.

    A probe (a path, or six cube-face paths +X −X +Y −Y +Z −Z) is read in ``layout`` (None or
    'auto': detected) and projected to ``lmax`` (R&H eq. 10). A preset (lmax 2) or coefficient
    file (any export format; one channel is repeated to RGB) is cut to ``lmax`` when that is
    lower, and refused when it is higher; ``lmax=None`` keeps its own degree (a probe then uses
    2). ``cone`` = (axis, aperture in degrees) is the LH §3.2 circular window (LH eq. 11, their
    normalisation: total power 4π) at ``lmax`` (default 2). ``need_env`` refuses sources
    without a probe image.

    A lat-long or cube probe whose decoded image would pass `STREAM_ABOVE_BYTES` is
    projected block by block straight from the file (`project_file`, bounded memory) unless
    ``need_env`` asks for the image itself.
    """
    given = [n for n, v in (("a probe", probe), ("a preset", preset),
                            ("a coefficient file", coeffs), ("a cone light", cone))
             if v is not None and v != "" and v != []]
    if len(given) != 1:
        raise SourceChoiceError("give exactly one lighting source: a probe, a preset, a "
                                "coefficient file or a cone light "
                                f"(got {', '.join(given) or 'none'})", given)
    if need_env and probe is None:
        raise SourceChoiceError(f"this needs a probe image, not {given[0]}", given, True)
    if probe is not None and not need_env and isinstance(probe, str | os.PathLike):
        streamed = _streamed(probe, layout, lmax, clamp)
        if streamed is not None:
            return streamed
    if probe is not None:
        faces = not isinstance(probe, str | os.PathLike)
        if faces and layout not in (None, "auto", "cube"):
            raise ShprobeError(f"six face images make a cube map, not layout {layout}")
        env = load_env(probe, layout=None if faces or layout == "auto" else layout,
                       clamp=clamp)
        paths = [os.fspath(p) for p in probe] if faces else [os.fspath(probe)]
        name = paths[0] if not faces else f"{paths[0]} … {paths[-1]} (cube faces)"
        return Lighting(project(env, 2 if lmax is None else lmax), name, env.layout.name, env)
    if cone is not None:
        axis, aperture = cone
        ap = float(aperture)
        if not 0 < ap <= 180:
            raise ShprobeError(f"cone aperture must be in (0, 180] degrees, got {aperture}")
        c = circular_window(unit_vectors(axis, "cone axis"), np.radians(ap),
                            check_lmax(2 if lmax is None else lmax))
        return Lighting(as_rgb(c), f"cone {ap:g}°")
    if preset is not None:
        c, name, where = get_preset(preset), f"preset:{preset}", None
    else:
        where = os.fspath(coeffs)
        c, name = read_coeff_file(where), where
    if lmax is not None:
        own = lmax_of(c.shape[0])
        if check_lmax(lmax) > own:
            raise ShprobeError(f"has coefficients up to lmax={own}, not {lmax}", where or name)
        c = c[: num_coeffs(lmax)]
    return Lighting(np.asarray(c, dtype=np.float64), name)


def read_coeff_file(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Lighting coefficients L_lm (K, 3) from a file: any export format, or an .npy / .npz of
    L_lm (K, 3) or (K,) ([`import_coeffs`][shprobe.lighting.import_coeffs], which reads the arrays
    through the checked [`shprobe.files.load_npz`][shprobe.files.load_npz]). One channel is repeated
    to RGB."""
    p = os.fspath(path)
    return as_rgb(import_coeffs(p), p)


def blend_lighting(blend: Any, lmax: int, layout: str | None = None,
                   clamp: bool = False) -> NDArray[np.float64]:
    """The coefficients of a `Blend` at ``lmax``, as
    ``shprobe edit --blend`` reads them: a preset, a probe image (projected to ``lmax`` in
    ``layout``) or a coefficient file (cut or zero-padded by the edit)."""
    from ..probes.images import READ_EXTENSIONS

    if blend.kind == "preset":
        return resolve_lighting(preset=blend.name, lmax=None).coeffs
    if blend.kind != "file":
        raise ShprobeError(f"blend probe {blend.name} is not loaded here")
    if os.path.splitext(blend.name)[1].lower() in READ_EXTENSIONS:  # a probe image
        return resolve_lighting(blend.name, layout=layout, lmax=lmax, clamp=clamp).coeffs
    return resolve_lighting(coeffs=blend.name, lmax=None).coeffs
