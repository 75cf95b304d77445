"""Files uploaded through the page: kept in a private temporary folder under names the server
chooses (only a known extension of the user's name is kept; no path from the page is ever
opened), bounded in size before they are read (`MAX_UPLOAD` on the declared length and
while streaming; an ``.npz`` by the inflated size of its arrays, `MAX_INFLATED`)."""

from __future__ import annotations

import os
import shutil
import tempfile
import threading
from pathlib import Path

from ..errors import ShprobeError
from .wire import unpack_files

__all__ = ["EXTENSIONS", "MAX_INFLATED", "MAX_UPLOAD", "Uploads"]

#: largest upload accepted (bytes)
MAX_UPLOAD = 512 << 20
#: largest total size of the arrays of an uploaded ``.npz`` once inflated (bytes): four times
#: the upload limit, so that a small compressed file cannot expand to gigabytes
MAX_INFLATED = 4 * MAX_UPLOAD
#: extensions accepted per kind of upload
EXTENSIONS = {
    "probe": (".hdr", ".exr", ".pfm", ".tif", ".tiff", ".png", ".jpg", ".jpeg"),
    "mesh": (".obj", ".ply", ".gltf", ".glb", ".stl", ".off"),
    "coeffs": (".json", ".txt", ".glsl", ".hlsl", ".wgsl"),
    "transfer": (".npz",),
}


def _mib(n: float) -> str:
    return f"{n / (1 << 20):.0f} MiB"


class Uploads:
    """The session's private folder of uploaded files."""

    def __init__(self) -> None:
        self._dir = tempfile.TemporaryDirectory(prefix="shprobe-view-")
        self._n = 0
        self._lock = threading.Lock()

    def reserve(self, filename: str, kinds: tuple[str, ...]) -> tuple[Path, str]:
        """A new path in the folder for an upload named ``filename`` by the page, of one of
        ``kinds``; → (path, shown name). Refuses an unknown extension."""
        base = os.path.basename(str(filename).replace("\\", "/"))[:200] or "upload"
        ext = os.path.splitext(base)[1].lower()
        ok = tuple(e for k in kinds for e in EXTENSIONS[k])
        if ext not in ok:
            raise ShprobeError(f"{base}: cannot load a {'/'.join(kinds)} with extension "
                               f"{ext[:20] or '(none)'!r}; expected one of {' '.join(ok)}")
        with self._lock:
            self._n += 1
            return Path(self._dir.name) / f"upload-{self._n}{ext}", base

    @staticmethod
    def check_npz(path: Path, name: str) -> None:
        """Refuse an ``.npz`` whose arrays would inflate past `MAX_INFLATED`, from the
        headers of its members ([`shprobe.files.npz_headers`][shprobe.files.npz_headers]; nothing is
        inflated)."""
        import numpy as np

        from ..files import npz_headers

        try:
            heads = npz_headers(path, "transfer file")
        except ShprobeError as e:
            raise ShprobeError(f"{name}: {e.message}") from None
        total = sum(float(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                    for shape, dtype, _ in heads.values())
        if total > MAX_INFLATED:
            raise ShprobeError(f"{name}: its arrays inflate to {_mib(total)}, over the "
                               f"{_mib(MAX_INFLATED)} an upload may hold")

    def split(self, path: Path, most: int = 6) -> tuple[list[str], list[str]]:
        """The files of a multi-file upload (`unpack_files`) at
        ``path``, each stored as a probe upload; → (paths, shown names) in the page's order."""
        size = path.stat().st_size
        paths, names = [], []
        with open(path, "rb") as f:
            for name, off, n in unpack_files(f, size, most):
                p, shown = self.reserve(name, ("probe",))
                f.seek(off)
                with open(p, "wb") as out:
                    shutil.copyfileobj(_Limited(f, n), out, 1 << 20)
                paths.append(str(p))
                names.append(shown)
        path.unlink(missing_ok=True)
        return paths, names

    def close(self) -> None:
        self._dir.cleanup()


class _Limited:
    """The next ``n`` bytes of a file, for `shutil.copyfileobj`."""

    def __init__(self, f, n: int) -> None:
        self.f, self.left = f, n

    def read(self, k: int = -1) -> bytes:
        k = self.left if k < 0 else min(k, self.left)
        data = self.f.read(k) if k > 0 else b""
        self.left -= len(data)
        return data
