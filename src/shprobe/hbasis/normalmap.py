"""Irradiance normal mapping with the H-basis (Habel & Wimmer 2010 §4.1–4.3).

Tangent frame convention (docs/hbasis.md): a frame is a rotation matrix F (3×3) whose columns
are (t, b, n) — tangent, bitangent, normal — in world coordinates, right-handed (b = n × t,
det F = +1). A tangent-space direction v has world direction F v; z = v·(0,0,1) is the normal.

* With UVs: t is the per-vertex average of the triangle tangents ∂p/∂u (area weighted, the
  usual Lengyel construction), Gram–Schmidt orthogonalised against the vertex normal; b = n × t.
  ``handedness`` = sign((n × t) · ∂p/∂v) is returned so a mirrored normal map can flip its
  green channel; the irradiance frame itself is always right-handed.
* Without UVs (or where ∂p/∂u degenerates): the branchless frame of Duff et al. 2017
  ("Building an orthonormal basis, revisited") from the normal alone — continuous except at
  n = (0, 0, −1).

Baking (§4.1): the world irradiance E(ω) = Σ e_lm y_lm(ω) (e = Â_l L_lm) becomes, in the frame
F, the function v ↦ E(F v) = (E∘F)(v); since ``shprobe.rotation.rotate(c, R)`` returns the
coefficients of f∘R⁻¹, the tangent-space SH coefficients are ``rotate(e, Fᵀ)``, and the H
coefficients are T_h times them. Shading (§4.2, eq. 15) evaluates Σ h_i Hⁱ(v) at the
tangent-space normal v read from a normal map.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..sh import lmax_of, num_coeffs, sh_basis
from .basis import evaluate_h, sh_to_h_matrix


def _unit(v: NDArray) -> NDArray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def frame_from_normal(normals: ArrayLike) -> NDArray[np.float64]:
    """Right-handed frames (..., 3, 3), columns (t, b, n), from unit normals alone (Duff et
    al. 2017). Continuous except at n = (0, 0, −1)."""
    n = _unit(np.asarray(normals, dtype=np.float64))
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sign = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bt = np.stack([b, sign + y * y * a, -y], axis=-1)
    return np.stack([t, bt, n], axis=-1)


@dataclass
class Frames:
    """Per-vertex tangent frames: ``matrix`` (V, 3, 3) columns (t, b, n); ``handedness`` (V,)
    is +1, or −1 where the UV chart is mirrored (0 where no UV tangent was available)."""

    matrix: NDArray[np.float64]
    handedness: NDArray[np.float64]


def tangent_frames(vertices: ArrayLike, faces: ArrayLike, normals: ArrayLike | None = None,
                   uvs: ArrayLike | None = None) -> Frames:
    """Per-vertex tangent frames of a triangle mesh (see the module docstring)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ShprobeError(f"need vertices (V, 3) and faces (F, 3), got {v.shape}, {f.shape}")
    p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    if normals is None:
        fn = np.cross(p1 - p0, p2 - p0)  # area-weighted face normals
        nrm = np.zeros_like(v)
        for i in range(3):
            np.add.at(nrm, f[:, i], fn)
        normals = nrm
    n = _unit(np.asarray(normals, dtype=np.float64))
    frames = frame_from_normal(n)
    hand = np.zeros(len(v))
    if uvs is None:
        return Frames(frames, hand)
    uv = np.asarray(uvs, dtype=np.float64)
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    # tangent ∂p/∂u and bitangent ∂p/∂v times det (keeps the area weight, no division)
    tu = e1 * d2[:, 1:2] - e2 * d1[:, 1:2]
    tv = e2 * d1[:, 0:1] - e1 * d2[:, 0:1]
    sgn = np.sign(det)[:, None]
    tu, tv = tu * sgn, tv * sgn
    at, ab = np.zeros_like(v), np.zeros_like(v)
    for i in range(3):
        np.add.at(at, f[:, i], tu)
        np.add.at(ab, f[:, i], tv)
    t = at - np.sum(at * n, axis=-1, keepdims=True) * n
    tn = np.linalg.norm(t, axis=-1)
    ok = tn > 1e-12 * np.maximum(1.0, np.linalg.norm(at, axis=-1))
    t = t / np.where(ok, tn, 1.0)[:, None]
    b = np.cross(n, t)
    uvf = np.stack([t, b, n], axis=-1)
    frames[ok] = uvf[ok]
    hand[ok] = np.where(np.sum(b * ab, axis=-1)[ok] < 0, -1.0, 1.0)
    return Frames(frames, hand)


def to_tangent_sh(sh_coeffs: ArrayLike, frames: ArrayLike) -> NDArray[np.float64]:
    """SH coefficients (..., K, C) of v ↦ E(F v) for world SH coefficients (K, C) and frames
    (..., 3, 3): ``rotate(e, Fᵀ)``."""
    e = np.asarray(sh_coeffs, dtype=np.float64)
    if e.ndim == 1:
        e = e[:, None]
    fr = np.asarray(frames, dtype=np.float64)
    from ..sh.rotation import rotate

    return rotate(e, np.swapaxes(fr, -1, -2))


@dataclass
class Bake:
    """Per-vertex tangent-space coefficients: ``h`` (V, n, C) H coefficients (n = 6 or 4),
    ``sh`` (V, 9, C) the tangent-space quadratic SH of the same irradiance (for comparison),
    ``frames`` (V, 3, 3) the tangent frames they are expressed in."""

    h: NDArray[np.float64]
    sh: NDArray[np.float64]
    frames: NDArray[np.float64]


def load_bake(path: str | os.PathLike[str], mesh: Any = None) -> Bake:
    """Read a ``shprobe hbasis bake`` .npz (arrays ``h``, ``sh9``, ``frames``, ``mesh_hash``).

    With ``mesh`` (a trimesh), refuse a file baked for another mesh: its ``mesh_hash``
    (:func:`shprobe.prt.scene.mesh_hash` of the vertices and faces) must match. One-line
    :class:`ShprobeError` on any problem.
    """
    from pathlib import Path

    p = Path(path)
    if not p.is_file():
        raise ShprobeError("no such file", p)
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as e:
        raise ShprobeError(f"cannot read baked coefficients: {e}", p) from None
    missing = [k for k in ("h", "sh9", "frames", "mesh_hash") if k not in data]
    if missing:
        raise ShprobeError(f"not a 'shprobe hbasis bake' file (missing {', '.join(missing)})",
                           p)
    h, sh9, fr = (np.asarray(data[k], dtype=np.float64) for k in ("h", "sh9", "frames"))
    v = h.shape[0] if h.ndim == 3 else -1
    if (h.ndim != 3 or h.shape[1] not in (4, 6) or sh9.shape[:2] != (v, 9)
            or fr.shape != (v, 3, 3) or sh9.shape[2] != h.shape[2]):
        raise ShprobeError(f"inconsistent baked arrays h {h.shape}, sh9 {sh9.shape}, "
                           f"frames {fr.shape}", p)
    if mesh is not None:
        from ..prt.scene import mesh_hash

        want, got = mesh_hash(mesh.vertices, mesh.faces), str(data["mesh_hash"])
        if got != want:
            raise ShprobeError(f"was baked for another mesh (mesh hash {got[:12]}… ≠ "
                               f"{want[:12]}…); bake it again for this mesh", p)
    return Bake(h, sh9, fr)


def bake(irradiance_sh: ArrayLike, frames: ArrayLike, n: int = 6, lmax: int | None = 4) -> Bake:
    """Bake H_n coefficients per frame (H&W §4.1): T_h · rotate(E_lm, Fᵀ).

    ``irradiance_sh`` are world SH irradiance coefficients E_lm = Â_l L_lm (K, C). Bands up to
    ``lmax`` are used (default 4: the paper's T_h plus its Appendix A l = 4 block; 2: the
    paper's 6×9 T_h only; None: every band given, the exact hemispherical projection).
    """
    e = np.asarray(irradiance_sh, dtype=np.float64)
    if e.ndim == 1:
        e = e[:, None]
    if lmax is not None:
        e = e[: min(num_coeffs(lmax), e.shape[0])]
    tsh = to_tangent_sh(e, frames)
    lmax = lmax_of(tsh.shape[-2])
    h = np.matmul(sh_to_h_matrix(lmax, n), tsh)
    sh9 = tsh[..., : min(9, tsh.shape[-2]), :]
    return Bake(h, sh9, np.asarray(frames, dtype=np.float64))


def shade_h(h: ArrayLike, tangent_normals: ArrayLike) -> NDArray[np.float64]:
    """E_H(v) = Σ h_i Hⁱ(v) (eq. 15) for coefficients (..., n, C) at tangent normals (..., 3)."""
    return evaluate_h(h, tangent_normals)


def shade_sh(sh: ArrayLike, tangent_normals: ArrayLike) -> NDArray[np.float64]:
    """Σ e_k y_k(v) for tangent-space SH coefficients (..., K, C) at tangent normals (..., 3)."""
    s = np.asarray(sh)
    y = sh_basis(np.asarray(tangent_normals, dtype=np.float64), lmax_of(s.shape[-2]))
    return np.einsum("...k,...kc->...c", y, s)


def bump_normals(u: ArrayLike, v: ArrayLike, amplitude: float = 0.3,
                 frequency: float = 4.0) -> NDArray[np.float64]:
    """Tangent-space normals of the height field h = A sin(2πfu) sin(2πfv) (procedural normal
    map): normalize(−∂h/∂u, −∂h/∂v, 1)."""
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    w = 2 * np.pi * frequency
    du = amplitude * w * np.cos(w * u) * np.sin(w * v)
    dv = amplitude * w * np.sin(w * u) * np.cos(w * v)
    return _unit(np.stack([-du, -dv, np.ones_like(du)], axis=-1))


def bump_world(points: ArrayLike, normals: ArrayLike, amplitude: float = 0.3,
               frequency: float = 20.0) -> NDArray[np.float64]:
    """Perturbed world normals of a UV-free procedural bump h(p) = A Π sin(f p_i) / f applied
    along the surface: n' = normalize(n − (∇h − (∇h·n) n))."""
    p = np.asarray(points, dtype=np.float64)
    n = _unit(np.asarray(normals, dtype=np.float64))
    s, c = np.sin(frequency * p), np.cos(frequency * p)
    g = amplitude * np.stack([c[..., 0] * s[..., 1] * s[..., 2], s[..., 0] * c[..., 1] * s[..., 2],
                              s[..., 0] * s[..., 1] * c[..., 2]], axis=-1)
    gs = g - np.sum(g * n, axis=-1, keepdims=True) * n
    return _unit(n - gs)


def read_normal_map(path) -> NDArray[np.float64]:
    """Tangent-space normals (H, W, 3) from an RGB normal-map image (n = 2c − 1, c in [0, 1])."""
    from PIL import Image

    try:
        img = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    except OSError as e:
        raise ShprobeError(f"cannot read normal map: {e}", path) from None
    return _unit(2.0 * img - 1.0)


@dataclass
class RenderResult:
    """Orthographic render (camera on +Z looking along −Z, +Y up) of a normal-mapped mesh.

    ``images`` maps "reference", "H6" (when the bake has 6 functions), "H4", "SH9" to
    (H, W, 3) irradiance images (NaN where no surface was hit); ``rel_rms`` the RMS error over
    hit pixels and channels divided by the RMS of the reference irradiance there. Per hit
    pixel (P of them, in the order of ``pixel_index``, flat indices into H × W):
    ``world_normals`` the perturbed world normal n′, ``tangent_normals`` v = F_pᵀ n′ in the
    interpolated frame ``pixel_frames`` F_p, ``triangles`` the hit face and ``bary`` the
    barycentric weights used to interpolate the per-vertex coefficients.
    """

    images: dict[str, NDArray[np.float64]]
    rel_rms: dict[str, float]
    mask: NDArray[np.bool_]
    pixel_index: NDArray[np.int64] | None = None
    world_normals: NDArray[np.float64] | None = None
    tangent_normals: NDArray[np.float64] | None = None
    pixel_frames: NDArray[np.float64] | None = None
    triangles: NDArray[np.int64] | None = None
    bary: NDArray[np.float64] | None = None


def load_mesh(path):
    """A triangle mesh (trimesh) with vertex normals; one-line error on bad input."""
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types for bad files
        raise ShprobeError(f"cannot read mesh: {e}", path) from None
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise ShprobeError("mesh has no triangles", path)
    return mesh


def mesh_uvs(mesh) -> NDArray | None:
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    return None if uv is None or len(uv) != len(mesh.vertices) else np.asarray(uv)


def render_normal_mapped(mesh, lighting, size: int = 256, bump_amplitude: float = 0.3,
                         bump_frequency: float | None = None,
                         normal_map: NDArray | None = None,
                         baked: Bake | None = None) -> RenderResult:
    """Render ``mesh`` under ``lighting`` (``_env.Lighting``) with a tangent-space
    ``normal_map`` (H, W, 3) looked up at the interpolated UV (nearest texel, v up, wrapping;
    green flipped on mirrored charts; needs UVs), or else a UV-free procedural bump
    (:func:`bump_world`), shading with per-vertex baked H6, H4 and tangent-space SH9
    (linearly interpolated, as the paper's per-vertex variant), against the reference E(n') at
    the perturbed world normal: brute force over the probe's pixels, or the lighting's own SH
    expansion (lmax ≥ 2) when only coefficients were given. ``baked``: per-vertex coefficients
    from :func:`bake` / :func:`load_bake` for this mesh (with their frames) instead of baking
    here (H4-only bakes give no "H6" image)."""
    from ..sh.zonal import clamped_cosine_factors, convolve
    from ._env import brute_force_irradiance

    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    frames = tangent_frames(v, f, np.asarray(mesh.vertex_normals), mesh_uvs(mesh))
    lmax = lmax_of(lighting.sh.shape[0])
    e = convolve(lighting.sh, clamped_cosine_factors(lmax))
    if baked is None:
        bk = bake(e, frames.matrix, n=6)
    else:
        if baked.h.shape[0] != len(v) or baked.frames.shape != (len(v), 3, 3):
            raise ShprobeError(f"baked coefficients are for {baked.h.shape[0]} vertices, the "
                               f"mesh has {len(v)}")
        bk = baked
        frames = Frames(np.asarray(baked.frames, dtype=np.float64), frames.handedness)

    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = float(max(hi[0] - lo[0], hi[1] - lo[1])) * 1.05
    c = 0.5 * (lo + hi)
    px = (np.arange(size) + 0.5) / size - 0.5
    xx, yy = np.meshgrid(c[0] + ext * px, c[1] - ext * px)
    origins = np.stack([xx, yy, np.full_like(xx, hi[2] + ext)], axis=-1).reshape(-1, 3)
    dirs = np.broadcast_to([0.0, 0.0, -1.0], origins.shape)
    loc, iray, itri = mesh.ray.intersects_location(origins, dirs, multiple_hits=False)
    from trimesh.triangles import points_to_barycentric

    bary = points_to_barycentric(mesh.triangles[itri], loc)
    tri = f[itri]  # (P, 3)

    def interp(a: NDArray) -> NDArray:
        return np.einsum("pi,pi...->p...", bary, a[tri])

    nrm = _unit(interp(frames.matrix[..., 2]))
    tan = interp(frames.matrix[..., 0])
    tan = _unit(tan - np.sum(tan * nrm, -1, keepdims=True) * nrm)
    fp = np.stack([tan, np.cross(nrm, tan), nrm], axis=-1)
    if normal_map is not None:
        uvs = mesh_uvs(mesh)
        if uvs is None:
            raise ShprobeError("a normal-map image needs a mesh with UVs")
        nm = np.asarray(normal_map, dtype=np.float64)
        uvp = interp(uvs)
        col = np.floor(uvp[:, 0] * nm.shape[1]).astype(np.int64) % nm.shape[1]
        row = np.floor((1.0 - uvp[:, 1]) * nm.shape[0]).astype(np.int64) % nm.shape[0]
        vt = nm[row, col].copy()
        vt[:, 1] *= np.where(interp(frames.handedness) < 0, -1.0, 1.0)
        vt = _unit(vt)
        nw = np.einsum("pij,pj->pi", fp, vt)
    else:
        freq = bump_frequency if bump_frequency is not None else 60.0 / ext
        nw = bump_world(loc, nrm, bump_amplitude, freq)
        vt = np.einsum("pji,pj->pi", fp, nw)  # tangent-space normal Fᵀ n'
    vals = {}
    if bk.h.shape[1] == 6:
        vals["H6"] = shade_h(interp(bk.h), vt)
    vals["H4"] = shade_h(interp(bk.h[:, :4]), vt)
    vals["SH9"] = shade_sh(interp(bk.sh), vt)
    if lighting.dirs is not None:
        ref = brute_force_irradiance(lighting, nw)
    else:
        ref = shade_sh(e[None], nw)
    vals = {"reference": ref, **vals}
    mask = np.zeros(size * size, dtype=bool)
    mask[iray] = True
    images = {}
    for k, val in vals.items():
        img = np.full((size * size, 3), np.nan)
        img[iray] = val
        images[k] = img.reshape(size, size, 3)
    scale = float(np.sqrt(np.mean(ref**2)))
    rel = {k: float(np.sqrt(np.mean((vals[k] - ref) ** 2)) / scale)
           for k in vals if k != "reference"}
    return RenderResult(images, rel, mask.reshape(size, size), np.asarray(iray, dtype=np.int64),
                        nw, vt, fp, np.asarray(itri, dtype=np.int64), bary)


def panel_image(res: RenderResult, gain: float = 4.0) -> NDArray[np.uint8]:
    """2×4 panel (2×3 without H6), 8-bit sRGB-ish: top reference | H6 | H4 | SH9, bottom
    |error|×gain."""
    ref = res.images["reference"]
    scale = np.nanpercentile(ref, 99) or 1.0

    def tone(x: NDArray) -> NDArray:
        y = np.clip(np.nan_to_num(x / scale, nan=0.0), 0, 1) ** (1 / 2.2)
        return (255 * y + 0.5).astype(np.uint8)

    keys = [k for k in ("H6", "H4", "SH9") if k in res.images]
    top = [tone(res.images[k]) for k in ("reference", *keys)]
    blank = np.zeros_like(ref)
    bot = [tone(blank)] + [tone(gain * np.abs(res.images[k] - ref)) for k in keys]
    return np.concatenate([np.concatenate(top, 1), np.concatenate(bot, 1)], 0)
