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

Lighting: an environment map (:func:`shprobe.probes.layouts.load_env`, any layout), projected
with :func:`shprobe.lighting.project` to l ≤ 16, with the brute-force reference
:func:`shprobe.lighting.reference_irradiance`; or SH radiance coefficients L_lm (K, 3), whose
own expansion is then the reference. Rendering goes through the scene layer (one orthographic
:class:`~shprobe.scene.Camera`, the one ray caster) and returns its
:class:`~shprobe.scene.RenderResult`.

Bake files (:func:`save_bake` / :func:`load_bake`): an .npz of ``h`` (V, n, C), ``sh9``
(V, 9, C), ``frames`` (V, 3, 3), ``handedness`` (V,) int8, ``t_h``, ``basis``, ``bands``, ``L``
(the probe's radiance SH, l ≤ 16) and ``mesh_hash`` (:func:`shprobe.scene.mesh_hash`), written
atomically; on load every array's header is checked (shapes, types, sizes) before anything is
inflated, and a bake is refused for another mesh.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..files import load_npz, npz_headers, save_npz
from ..lighting import irradiance, irradiance_coeffs, project, reference_irradiance
from ..probes.layouts import Env
from ..scene import (
    Camera,
    RenderResult,
    mesh_hash,
    mesh_uvs,
    render_result,
    sample_texture,
    trace,
)
from ..sh import lmax_of, num_coeffs, sh_basis
from ..sh.rotation import frame_from_normal, unit_vectors
from .basis import evaluate_h, sh_to_h_matrix

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = [
    "LIGHTING_LMAX",
    "Bake",
    "Frames",
    "bake",
    "bake_mesh",
    "bump_normals",
    "bump_world",
    "frame_from_normal",
    "is_bake",
    "lighting_coeffs",
    "load_bake",
    "panel_image",
    "read_lighting",
    "read_normal_map",
    "render_normal_mapped",
    "save_bake",
    "save_panel",
    "shade_h",
    "shade_sh",
    "tangent_frames",
    "to_tangent_sh",
]

#: Degree of the SH expansion of an environment map's radiance kept by the bake (and used for
#: the per-vertex coefficients): high enough that the bands the bake drops hardly matter.
LIGHTING_LMAX = 16


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
    n = unit_vectors(normals, "normals", zero="keep")
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
    ``frames`` (V, 3, 3) the tangent frames they are expressed in. A bake of a mesh
    (:func:`bake_mesh`, :func:`load_bake`) also has the frames' ``handedness`` (V,), the
    probe's radiance SH ``lighting`` L_lm (K, 3), the SH ``bands`` projected into H and the
    ``mesh_hash`` of the mesh it belongs to."""

    h: NDArray[np.float64]
    sh: NDArray[np.float64]
    frames: NDArray[np.float64]
    handedness: NDArray[np.float64] | None = None
    lighting: NDArray[np.float64] | None = None
    bands: int | None = None
    mesh_hash: str | None = None

    @property
    def basis(self) -> str:
        """"H6" or "H4"."""
        return f"H{self.h.shape[1]}"

    def __repr__(self) -> str:
        mesh = f", mesh {self.mesh_hash[:12]}…" if self.mesh_hash else ""
        return (f"Bake({self.h.shape[0]} vertices, {self.basis}, {self.h.shape[2]} channels"
                f"{'' if self.bands is None else f', bands ≤ {self.bands}'}{mesh})")


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
    return unit_vectors(np.stack([-du, -dv, np.ones_like(du)], axis=-1), zero="keep")


def bump_world(points: ArrayLike, normals: ArrayLike, amplitude: float = 0.3,
               frequency: float = 20.0) -> NDArray[np.float64]:
    """Perturbed world normals of a UV-free procedural bump h(p) = A Π sin(f p_i) / f applied
    along the surface: n' = normalize(n − (∇h − (∇h·n) n))."""
    p = np.asarray(points, dtype=np.float64)
    n = unit_vectors(normals, "normals", zero="keep")
    s, c = np.sin(frequency * p), np.cos(frequency * p)
    g = amplitude * np.stack([c[..., 0] * s[..., 1] * s[..., 2], s[..., 0] * c[..., 1] * s[..., 2],
                              s[..., 0] * s[..., 1] * c[..., 2]], axis=-1)
    gs = g - np.sum(g * n, axis=-1, keepdims=True) * n
    return unit_vectors(n - gs, zero="keep")


def read_normal_map(path) -> NDArray[np.float64]:
    """Tangent-space normals (H, W, 3) from an RGB normal-map image (n = 2c − 1, c in [0, 1])."""
    from PIL import Image

    try:
        img = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    except OSError as e:
        raise ShprobeError(f"cannot read normal map: {e}", path) from None
    return unit_vectors(2.0 * img - 1.0, zero="keep")




# ----------------------------------------------------------------------------- lighting


def read_lighting(path: str | os.PathLike[str]) -> Env | NDArray[np.float64]:
    """Lighting from a file: an environment map (any layout :func:`load_env` detects), or an
    .npy / .npz of SH radiance coefficients L_lm (K, 3) or (K,) (npz: array ``L``, else
    ``coeffs``, else the first array — a bake file gives its probe's ``L``)."""
    from ..lighting import as_coeffs
    from ..probes.layouts import load_env

    p = Path(path)
    if not p.is_file():
        raise ShprobeError("no such file", p)
    if p.suffix.lower() not in (".npy", ".npz"):
        return load_env(p)
    try:
        if p.suffix.lower() == ".npy":
            c = np.load(p, allow_pickle=False)
        else:  # the checked reader (headers and sizes first; no file left open on a bad one)
            data = load_npz(p, what="file of SH coefficients")
            key = next((k for k in ("L", "coeffs") if k in data), None)
            if key is None and not data:
                raise ShprobeError("holds no array of SH coefficients", p)
            c = data[key or next(iter(data))]
    except ShprobeError:
        raise
    except Exception as e:  # numpy/zipfile raise many types on bad files
        raise ShprobeError(f"cannot read SH coefficients: {' '.join(str(e).split())[:200]}",
                           p) from None
    c = as_coeffs(c, p, "SH coefficients")
    if c.shape[1] == 1:
        c = np.repeat(c, 3, axis=1)
    if c.shape[1] != 3:
        raise ShprobeError(f"SH coefficients must be (K, 3), got {c.shape}", p)
    return c


def lighting_coeffs(lighting: Env | ArrayLike) -> NDArray[np.float64]:
    """Radiance SH L_lm (K, 3): an Env projected to l ≤ :data:`LIGHTING_LMAX` (R&H eq. 10),
    or the coefficients given."""
    if isinstance(lighting, Env):
        return project(lighting, LIGHTING_LMAX)
    from ..lighting import as_coeffs

    c = as_coeffs(lighting, what="SH lighting coefficients")
    return np.repeat(c, 3, axis=1) if c.shape[1] == 1 else c


# ----------------------------------------------------------------------------- bake files

#: ``format`` entry of a bake file.
BAKE_FORMAT = "shprobe-hbasis-bake"
#: A bake file whose arrays would take more memory than this is refused before reading.
MAX_BAKE_BYTES = 8 << 30


def bake_mesh(mesh: trimesh.Trimesh, lighting: Env | ArrayLike, n: int = 6,
              bands: int = 4) -> Bake:
    """Bake per-vertex tangent-space H_n coefficients of ``mesh`` under ``lighting`` (an Env
    or radiance SH (K, 3)), with SH bands ≤ ``bands`` of the irradiance projected into H (2:
    the paper's T_h; 4: + Appendix A). Keeps the frames' handedness, the lighting's SH and the
    mesh hash, so the bake can be saved (:func:`save_bake`) and rendered later."""
    L = lighting_coeffs(lighting)
    e = irradiance_coeffs(L)
    fr = tangent_frames(mesh.vertices, mesh.faces, np.asarray(mesh.vertex_normals),
                        mesh_uvs(mesh))
    b = min(int(bands), lmax_of(L.shape[0]))
    bk = bake(e[: num_coeffs(b)], fr.matrix, n=n, lmax=bands)
    return Bake(bk.h, bk.sh, fr.matrix, fr.handedness, L, b,
                mesh_hash(mesh.vertices, mesh.faces))


def save_bake(path: str | os.PathLike[str], bk: Bake, overwrite: bool = False) -> Path:
    """Write a mesh's bake (from :func:`bake_mesh`) as .npz, atomically (an existing file is
    replaced only with ``overwrite``)."""

    if bk.mesh_hash is None or bk.bands is None:
        raise ShprobeError("only a bake of a mesh (bake_mesh) can be saved: it needs the "
                           "mesh hash and bands")
    for name, a in (("h", bk.h), ("sh9", bk.sh), ("frames", bk.frames), ("L", bk.lighting)):
        if a is not None and not np.all(np.isfinite(a)):
            raise ShprobeError(f"refusing to write a bake with non-finite {name}", path)
    n = bk.h.shape[1]
    v = bk.h.shape[0]
    hand = np.zeros(v) if bk.handedness is None else bk.handedness
    arrays: dict[str, Any] = dict(
        h=bk.h, sh9=bk.sh, frames=bk.frames, handedness=np.asarray(hand).astype(np.int8),
        t_h=sh_to_h_matrix(bk.bands, n), basis=np.array(bk.basis), bands=np.array(bk.bands),
        mesh_hash=np.array(bk.mesh_hash), format=np.array(BAKE_FORMAT))
    if bk.lighting is not None:
        arrays["L"] = bk.lighting
    return save_npz(path, overwrite=overwrite, **arrays)


def is_bake(path: str | os.PathLike[str]) -> bool:
    """True for an .npz that looks like a bake file (it has arrays ``h`` and ``frames``)."""
    p = Path(path)
    if p.suffix.lower() != ".npz" or not p.is_file():
        return False
    try:
        with zipfile.ZipFile(p) as z:
            names = set(z.namelist())
    except (OSError, zipfile.BadZipFile):
        return False
    return {"h.npy", "frames.npy"} <= names


def load_bake(path: str | os.PathLike[str], mesh: trimesh.Trimesh | None = None) -> Bake:
    """Read a bake file (:func:`save_bake`, ``shprobe hbasis bake``).

    Every array's shape and type is checked from its header before anything is inflated; with
    ``mesh``, a file baked for another mesh (another :func:`mesh_hash`) is refused. One-line
    :class:`ShprobeError` naming the file on any problem.
    """
    p = Path(path)
    heads = npz_headers(p, "bake file")
    lying = [k for k, (_, _, ok) in heads.items() if not ok]
    if lying:
        raise ShprobeError(f"array {lying[0]} is not the size its header says (truncated or "
                           "malformed)", p)
    missing = [k for k in ("h", "sh9", "frames", "mesh_hash") if k not in heads]
    if missing:
        raise ShprobeError(f"not a 'shprobe hbasis bake' file (missing {', '.join(missing)})",
                           p)
    (hs, ht, _), (ss, st, _), (fs, ft, _) = heads["h"], heads["sh9"], heads["frames"]
    v = hs[0] if len(hs) == 3 else -1
    if (len(hs) != 3 or hs[1] not in (4, 6) or len(ss) != 3 or ss[:2] != (v, 9)
            or fs != (v, 3, 3) or ss[2] != hs[2]):
        raise ShprobeError(f"inconsistent baked arrays h {hs}, sh9 {ss}, frames {fs}", p)
    if any(t.kind != "f" for t in (ht, st, ft)):
        raise ShprobeError("baked arrays h, sh9 and frames must hold floats", p)
    if heads["mesh_hash"][1].kind != "U" or heads["mesh_hash"][0] != ():
        raise ShprobeError("mesh_hash must be one string", p)
    opt = {"handedness": ((v,), "iuf"), "bands": ((), "iu"), "format": ((), "U")}
    for k, (shape, kinds) in opt.items():
        if k in heads and (heads[k][0] != shape or heads[k][1].kind not in kinds):
            raise ShprobeError(f"array {k} has shape {heads[k][0]} / type {heads[k][1]}, "
                               f"expected {shape}", p)
    if "L" in heads:
        ls, lt, _ = heads["L"]
        if len(ls) != 2 or ls[1] != 3 or lt.kind != "f" or int(np.sqrt(ls[0])) ** 2 != ls[0]:
            raise ShprobeError(f"array L has shape {ls}, expected (K, 3) with K = (lmax+1)²",
                               p)
    need = sum(int(np.prod(s, dtype=np.int64)) * 8 for s, _, _ in heads.values())
    if need > MAX_BAKE_BYTES:
        raise ShprobeError(f"bake would take {need / 2**30:.1f} GiB (limit "
                           f"{MAX_BAKE_BYTES / 2**30:.0f} GiB)", p)
    data = load_npz(p, heads, "bake file")
    if "format" in data and str(data["format"]) != BAKE_FORMAT:
        raise ShprobeError(f"not a 'shprobe hbasis bake' file (format {str(data['format'])!r})",
                           p)
    h, sh9, fr = (np.asarray(data[k], dtype=np.float64) for k in ("h", "sh9", "frames"))
    L = np.asarray(data["L"], dtype=np.float64) if "L" in data else None
    for name, a in (("h", h), ("sh9", sh9), ("frames", fr), ("L", L)):
        if a is not None and not np.all(np.isfinite(a)):
            raise ShprobeError(f"array {name} holds NaN or infinity", p)
    got = str(data["mesh_hash"])
    if mesh is not None:
        want = mesh_hash(mesh.vertices, mesh.faces)
        if got != want:
            raise ShprobeError(f"was baked for another mesh (mesh hash {got[:12]}… ≠ "
                               f"{want[:12]}…); bake it again for this mesh", p)
    hand = (np.asarray(data["handedness"], dtype=np.float64) if "handedness" in data
            else None)
    bands = int(data["bands"]) if "bands" in data else None
    return Bake(h, sh9, fr, hand, L, bands, got)


# ----------------------------------------------------------------------------- rendering


def render_normal_mapped(mesh: trimesh.Trimesh, lighting: Env | ArrayLike, size: int = 256,
                         bump_amplitude: float = 0.3, bump_frequency: float | None = None,
                         normal_map: NDArray | None = None,
                         baked: Bake | None = None) -> RenderResult:
    """Render ``mesh`` under ``lighting`` (an Env, or radiance SH (K, 3)) with a tangent-space
    ``normal_map`` (H, W, 3) looked up bilinearly at the interpolated UV (u wraps, v up;
    green flipped on mirrored charts; needs UVs), or else a UV-free procedural bump
    (:func:`bump_world`), shading with per-vertex baked H6, H4 and tangent-space SH9
    (linearly interpolated, as the paper's per-vertex variant), against the reference E(n′) at
    the perturbed world normal: brute force over the probe's pixels
    (:func:`shprobe.lighting.reference_irradiance`), or the lighting's own SH expansion when
    only coefficients were given. ``baked``: per-vertex coefficients from :func:`bake` /
    :func:`load_bake` for this mesh (with their frames) instead of baking here (H4-only bakes
    give no "H6" image).

    The camera is orthographic on +Z looking along −Z, +Y up, framing the mesh's x–y extent.
    Returns a :class:`~shprobe.scene.RenderResult`: ``irradiance`` the reference E(n′) (and
    ``image`` = ``radiance`` = E/π, a white diffuse surface), ``normals`` the perturbed world
    normals n′; ``layers`` "H6" (6-function bakes), "H4", "SH9" (irradiance (H, W, 3)),
    "tangent_normals" v = F_pᵀ n′ and "frames" F_p (H, W, 3, 3), the frame interpolated at each
    pixel; ``info["rel_rms"]`` the RMS error of each basis over hit pixels and channels divided
    by the RMS of the reference there. Everything is 0 where no surface was hit (``mask``).
    """
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    frames = tangent_frames(v, f, np.asarray(mesh.vertex_normals), mesh_uvs(mesh))
    L = lighting_coeffs(lighting)
    e = irradiance_coeffs(L)
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
    cam = Camera(size, size, projection="orthographic", target=tuple(c), ortho_height=ext,
                 distance=float(hi[2] - c[2]) + ext)
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
    ref = reference_irradiance(lighting, nw) if isinstance(lighting, Env) else irradiance(L, nw)
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
    return render_result(hits, E / np.pi, E, cam, "normal-mapped", normals=full(nw),
                         layers=layers, info={"rel_rms": rel})


def panel_image(res: RenderResult, gain: float = 4.0) -> NDArray[np.float32]:
    """2×4 panel (2×3 without H6) of linear irradiance: top reference | H6 | H4 | SH9, bottom
    (blank) | |error| × gain of each basis. Write it with :func:`save_panel`."""
    ref = res.irradiance
    keys = [k for k in ("H6", "H4", "SH9") if k in res.layers]
    top = [ref, *(res.layers[k] for k in keys)]
    bot = [np.zeros_like(ref), *(gain * np.abs(res.layers[k] - ref) for k in keys)]
    return np.concatenate([np.concatenate(top, 1), np.concatenate(bot, 1)], 0).astype(
        np.float32)


def save_panel(path: str | os.PathLike[str], res: RenderResult, gain: float = 4.0,
               overwrite: bool = False) -> Path:
    """Write the comparison as a labelled figure (:mod:`shprobe.probes.figures`): top, the
    reference and each basis as E/π (the radiance of a white diffuse surface) at one exposure
    (the reference's 99th percentile at white); bottom, |basis − reference| / π on one shared
    error scale with its colour bar, each titled with the basis's relative RMS error. ``gain``
    is kept for the raw :func:`panel_image`; the figure's colour bar replaces it."""
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
    write_figure(path, rows, overwrite=overwrite, shared_colorbar=True,
                 title="normal mapping (H&W 2010): per-vertex bases vs exact E at n′")
    return Path(path)
