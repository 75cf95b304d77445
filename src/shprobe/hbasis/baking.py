"""The H-basis bake as a workflow: [`HBasisSettings`][shprobe.hbasis.HBasisSettings] (the defaults
``shprobe hbasis bake`` reads) and its one entry, [`bake_hbasis`][shprobe.hbasis.bake_hbasis], over
[`shprobe.hbasis.normalmap.bake_mesh`][shprobe.hbasis.normalmap.bake_mesh] (Habel & Wimmer 2010
§4–5: per-vertex tangent-space H coefficients)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..errors import ShprobeError
from ..limits import Limits
from ..progress import Progress, stage
from .normalmap import NormalMapBake, bake_mesh

__all__ = ["BASES", "HBasisSettings", "bake_hbasis"]

#: The bases a bake can store, by name: the H coefficients per vertex.
BASES = {"h6": 6, "h4": 4}


@dataclass(frozen=True)
class HBasisSettings:
    """Settings of an H-basis bake ([`bake_hbasis`][shprobe.hbasis.bake_hbasis]); the defaults are
    the CLI's.

    Parameters
    ----------
    basis
        'h6' (6 coefficients per vertex and channel) or 'h4'.
    bands
        SH bands (2..16) of the irradiance projected into H: 2 is the paper's T_h, 4 adds
        Appendix A's bands.
    limits
        The memory limit the bake is refused over
        ([`shprobe.limits.Limits`][shprobe.limits.Limits]).
    """

    basis: str = "h6"
    bands: int = 4
    limits: Limits = field(default_factory=Limits, compare=False)

    def __post_init__(self) -> None:
        if self.basis not in BASES:
            raise ShprobeError(f"basis must be one of {', '.join(BASES)}, got {self.basis!r}")
        b = self.bands
        if isinstance(b, bool) or not isinstance(b, int) or not 2 <= b <= 16:
            raise ShprobeError(f"bands must be an integer in 2..16, got {b!r}")

    def as_dict(self) -> dict[str, Any]:
        """The settings as JSON-able values.

        Returns
        -------
        dict
            basis, bands and limits.
        """
        return {"basis": self.basis, "bands": self.bands, "limits": self.limits.as_dict()}


def bake_hbasis(mesh: Any, lighting: Any, settings: HBasisSettings | None = None,
                progress: Progress | None = None) -> NormalMapBake:
    """Bake per-vertex tangent-space H coefficients of ``mesh`` under ``lighting``.

    Parameters
    ----------
    mesh
        A trimesh mesh ([`shprobe.load_mesh`][shprobe.scene.load_mesh]).
    lighting
        An [`shprobe.Env`][shprobe.probes.env.Env] (the probe image) or radiance SH (K, 3).
    settings
        The bake's [`HBasisSettings`][shprobe.hbasis.HBasisSettings] (default: its defaults).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter (one stage).

    Returns
    -------
    NormalMapBake
        The coefficients, frames, the lighting's SH and the mesh hash (`save_bake`
        writes it; ``as_dict()`` summarises it).
    """
    s = settings if settings is not None else HBasisSettings()
    with s.limits.applied(), stage(progress, f"baking {s.basis.upper()} at "
                                             f"{len(mesh.vertices):,} vertices"):
        return bake_mesh(mesh, lighting, n=BASES[s.basis], bands=s.bands)
