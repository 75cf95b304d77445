"""Normal-mapped rendering of a mesh shaded with per-vertex H6, H4 and tangent-space SH9 against
the exact irradiance at the perturbed normal (Habel & Wimmer 2010 §4.2–4.3, their Fig. 6), and
the labelled comparison figure. Rendering goes through the scene layer (one orthographic
[`Camera`][shprobe.scene.Camera], the one ray caster) and returns its
[`RenderResult`][shprobe.scene.RenderResult]."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting import irradiance, irradiance_coeffs, reference_irradiance
from ..probes.env import Env
from ..progress import Progress, numbered, stage
from ..scene import Camera, RenderResult, mesh_uvs, render_result, sample_texture, trace
from ..sh.rotation import unit_vectors
from .frames import Frames, tangent_frames
from .normalmap import (
    NormalMapBake,
    bake_normalmap,
    bump_world,
    lighting_coeffs,
    shade_h,
    shade_sh,
)

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = ["panel_image", "render_normal_mapped", "save_panel"]


def render_normal_mapped(mesh: trimesh.Trimesh, lighting: Env | ArrayLike, size: int = 256,
                         bump_amplitude: float = 0.3, bump_frequency: float | None = None,
                         normal_map: NDArray | None = None,
                         baked: NormalMapBake | None = None,
                         progress: Progress | None = None) -> RenderResult:
    """Render ``mesh`` under ``lighting`` (an Env, or radiance SH (K, 3)) with a tangent-space
    ``normal_map`` (H, W, 3) looked up bilinearly at the interpolated UV (u wraps, v up;
    green flipped on mirrored charts; needs UVs), or else a UV-free procedural bump
    (`bump_world`), shading with per-vertex baked H6, H4 and tangent-space SH9
    (linearly interpolated, as the paper's per-vertex variant), against the reference E(n′) at
    the perturbed world normal: brute force over the probe's pixels
    ([`shprobe.lighting.reference_irradiance`][shprobe.lighting.reference_irradiance]), or the
    lighting's own SH expansion when only coefficients were given. ``baked``: per-vertex
    coefficients from `bake_normalmap` / `load_bake` for this mesh (with their frames) instead of
    baking here (H4-only bakes give no "H6" image).

    The camera is orthographic on +Z looking along −Z, +Y up, framing the mesh's x–y extent.
    Returns a [`RenderResult`][shprobe.scene.RenderResult]: ``irradiance`` the reference E(n′) (and
    ``image`` = ``radiance`` = E/π, a white diffuse surface), ``normals`` the perturbed world
    normals n′; ``layers`` "H6" (6-function bakes), "H4", "SH9" (irradiance (H, W, 3)),
    "tangent_normals" v = F_pᵀ n′ and "frames" F_p (H, W, 3, 3), the frame interpolated at each
    pixel; ``info["rel_rms"]`` the RMS error of each basis over hit pixels and channels divided
    by the RMS of the reference there. Everything is 0 where no surface was hit (``mask``).
    ``progress`` gets three stages (the bake, the camera rays, the reference; the brute-force
    reference counts its normal–pixel pairs, so it shows an ETA).
    """
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    frames = tangent_frames(v, f, np.asarray(mesh.vertex_normals), mesh_uvs(mesh))
    L = lighting_coeffs(lighting)
    e = irradiance_coeffs(L)
    if baked is None:
        with stage(progress, "baking per-vertex H6, H4 and SH9", index=1, count=3):
            bk = bake_normalmap(e, frames.matrix, n=6)
    else:
        if baked.h.shape[0] != len(v) or baked.frames.shape != (len(v), 3, 3):
            raise ShprobeError(f"baked coefficients are for {baked.h.shape[0]} vertices, the "
                               f"mesh has {len(v)}")
        bk = baked
        frames = Frames(np.asarray(baked.frames, dtype=np.float64), frames.handedness)

    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1])) * 1.05
    c = 0.5 * (lo + hi)
    cam = Camera(size, size, projection="orthographic", target=tuple(c), ortho_height=ext,
                 distance=float(hi[2] - c[2]) + ext)
    with stage(progress, f"tracing {size}x{size} camera rays", index=2, count=3):
        hits = trace(mesh, cam)
    hit = hits.face >= 0
    tri = f[hits.face[hit]]  # (P, 3)
    bary = hits.bary[hit].astype(np.float64)
    bary[:, 0] = 1.0 - bary[:, 1] - bary[:, 2]  # Embree's u, v: weights that sum to 1 exactly

    def interp(a: NDArray) -> NDArray:
        return np.einsum("pi,pi...->p...", bary, a[tri])

    nrm = unit_vectors(interp(frames.matrix[..., 2]), zero="keep")
    tan = interp(frames.matrix[..., 0])
    tan = unit_vectors(tan - np.sum(tan * nrm, -1, keepdims=True) * nrm, zero="keep")
    fp = np.stack([tan, np.cross(nrm, tan), nrm], axis=-1)
    if normal_map is not None:
        uvs = mesh_uvs(mesh)
        if uvs is None:
            raise ShprobeError("a normal-map image needs a mesh with UVs")
        vt = sample_texture(np.asarray(normal_map, dtype=np.float64), interp(uvs))
        vt = vt.astype(np.float64)
        vt[:, 1] *= np.where(interp(frames.handedness) < 0, -1.0, 1.0)
        vt = unit_vectors(vt, "normal-map normals", zero="keep")
        nw = np.einsum("pij,pj->pi", fp, vt)
    else:
        freq = bump_frequency if bump_frequency is not None else 60.0 / ext
        nw = bump_world(hits.position[hit], nrm, bump_amplitude, freq)
        vt = np.einsum("pji,pj->pi", fp, nw)  # tangent-space normal Fᵀ n'
    vals = {}
    if bk.h.shape[1] == 6:
        vals["H6"] = shade_h(interp(bk.h), vt)
    vals["H4"] = shade_h(interp(bk.h[:, :4]), vt)
    vals["SH9"] = shade_sh(interp(bk.sh), vt)
    if isinstance(lighting, Env):
        ref = reference_irradiance(lighting, nw, progress=numbered(progress, 3, 3))
    else:
        with stage(progress, "the reference from the lighting's SH", index=3, count=3):
            ref = irradiance(L, nw)
    scale = float(np.sqrt(np.mean(ref**2)))
    rel = {k: float(np.sqrt(np.mean((val - ref) ** 2)) / scale) for k, val in vals.items()}
    P = hit.size

    def full(a: NDArray) -> NDArray:
        out = np.zeros((P, *a.shape[1:]), dtype=a.dtype)
        out[hit] = a
        return out

    layers = {k: full(val) for k, val in vals.items()}
    layers.update(tangent_normals=full(vt), frames=full(fp))
    E = full(ref)
    hits.bary = full(bary)  # the float64 weights used above
    return render_result(hits, (E / np.pi, E), cam, "normal-mapped", normals=full(nw),
                         layers=layers, info={"rel_rms": rel})


def panel_image(res: RenderResult, gain: float = 4.0) -> NDArray[np.float32]:
    """2×4 panel (2×3 without H6) of linear irradiance: top reference | H6 | H4 | SH9, bottom
    (blank) | |error| × gain of each basis. Write it with `save_panel`."""
    ref = res.irradiance
    keys = [k for k in ("H6", "H4", "SH9") if k in res.layers]
    top = [ref, *(res.layers[k] for k in keys)]
    bot = [np.zeros_like(ref), *(gain * np.abs(res.layers[k] - ref) for k in keys)]
    return np.concatenate([np.concatenate(top, 1), np.concatenate(bot, 1)], 0).astype(
        np.float32)


def save_panel(path: str | os.PathLike[str], res: RenderResult, gain: float = 4.0,
               overwrite: bool = False) -> Path:
    """Write the comparison as a labelled figure (`shprobe.probes.figures`): top, the
    reference and each basis as E/π (the radiance of a white diffuse surface) at one exposure
    (the reference's 99th percentile at white); bottom, |basis − reference| / π on one shared
    error scale with its colour bar, each titled with the basis's relative RMS error. ``gain``
    is kept for the raw `panel_image`; the figure's colour bar replaces it."""
    from ..probes.figures import Panel, write_figure
    from ..probes.tonemap import auto_exposure

    ref = res.irradiance / np.pi
    stops = auto_exposure(ref[res.mask], target=1.0)
    keys = [k for k in ("H6", "H4", "SH9") if k in res.layers]
    rms = res.info.get("rel_rms", {})
    errs = {k: np.abs(res.layers[k] / np.pi - ref).max(axis=-1) for k in keys}
    top = max((float(e.max()) for e in errs.values()), default=0.0) or 1.0
    units = "W m⁻² sr⁻¹ (E/π)"
    rows = [[Panel(ref, "reference (exact)", units=units, exposure=stops),
             *(Panel(res.layers[k] / np.pi, k, units=units, exposure=stops) for k in keys)],
            [None, *(Panel(errs[k], f"|{k} − ref|, rel. RMS {100 * rms.get(k, np.nan):.1f} %",
                           "error", units=units, scale=top) for k in keys)]]
    # why the H6 and H4 panels look alike, said where a reader compares them
    why = ("; H6 ≈ H4 when the normal map keeps v near the pole, where H⁵ and H⁶ vanish"
           if "H6" in keys and "H4" in keys else "")
    write_figure(path, rows, overwrite=overwrite, shared_colorbar=True,
                 title="normal mapping (H&W 2010): per-vertex bases vs exact E at n′" + why)
    return Path(path)
