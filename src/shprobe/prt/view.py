"""Pictures of relit transfer: one frame, or a turntable of the lighting turning around the
object (Lisle & Huang 2007 §4: model, degree and probe switchable at run time, no re-bake).
Uses the per-vertex renderer ``shprobe.scene.render_vertex_colors``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..sh.rotation import from_axis_angle, one_rotation
from .relighting import relight
from .transfer import Transfer


def frame_radiance(transfer: Transfer, coeffs: ArrayLike, rotation: ArrayLike | None = None,
                   light_rotation: ArrayLike | None = None, lmax: int | None = None,
                   mode: str | None = None, bounces: int | None = None) -> NDArray[np.float32]:
    """Per-vertex radiance (V, 3) of the scene turned by ``rotation`` under the lighting turned
    by ``light_rotation``: in the scene's frame the lighting is rotate(L, R_s⁻¹ R_l), i.e.
    ``relight`` with scene rotation R_l⁻¹ R_s (LH eq. 4–5). mode, bounces: the model, picked
    at run time ([`Transfer.select`][shprobe.prt.Transfer.select])."""
    rs = np.eye(3) if rotation is None else one_rotation(rotation)
    rl = np.eye(3) if light_rotation is None else one_rotation(light_rotation)
    return relight(transfer, coeffs, rotation=rl.T @ rs, lmax=lmax, mode=mode, bounces=bounces)


def render_frame(transfer: Transfer, coeffs: ArrayLike, rotation: ArrayLike | None = None,
                 light_rotation: ArrayLike | None = None, lmax: int | None = None,
                 camera: Any = None, background: Any = None, mode: str | None = None,
                 bounces: int | None = None):
    """Render the scene turned by ``rotation`` (3×3, the mesh moves) under the lighting
    ``coeffs`` turned by ``light_rotation`` (the mesh stays).

    Lighting turned by R_l and scene by R_s: in the scene's frame the lighting is
    rotate(L, R_s⁻¹ R_l), i.e. ``relight`` with scene rotation R_l⁻¹ R_s. Returns the renderer's
    RenderResult. mode, bounces: the model, picked at run time
    ([`Transfer.select`][shprobe.prt.Transfer.select]).
    """
    import trimesh

    from ..scene.render import render_vertex_colors

    rs = np.eye(3) if rotation is None else one_rotation(rotation)
    radiance = frame_radiance(transfer, coeffs, rs, light_rotation, lmax, mode, bounces)
    mesh = trimesh.Trimesh(transfer.vertices @ rs.T, transfer.faces,
                           vertex_normals=transfer.normals @ rs.T, process=False)
    return render_vertex_colors(mesh, radiance, camera, background=background,
                                frame=object_frame(transfer, rs))


def object_frame(transfer: Transfer, rotation: ArrayLike | None = None
                 ) -> tuple[NDArray[np.float64], float] | None:
    """The bounding sphere of the scene's objects without its ground plane (which is several
    times larger: framing it would leave the objects a quarter of the picture), turned by
    ``rotation``; None when the bake has no ground."""
    if not transfer.metadata.get("ground"):
        return None
    v, n = transfer.vertices, transfer.normals
    floor = v[:, 1].min()
    tol = 1e-9 * float(np.ptp(v, axis=0).max())
    ground = (v[:, 1] <= floor + tol) & (n[:, 1] > 1.0 - 1e-9)
    obj = v[~ground] if (~ground).any() else v
    rs = np.eye(3) if rotation is None else one_rotation(rotation)
    lo, hi = obj.min(axis=0), obj.max(axis=0)
    c = 0.5 * (lo + hi)
    r = float(np.sqrt(((obj - c) ** 2).sum(axis=1).max()))
    return c @ rs.T, max(r, 1e-12)


def turntable(transfer: Transfer, coeffs: ArrayLike, frames: int,
              rotation: ArrayLike | None = None, lmax: int | None = None, camera: Any = None,
              axis: ArrayLike = (0.0, 1.0, 0.0), mode: str | None = None,
              bounces: int | None = None) -> Iterator[Any]:
    """``frames`` renders with the lighting turned by 360°·i/frames about ``axis`` (+Y) around
    the (fixed, optionally turned by ``rotation``) scene."""
    for i in range(int(frames)):
        yield render_frame(transfer, coeffs, rotation, from_axis_angle(axis, 360.0 * i / frames),
                           lmax=lmax, camera=camera, mode=mode, bounces=bounces)
