"""What a viewer session draws besides the lighting (`SceneFiles`, a part of
`Session`): the mesh (its page arrays possibly from the loader,
the trimesh object loaded on first use), a PRT transfer (``shprobe prt bake``) and an H-basis
bake (``shprobe hbasis bake``) checked against the mesh; each file given to the wrong option is
named as what it is."""

from __future__ import annotations

import os
import threading
from typing import Any

import numpy as np

from ..errors import ShprobeError
from .design import DESIGN_LMAX
from .payloads import ground_mask, mesh_payload, view_cameras
from .source import Source
from .wire import pack_binary

__all__ = ["SceneFiles"]


class SceneFiles:
    """The session's mesh, transfer and H-basis bake. Needs, from the session: ``_mesh``,
    ``_mesh_path``, ``_mesh_bytes``, ``_mesh_lock``, ``mesh_name``, ``transfer``,
    ``transfer_name``, ``hbasis_bake`` and ``hbasis_name``."""

    _mesh: Any
    _mesh_path: str | None
    _mesh_bytes: bytes | None
    _mesh_lock: threading.RLock
    mesh_name: str
    transfer: Any
    transfer_name: str | None
    hbasis_bake: Any
    hbasis_name: str | None

    @property
    def mesh(self) -> Any:
        """The trimesh mesh drawn (None: the built-in sphere); a mesh the loading process
        read for the first frame is loaded here on first use."""
        with self._mesh_lock:
            if self._mesh is None and self._mesh_path is not None:
                from ..scene import load_mesh

                self._mesh = load_mesh(self._mesh_path)
            return self._mesh

    def load_mesh(self, path: str, name: str | None = None) -> None:
        from ..scene import load_mesh

        m = load_mesh(path)
        with self._mesh_lock:
            self._mesh, self._mesh_path, self._mesh_bytes = m, None, None
            self.mesh_name = name or os.path.basename(path)
        self.hbasis_bake = None  # per vertex of the mesh it was baked for

    def load_transfer(self, path: str, name: str | None = None) -> None:
        """A transfer file (``shprobe prt bake``), read by the library's checked reader; an
        H-basis bake given instead is named as one."""
        from ..hbasis.bakefile import is_bake
        from ..prt.transfer import load_transfer

        if is_bake(path):
            raise ShprobeError("is an H-basis bake (`shprobe hbasis bake`), not a PRT "
                               "transfer: open it with `shprobe view --hbasis FILE` or the "
                               "page's H-basis loader", name or path)
        self.transfer = load_transfer(path)
        self.transfer_name = name or os.path.basename(path)

    def _read_hbasis(self, path: str, name: str | None = None) -> None:
        """Read a ``shprobe hbasis bake`` file (`load_bake`);
        a PRT transfer given instead is named as one."""
        from ..hbasis.bakefile import is_bake, load_bake

        shown = name or os.path.basename(path)
        if not is_bake(path) and str(path).lower().endswith(".npz"):
            from ..files import npz_headers

            try:
                heads = npz_headers(path, "bake file")
            except ShprobeError:
                heads = {}
            if "vertices" in heads:
                raise ShprobeError("is a PRT transfer (`shprobe prt bake`), not an H-basis "
                                   "bake: open it with `shprobe view --transfer FILE`",
                                   name or path)
        self.hbasis_bake = load_bake(path)
        self.hbasis_name = shown

    def _check_hbasis(self, bake: Any, path: Any) -> None:
        """Refuse a bake made for another mesh than the one shown (one line)."""
        from ..scene import mesh_hash

        m = self.mesh
        if m is None:
            raise ShprobeError("an H-basis bake is per vertex of its mesh: give that mesh "
                               "with --mesh", path)
        if mesh_hash(m.vertices, m.faces) != bake.mesh_hash:
            raise ShprobeError(f"was baked for another mesh than {self.mesh_name}: give the "
                               "mesh it was baked for with --mesh", path)

    def load_hbasis(self, path: str, name: str | None = None) -> None:
        """An H-basis bake (``shprobe hbasis bake``) for the mesh shown, checked against it
        (the bake shown before is kept when this one is refused)."""
        keep = (self.hbasis_bake, self.hbasis_name)
        try:
            self._read_hbasis(path, name)
            self._check_hbasis(self.hbasis_bake, name or path)
        except BaseException:
            self.hbasis_bake, self.hbasis_name = keep
            raise

    def _bake_source(self) -> Source:
        """The lighting an H-basis bake was made for (its radiance SH, to the design's
        highest degree) as the source."""
        L = np.asarray(self.hbasis_bake.lighting, np.float64)
        return Source(f"{self.hbasis_name} (baked lighting)", L[: (DESIGN_LMAX + 1) ** 2])

    def mesh_bytes(self) -> bytes:
        """The page's mesh (`mesh_payload`), made once per mesh (under the mesh lock: an
        upload meanwhile waits, so the payload cached is always the current mesh's)."""
        with self._mesh_lock:
            if self._mesh_bytes is None:
                self._mesh_bytes = mesh_payload(self.mesh, self.mesh_name)
            return self._mesh_bytes

    def transfer_bytes(self, mode: str | None, bounces: int | None) -> bytes:
        t = self.transfer
        if t is None:
            raise ShprobeError("no transfer: start `shprobe view --transfer T.npz`")
        T = t.select(mode, bounces)
        v = np.asarray(t.vertices)
        # framed on the object; the ground plane (the last vertices) is seen around it
        flat = ground_mask(v, t.normals, bool(t.metadata.get("ground")))
        ng = int(flat.sum())
        obj = v[~flat] if ng < len(v) else v
        c = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
        r = float(np.sqrt(((obj - c) ** 2).sum(axis=1).max()))
        return pack_binary(
            {"name": self.transfer_name, "lmax": t.lmax, "modes": list(t.modes),
             "max_bounces": t.max_bounces, "mode": mode or t.mode, "bounces": bounces,
             "ground_vertices": ng, "center": c.tolist(), "radius": r,
             **view_cameras(c, r, ground=ng > 0)},
            {"position": v, "normal": t.normals, "index": t.faces,
             "transfer": T.reshape(T.shape[0], -1)})
