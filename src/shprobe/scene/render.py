"""Rendering diffuse objects from SH lighting (R&H 2001 §3.2): cameras, Embree primary rays, per-
pixel and per-vertex shading.

Outgoing radiance of a diffuse surface of albedo ρ is ρ E(n) / π with the irradiance
E(n) = Σ Â_l L_lm y_lm(n) (R&H eq. 7); for lmax ≤ 2 it is evaluated as the quadratic form
nᵀ M n of eq. 11–12 by a numba kernel. Two shading modes:

* ``"pixel"``: the normal is interpolated (barycentric, then normalised) at every pixel and
  E is evaluated there;
* ``"vertex"``: E is evaluated at the vertices and the radiance is interpolated across the
  triangles — the procedural shader of R&H §3.2.

Tone mapping (PNG output): ``exposure`` stops (× 2^exposure), clamp to [0, 1], sRGB transfer
curve, 8 bits. EXR output is linear radiance, untouched.

Camera frame: world +Y up. At azimuth 0 and elevation 0 the camera sits on the +Z side of the
object looking along −Z (the direction at the centre u = 0.5 of a lat-long map); positive
azimuth turns the camera position from +Z towards +X about +Y, positive elevation lifts it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting.irradiance import shade_irradiance
from ..probes.images import srgb_to_linear, tonemap

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = [
    "Camera",
    "Hits",
    "RenderResult",
    "basis_images",
    "basis_visual",
    "load_mesh",
    "relight",
    "render",
    "render_vertex_colors",
    "save_image",
    "sphere_mesh",
    "trace",
]

PROJECTIONS = ("perspective", "orthographic")


# ----------------------------------------------------------------------------- camera


@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera orbiting the object.

    Angles in degrees. ``fov`` is the vertical field of view of the perspective camera.
    ``distance`` (from the target) and ``target`` default to a fit of the object's bounding
    sphere with ``margin`` (1.0 = the sphere just touches the nearer image edge). For the
    orthographic camera ``distance`` only places the ray origins; ``ortho_height`` (the
    world-space height of the view) defaults to the fit.
    """

    width: int = 512
    height: int = 512
    projection: str = "perspective"
    azimuth: float = 0.0
    elevation: float = 0.0
    fov: float = 40.0
    distance: float | None = None
    target: tuple[float, float, float] | None = None
    margin: float = 1.1
    ortho_height: float | None = None

    def __post_init__(self) -> None:
        if self.projection not in PROJECTIONS:
            raise ShprobeError(f"projection must be one of {PROJECTIONS}, got {self.projection!r}")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ShprobeError(f"image size must be positive, got {self.width}x{self.height}")
        if not 0.0 < self.fov < 180.0:
            raise ShprobeError(f"field of view must be in (0, 180) degrees, got {self.fov}")
        if self.margin <= 0.0:
            raise ShprobeError(f"margin must be positive, got {self.margin}")

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def basis(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(forward, right, up) unit vectors of the camera in world space."""
        az, el = np.radians(self.azimuth), np.radians(self.elevation)
        back = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        fwd = -back
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        if np.linalg.norm(right) < 1e-9:  # looking straight up/down: keep +X to the right
            right = np.array([np.cos(az), 0.0, -np.sin(az)])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        return fwd, right, up / np.linalg.norm(up)

    def framing(self, center: ArrayLike, radius: float) -> tuple[NDArray, float, float]:
        """(target, distance, half height of the view at the target) for a bounding sphere."""
        c = np.asarray(self.target if self.target is not None else center, dtype=np.float64)
        r = float(radius) * self.margin
        t = np.tan(np.radians(self.fov) / 2.0)
        half_angle = min(np.arctan(t), np.arctan(t * self.aspect))
        if self.distance is not None:
            d = float(self.distance)
        elif self.projection == "perspective":
            d = r / np.sin(half_angle)
        else:
            d = 2.0 * r + 1e-6
        if self.ortho_height is not None:
            hh = self.ortho_height / 2.0
        else:
            hh = r * max(1.0, 1.0 / self.aspect)
        return c, d, hh

    def rays(self, center: ArrayLike, radius: float) -> tuple[NDArray, NDArray]:
        """Primary rays through pixel centres, (H·W, 3) origins and unit directions, row-major
        with row 0 at the top of the image."""
        c, d, hh = self.framing(center, radius)
        fwd, right, up = self.basis()
        w, h = int(self.width), int(self.height)
        sx = (np.arange(w) + 0.5) / w * 2.0 - 1.0
        sy = 1.0 - (np.arange(h) + 0.5) / h * 2.0
        eye = c - d * fwd
        if self.projection == "perspective":
            t = np.tan(np.radians(self.fov) / 2.0)
            px = sx * t * self.aspect
            py = sy * t
            dirs = fwd + px[None, :, None] * right + py[:, None, None] * up
            dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
            origins = np.broadcast_to(eye, dirs.shape)
        else:
            px = sx * hh * self.aspect
            py = sy * hh
            origins = eye + px[None, :, None] * right + py[:, None, None] * up
            dirs = np.broadcast_to(fwd, origins.shape)
        return (np.ascontiguousarray(origins.reshape(-1, 3)),
                np.ascontiguousarray(dirs.reshape(-1, 3)))


# ----------------------------------------------------------------------------- meshes


def load_mesh(path: str | os.PathLike[str]) -> trimesh.Trimesh:
    """Load OBJ / PLY / glTF / GLB (anything trimesh reads) as one triangle mesh.

    A scene is flattened (its graph transforms applied) and concatenated. Bad or empty files
    raise a one-line :class:`ShprobeError` naming the file.
    """
    import trimesh

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ShprobeError("no such mesh file", p)
    try:
        obj = trimesh.load(p, process=True)
    except Exception as e:  # trimesh raises many types on bad input
        raise ShprobeError(f"cannot read mesh: {str(e).splitlines()[0] if str(e) else e!r}",
                           p) from None
    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            raise ShprobeError("mesh file holds no triangles", p)
        obj = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(obj, trimesh.Trimesh) or len(obj.faces) == 0:
        raise ShprobeError("mesh file holds no triangles", p)
    if not np.all(np.isfinite(obj.vertices)):
        raise ShprobeError("mesh has non-finite vertex coordinates", p)
    if not np.ptp(obj.vertices, axis=0).max() > 0:
        raise ShprobeError("mesh has zero extent (all vertices coincide)", p)
    if not obj.area > 0:
        raise ShprobeError("mesh has no triangle of non-zero area (no normals)", p)
    return obj


def sphere_mesh(subdivisions: int = 5, radius: float = 1.0) -> trimesh.Trimesh:
    """A finely tessellated sphere (icosphere) with exact vertex normals."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    n = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    return trimesh.Trimesh(m.vertices, m.faces, vertex_normals=n, process=False)


def _bounding_sphere(mesh: trimesh.Trimesh | None) -> tuple[NDArray, float]:
    if mesh is None:
        return np.zeros(3), 1.0
    v = np.asarray(mesh.vertices, dtype=np.float64)
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    r = float(np.sqrt(((v - c) ** 2).sum(axis=1).max()))
    if not r > 0:
        raise ShprobeError("mesh has zero extent (all vertices coincide)")
    return c, r


# ----------------------------------------------------------------------------- ray casting


@dataclass
class Hits:
    """First hits of the primary rays (flat over pixels; miss → face −1)."""

    face: NDArray[np.int64]  # (P,) triangle index, -1 where the ray misses
    bary: NDArray[np.float32]  # (P, 3) barycentric weights of the face's 3 vertices
    position: NDArray[np.float64]  # (P, 3) hit point (0 where missed)
    geo_normal: NDArray[np.float64]  # (P, 3) geometric normal facing the camera
    normal: NDArray[np.float32]  # (P, 3) smooth shading normal (unit; 0 where missed)
    directions: NDArray[np.float64]  # (P, 3) ray directions


def trace(mesh: trimesh.Trimesh | None, camera: Camera) -> Hits:
    """Cast the camera's primary rays: Embree (trimesh.ray.ray_pyembree) on a mesh, or the
    analytic unit sphere at the origin when ``mesh`` is None."""
    center, radius = _bounding_sphere(mesh)
    origins, dirs = camera.rays(center, radius)
    P = origins.shape[0]
    if mesh is None:
        return _trace_sphere(origins, dirs)
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    inter = RayMeshIntersector(mesh)
    res = inter._scene.run(origins, dirs, output=1)
    face = res["primID"].astype(np.int64)
    hit = face >= 0
    fh = face[hit]
    u = res["u"][hit].astype(np.float32)
    v = res["v"][hit].astype(np.float32)
    bary = np.zeros((P, 3), np.float32)
    bary[hit] = np.stack([1.0 - u - v, u, v], axis=-1)  # Embree: p = (1-u-v)v0 + u v1 + v v2
    tri = np.asarray(mesh.faces)[fh]
    V = np.asarray(mesh.vertices, dtype=np.float64)
    b = bary[hit].astype(np.float64)
    pos = np.zeros((P, 3))
    pos[hit] = np.einsum("pk,pkj->pj", b, V[tri])
    vn = np.asarray(mesh.vertex_normals, dtype=np.float32)
    n = np.einsum("pk,pkj->pj", bary[hit], vn[tri])
    fnorm = np.asarray(mesh.face_normals, dtype=np.float64)[fh]
    # face the camera: flip both normals on back faces
    back = np.einsum("pj,pj->p", fnorm, dirs[hit]) > 0.0
    fnorm[back] *= -1.0
    n[back] *= -1.0
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    bad = ln[:, 0] < 1e-12
    n = np.where(bad[:, None], fnorm.astype(np.float32), n / np.maximum(ln, 1e-30))
    normal = np.zeros((P, 3), np.float32)
    normal[hit] = n
    geo = np.zeros((P, 3))
    geo[hit] = fnorm
    return Hits(face, bary, pos, geo, normal, dirs)


def _trace_sphere(origins: NDArray, dirs: NDArray) -> Hits:
    # |o + t d|² = 1 with |d| = 1: t = −o·d − √((o·d)² − |o|² + 1)
    od = np.einsum("pj,pj->p", origins, dirs)
    disc = od * od - np.einsum("pj,pj->p", origins, origins) + 1.0
    hit = disc >= 0.0
    t = -od - np.sqrt(np.maximum(disc, 0.0))
    pos = np.where(hit[:, None], origins + t[:, None] * dirs, 0.0)
    n = pos / np.maximum(np.linalg.norm(pos, axis=-1, keepdims=True), 1e-30)
    face = np.where(hit, 0, -1).astype(np.int64)
    P = origins.shape[0]
    return Hits(face, np.zeros((P, 3), np.float32), pos, n, n.astype(np.float32), dirs)


# ----------------------------------------------------------------------------- albedo


def _mesh_texture(mesh: trimesh.Trimesh) -> tuple[NDArray, NDArray] | None:
    """(uv (V, 2), linear texture (h, w, 3)) of a textured mesh, else None. A glTF texture is
    multiplied by its ``baseColorFactor`` (glTF 2.0 §3.9.2)."""
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "texture":
        return None
    uv = getattr(vis, "uv", None)
    mat = getattr(vis, "material", None)
    img = None
    for attr in ("baseColorTexture", "image"):
        img = getattr(mat, attr, None) if mat is not None else None
        if img is not None:
            break
    if uv is None or img is None:
        return None
    tex = srgb_to_linear(np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0)
    factor = getattr(mat, "baseColorFactor", None)
    if factor is not None:
        tex = tex * (np.asarray(factor, np.float32)[:3] / 255.0)
    return np.asarray(uv, dtype=np.float64), tex


def _mesh_vertex_colors(mesh: trimesh.Trimesh) -> NDArray | None:
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "vertex":
        return None
    return srgb_to_linear(np.asarray(vis.vertex_colors)[:, :3] / 255.0)


def _mesh_face_colors(mesh: trimesh.Trimesh) -> NDArray | None:
    """Per-face colours (PLY face colours; 8-bit sRGB, like vertex colours) in linear RGB."""
    vis = getattr(mesh, "visual", None)
    if vis is None or getattr(vis, "kind", None) != "face":
        return None
    return srgb_to_linear(np.asarray(vis.face_colors)[:, :3] / 255.0)


def _mesh_material_color(mesh: trimesh.Trimesh) -> NDArray | None:
    """The constant colour of an untextured material: glTF ``baseColorFactor`` or OBJ ``Kd``
    (both linear reflectances), else None."""
    mat = getattr(getattr(mesh, "visual", None), "material", None)
    for attr in ("baseColorFactor", "diffuse"):
        v = getattr(mat, attr, None) if mat is not None else None
        if v is not None:
            return np.asarray(v, np.float32)[:3] / 255.0
    return None


def mesh_vertex_albedo(mesh: trimesh.Trimesh) -> NDArray[np.float64] | None:
    """A mesh's own albedo per vertex (V, 3), linear, for per-vertex shading (PRT): its
    texture sampled at the vertex UVs (× glTF ``baseColorFactor``), else its vertex colours,
    else its face colours averaged over each vertex's faces, else its material colour (glTF
    ``baseColorFactor`` / OBJ ``Kd``); None when it has none of them."""
    nv = len(mesh.vertices)
    tex = _mesh_texture(mesh)
    if tex is not None and len(tex[0]) == nv:
        return sample_texture(tex[1], tex[0])[:, :3].astype(np.float64)
    vc = _mesh_vertex_colors(mesh)
    if vc is not None and len(vc) == nv:
        return np.asarray(vc, np.float64)
    fc = _mesh_face_colors(mesh)
    if fc is not None:
        faces = np.asarray(mesh.faces)
        acc = np.zeros((nv, 3))
        np.add.at(acc, faces.reshape(-1), np.repeat(fc.astype(np.float64), 3, axis=0))
        cnt = np.bincount(faces.reshape(-1), minlength=nv)[:, None]
        return np.where(cnt > 0, acc / np.maximum(cnt, 1), 1.0)
    mc = _mesh_material_color(mesh)
    return None if mc is None else np.broadcast_to(mc.astype(np.float64), (nv, 3)).copy()


def sample_texture(tex: NDArray, uv: NDArray) -> NDArray[np.float32]:
    """Bilinear lookup with wrap-around; uv (P, 2), v = 0 at the bottom row of the image."""
    h, w = tex.shape[:2]
    x = (uv[:, 0] % 1.0) * w - 0.5
    y = (1.0 - uv[:, 1] % 1.0) * h - 0.5
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y0, y1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    top = tex[y0, x0] * (1 - fx) + tex[y0, x1] * fx
    bot = tex[y1, x0] * (1 - fx) + tex[y1, x1] * fx
    return (top * (1 - fy) + bot * fy).astype(np.float32)


# ----------------------------------------------------------------------------- render


@dataclass
class RenderResult:
    """A rendered image and its geometry buffers.

    ``image``: (H, W, C) linear radiance, background included; ``radiance``: the same with the
    background 0; ``mask``: (H, W) True where the object is hit; ``normals``: (H, W, 3) unit
    shading normals (0 on the background); ``irradiance``: (H, W, C) E at each pixel (per-pixel
    mode: E(n); per-vertex mode: interpolated vertex E; 0 on the background); ``face``: (H, W)
    triangle index (−1 on the background); ``bary``: (H, W, 3) barycentric weights.
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

    def tonemapped(self, exposure: float = 0.0) -> NDArray[np.uint8]:
        """8-bit sRGB image: × 2^exposure, clamp, sRGB curve (see :func:`tonemap`)."""
        return tonemap(self.image, exposure)

    def save(self, path: str | os.PathLike[str], exposure: float = 0.0,
             overwrite: bool = False) -> None:
        """PNG/JPEG (tone-mapped) or EXR/HDR/PFM (linear), by the file's suffix."""
        save_image(path, self.image, exposure=exposure, overwrite=overwrite)


def _albedo_per_pixel(mesh, albedo, hits: Hits, hit: NDArray, C: int) -> NDArray | None:
    """Per-hit albedo (Ph, C) or None for 1."""
    if albedo is None:
        if mesh is None:
            return None
        tex = _mesh_texture(mesh)
        if tex is not None:
            uv, img = tex
            tri = np.asarray(mesh.faces)[hits.face[hit]]
            uvp = np.einsum("pk,pkj->pj", hits.bary[hit].astype(np.float64), uv[tri])
            return sample_texture(img, uvp)[:, :C]
        vc = _mesh_vertex_colors(mesh)
        if vc is not None:
            return _interp(vc, mesh, hits, hit)[:, :C]
        fc = _mesh_face_colors(mesh)
        if fc is not None:
            return fc[hits.face[hit]][:, :C]
        mc = _mesh_material_color(mesh)
        if mc is not None:
            return np.broadcast_to(mc[None, :C], (int(hit.sum()), min(C, 3)))
        return None
    a = np.asarray(albedo, dtype=np.float32)
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
        from ..probes.layouts import Env

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
    return _result(hits, rad, E, background, camera, mode)


def _result(hits: Hits, rad: NDArray, E: NDArray, background: Any, camera: Camera,
            mode: str) -> RenderResult:
    hit = hits.face >= 0
    img = rad.copy()
    if background is not None:
        img[~hit] = _background(background, hits.directions[~hit], rad.shape[1])
    H, W, C = camera.height, camera.width, rad.shape[1]
    return RenderResult(
        image=img.reshape(H, W, C), radiance=rad.reshape(H, W, C), mask=hit.reshape(H, W),
        normals=hits.normal.reshape(H, W, 3), irradiance=E.reshape(H, W, C),
        face=hits.face.reshape(H, W), bary=hits.bary.reshape(H, W, 3), camera=camera,
        mode=mode)


def render_vertex_colors(mesh: trimesh.Trimesh, vertex_radiance: ArrayLike,
                         camera: Camera | None = None, background: Any = None) -> RenderResult:
    """Render per-vertex outgoing radiance (V, C), interpolated barycentrically across the
    triangles (e.g. the result of PRT relighting). No shading is applied; ``irradiance`` in the
    result is 0 and ``radiance``/``image`` hold the interpolated values."""
    camera = camera or Camera()
    vr = np.asarray(vertex_radiance, dtype=np.float32)
    if vr.ndim == 1:
        vr = vr[:, None]
    if vr.shape[0] != len(mesh.vertices):
        raise ShprobeError(
            f"vertex_radiance has {vr.shape[0]} rows but the mesh has {len(mesh.vertices)} "
            "vertices")
    C = vr.shape[1]
    hits = trace(mesh, camera)
    hit = hits.face >= 0
    rad = np.zeros((hit.size, C), np.float32)
    rad[hit] = _interp(vr, mesh, hits, hit)
    return _result(hits, rad, np.zeros_like(rad), background, camera, "vertex-colors")


# ----------------------------------------------------------------------------- basis images


def basis_images(mesh: trimesh.Trimesh | None, camera: Camera | None = None, lmax: int = 2,
                 mode: str = "pixel", albedo: Any = None) -> RenderResult:
    """The irradiance basis images of R&H §3.3 / Fig. 4: channel k of ``image`` is the object
    rendered under the lighting L = e_k, i.e. ρ Â_l y_lm(n) / π (background 0).

    Rendering is linear in L, so for any lighting (K, C) the relighting identity
    image_c = Σ_k L_kc · basis_k holds (to float32 rounding) in both shading modes.
    """
    from ..sh import num_coeffs

    K = num_coeffs(lmax)
    return render(mesh, np.eye(K), camera, mode=mode, albedo=albedo, background=None)


def relight(basis: ArrayLike, coeffs: ArrayLike) -> NDArray[np.float32]:
    """Σ_k L_kc · basis_k: an image (H, W, C) from basis images (H, W, K) and lighting
    (K, C)."""
    b = np.asarray(basis, dtype=np.float32)
    c = np.asarray(coeffs, dtype=np.float32)
    if c.ndim == 1:
        c = c[:, None]
    if b.shape[-1] != c.shape[0]:
        raise ShprobeError(f"{b.shape[-1]} basis images but {c.shape[0]} coefficients")
    return b @ c


def basis_visual(values: ArrayLike, scale: float | None = None) -> NDArray[np.float32]:
    """R&H Fig. 4 colouring of a signed image (H, W): positive green, negative blue, linear,
    divided by ``scale`` (default: its own max |value|)."""
    v = np.asarray(values, dtype=np.float32)
    s = float(np.abs(v).max()) if scale is None else float(scale)
    v = v / (s if s > 0 else 1.0)
    return np.stack([np.zeros_like(v), np.maximum(v, 0), np.maximum(-v, 0)], -1)


# ----------------------------------------------------------------------------- output


def save_image(path: str | os.PathLike[str], image: ArrayLike, exposure: float = 0.0,
               overwrite: bool = False) -> None:
    """Write a render with :func:`shprobe.images.write_image`: ``.png`` tone-mapped by
    :func:`tonemap` (× 2^exposure, clamp, sRGB, 8 bits), ``.exr``/``.hdr``/``.pfm`` linear."""
    from ..probes.images import write_image

    write_image(path, image, overwrite=overwrite, exposure=exposure)
