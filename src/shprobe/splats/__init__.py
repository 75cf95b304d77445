"""Gaussian-splat scenes: 3DGS PLY, Niantic SPZ and glTF ``KHR_gaussian_splatting`` files read,
written and transformed (rotation, mirror, uniform scale, translation, frame changes) with
every SH band moved exactly; the renderer's SH convention and converters to shprobe's.

In memory ([`Splats`][shprobe.splats.Splats]) splats keep the reference trainer's parametrisation,
frame and SH convention (`shprobe.splats.conventions`); docs/splats.md has the details.
"""

from .cloud import Splats, concatenate
from .conventions import (
                          DC_BIAS,
                          SH_C0,
                          colour_to_dc,
                          dc_to_colour,
                          from_shprobe,
                          to_shprobe,
                          view_colour,
)
from .formats import (
                          SplatInfo,
                          TransformResult,
                          TransformSettings,
                          format_of,
                          info,
                          read,
                          transform_file,
                          write,
)
from .transform import (
                          FRAMES,
                          Similarity,
                          apply,
                          frame,
                          mirror,
                          rotation,
                          sh_matrix,
                          translation,
                          uniform_scale,
)

__all__ = ["DC_BIAS", "FRAMES", "SH_C0", "Similarity", "SplatInfo", "Splats",
           "TransformResult", "TransformSettings", "apply", "colour_to_dc", "concatenate",
           "dc_to_colour", "format_of", "frame", "from_shprobe", "info", "mirror", "read",
           "rotation", "sh_matrix", "to_shprobe", "transform_file", "translation",
           "uniform_scale", "view_colour", "write"]
