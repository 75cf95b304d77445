"""A set of Gaussian splats in memory, as the 3DGS reference trainer stores them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError
from .conventions import MAX_DEGREE

_F32 = np.float32
#: Bytes of memory per float of the splats (the K·3 SH and 14 others) at the peak of reading
#: a whole file, by format (measured by bench/bench_estimates.py): the chunks or packed
#: bytes, their decoding in float64, the concatenated arrays; a PLY read adds a fixed 24 MB
#: (its chunks).
READ_BYTES_PER_FLOAT = {".ply": 7.5, ".spz": 12.6, ".glb": 20.0}
PLY_READ_BASE_BYTES = 24e6


def floats_per_splat(degree: int) -> int:
    """Floats of one splat in memory: (degree + 1)² RGB SH coefficients, position, scales,
    rotation, opacity and normal.

    Parameters
    ----------
    degree : int
        The SH degree.

    Returns
    -------
    int
        3 (degree + 1)² + 14.
    """
    return 3 * (degree + 1) ** 2 + 14
_WHAT = {"positions": "position", "log_scales": "scales", "rotations": "rotation",
         "opacity": "opacity", "sh": "SH coefficients", "normals": "normal"}


@dataclass(repr=False)
class Splats:
    """N splats in the reference trainer's parametrisation and frame (the PLY's axes).

    ``positions`` (N, 3); ``log_scales`` (N, 3), or (N, 2) for 2D Gaussian splats (surfels);
    ``rotations`` (N, 4) quaternions (w, x, y, z), not necessarily normalised (the renderer
    normalises); ``opacity`` (N,) logits; ``sh`` (N, K, 3) the renderer's SH coefficients
    (CS phase, `shprobe.splats.conventions`), k = 0 the DC term ``f_dc``, K = (degree+1)²;
    ``normals`` (N, 3) or None (the trainer writes zeros). All float32.

    Parameters
    ----------
    positions
        (N, 3).
    log_scales
        (N, 3), or (N, 2) for 2D Gaussian splats.
    rotations
        (N, 4) quaternions (w, x, y, z).
    opacity
        (N,) logits.
    sh
        (N, K, 3) the renderer's SH coefficients, k = 0 the DC term.
    normals
        (N, 3) or None.
    """

    positions: NDArray[np.float32]
    log_scales: NDArray[np.float32]
    rotations: NDArray[np.float32]
    opacity: NDArray[np.float32]
    sh: NDArray[np.float32]
    normals: NDArray[np.float32] | None = None

    def __post_init__(self) -> None:
        n = self.positions.shape[0]
        for name in ("positions", "log_scales", "rotations", "opacity", "sh", "normals"):
            a = getattr(self, name)
            if a is None:
                continue
            with np.errstate(over="ignore"):  # beyond float32: inf, refused by check_finite
                a = np.asarray(a, dtype=_F32)
            setattr(self, name, a)
            if a.shape[0] != n:
                raise ShprobeError(f"splat {name} has {a.shape[0]} rows, positions {n}")
        if self.positions.shape[1:] != (3,) or self.rotations.shape[1:] != (4,):
            raise ShprobeError("splat positions must be (N, 3) and rotations (N, 4)")
        if self.log_scales.shape[1:] not in ((2,), (3,)):
            raise ShprobeError("splat scales must be (N, 2) or (N, 3), got "
                               f"{self.log_scales.shape}")
        k = self.sh.shape[1] if self.sh.ndim == 3 else -1
        if self.sh.ndim != 3 or self.sh.shape[2] != 3 or k not in (1, 4, 9, 16):
            raise ShprobeError(f"splat SH must be (N, K, 3) with K = 1, 4, 9 or 16 (degree ≤ "
                               f"{MAX_DEGREE}), got {self.sh.shape}")

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def degree(self) -> int:
        return round(np.sqrt(self.sh.shape[1])) - 1

    def __len__(self) -> int:
        return self.count

    def __repr__(self) -> str:
        kind = "2DGS" if self.log_scales.shape[1] == 2 else "3DGS"
        return f"Splats({self.count} {kind} splats, SH degree {self.degree})"

    def take(self, index) -> Splats:
        """The splats selected by ``index`` (a slice, mask or index array).

        Parameters
        ----------
        index
            A slice, boolean mask or index array.

        Returns
        -------
        Splats
            The selected splats.
        """
        return Splats(self.positions[index], self.log_scales[index], self.rotations[index],
                      self.opacity[index], self.sh[index],
                      None if self.normals is None else self.normals[index])

    def truncated(self, degree: int) -> Splats:
        """The same splats with SH bands above ``degree`` dropped.

        Parameters
        ----------
        degree
            The highest SH degree kept.

        Returns
        -------
        Splats
            The splats with the higher bands dropped.
        """
        if not 0 <= degree <= self.degree:
            raise ShprobeError(f"SH degree {degree} must be between 0 and the data's "
                               f"{self.degree}")
        return Splats(self.positions, self.log_scales, self.rotations, self.opacity,
                      self.sh[:, : (degree + 1) ** 2], self.normals)

    def check_finite(self, where=None, offset: int = 0) -> None:
        """Refuse non-finite values, naming the first splat (numbered from ``offset``) and
        attribute.

        Parameters
        ----------
        where
            The file, named in the error.
        offset
            The number of the first splat.
        """
        for name in ("positions", "log_scales", "rotations", "opacity", "sh", "normals"):
            a = getattr(self, name)
            if a is None:
                continue
            ok = np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
            if not ok.all():
                i = offset + int(np.argmin(ok))
                raise ShprobeError(f"splat {i} has a non-finite value (NaN or Inf) in its "
                                   f"{_WHAT[name]}", where)


    def check_rotations(self, where=None, offset: int = 0) -> None:
        """Refuse a zero quaternion (it is no rotation: normalising it gives NaN), naming the
        first splat (numbered from ``offset``).

        Parameters
        ----------
        where : str or os.PathLike, optional
            The file named in the message.
        offset : int
            Number of the first splat here (for chunks of a file).
        """
        norm2 = np.square(self.rotations, dtype=np.float64).sum(axis=1)
        if not np.all(norm2 > 0):
            i = offset + int(np.argmin(norm2 > 0))
            raise ShprobeError(f"splat {i} has a zero rotation quaternion (no rotation: "
                               "nothing written)", where)


def read_bytes(path, per_byte: int = 1) -> bytes:
    """The bytes of a splat file that must be a regular file (a FIFO or ``/dev/zero`` is
    refused at once, never read), its size times ``per_byte`` (the memory reading it takes)
    checked against the memory limit first.

    Parameters
    ----------
    path : str or os.PathLike
        The splat file.
    per_byte : int
        Bytes of memory per byte of the file while it is read and decoded.

    Returns
    -------
    bytes
        The file's content.
    """
    import os

    from ..files import open_regular
    from ..limits import check_memory

    with open_regular(path, "splat file") as f:
        check_memory(per_byte * os.fstat(f.fileno()).st_size, "reading this file", path)
        try:
            return f.read()
        except OSError as e:
            raise ShprobeError(f"cannot read: {e.strerror or e}", path) from None


def concatenate(parts: list[Splats]) -> Splats:
    """One [`Splats`][shprobe.splats.Splats] from several of the same layout.

    Parameters
    ----------
    parts
        Splats of the same layout (SH degree and attributes).

    Returns
    -------
    Splats
        All of them, in order.
    """
    if not parts:
        raise ShprobeError("no splats")
    normals = None if parts[0].normals is None else np.concatenate([p.normals for p in parts])
    return Splats(*(np.concatenate([getattr(p, f) for p in parts])
                    for f in ("positions", "log_scales", "rotations", "opacity", "sh")),
                  normals=normals)
