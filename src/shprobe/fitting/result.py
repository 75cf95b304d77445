"""The result of a lighting fit: [`LightingFit`][shprobe.fitting.LightingFit], the nine RGB
coefficients with their standard errors, conditioning and the pixels' weights."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..lighting.coeffs import RH_LABELS

__all__ = ["POOR_CONDITION", "LightingFit"]

#: Per-coefficient condition (see :attr:`LightingFit.conditioning`) above which a coefficient
#: is reported as poorly determined.
POOR_CONDITION = 10.0

@dataclass(repr=False)
class LightingFit:
    """Nine RGB lighting coefficients fitted to pixels, with their quality.

    ``coeffs`` (9, 3): L_lm (radiance) divided by ``albedo`` — with ``albedo`` 1 they are
    albedo × exposure × L_lm, the one scale a photograph cannot separate. ``stderr`` (9, 3):
    standard errors from the inliers' residual (σ √(G⁻¹)_kk). ``conditioning`` (9,): per
    coefficient √((Ĝ⁻¹)_kk) of the normal matrix with unit diagonal Ĝ = D G D — 1 when the
    coefficient's basis image is orthogonal to the others over the pixels used, large when
    the pixels cannot tell it from a combination of the others (a visible hemisphere).
    ``condition``: the 2-norm condition number of Ĝ. ``weights`` (P,): final IRLS weights
    relative to the prior weights (1 = fully used, 0 = rejected or clipped), ``fitted`` and
    ``residual`` (P, 3) in the pixels' units.

    Attributes
    ----------
    coeffs
        (9, 3) L_lm divided by ``albedo``.
    albedo
        The albedo (× exposure) the coefficients were divided by.
    stderr
        (9, 3) standard errors.
    conditioning
        (9,) how well each coefficient is determined (1: independently of the others).
    condition
        The normal matrix's condition number.
    weights, fitted, residual
        Per pixel: the final IRLS weights, the model's values, the residuals.
    clipped
        Per pixel: left out as clipped.
    rms
        The inliers' RMS residual.
    iterations
        IRLS iterations run.
    model
        "diffuse" or "mirror".
    info
        Further figures about the fit.
    """

    coeffs: NDArray[np.float64]
    albedo: float
    stderr: NDArray[np.float64]
    conditioning: NDArray[np.float64]
    condition: float
    weights: NDArray[np.float32]
    fitted: NDArray[np.float32]
    residual: NDArray[np.float32]
    clipped: NDArray[np.bool_]
    rms: float
    iterations: int
    model: str = "diffuse"
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def rejected(self) -> NDArray[np.bool_]:
        """(P,) pixels left out of the fit: clipped, or given weight < 0.5 by the M-estimator
        (Tukey weights fall to 0 beyond 4.685 robust standard deviations)."""
        return self.clipped | (self.weights < 0.5)

    @property
    def rejected_fraction(self) -> float:
        return float(self.rejected.mean()) if self.rejected.size else 0.0

    @property
    def poorly_determined(self) -> tuple[str, ...]:
        """Labels (L00 … L22) of the coefficients whose conditioning exceeds
        `POOR_CONDITION`."""
        return tuple(RH_LABELS[k] for k in np.flatnonzero(self.conditioning > POOR_CONDITION))

    def summary(self) -> str:
        """One line: RMS residual, fraction rejected, poorly determined coefficients.

        Returns
        -------
        str
            One line about the fit's quality.
        """
        poor = ", ".join(self.poorly_determined) or "none"
        what = "RMS residual" if self.model == "diffuse" else "RMS detail above l = 2"
        return (f"{self.weights.size} pixels, {what} {self.rms:.4g} "
                f"({100 * self.info.get('rms_relative', 0.0):.2f} % of the mean), "
                f"{100 * self.rejected_fraction:.2f} % rejected "
                f"({int(self.clipped.sum())} clipped), condition {self.condition:.3g}, "
                f"poorly determined: {poor}")

    def __repr__(self) -> str:
        return (f"LightingFit(model={self.model!r}, pixels={self.weights.size}, "
                f"rms={self.rms:.4g}, rejected={100 * self.rejected_fraction:.2f}%, "
                f"condition={self.condition:.3g})")
