"""Bake files of ``shprobe hbasis bake``: an .npz of ``h`` (V, n, C), ``sh9`` (V, 9, C),
``frames`` (V, 3, 3), ``handedness`` (V,) int8, ``t_h``, ``basis``, ``bands``, ``L`` (the probe's
radiance SH, l ≤ 16) and ``mesh_hash`` ([`shprobe.scene.mesh_hash`][shprobe.prt.mesh_hash]), written
atomically; on load every array's header is checked (shapes, types, sizes) before anything is
inflated, and a bake is refused for another mesh."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ShprobeError
from ..files import load_npz, npz_headers, save_npz
from ..scene import mesh_hash
from .basis import sh_to_h_matrix
from .normalmap import NormalMapBake

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

__all__ = ["BAKE_FORMAT", "MAX_BAKE_BYTES", "is_bake", "load_bake", "save_bake"]

#: ``format`` entry of a bake file.
BAKE_FORMAT = "shprobe-hbasis-bake"
#: A bake file whose arrays would take more memory than this is refused before reading.
MAX_BAKE_BYTES = 8 << 30


def save_bake(path: str | os.PathLike[str], bk: NormalMapBake, overwrite: bool = False
              ) -> Path:
    """Write a mesh's bake (from [`bake_mesh`][shprobe.hbasis.normalmap.bake_mesh]) as .npz,
    atomically (an existing file is replaced only with ``overwrite``)."""

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


def load_bake(path: str | os.PathLike[str], mesh: trimesh.Trimesh | None = None) -> NormalMapBake:
    """Read a bake file (`save_bake`, ``shprobe hbasis bake``).

    Every array's shape and type is checked from its header before anything is inflated; with
    ``mesh``, a file baked for another mesh (another [`mesh_hash`][shprobe.prt.mesh_hash]) is
    refused. One-line [`ShprobeError`][shprobe.errors.ShprobeError] naming the file on any problem.
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
    return NormalMapBake(h, sh9, fr, hand, L, bands, got)
