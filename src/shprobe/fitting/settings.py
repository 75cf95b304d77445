"""How lighting is fitted to pixels: [`FitSettings`][shprobe.fitting.FitSettings], the one defaults
table of the fits (``shprobe fit`` reads it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["IRLS_SAMPLES", "MAX_RADIUS", "FitSettings"]

#: Pixels used for the IRLS iterations; the final weighted solve uses every pixel.
IRLS_SAMPLES = 1 << 16
#: A grey ball of a larger radius (pixels) is fitted on block means of the photo
#: (:func:`shprobe.fitting.ball.fit_grey_ball`).
MAX_RADIUS = 512.0


@dataclass(frozen=True)
class FitSettings:
    """How lighting is fitted to pixels ([`fit_samples`][shprobe.fitting.fit_samples] and the photo
    fits of [`shprobe.fitting`][shprobe.fitting]); the defaults are ``shprobe fit``'s.

    Parameters
    ----------
    model
        'diffuse' (value = ρ E(n)/π) or 'mirror' (value = ρ L(ω)).
    saturation
        Pixels with any channel at or above it are clipped and left out (None: none).
    black
        Pixels with any channel at or below it are left out (None: none).
    robust
        The MM-estimator (outliers rejected), else plain weighted least squares.
    scale_floor
        The residual scale never falls below this × the mean |value|.
    max_iter
        Iterations of the robust fit.
    irls_samples
        The most pixels the robust iterations run on (a fixed random subset).
    seed
        Seed of the subsets.
    max_radius
        A grey ball of a larger radius (pixels) is fitted on block means (None: never).
    """

    model: str = "diffuse"
    saturation: float | None = None
    black: float | None = None
    robust: bool = True
    scale_floor: float = 0.02
    max_iter: int = 30
    irls_samples: int = IRLS_SAMPLES
    seed: int = 0
    max_radius: float | None = MAX_RADIUS

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            Each field.
        """
        return {f: getattr(self, f) for f in self.__dataclass_fields__}
