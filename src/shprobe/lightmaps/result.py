"""The result of a lightmap bake, [`Lightmap`][shprobe.lightmaps.Lightmap], and
[`load_lightmap`][shprobe.lightmaps.load_lightmap]."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ShprobeError
from .atlas import Atlas, Texels
from .format import N_COEFFS, check_encoding, evaluate, read_glb, read_lightmap
from .gather import bilinear
from .scene import LightmapScene

__all__ = ["Lightmap", "load_lightmap"]


@dataclass(eq=False)
class Lightmap:
    """A baked (or loaded) directional lightmap.

    Parameters
    ----------
    encodings : dict
        Encoding name → coefficient images (H, W, n, 3) float32 (a loaded file holds one).
    basis : str
        The encoding a .glb stores.
    valid : ndarray (H, W) bool
        Texels that were baked (the rest are dilated copies).
    stats : dict
        Figures of the bake (texels, rays, seconds, noise, ...).
    atlas : Atlas, optional
        The primitives as baked (for writing the .glb).
    texels : Texels, optional
        Per texel sample points and frames.
    scene : LightmapScene, optional
        The scene baked.
    noisy : dict, optional
        With ``denoise``: the encodings before denoising.
    transfer : dict, optional
        With ``transfer``: encoding name → (H, W, n, 9, 3) matrices from the sky's radiance
        SH (lmax 2, per colour) to the coefficients, shadows and bounces included (LH 2007
        §4, per texel); [`relight`][shprobe.lightmaps.Lightmap.relight] applies them. A sun is not
        part of them.
    """

    encodings: dict[str, NDArray[np.float32]] = field(repr=False)
    basis: str
    valid: NDArray[np.bool_] = field(repr=False)
    stats: dict[str, Any] = field(default_factory=dict, repr=False)
    atlas: Atlas | None = field(default=None, repr=False)
    texels: Texels | None = field(default=None, repr=False)
    scene: LightmapScene | None = field(default=None, repr=False)
    noisy: dict[str, NDArray[np.float32]] | None = field(default=None, repr=False)
    transfer: dict[str, NDArray[np.float32]] | None = field(default=None, repr=False)

    @property
    def width(self) -> int:
        """Texels across."""
        return int(self.valid.shape[1])

    @property
    def height(self) -> int:
        """Texels down."""
        return int(self.valid.shape[0])

    def __repr__(self) -> str:
        return (f"Lightmap({self.basis}, {self.width}x{self.height}, "
                f"{int(self.valid.sum())} texels)")

    def coefficients(self, encoding: str | None = None) -> NDArray[np.float32]:
        """Coefficient images (H, W, n, 3) of one encoding.

        Parameters
        ----------
        encoding : str, optional
            Default: the lightmap's basis.

        Returns
        -------
        ndarray (H, W, n, 3)
            Irradiance coefficients.
        """
        e = check_encoding(encoding or self.basis)
        if e not in self.encodings:
            raise ShprobeError(f"this lightmap holds {', '.join(self.encodings)}, not {e}")
        return self.encodings[e]

    def irradiance(self, points_or_texels: ArrayLike, normals: ArrayLike,
                   encoding: str | None = None) -> NDArray[np.float64]:
        """Irradiance (N, 3) at texels or lightmap UVs for tangent-frame normals (eq. 15).

        Parameters
        ----------
        points_or_texels : array_like (N, 2) or (N, 3)
            Integer (row, column) texels; float lightmap UVs (TEXCOORD_1) read bilinearly as
            a GPU samples the texture; or world-space surface points (N, 3), each read at the
            texel whose sample point is nearest (baked lightmaps).
        normals : array_like (N, 3)
            Unit normals in the texel's tangent frame (the normal map's normals).
        encoding : str, optional
            Default: the lightmap's basis.

        Returns
        -------
        ndarray (N, 3)
            E per colour.
        """
        c = self.coefficients(encoding)
        e = check_encoding(encoding or self.basis)
        q = np.asarray(points_or_texels)
        if q.ndim == 2 and q.shape[1] == 3:  # world points: their nearest texel's sample
            if self.texels is None:
                raise ShprobeError("world points need a baked lightmap (texel positions); "
                                   "a loaded one takes texels or TEXCOORD_1 UVs")
            from scipy.spatial import cKDTree

            _, i = cKDTree(self.texels.points).query(np.asarray(q, dtype=np.float64))
            q = self.texels.rc[i]
        if q.ndim != 2 or q.shape[1] != 2:
            raise ShprobeError(f"texels or UVs must be (N, 2), world points (N, 3); got "
                               f"{q.shape}")
        if q.dtype.kind in "iu":
            if (q < 0).any() or (q[:, 0] >= self.height).any() or (q[:, 1] >= self.width).any():
                raise ShprobeError("texel indices outside the lightmap")
            k = c[q[:, 0], q[:, 1]].astype(np.float64)
        else:
            n = N_COEFFS[e]
            k = bilinear(c.reshape(self.height, self.width, n * 3), q).reshape(-1, n, 3)
        return evaluate(e, k, normals)

    def relight(self, sky: ArrayLike) -> Lightmap:
        """The lightmap under another distant sky, from the transfer matrices.

        Parameters
        ----------
        sky : array_like (K >= 9, 3)
            World-frame radiance SH (cut to lmax 2), or a ``Lighting``.

        Returns
        -------
        Lightmap
            The encodings the transfer holds, relit (no sun).
        """
        if not self.transfer:
            raise ShprobeError("this lightmap has no transfer: bake it with transfer=True "
                               "(--transfer)")
        from .checks import sky_coeffs

        c = sky_coeffs(sky)
        enc = {k: np.einsum("hwnjc,jc->hwnc", v, c).astype(np.float32)
               for k, v in self.transfer.items()}
        return Lightmap(enc, self.basis if self.basis in enc else next(iter(enc)),
                        self.valid, {**self.stats, "relit": True}, self.atlas, self.texels,
                        self.scene)

    def as_dict(self) -> dict[str, Any]:
        """A JSON-able summary.

        Returns
        -------
        dict
            Basis, size, texel count and the bake's figures.
        """
        return {"basis": self.basis, "width": self.width, "height": self.height,
                "texels": int(self.valid.sum()), "encodings": list(self.encodings),
                "transfer": bool(self.transfer),
                **self.stats}

    def save(self, path: str | os.PathLike[str], overwrite: bool = False) -> None:
        """Write the scene with TEXCOORD_1 and the ``SHPROBE_lightmap`` textures as a .glb.

        Parameters
        ----------
        path : str or PathLike
            The output .glb (temporary file renamed into place).
        overwrite : bool
            Replace an existing file.
        """
        from .io import write_lightmap_glb

        write_lightmap_glb(self, path, overwrite)



def load_lightmap(path: str | os.PathLike[str]) -> Lightmap:
    """Read a lightmap .glb written by [`Lightmap.save`][shprobe.lightmaps.Lightmap.save] (or any
    ``SHPROBE_lightmap`` file).

    Parameters
    ----------
    path : str or PathLike
        The .glb.

    Returns
    -------
    Lightmap
        Its one encoding's coefficient images (half-float precision); ``valid`` marks every
        texel.
    """
    p = os.fspath(path)
    doc, binary = read_glb(p)
    s = read_lightmap(doc, binary, p)
    from .transfer_format import read_transfer

    valid = np.ones(s.coeffs.shape[:2], bool)
    t = read_transfer(doc, binary, p)
    extra = {k: v for k, v in s.extra.items() if k != "transfer"}
    if isinstance(s.extra.get("transfer"), dict) and "sky" in s.extra["transfer"]:
        extra["sky"] = s.extra["transfer"]["sky"]  # the sky of the bake
    return Lightmap({s.encoding: s.coeffs}, s.encoding, valid,
                    {"scale": s.scale, "primitives": [list(x) for x in s.primitives],
                     **extra}, transfer=None if t is None else {s.encoding: t})
