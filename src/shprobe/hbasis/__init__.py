"""The H-basis and rival hemispherical bases (Habel & Wimmer 2010).

* `shprobe.hbasis.basis` — H4/H6 (eq. 8–13), T_h (SH → H), hemispherical quadrature and projection.
* `shprobe.hbasis.rivals` — HL2, HSH, Makhotkin, Zernike, least-squares SH: one ``HemiBasis``
  interface.
* `shprobe.hbasis.study` — the Fig. 3 IMSE study.
* `shprobe.hbasis.frames` — per-vertex tangent frames, world SH turned into a frame.
* `shprobe.hbasis.normalmap` — per-vertex bakes (``bake_normalmap``, ``bake_mesh``), shading, normal
  maps.
* `shprobe.hbasis.bakefile` — bake files (``save_bake`` / ``load_bake``).
* `shprobe.hbasis.rendering` — normal-mapped rendering through the scene layer against the exact
  reference, and its comparison figure.

Conventions: docs/hbasis.md.
"""

from __future__ import annotations

from .baking import HBasisSettings, bake_hbasis
from .basis import (
    T_H4_PAPER,
    T_H_CLOSED_FORM,
    evaluate_h,
    h_basis,
    hemisphere_quadrature,
    project_h,
    sh_to_h,
    sh_to_h_matrix,
)
from .rivals import HemiBasis, all_bases, get_basis

__all__ = [
    "T_H4_PAPER",
    "T_H_CLOSED_FORM",
    "HBasisSettings",
    "HemiBasis",
    "all_bases",
    "bake_hbasis",
    "evaluate_h",
    "get_basis",
    "h_basis",
    "hemisphere_quadrature",
    "project_h",
    "sh_to_h",
    "sh_to_h_matrix",
]
