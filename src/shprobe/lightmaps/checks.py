"""Bad input, refused in one line before any work: a scene without geometry, non-finite or
absurd coordinates, degenerate UVs, unreadable lighting."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .scene import LightmapScene

__all__ = ["MAX_COORD", "check_scene", "sky_coeffs"]

#: coordinates beyond this are refused (float32 ray tracing could not resolve the scene)
MAX_COORD = 1e12


def check_scene(scene: LightmapScene) -> None:
    """Refuse a scene that cannot be baked, in one line naming the file and the problem.

    Parameters
    ----------
    scene : LightmapScene
        The loaded scene.
    """
    where = scene.path
    prims = [p for p in scene.primitives if len(p.faces)]
    if not prims:
        raise ShprobeError("has no triangles to bake (no geometry)", where)
    for i, p in enumerate(prims):
        v = p.positions
        if not np.isfinite(v).all():
            raise ShprobeError(f"primitive {i} has NaN or infinite vertex coordinates", where)
        if np.abs(v).max() > MAX_COORD:
            raise ShprobeError(f"primitive {i} has vertex coordinates beyond ±{MAX_COORD:g} "
                               f"(largest {np.abs(v).max():.3g})", where)
        for name in ("uv0", "uv1", "normals", "tangents"):
            a = getattr(p, name)
            if a is not None and (len(a) != len(v) or not np.isfinite(a).all()):
                raise ShprobeError(f"primitive {i}'s {name} are not finite or do not match its "
                                   "vertices", where)
        if p.uv1 is not None and _degenerate(p.uv1, p.faces) > 0.5:
            raise ShprobeError(f"primitive {i}'s TEXCOORD_1 is degenerate (most triangles have "
                               "zero UV area)", where)
        if p.normal_texture is not None and p.uv0 is None:
            raise ShprobeError(f"primitive {i} has a normal map but no TEXCOORD_0", where)
        if p.normal_texture is not None and _degenerate(p.uv0, p.faces) > 0.5:
            raise ShprobeError(f"primitive {i}'s TEXCOORD_0 is degenerate (most triangles have "
                               "zero UV area): no tangent frame for its normal map", where)
    area = sum(_area3(p.positions, p.faces) for p in prims)
    if not area > 0:
        raise ShprobeError("has only degenerate (zero-area) triangles", where)


def _degenerate(uv: NDArray, faces: NDArray) -> float:
    t = uv[faces]
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    a = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return float((a <= 1e-14).mean()) if len(a) else 1.0


def _area3(p: NDArray, f: NDArray) -> float:
    t = p[f]
    return float(np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def sky_coeffs(lighting: Any) -> NDArray[np.float64]:
    """World radiance SH (9, 3) of a lighting: a ``Lighting`` or coefficients (K ≥ 9, 3|1).

    Parameters
    ----------
    lighting : Lighting or array_like
        The distant environment (its SH are cut to lmax 2).

    Returns
    -------
    ndarray (9, 3)
        L_lm, lmax 2.
    """
    if lighting is None:
        raise ShprobeError("no lighting given: a probe, a preset or SH coefficients")
    c = np.asarray(getattr(lighting, "coeffs", lighting), dtype=np.float64)
    if c.ndim == 1:
        c = c[:, None]
    if c.ndim != 2 or c.shape[0] < 9 or c.shape[1] not in (1, 3):
        raise ShprobeError(f"lighting coefficients must be (K >= 9, 3), got {c.shape}")
    if not np.isfinite(c).all():
        raise ShprobeError("lighting coefficients hold NaN or infinite values")
    return np.ascontiguousarray(np.broadcast_to(c[:9], (9, 3)))
