"""The document of a fit: the coefficients as ``shprobe prefilter --format json`` writes them
with the fit's quality (the fits' ``as_dict``, ``shprobe fit --format json``). It knows the fit
results by their fields, so the result classes can call it without an import cycle."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..lighting.coeffs import RH_LABELS
from ..lighting.document import coeffs_document
from .result import POOR_CONDITION

if TYPE_CHECKING:
    from .photo import Photo

__all__ = ["FitDocument", "fit_document"]


def fit_document(result: Any, source: str | None = None, photo: Photo | None = None
                 ) -> dict[str, Any]:
    """The document of ``shprobe prefilter --format json`` (``coefficients`` …) with a
    ``fit`` object: quality, standard errors and conditioning per coefficient, the circle,
    and, given the ``photo``, the exposure its metadata recorded (undone before the fit) or
    null with the scale the coefficients then carry.

    Parameters
    ----------
    result
        A ball's fit ([`BallFit`][shprobe.fitting.BallFit]) or an object's
        ([`ObjectFit`][shprobe.fitting.ObjectFit]).
    source
        The photo's name for the document (None: none).
    photo
        The photo read for the fit, for the exposure it recorded (None: not known).

    Returns
    -------
    dict
        The coefficient document with its ``fit`` object (JSON-able).
    """
    f = result.fit
    doc = coeffs_document(f.coeffs, source, "photo")
    q: dict[str, Any] = {
        "model": f.model, "pixels": int(f.weights.size), "rms_residual": f.rms,
        "rms_relative": f.info.get("rms_relative"), "rejected_fraction": f.rejected_fraction,
        "clipped": int(f.clipped.sum()), "albedo": f.albedo,
        "scale_note": "coefficients = L_lm x (albedo x exposure) / albedo",
        "photo_exposure": None if photo is None else photo.exposure,
        "stderr": f.stderr.tolist(), "conditioning": dict(zip(RH_LABELS, f.conditioning.tolist(),
                                                              strict=True)),
        "condition": f.condition, "poor_condition_threshold": POOR_CONDITION,
        "poorly_determined": list(f.poorly_determined), "summary": result.summary(),
    }
    if getattr(result, "circle", None) is not None:  # a ball's fit (BallFit)
        full = result.info.get("circle_full", result.circle)
        q.update(kind=result.kind, circle=[full.cx, full.cy, full.r], binning=result.binning,
                 camera=str(result.camera), frame="camera: looking along -Z, +Y up, +X right")
        if result.kind == "chrome":
            q.update(blind_spot_degrees=result.blind_angle,
                     blind_spot_sr=result.blind_solid_angle,
                     clipped_kept=result.info.get("clipped", 0))
    else:
        q.update(views=len(result.views), frame="world")
        if result.vertex_albedo is not None:
            q.update(albedo_rounds=result.info.get("albedo_iterations"))
    if photo is not None and photo.exposure is not None:
        q["scale_note"] = (f"the photo's recorded exposure ({photo.exposure:+.6g} EV) was "
                           "undone: coefficients = L_lm x albedo / albedo")
    doc["fit"] = q
    return doc


class FitDocument:
    """What every fit result offers: its JSON document (`fit_document`)."""

    def as_dict(self, source: str | None = None, photo: Photo | None = None) -> dict[str, Any]:
        """The fit's JSON document: the coefficients with the fit's quality
        (`shprobe.fitting.document.fit_document`, ``shprobe fit --format json``).

        Parameters
        ----------
        source
            The photo's name for the document (None: none).
        photo
            The photo read for the fit, for the exposure it recorded (None: not known).

        Returns
        -------
        dict
            JSON-able values.
        """
        return fit_document(self, source, photo)
