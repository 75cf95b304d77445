"""The photo a fit reads: linear radiance, with the exposure a shprobe picture records undone.

A picture written by shprobe (``shprobe render -o ball.png``) is the radiance × 2^EV, sRGB
encoded, with EV in its metadata (`shprobe.probes.codecs.read_exposure`); reading it
back divides by 2^EV, so a fit returns the lighting the picture was rendered with. A photo
without that metadata is fitted as it is: its coefficients carry the photo's own (unknown)
exposure, which the fit's document says.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..probes.codecs import read_exposure
from ..probes.images import LDRWarning, read_image
from .solve import check_level

#: The default clipping level of 8/16-bit photos, in the file's linear units: the top code
#: value and anything that rounds to it.
LDR_SATURATION = 0.999


@dataclass(frozen=True)
class Photo:
    """``image`` (H, W, 3) linear radiance, the recorded exposure undone; ``ldr`` whether the
    file was 8/16-bit (sRGB-decoded); ``exposure`` the EV shprobe recorded (None for a photo
    without it); ``path`` the file.

    Attributes
    ----------
    image
        (H, W, 3) linear radiance, the recorded exposure undone.
    ldr
        Whether the file was 8/16-bit (sRGB-decoded).
    exposure
        The EV shprobe recorded, or None.
    path
        The file.
    """

    image: NDArray[np.float32]
    ldr: bool
    exposure: float | None
    path: str

    @property
    def scale(self) -> float:
        """What the file's linear values were multiplied by: 2^−EV (1 without metadata)."""
        return 1.0 if self.exposure is None else float(2.0 ** -self.exposure)

    def saturation(self, level: float | None = None) -> float | None:
        """The clipping level in `image`'s units: ``level`` is in the file's linear
        values (default: `LDR_SATURATION` for 8/16-bit files, none for HDR).

        Parameters
        ----------
        level
            The clipping level in the file's linear values (default: the LDR level for 8/16-bit
            files, none for HDR).

        Returns
        -------
        float or None
            The level in ``image``'s units.
        """
        check_level(level, "saturation")
        if level is None and self.ldr:
            level = LDR_SATURATION
        return None if level is None else float(level) * self.scale

    def __repr__(self) -> str:
        ev = "no exposure recorded" if self.exposure is None else f"{self.exposure:+.3g} EV undone"
        h, w = self.image.shape[:2]
        return f"Photo({self.path!r}, {w}x{h}, {'8/16-bit' if self.ldr else 'HDR'}, {ev})"


def read_photo(path: str | os.PathLike[str]) -> Photo:
    """Read a photo for fitting (see the module docstring). An 8/16-bit file issues one
    [`LDRWarning`][shprobe.probes.images.LDRWarning], as
    [`read_image`][shprobe.probes.images.read_image].

    Parameters
    ----------
    path
        The photo's file.

    Returns
    -------
    Photo
        Its linear pixels, with the exposure shprobe recorded undone.
    """
    p = os.fspath(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LDRWarning)
        img = read_image(p)
    ldr = any(issubclass(w.category, LDRWarning) for w in caught)
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    ev = read_exposure(p)
    if ev:
        img = img * np.float32(2.0 ** -ev)
    return Photo(img, ldr, ev, p)
