"""Rendering diffuse objects from SH lighting (R&H 2001 §3.2): primary rays
(`shprobe.scene.primary`, through the one ray caster), per-pixel and per-vertex shading, basis
images; relighting, Fig. 4 colouring and saving in `shprobe.scene.images` (re-exported here).

Outgoing radiance of a diffuse surface of albedo ρ is ρ E(n) / π with the irradiance
E(n) = Σ Â_l L_lm y_lm(n) (R&H eq. 7); for lmax ≤ 2 it is evaluated as the quadratic form
nᵀ M n of eq. 11–12
([`shprobe.lighting.irradiance.shade_irradiance`][shprobe.lighting.shade_irradiance]). Two shading
modes:

* ``"pixel"``: the normal is interpolated (barycentric, then normalised) at every pixel and
  E is evaluated there;
* ``"vertex"``: E is evaluated at the vertices and the radiance is interpolated across the
  triangles — the procedural shader of R&H §3.2.

Tone mapping (PNG output): `shprobe.probes.tonemap.tonemap` — ``exposure`` stops
(× 2^exposure), clamp to [0, 1], sRGB transfer curve, 8 bits. EXR output is linear radiance,
untouched. Camera frame: see `shprobe.scene.camera`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting.irradiance import shade_irradiance
from ..probes.tonemap import tonemap
from .camera import Camera
from .images import basis_visual, relight, save_image
from .mesh import (
    mesh_face_colors,
    mesh_material_color,
    mesh_texture,
    mesh_vertex_colors,
    sample_texture,
    sphere_mesh,
)
from .primary import Hits, trace

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = [
    "Hits",
    "RenderResult",
    "basis_images",
    "basis_visual",
    "relight",
    "render",
    "render_result",
    "render_vertex_colors",
    "save_image",
    "trace",
]

# ----------------------------------------------------------------------------- render


@dataclass
class RenderResult:
    """A rendered image and its geometry buffers.

    ``image``: (H, W, C) linear radiance, background included; ``radiance``: the same with the
    background 0; ``mask``: (H, W) True where the object is hit; ``normals``: (H, W, 3) unit
    shading normals (0 on the background); ``irradiance``: (H, W, C) E at each pixel (per-pixel
    mode: E(n); per-vertex mode: interpolated vertex E; 0 on the background); ``face``: (H, W)
    triangle index (−1 on the background); ``bary``: (H, W, 3) barycentric weights;
    ``layers``: further named per-pixel images (H, W, ...) a renderer produces beside the
    radiance (e.g. the H-basis normal-mapped render's irradiance per basis and its
    tangent-space normals); ``info``: scalars about the render (e.g. error figures).

    Attributes
    ----------
    image
        (H, W, C) linear radiance, background included.
    radiance
        The same with the background 0.
    mask
        (H, W) True where the object is hit.
    normals
        (H, W, 3) unit shading normals (0 on the background).
    irradiance
        (H, W, C) E at each pixel.
    face
        (H, W) triangle index (−1 on the background).
    bary
        (H, W, 3) barycentric weights.
    camera
        The camera.
    mode
        "pixel" or "vertex".
    info
        Scalars about the render.
    layers
        Further named per-pixel images.
    """

    image: NDArray[np.float32]
    radiance: NDArray[np.float32]
    mask: NDArray[np.bool_]
    normals: NDArray[np.float32]
    irradiance: NDArray[np.float32]
    face: NDArray[np.int64]
    bary: NDArray[np.float32]
    camera: Camera
    mode: str
    info: dict[str, Any] = field(default_factory=dict)
    layers: dict[str, NDArray[Any]] = field(default_factory=dict)

    def __repr__(self) -> str:
        h, w, c = self.image.shape
        extra = f", layers={sorted(self.layers)}" if self.layers else ""
        return (f"RenderResult({w}x{h}x{c}, mode={self.mode!r}, "
                f"{int(self.mask.sum())} pixels hit{extra})")

    def tonemapped(self, exposure: float = 0.0) -> NDArray[np.uint8]:
        """8-bit sRGB image: × 2^exposure, clamp, sRGB curve (see `tonemap`).

        Parameters
        ----------
        exposure
            Stops.

        Returns
        -------
        ndarray of shape (H, W, 3), uint8
            The sRGB image.
        """
        return tonemap(self.image, exposure)

    def save(self, path: str | os.PathLike[str], exposure: float = 0.0,
             overwrite: bool = False) -> None:
        """PNG/JPEG (tone-mapped) or EXR/HDR/PFM (linear), by the file's suffix.

        Parameters
        ----------
        path
            The output file; its suffix picks the format.
        exposure
            Stops (PNG / JPEG only).
        overwrite
            Replace an existing file.
        """
        save_image(path, self.image, exposure=exposure, overwrite=overwrite)


#: Largest albedo a render multiplies by: the radiance is kept in 32-bit floats.
MAX_ALBEDO = 1e30


def _albedo_per_pixel(mesh, albedo, hits: Hits, hit: NDArray, C: int) -> NDArray | None:
    """Per-hit albedo (Ph, C) or None for 1."""
    if albedo is None:
        if mesh is None:
            return None
        tex = mesh_texture(mesh)
        if tex is not None:
            uv, img = tex
            tri = np.asarray(mesh.faces)[hits.face[hit]]
            uvp = np.einsum("pk,pkj->pj", hits.bary[hit].astype(np.float64), uv[tri])
            return sample_texture(img, uvp)[:, :C]
        vc = mesh_vertex_colors(mesh)
        if vc is not None:
            return _interp(vc, mesh, hits, hit)[:, :C]
        fc = mesh_face_colors(mesh)
        if fc is not None:
            return fc[hits.face[hit]][:, :C]
        mc = mesh_material_color(mesh)
        if mc is not None:
            return np.broadcast_to(mc[None, :C], (int(hit.sum()), min(C, 3)))
        return None
    a64 = np.asarray(albedo, dtype=np.float64)
    if not np.all((a64 >= 0) & (a64 <= MAX_ALBEDO)):  # NaN fails too
        raise ShprobeError(f"albedo must be in [0, {MAX_ALBEDO:g}] (radiance is albedo x E / "
                           "pi, in 32-bit floats)")
    a = a64.astype(np.float32)
    if a.ndim <= 1:
        return np.broadcast_to(a.reshape(1, -1), (int(hit.sum()), a.size if a.ndim else 1))
    if mesh is None or a.shape[0] != len(mesh.vertices):
        raise ShprobeError(f"per-vertex albedo needs one row per vertex, got shape {a.shape}")
    return _interp(a, mesh, hits, hit)


def _interp(values: NDArray, mesh, hits: Hits, hit: NDArray) -> NDArray[np.float32]:
    tri = np.asarray(mesh.faces)[hits.face[hit]]
    vals = np.asarray(values, dtype=np.float32)
    return np.einsum("pk,pkj->pj", hits.bary[hit], vals[tri])


def _background(background: Any, dirs: NDArray, C: int) -> NDArray[np.float32]:
    """Background radiance for missed rays: a colour, an Env-like object with ``sample``,
    a callable dirs → radiance, or a lat-long (H, W, C) array (world +Y up, u=0.5 → −Z)."""
    if background is None:
        return np.zeros((dirs.shape[0], C), np.float32)
    if hasattr(background, "sample"):
        return np.asarray(background.sample(dirs), dtype=np.float32).reshape(-1, C)
    if callable(background):
        return np.asarray(background(dirs), dtype=np.float32).reshape(-1, C)
    b = np.asarray(background, dtype=np.float32)
    if b.ndim == 3:
        from ..probes.env import Env

        return Env(b, "latlong").sample(dirs)[:, :C]
    return np.broadcast_to(b.reshape(1, -1), (dirs.shape[0], C)).astype(np.float32)


def render(mesh: trimesh.Trimesh | None, coeffs: ArrayLike, camera: Camera | None = None,
           mode: str = "pixel", albedo: Any = None, background: Any = None) -> RenderResult:
    """Render a diffuse object lit by SH lighting ``coeffs`` (L_lm, (K, C) or (K,)).

    ``mesh``: a trimesh mesh, or None for the analytic unit sphere (per-vertex mode then uses a
    tessellated sphere). ``mode``: ``"pixel"`` or ``"vertex"`` (R&H §3.2 procedural shader:
    E at vertices, radiance interpolated). ``albedo``: None (the mesh's own: its texture, ×
    glTF ``baseColorFactor``; else vertex colours; else face colours; else the material's
    colour, glTF ``baseColorFactor`` or OBJ ``Kd``; else 1), a scalar or (C,) colour, or
    (V, C) per-vertex values (linear). ``background``: None (black), a colour, an Env / object
    with ``sample(dirs)``, a callable, or a lat-long array. Radiance = ρ E(n) / π.

    Parameters
    ----------
    mesh
        A trimesh mesh, or None for the analytic unit sphere.
    coeffs
        (K, C) or (K,) lighting coefficients L_lm.
    camera
        The camera (default: ``Camera()``, framing the object).
    mode
        "pixel" (E per pixel) or "vertex" (E at the vertices, radiance interpolated).
    albedo
        None (the mesh's own), a scalar or (C,) colour, or (V, C) per-vertex values (linear).
    background
        None (black), a colour, or an Env seen behind the object.

    Returns
    -------
    RenderResult
        The image, its radiance, mask, normals and irradiance per pixel.
    """
    camera = camera or Camera()
    if mode not in ("pixel", "vertex"):
        raise ShprobeError(f"shading mode must be 'pixel' or 'vertex', got {mode!r}")
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim == 1:
        c = c[:, None]
    C = c.shape[1]
    if mesh is None and mode == "vertex":
        mesh = sphere_mesh(6)
    hits = trace(mesh, camera)
    hit = hits.face >= 0
    P = hit.size
    E = np.zeros((P, C), np.float32)
    if mode == "pixel":
        E[hit] = shade_irradiance(c, hits.normal[hit])
    else:
        Ev = shade_irradiance(c, np.asarray(mesh.vertex_normals, dtype=np.float32))
        E[hit] = _interp(Ev, mesh, hits, hit)
    rad = np.zeros((P, C), np.float32)
    alb = _albedo_per_pixel(mesh, albedo, hits, hit, C)
    rad[hit] = E[hit] / np.float32(np.pi) if alb is None else alb * E[hit] / np.float32(np.pi)
    return render_result(hits, (rad, E), camera, mode, background)


def render_result(hits: Hits, shading: tuple[NDArray, NDArray], camera: Camera, mode: str,
                  background: Any = None, *, normals: NDArray | None = None,
                  layers: dict[str, NDArray] | None = None,
                  info: dict[str, Any] | None = None) -> RenderResult:
    """A [`RenderResult`][shprobe.scene.RenderResult] from flat per-pixel buffers (P, ...) of
    ``hits`` (``shading``: radiance and irradiance (P, C); ``normals`` (P, 3), default the hits'
    shading normals; ``layers`` (P, ...) each), with ``background`` filled in where the rays
    missed."""
    radiance, irradiance = shading
    hit = hits.face >= 0
    img = radiance.copy()
    if background is not None:
        img[~hit] = _background(background, hits.directions[~hit], radiance.shape[1])
    H, W, C = camera.height, camera.width, radiance.shape[1]
    nrm = hits.normal if normals is None else normals
    return RenderResult(
        image=img.reshape(H, W, C), radiance=radiance.reshape(H, W, C), mask=hit.reshape(H, W),
        normals=nrm.reshape(H, W, 3), irradiance=irradiance.reshape(H, W, C),
        face=hits.face.reshape(H, W), bary=hits.bary.reshape(H, W, 3), camera=camera,
        mode=mode, info=dict(info or {}),
        layers={k: v.reshape(H, W, *v.shape[1:]) for k, v in (layers or {}).items()})


def render_vertex_colors(mesh: trimesh.Trimesh, vertex_radiance: ArrayLike,
                         camera: Camera | None = None, background: Any = None,
                         frame: tuple[ArrayLike, float] | None = None) -> RenderResult:
    """Render per-vertex outgoing radiance (V, C), interpolated barycentrically across the
    triangles (e.g. the result of PRT relighting). No shading is applied; ``irradiance`` in the
    result is 0 and ``radiance``/``image`` hold the interpolated values. ``frame``: the sphere
    the camera frames (see [`trace`][shprobe.scene.trace]).

    Parameters
    ----------
    mesh
        The mesh.
    vertex_radiance
        (V, C) outgoing radiance per vertex.
    camera
        The camera (default: ``Camera()``).
    background
        None (black), a colour or an Env.
    frame
        (centre, radius) of the sphere the camera frames.

    Returns
    -------
    RenderResult
        The interpolated radiance; ``irradiance`` is 0.
    """
    camera = camera or Camera()
    vr = np.asarray(vertex_radiance, dtype=np.float32)
    if vr.ndim == 1:
        vr = vr[:, None]
    if vr.shape[0] != len(mesh.vertices):
        raise ShprobeError(
            f"vertex_radiance has {vr.shape[0]} rows but the mesh has {len(mesh.vertices)} "
            "vertices")
    C = vr.shape[1]
    hits = trace(mesh, camera, frame=frame)
    hit = hits.face >= 0
    rad = np.zeros((hit.size, C), np.float32)
    rad[hit] = _interp(vr, mesh, hits, hit)
    return render_result(hits, (rad, np.zeros_like(rad)), camera, "vertex-colors", background)


# ----------------------------------------------------------------------------- basis images


def basis_images(mesh: trimesh.Trimesh | None, camera: Camera | None = None, lmax: int = 2,
                 mode: str = "pixel", albedo: Any = None) -> RenderResult:
    """The irradiance basis images of R&H §3.3 / Fig. 4: channel k of ``image`` is the object
    rendered under the lighting L = e_k, i.e. ρ Â_l y_lm(n) / π (background 0).

    Rendering is linear in L, so for any lighting (K, C) the relighting identity
    image_c = Σ_k L_kc · basis_k holds (to float32 rounding) in both shading modes.

    Parameters
    ----------
    mesh
        A mesh, or None for the unit sphere.
    camera
        The camera (default: ``Camera()``).
    lmax
        The highest degree (K = (lmax + 1)² images).
    mode
        "pixel" or "vertex".
    albedo
        As in [`render`][shprobe.scene.render.render].

    Returns
    -------
    RenderResult
        ``image`` (H, W, K): channel k is the object under the lighting e_k.
    """
    from ..sh import num_coeffs

    K = num_coeffs(lmax)
    return render(mesh, np.eye(K), camera, mode=mode, albedo=albedo, background=None)
