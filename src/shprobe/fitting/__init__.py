"""Lighting from photographs (R&H 2001 §2–3 run backwards): a diffuse object's image keeps
only the l ≤ 2 part of the lighting, so images of an object of known shape determine the nine
coefficients L_lm through a linear least-squares problem.

- `shprobe.fitting.solve`: the 9×9 normal equations, IRLS (Huber / Tukey) rejection
  (`shprobe.fitting.robust`), conditioning per coefficient
  ([`LightingFit`][shprobe.fitting.LightingFit], `shprobe.fitting.result`);
- `shprobe.fitting.circle`: a ball's outline, given (``CX,CY,R``) or detected;
- `shprobe.fitting.ball`: grey-ball and chrome-ball photos (orthographic or perspective camera,
  `shprobe.fitting.ball_geometry`);
- `shprobe.fitting.objects`: any diffuse object — per-pixel normals, or a mesh seen by cameras, with
  optional per-vertex albedo fitted jointly;
- `shprobe.fitting.photo`: the photo read for a fit, the exposure a shprobe picture records undone.

Scene names come from [`shprobe.scene`][shprobe.scene].
"""

from .ball import (
    BallCamera,
    BallFit,
    BallPixels,
    ball_pixels,
    fit_chrome_ball,
    fit_grey_ball,
    parse_ball_camera,
)
from .circle import Circle, check_circle, detect_circle, parse_circle
from .objects import ObjectFit, fit_mesh, fit_normals, read_normal_map
from .photo import Photo, read_photo
from .solve import FitSettings, LightingFit, design_factors, fit_samples

__all__ = [
    "BallCamera",
    "BallFit",
    "BallPixels",
    "Circle",
    "FitSettings",
    "LightingFit",
    "ObjectFit",
    "Photo",
    "ball_pixels",
    "check_circle",
    "design_factors",
    "detect_circle",
    "fit_chrome_ball",
    "fit_grey_ball",
    "fit_mesh",
    "fit_normals",
    "fit_samples",
    "parse_ball_camera",
    "parse_circle",
    "read_normal_map",
    "read_photo",
]
