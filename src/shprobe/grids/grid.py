"""A grid of SH irradiance probes (an irradiance volume) and its engine-side interpolation.

The volume ``bounds`` is split into one cell per probe, the probes at the cell centres, the
convention of three.js's ``LightProbeGrid`` (so the three.js export is the data as it stands).
Each probe holds the radiance L_lm it sees (R&H 2001 eq. 6), RGB, in the world frame (+Y up,
shprobe's real SH); irradiance is Â_l L_lm (R&H eq. 7) at the normal.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting.irradiance import irradiance_coeffs, unit_normals
from ..sh.basis import sh_basis
from ..sh.indexing import lmax_of
from .cells import cell_centres, cell_probes

__all__ = ["GRID_FORMAT", "GRID_VERSION", "ProbeGrid", "cell_centres", "plain_weights"]

#: The ``format`` string of a grid file and its version.
GRID_FORMAT = "shprobe-grid"
GRID_VERSION = 1


@dataclass(frozen=True, repr=False)
class ProbeGrid:
    """An irradiance volume.

    Parameters
    ----------
    coeffs
        (NX, NY, NZ, (lmax+1)², 3) radiance L_lm per probe (lmax 1 or 2).
    bounds
        (2, 3) the volume's min and max corners (probes at cell centres).
    positions
        (NX, NY, NZ, 3) where each probe was baked, when a probe was moved out of geometry
        (None: the cell centres).
    validity
        (NX, NY, NZ) in [0, 1], 0 for a probe that was inside geometry and whose value is
        filled from its neighbours (None: all valid).
    depth
        (NX, NY, NZ, D, D, 2) mean and mean-square distance to the first hit over an
        octahedral map of directions (None: no visibility data, interpolation is plain
        trilinear).
    meta
        How it was baked (lmax, bounces, albedo, samples, lighting, scene).
    """

    coeffs: NDArray[np.float32]
    bounds: NDArray[np.float64]
    positions: NDArray[np.float64] | None = None
    validity: NDArray[np.float32] | None = None
    depth: NDArray[np.float32] | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        c = np.asarray(self.coeffs)
        if c.ndim != 5 or c.shape[-1] != 3 or c.shape[-2] not in (4, 9) or min(c.shape[:3]) < 1:
            raise ShprobeError(f"grid coefficients must be (NX, NY, NZ, 4 or 9, 3), got {c.shape}")
        b = np.asarray(self.bounds, dtype=np.float64)
        if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
            raise ShprobeError("grid bounds must be finite (min corner, max corner) with "
                               "max > min on every axis")
        object.__setattr__(self, "bounds", b)
        n = c.shape[:3]
        for name, tail in (("positions", (3,)), ("validity", ()), ("depth", None)):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.asarray(a)
            if a.shape[:3] != n or (tail is not None and a.shape[3:] != tail):
                raise ShprobeError(f"grid {name} has shape {a.shape}, not that of its "
                                   f"{n} probes")

    # ------------------------------------------------------------------ shape
    @property
    def resolution(self) -> tuple[int, int, int]:
        """Probes along X, Y, Z."""
        nx, ny, nz = self.coeffs.shape[:3]
        return int(nx), int(ny), int(nz)

    @property
    def lmax(self) -> int:
        return lmax_of(self.coeffs.shape[-2])

    @property
    def spacing(self) -> NDArray[np.float64]:
        """Cell size along X, Y, Z."""
        return (self.bounds[1] - self.bounds[0]) / np.asarray(self.resolution, dtype=np.float64)

    def centres(self) -> NDArray[np.float64]:
        """Cell centres (NX, NY, NZ, 3): where the probes stand unless moved.

        Returns
        -------
        ndarray of shape (NX, NY, NZ, 3)
            The cell centres.
        """
        return cell_centres(self.bounds, self.resolution)

    def probe_positions(self) -> NDArray[np.float64]:
        """Where each probe was baked (NX, NY, NZ, 3).

        Returns
        -------
        ndarray of shape (NX, NY, NZ, 3)
            Where each probe was baked.
        """
        return self.centres() if self.positions is None else np.asarray(self.positions,
                                                                        dtype=np.float64)

    # ------------------------------------------------------------------ lighting
    def interpolate(self, points: ArrayLike, normals: ArrayLike,
                    leak_control: bool = True) -> NDArray[np.float64]:
        """Radiance coefficients (..., (lmax+1)², 3) seen at ``points`` for surfaces facing
        ``normals`` (both (..., 3)): the engine-side blend of the neighbouring probes.

        Plain (``leak_control=False``, or a grid without depth data): three.js's
        ``LightProbeGrid`` sampling — the point moved half a cell along the normal, clamped to
        the outermost probe centres, trilinear weights.

        Parameters
        ----------
        points
            (..., 3) positions.
        normals
            (..., 3) normals of the surfaces there.
        leak_control
            Weigh probes by visibility (needs depth data); False: three.js's plain trilinear.

        Returns
        -------
        ndarray of shape (..., (lmax+1)², 3)
            The blended radiance coefficients.
        """
        p, n = _points_normals(points, normals)
        if leak_control and self.depth is not None:
            from .visibility import visibility_weights

            idx, w = visibility_weights(self, p, n)
        else:
            idx, w = plain_weights(self.bounds, self.resolution, p, n)
        from ._kernels import blend

        c = np.asarray(self.coeffs, dtype=np.float64).reshape(-1, *self.coeffs.shape[-2:])
        out = np.zeros((int(np.prod(w.shape[:-1])), *c.shape[1:]))
        blend(np.ascontiguousarray(idx.reshape(-1, idx.shape[-1]), dtype=np.int64),
              np.ascontiguousarray(w.reshape(-1, w.shape[-1]), dtype=np.float64), c, out)
        return out.reshape(*w.shape[:-1], *c.shape[1:])

    def irradiance(self, points: ArrayLike, normals: ArrayLike,
                   leak_control: bool = True) -> NDArray[np.float64]:
        """Irradiance E (..., 3) at ``points`` on surfaces facing ``normals`` (R&H eq. 7 on the
        interpolated L_lm), clamped at 0 as three.js's shader does.

        Parameters
        ----------
        points
            (..., 3) positions.
        normals
            (..., 3) normals of the surfaces there.
        leak_control
            Weigh probes by visibility (needs depth data).

        Returns
        -------
        ndarray of shape (..., 3)
            E, clamped at 0.
        """
        n = unit_normals(normals)
        c = irradiance_coeffs(self.interpolate(points, n, leak_control))
        y = sh_basis(n, self.lmax)
        return np.maximum(np.einsum("...k,...kc->...c", y, c), 0.0)

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary of the grid (not its arrays): what the CLI prints from.

        Returns
        -------
        dict
            resolution, lmax, bounds, whether it has leak control, and how it was baked
            (``meta``: bounces, samples, lighting, probes moved and invalid, seconds, …).
        """
        import json

        lo, hi = self.bounds
        return {"resolution": list(self.resolution), "lmax": int(self.lmax),
                "bounds": [np.asarray(lo, float).tolist(), np.asarray(hi, float).tolist()],
                "leak_control": self.depth is not None,
                "meta": json.loads(json.dumps(dict(self.meta), default=str))}

    def __repr__(self) -> str:
        nx, ny, nz = self.resolution
        lo, hi = self.bounds
        extra = ", leak control" if self.depth is not None else ""
        return (f"ProbeGrid({nx}×{ny}×{nz}, lmax {self.lmax}, bounds "
                f"{np.round(lo, 3).tolist()}..{np.round(hi, 3).tolist()}{extra})")


def plain_weights(bounds: ArrayLike, resolution: tuple[int, int, int], points: NDArray,
                  normals: NDArray) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Flat probe indices (..., 8) and trilinear weights (..., 8) as three.js samples its
    ``LightProbeGrid`` texture: sample point p + n·spacing/2, clamped to the outer probe
    centres, hardware trilinear filtering between cell centres.

    Parameters
    ----------
    bounds
        (2, 3) the grid's corners.
    resolution
        Probes along x, y and z.
    points
        (..., 3) positions.
    normals
        (..., 3) normals at the positions.

    Returns
    -------
    tuple
        Flat probe indices (..., 8) and trilinear weights (..., 8).
    """
    b = np.asarray(bounds, dtype=np.float64)
    spacing = (b[1] - b[0]) / np.asarray(resolution, dtype=np.float64)
    return cell_probes(b, resolution, points + normals * spacing * 0.5)


def _points_normals(points: ArrayLike, normals: ArrayLike
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    p = np.asarray(points, dtype=np.float64)
    n = unit_normals(normals)
    if p.shape[-1:] != (3,) or not np.all(np.isfinite(p)):
        raise ShprobeError("grid lookup points must be finite (..., 3) arrays")
    p, n = np.broadcast_arrays(p, n)
    return p, n
