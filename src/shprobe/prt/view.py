"""Pictures of relit transfer: one frame, or a turntable of the lighting turning around the
object (Lisle & Huang 2007 §4: model, degree and probe switchable at run time, no re-bake).
Uses the per-vertex renderer ``shprobe.scene.render_vertex_colors``. The workflow's entry is
`render` (`PrtRenderSettings` → `PrtRenderResult`), which ``shprobe prt
render`` calls.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..progress import Progress, track
from ..sh.rotation import from_axis_angle, one_rotation
from .relighting import relight
from .transfer import MODES, Transfer, check_int

__all__ = ["EXPOSURE_FRAMES", "MAX_TURNTABLE", "PrtRenderResult", "PrtRenderSettings",
           "frame_radiance", "object_frame", "render", "render_frame", "turntable"]

#: The most frames of a turntable (0.1 degree apart).
MAX_TURNTABLE = 3600
#: Frames (angles spread over the turn) the automatic exposure of a turntable reads.
EXPOSURE_FRAMES = 72


@dataclass(frozen=True)
class PrtRenderSettings:
    """Settings of a PRT render (`render`); the defaults are ``shprobe prt render``'s.

    Parameters
    ----------
    lmax
        SH degree used (None: the transfer's; at most the baked one).
    mode
        The model, picked at run time (None: the baked one).
    bounces
        Interreflection bounces used (None: all baked).
    rotation
        3×3 rotation turning the scene relative to the lighting (None: none).
    size
        Image (width, height) in pixels.
    azimuth
        Camera azimuth, degrees.
    elevation
        Camera elevation, degrees.
    exposure
        PNG exposure in stops; None: automatic (the 99th percentile of the vertex radiance
        over all frames at 80 % of white).
    turntable
        None: one frame; N: N frames of the lighting turning around +Y (1..MAX_TURNTABLE).
    """

    lmax: int | None = None
    mode: str | None = None
    bounces: int | None = None
    rotation: Any = None
    size: tuple[int, int] = (512, 512)
    azimuth: float = 0.0
    elevation: float = 20.0
    exposure: float | None = None
    turntable: int | None = None

    def __post_init__(self) -> None:
        if self.mode is not None and self.mode not in MODES:
            raise ShprobeError(f"unknown PRT mode {self.mode!r}; choose one of "
                               f"{', '.join(MODES)}")
        for name in ("azimuth", "elevation"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ShprobeError(f"{name} must be a finite number, got {v!r}")
        if self.exposure is not None and not math.isfinite(self.exposure):
            raise ShprobeError(f"exposure must be a finite number, got {self.exposure!r}")
        if self.turntable is not None and not (
                check_int(self.turntable, 1, "turntable frames") <= MAX_TURNTABLE):
            raise ShprobeError(f"turntable needs 1 to {MAX_TURNTABLE} frames (0.1 degree "
                               f"apart), got {self.turntable}")
        if self.rotation is not None:
            object.__setattr__(self, "rotation", one_rotation(self.rotation))

    def check(self, transfer: Transfer) -> int:
        """Refuse, before any work, a model or degree ``transfer`` does not hold.

        Parameters
        ----------
        transfer
            The baked transfer.

        Returns
        -------
        int
            The degree used.
        """
        use = transfer.lmax if self.lmax is None else int(self.lmax)
        if use > transfer.lmax:
            raise ShprobeError(f"transfer was baked to lmax={transfer.lmax}, cannot render at "
                               f"{use}")
        transfer.select(self.mode, self.bounces, use)
        return use

    @property
    def model(self) -> dict[str, Any]:
        """The model's keywords (mode, bounces, lmax) as [`relight`][shprobe.prt.relight] takes
        them."""
        return {"lmax": self.lmax, "mode": self.mode, "bounces": self.bounces}

    def camera(self) -> Any:
        """The camera of these settings.

        Returns
        -------
        Camera
            size, azimuth and elevation as set.
        """
        from ..scene.camera import Camera

        w, h = self.size
        return Camera(width=int(w), height=int(h), azimuth=float(self.azimuth),
                      elevation=float(self.elevation))


@dataclass(frozen=True)
class PrtRenderResult:
    """What `render` wrote: the files (one frame, or the turntable's in order), the
    exposure applied (stops) and the model used."""

    paths: tuple[Path, ...]
    exposure: float
    mode: str
    lmax: int

    def as_dict(self) -> dict[str, Any]:
        """The result as JSON-able values.

        Returns
        -------
        dict
            paths (strings), frames, exposure, mode, lmax.
        """
        return {"paths": [str(p) for p in self.paths], "frames": len(self.paths),
                "exposure": float(self.exposure), "mode": self.mode, "lmax": int(self.lmax)}


def frame_names(output: str | os.PathLike[str], frames: int | None) -> list[Path]:
    """The files a render writes: ``output`` itself, or OUT_000.ext … for a turntable.

    Parameters
    ----------
    output
        The output named by the caller.
    frames
        None (one frame) or the turntable's frames.

    Returns
    -------
    list of Path
        The files, in order.
    """
    out = Path(output)
    if frames is None:
        return [out]
    return [out.with_name(f"{out.stem}_{i:03d}{out.suffix}") for i in range(frames)]


def render(transfer: Transfer, coeffs: ArrayLike, output: str | os.PathLike[str],
           settings: PrtRenderSettings | None = None, progress: Progress | None = None, *,
           overwrite: bool = False) -> PrtRenderResult:
    """Relight ``transfer`` under the SH lighting ``coeffs`` and write the picture(s).

    Parameters
    ----------
    transfer
        A baked [`Transfer`][shprobe.prt.Transfer]
        ([`shprobe.prt.load_transfer`][shprobe.prt.load_transfer]).
    coeffs
        Lighting, radiance SH (K, 3) or (K,).
    output
        The picture: .png (tone-mapped) or .exr .hdr .pfm .tif (linear); a turntable
        writes OUT_000.ext ….
    settings
        The render's `PrtRenderSettings` (default: its defaults).
    progress
        A [`shprobe.progress.Progress`][shprobe.progress.Progress] reporter.
    overwrite
        Replace existing files.

    Returns
    -------
    PrtRenderResult
        The files written, the exposure and the model.
    """
    from ..probes.images import check_image_output
    from ..probes.tonemap import auto_exposure

    s = settings if settings is not None else PrtRenderSettings()
    use = s.check(transfer)  # the model must be in the file: before any work
    names = frame_names(output, s.turntable)
    for name in names:
        check_image_output(name, overwrite)
    stops = s.exposure
    n = s.turntable
    if stops is None:  # one exposure for all frames: the light turning must show (from at
        # most EXPOSURE_FRAMES angles spread over the turn: memory stays bounded)
        picked = ([None] if n is None else range(n) if n <= EXPOSURE_FRAMES
                  else sorted({i * n // EXPOSURE_FRAMES for i in range(EXPOSURE_FRAMES)}))
        stops = auto_exposure([frame_radiance(
            transfer, coeffs, s.rotation,
            None if i is None else from_axis_angle([0.0, 1.0, 0.0], 360.0 * i / n),
            **s.model) for i in picked])
    frames = (iter([render_frame(transfer, coeffs, s)]) if n is None
              else turntable(transfer, coeffs, s))
    for name, frame in zip(names, track(frames, progress if n is not None else None,
                                        "turntable frames", len(names)), strict=True):
        frame.save(name, stops, overwrite)  # one frame at a time: nothing accumulates
    mode = s.mode or transfer.mode
    return PrtRenderResult(tuple(names), float(stops), mode, use)


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


def render_frame(transfer: Transfer, coeffs: ArrayLike,
                 settings: PrtRenderSettings | None = None,
                 light_rotation: ArrayLike | None = None, camera: Any = None,
                 background: Any = None):
    """Render the scene turned by ``settings.rotation`` (3×3, the mesh moves) under the
    lighting ``coeffs`` turned by ``light_rotation`` (the mesh stays).

    Lighting turned by R_l and scene by R_s: in the scene's frame the lighting is
    rotate(L, R_s⁻¹ R_l), i.e. ``relight`` with scene rotation R_l⁻¹ R_s.

    Parameters
    ----------
    transfer
        The baked transfer.
    coeffs
        Lighting, radiance SH.
    settings
        The model (lmax, mode, bounces), scene rotation and camera (default: the defaults).
    light_rotation
        3×3 rotation of the lighting, or None.
    camera
        A camera instead of the settings' one.
    background
        The renderer's background.

    Returns
    -------
    RenderResult
        The renderer's result.
    """
    import trimesh

    from ..scene.render import render_vertex_colors

    s = settings if settings is not None else PrtRenderSettings()
    camera = s.camera() if camera is None else camera
    rs = np.eye(3) if s.rotation is None else one_rotation(s.rotation)
    radiance = frame_radiance(transfer, coeffs, rs, light_rotation, **s.model)
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


def turntable(transfer: Transfer, coeffs: ArrayLike, settings: PrtRenderSettings,
              axis: ArrayLike = (0.0, 1.0, 0.0), camera: Any = None) -> Iterator[Any]:
    """``settings.turntable`` renders with the lighting turned by 360°·i/frames about
    ``axis`` (+Y) around the (fixed, optionally turned by ``settings.rotation``) scene.

    Parameters
    ----------
    transfer
        The baked transfer.
    coeffs
        Lighting, radiance SH.
    settings
        The frames, model, scene rotation and camera.
    axis
        The axis the lighting turns about.
    camera
        A camera instead of the settings' one.

    Returns
    -------
    Iterator
        The renderer's results, one per frame, made as they are read.
    """
    frames = int(settings.turntable or 1)
    for i in range(frames):
        yield render_frame(transfer, coeffs, settings, from_axis_angle(axis, 360.0 * i / frames),
                           camera)
