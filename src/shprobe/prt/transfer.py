"""The baked transfer: per-vertex transfer vectors with the scene they belong to, saved as .npz.

Radiance scale (one convention everywhere in ``shprobe.prt``): for lighting coefficients L_lm
(radiance), ``transfer[v] · L`` is the exit radiance of vertex v,

    B(v) = ρ_v/π · ( ∫ L(ω) V_v(ω) max(0, n_v·ω) dω  +  Σ bounces ),

so for the unshadowed model it is ρ/π times the irradiance E(n_v) = Σ Â_l L_lm y_lm(n_v)
(R&H eq. 7; LH eq. 9 with π H_l = Â_l).
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from ..files import save_npz
from ..sh import check_lmax, lmax_of, num_coeffs
from .scene import Scene, load_scene, mesh_hash

FORMAT = "shprobe-prt"
FORMAT_VERSION = 1
MODES = ("unshadowed", "shadowed", "interreflected")


@dataclass(frozen=True)
class Transfer:
    """Per-vertex transfer vectors and their scene.

    transfer: (V, K) float32, or (V, K, 3) when the albedo is coloured; K = (lmax+1)², flat SH
    index on axis 1. vertices/normals (V, 3), faces (F, 3), albedo (V, 3) as baked.
    metadata: mesh_hash, mode, lmax, samples, bounces, seed, albedo summary, and the scale.
    """

    transfer: NDArray[np.float32]
    vertices: NDArray[np.float64]
    normals: NDArray[np.float64]
    faces: NDArray[np.int64]
    albedo: NDArray[np.float64]
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def lmax(self) -> int:
        return lmax_of(self.transfer.shape[1])

    @property
    def mode(self) -> str:
        return str(self.metadata.get("mode", ""))

    @property
    def mesh_hash(self) -> str:
        return str(self.metadata.get("mesh_hash", ""))

    @property
    def n_vertices(self) -> int:
        return int(self.transfer.shape[0])

    def truncated(self, lmax: int) -> Transfer:
        """The same transfer at a lower degree: the first (lmax+1)² columns (no re-bake)."""
        lmax = check_lmax(lmax)
        if lmax > self.lmax:
            raise ShprobeError(f"transfer was baked to lmax={self.lmax}, cannot use lmax={lmax}")
        return replace(self, transfer=self.transfer[:, : num_coeffs(lmax)],
                       metadata={**self.metadata, "lmax": lmax})

    def scene(self) -> Scene:
        """The scene this transfer was baked for."""
        return Scene(self.vertices, self.normals, self.faces, self.albedo, self.mesh_hash)

    def save(self, path: str | os.PathLike[str], overwrite: bool = False) -> Path:
        """Write an .npz (atomic; an existing file is replaced only with ``overwrite``)."""
        meta = {"format": FORMAT, "version": FORMAT_VERSION, **self.metadata}
        return save_npz(path, overwrite=overwrite, transfer=self.transfer,
                        vertices=self.vertices, normals=self.normals, faces=self.faces,
                        albedo=self.albedo, metadata=np.array(json.dumps(meta)))


def load_transfer(path: str | os.PathLike[str], scene: Any = None) -> Transfer:
    """Read a transfer .npz; with ``scene`` (anything :func:`load_scene` takes: the mesh
    path(s) or object(s) given to :func:`~shprobe.prt.bake`; the ground plane is added again
    when the bake had one) refuse a file baked for another mesh (hash mismatch).
    """
    p = Path(path)
    if not p.is_file():
        raise ShprobeError("no such transfer file", p)
    if not zipfile.is_zipfile(p):
        raise ShprobeError("not a transfer file (not an .npz archive; empty, truncated or "
                           "another format)", p)
    names = ("transfer", "vertices", "normals", "faces", "albedo", "metadata")
    try:
        with np.load(p, allow_pickle=False) as d:
            missing = [k for k in names if k not in d.files]
            if missing:
                raise ShprobeError("not a shprobe transfer file (no "
                                   + ", ".join(missing) + " array)", p)
            arrays = {k: d[k] for k in names}
    except ShprobeError:
        raise
    except Exception as e:
        raise ShprobeError(f"cannot read transfer file (truncated or corrupt): "
                           f"{' '.join(str(e).split())[:200]}", p) from None
    try:
        meta = json.loads(str(arrays.pop("metadata")))
    except ValueError:
        raise ShprobeError("transfer metadata is not valid JSON", p) from None
    if meta.get("format") != FORMAT:
        raise ShprobeError("not a shprobe transfer file", p)
    if meta.get("mode") not in MODES:
        raise ShprobeError(f"unknown transfer mode {meta.get('mode')!r}", p)
    t = arrays["transfer"]
    v = arrays["vertices"]
    if t.ndim not in (2, 3) or t.shape[0] != v.shape[0] or (t.ndim == 3 and t.shape[2] != 3):
        raise ShprobeError(f"transfer array has shape {t.shape} for {v.shape[0]} vertices", p)
    try:
        lmax_of(t.shape[1])
    except ShprobeError as e:
        raise ShprobeError(e.message, p) from None
    if mesh_hash(v, arrays["faces"]) != meta.get("mesh_hash"):
        raise ShprobeError("stored mesh does not match the file's mesh hash (corrupt file)", p)
    if scene is not None:
        if isinstance(scene, Scene):
            want = scene.mesh_hash
        else:  # rebuild the scene as baked: the same meshes, with its ground plane if any
            want = load_scene(scene, ground=bool(meta.get("ground", False))).mesh_hash
        if want != meta["mesh_hash"]:
            raise ShprobeError(
                f"baked for mesh {meta['mesh_hash'][:12]}…, not for this mesh ({want[:12]}…); "
                "re-bake it", p)
    meta.pop("format", None)
    meta.pop("version", None)
    return Transfer(transfer=t, vertices=v, normals=arrays["normals"], faces=arrays["faces"],
                    albedo=arrays["albedo"], metadata=meta)
