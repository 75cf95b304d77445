"""Pictures of relit transfer: one frame, or a turntable of the lighting turning around the
object (Lisle & Huang 2007 §4: model, degree and probe switchable at run time, no re-bake).
Uses the per-vertex renderer ``shprobe.render.render_vertex_colors``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .relight import _as_matrix, relight
from .transfer import Transfer


def axis_angle(axis: ArrayLike, degrees: float) -> NDArray[np.float64]:
    """Rotation matrix turning by ``degrees`` (right-handed) about ``axis`` (Rodrigues).

    The axis must be a finite non-zero 3-vector (any length) and the angle finite.
    """
    from ..errors import ShprobeError

    try:
        a = np.asarray(axis, dtype=np.float64)
        deg = float(degrees)
    except (TypeError, ValueError):
        raise ShprobeError(f"rotation needs a 3-vector axis and an angle, got {axis!r}, "
                           f"{degrees!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.any(a != 0):
        raise ShprobeError(f"rotation axis must be a finite non-zero 3-vector, got {axis!r}")
    if not np.isfinite(deg):
        raise ShprobeError(f"rotation angle must be finite, got {degrees!r}")
    a = a / np.abs(a).max()  # no overflow in the norm for huge components
    x, y, z = a / np.linalg.norm(a)
    t = np.radians(deg)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def frame_radiance(transfer: Transfer, coeffs: ArrayLike, rotation: ArrayLike | None = None,
                   light_rotation: ArrayLike | None = None, lmax: int | None = None,
                   mode: str | None = None, bounces: int | None = None) -> NDArray[np.float32]:
    """Per-vertex radiance (V, 3) of the scene turned by ``rotation`` under the lighting turned
    by ``light_rotation``: in the scene's frame the lighting is rotate(L, R_s⁻¹ R_l), i.e.
    ``relight`` with scene rotation R_l⁻¹ R_s (LH eq. 4–5). mode, bounces: the model, picked
    at run time (:meth:`Transfer.select`)."""
    rs = np.eye(3) if rotation is None else _as_matrix(rotation)
    rl = np.eye(3) if light_rotation is None else _as_matrix(light_rotation)
    return relight(transfer, coeffs, rotation=rl.T @ rs, lmax=lmax, mode=mode, bounces=bounces)


def render_frame(transfer: Transfer, coeffs: ArrayLike, rotation: ArrayLike | None = None,
                 light_rotation: ArrayLike | None = None, lmax: int | None = None,
                 camera: Any = None, background: Any = None, mode: str | None = None,
                 bounces: int | None = None):
    """Render the scene turned by ``rotation`` (3×3, the mesh moves) under the lighting
    ``coeffs`` turned by ``light_rotation`` (the mesh stays).

    Lighting turned by R_l and scene by R_s: in the scene's frame the lighting is
    rotate(L, R_s⁻¹ R_l), i.e. ``relight`` with scene rotation R_l⁻¹ R_s. Returns the renderer's
    RenderResult. mode, bounces: the model, picked at run time (:meth:`Transfer.select`).
    """
    import trimesh

    from ..scene.render import render_vertex_colors

    rs = np.eye(3) if rotation is None else _as_matrix(rotation)
    radiance = frame_radiance(transfer, coeffs, rs, light_rotation, lmax, mode, bounces)
    mesh = trimesh.Trimesh(transfer.vertices @ rs.T, transfer.faces,
                           vertex_normals=transfer.normals @ rs.T, process=False)
    return render_vertex_colors(mesh, radiance, camera, background=background)


def turntable(transfer: Transfer, coeffs: ArrayLike, frames: int,
              rotation: ArrayLike | None = None, lmax: int | None = None, camera: Any = None,
              axis: ArrayLike = (0.0, 1.0, 0.0), mode: str | None = None,
              bounces: int | None = None) -> Iterator[Any]:
    """``frames`` renders with the lighting turned by 360°·i/frames about ``axis`` (+Y) around
    the (fixed, optionally turned by ``rotation``) scene."""
    for i in range(int(frames)):
        yield render_frame(transfer, coeffs, rotation, axis_angle(axis, 360.0 * i / frames),
                           lmax=lmax, camera=camera, mode=mode, bounces=bounces)
