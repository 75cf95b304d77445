"""Irradiance normal mapping with the H-basis (Habel & Wimmer 2010 §4.1–4.3): per-vertex bakes,
shading, procedural and image normal maps.

Baking (§4.1): the world irradiance E(ω) = Σ e_lm y_lm(ω) (e = Â_l L_lm) becomes, in the
tangent frame F (`shprobe.hbasis.frames`), the function v ↦ E(F v) = (E∘F)(v); since
``shprobe.sh.rotation.rotate(c, R)`` returns the coefficients of f∘R⁻¹, the tangent-space SH
coefficients are ``rotate(e, Fᵀ)``, and the H coefficients are T_h times them. Shading (§4.2,
eq. 15) evaluates Σ h_i Hⁱ(v) at the tangent-space normal v read from a normal map.

Lighting: an environment map ([`shprobe.probes.env.load_env`][shprobe.probes.env.load_env], any
layout), projected with [`shprobe.lighting.project`][shprobe.lighting.project] to l ≤ 16; or SH
radiance coefficients L_lm (K, 3) — as `shprobe.lighting.source.resolve_lighting` gives them. Bake
files: `shprobe.hbasis.bakefile`; rendering against the exact reference: `shprobe.hbasis.rendering`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from ..lighting import irradiance_coeffs, project
from ..lighting.coeffs import as_rgb
from ..probes.env import Env
from ..scene import mesh_hash, mesh_uvs
from ..sh import lmax_of, num_coeffs, sh_basis
from ..sh.rotation import unit_vectors
from .basis import evaluate_h, sh_to_h_matrix
from .frames import tangent_frames, to_tangent_sh

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = [
    "LIGHTING_LMAX",
    "NormalMapBake",
    "bake_mesh",
    "bake_normalmap",
    "bump_normals",
    "bump_world",
    "lighting_coeffs",
    "read_normal_map",
    "shade_h",
    "shade_sh",
]

#: Degree of the SH expansion of an environment map's radiance kept by the bake (and used for
#: the per-vertex coefficients): high enough that the bands the bake drops hardly matter.
LIGHTING_LMAX = 16


@dataclass
class NormalMapBake:
    """Per-vertex tangent-space coefficients: ``h`` (V, n, C) H coefficients (n = 6 or 4),
    ``sh`` (V, 9, C) the tangent-space quadratic SH of the same irradiance (for comparison),
    ``frames`` (V, 3, 3) the tangent frames they are expressed in. A bake of a mesh
    ([`bake_mesh`][shprobe.hbasis.normalmap.bake_mesh], `load_bake`) also has the frames'
    ``handedness`` (V,), the probe's radiance SH ``lighting`` L_lm (K, 3), the SH ``bands``
    projected into H and the ``mesh_hash`` of the mesh it belongs to."""

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

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary of the bake (not its arrays).

        Returns
        -------
        dict
            basis, vertices, channels, bands and the mesh hash.
        """
        return {"basis": self.basis, "vertices": int(self.h.shape[0]),
                "coefficients": int(self.h.shape[1]), "channels": int(self.h.shape[2]),
                "bands": self.bands, "mesh_hash": self.mesh_hash}

    def __repr__(self) -> str:
        mesh = f", mesh {self.mesh_hash[:12]}…" if self.mesh_hash else ""
        return (f"NormalMapBake({self.h.shape[0]} vertices, {self.basis}, {self.h.shape[2]} "
                f"channels{'' if self.bands is None else f', bands ≤ {self.bands}'}{mesh})")


def bake_normalmap(irradiance_sh: ArrayLike, frames: ArrayLike, n: int = 6,
                   lmax: int | None = 4) -> NormalMapBake:
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
    return NormalMapBake(h, sh9, np.asarray(frames, dtype=np.float64))


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


def lighting_coeffs(lighting: Env | ArrayLike) -> NDArray[np.float64]:
    """Radiance SH L_lm (K, 3): an Env projected to l ≤ `LIGHTING_LMAX` (R&H eq. 10),
    or the coefficients given."""
    if isinstance(lighting, Env):
        return project(lighting, LIGHTING_LMAX)
    return as_rgb(lighting, what="SH lighting coefficients")


def bake_mesh(mesh: trimesh.Trimesh, lighting: Env | ArrayLike, n: int = 6,
              bands: int = 4) -> NormalMapBake:
    """Bake per-vertex tangent-space H_n coefficients of ``mesh`` under ``lighting`` (an Env
    or radiance SH (K, 3)), with SH bands ≤ ``bands`` of the irradiance projected into H (2:
    the paper's T_h; 4: + Appendix A). Keeps the frames' handedness, the lighting's SH and the
    mesh hash, so the bake can be saved (`save_bake`) and rendered later.

    Parameters
    ----------
    mesh
        The mesh (its vertex normals and UVs give the tangent frames).
    lighting
        An Env, or radiance SH coefficients (K, 3).
    n
        4 (H4) or 6 (H6).
    bands
        The SH bands of the irradiance projected into H: 2 (the paper's T_h) or 4.

    Returns
    -------
    NormalMapBake
        Per-vertex H coefficients with their frames, the lighting's SH and the mesh hash.
    """
    L = lighting_coeffs(lighting)
    e = irradiance_coeffs(L)
    fr = tangent_frames(mesh.vertices, mesh.faces, np.asarray(mesh.vertex_normals),
                        mesh_uvs(mesh))
    b = min(int(bands), lmax_of(L.shape[0]))
    bk = bake_normalmap(e[: num_coeffs(b)], fr.matrix, n=n, lmax=bands)
    return NormalMapBake(bk.h, bk.sh, fr.matrix, fr.handedness, L, b,
                mesh_hash(mesh.vertices, mesh.faces))
