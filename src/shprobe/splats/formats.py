"""Splat files by name: read, write, transform (streamed PLY → PLY) and summarise.

Formats by suffix: ``.ply`` (3DGS / 2DGS, `shprobe.splats.ply`), ``.spz`` (`shprobe.splats.spz`),
``.glb`` (``KHR_gaussian_splatting``, `shprobe.splats.gltf`). In memory splats are always in the
trainer PLY's frame and SH convention; the SPZ and glTF modules convert their frames at the edge.
A PLY → PLY transform runs in chunks of `shprobe.splats.ply.CHUNK` splats, so its memory
does not grow with the file; SPZ and glTF are columnar and compressed, so reading or writing
them holds the whole scene (checked against
[`shprobe.limits.check_memory`][shprobe.limits.check_memory] first).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ShprobeError
from ..limits import check_memory
from ..progress import Progress, stage
from . import gltf, ply, spz
from .cloud import (
    PLY_READ_BASE_BYTES,
    READ_BYTES_PER_FLOAT,
    Splats,
    concatenate,
    floats_per_splat,
)
from .conventions import check_degree
from .transform import Similarity, apply

FORMATS = (".ply", ".spz", ".glb")
#: Bytes per float of a splat's attributes (K·3 SH, 3 + 3 + 4 + 1 + 3 others) at the peak of
#: each writer, by format (measured by bench/bench_estimates.py): the frame change's copy,
#: float64 temporaries, the packed bytes, and for SPZ the compressed stream too.
WRITE_BYTES_PER_FLOAT = {".ply": 0.0, ".spz": 24.0, ".glb": 17.0}
#: Copies of a chunk's records a streamed PLY → PLY transform holds at its peak.
STREAM_COPIES = 4.2


def estimate_read(count: int, degree: int, kind: str) -> float:
    """Peak bytes of reading a whole splat file of ``count`` splats of SH ``degree``.

    Parameters
    ----------
    count, degree : int
        The file's splats and SH degree (from its header).
    kind : str
        '.ply', '.spz' or '.glb'.

    Returns
    -------
    float
        The estimate the reader checks against the memory limit.
    """
    base = PLY_READ_BASE_BYTES if kind == ".ply" else 0.0
    return base + count * floats_per_splat(degree) * READ_BYTES_PER_FLOAT[kind]


def estimate_transform(count: int, degree: int, src: str, dst: str) -> float:
    """Peak bytes of a [`transform_file`][shprobe.splats.transform_file] that holds the whole scene
    (any but PLY → PLY, which `estimate_stream` covers): the larger of reading it and of holding it,
    its moved copy and the writer's peak.

    Parameters
    ----------
    count, degree : int
        The input's splats and SH degree.
    src, dst : str
        The input's and output's formats ('.ply', '.spz', '.glb').

    Returns
    -------
    float
        The estimate checked against the memory limit.
    """
    floats = count * floats_per_splat(degree)
    write_peak = (min(count, ply.CHUNK) * floats_per_splat(degree) * 12 if dst == ".ply"
                  else floats * WRITE_BYTES_PER_FLOAT[dst])
    return max(estimate_read(count, degree, src), 8.0 * floats + write_peak)


def estimate_write(splats: Splats, path: str | os.PathLike[str]) -> float:
    """Peak bytes [`write`][shprobe.splats.write] allocates for ``splats`` to ``path`` (its format
    by suffix); a PLY is written a chunk at a time.

    Parameters
    ----------
    splats : Splats
        What is written.
    path : str or os.PathLike
        The output (``.ply``, ``.spz`` or ``.glb``).

    Returns
    -------
    float
        The estimate checked against the memory limit before writing.
    """
    kind = format_of(path)
    floats = floats_per_splat(splats.degree)
    if kind == ".ply":
        return float(min(splats.count, ply.CHUNK) * floats * 4 * 3)
    return float(splats.count * floats * WRITE_BYTES_PER_FLOAT[kind])


def estimate_stream(layout: ply.PlyLayout) -> float:
    """Peak bytes of a streamed PLY → PLY [`transform_file`][shprobe.splats.transform_file] (a chunk
    of records, its float64 and moved copies), whatever the file's size.

    Parameters
    ----------
    layout : shprobe.splats.ply.PlyLayout
        The input's header.

    Returns
    -------
    float
        The estimate checked against the memory limit before the transform.
    """
    return float(min(layout.count, ply.CHUNK) * layout.dtype.itemsize * STREAM_COPIES)


def format_of(path: str | os.PathLike[str]) -> str:
    """'.ply', '.spz' or '.glb' from the file name; one line otherwise.

    Parameters
    ----------
    path
        A splat file's name.

    Returns
    -------
    str
        '.ply', '.spz' or '.glb'.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ShprobeError(f"unknown splat format {suffix or '(no suffix)'!r}: use "
                           f"{', '.join(FORMATS)}", path)
    return suffix


def _chunks(layout: ply.PlyLayout, progress: Progress | None,
            what: str) -> Iterator[tuple[np.ndarray, Splats]]:
    with stage(progress, what, total=layout.count) as bar:
        done = 0
        for rec in ply.records(layout):
            s = ply.to_splats(rec, layout)
            s.check_finite(layout.path, offset=done)
            yield rec, s
            done += rec.shape[0]
            bar.advance(rec.shape[0])


def read(path: str | os.PathLike[str], progress: Progress | None = None) -> Splats:
    """A whole splat file in memory (PLY, SPZ or glb), checked finite.

    Parameters
    ----------
    path
        A PLY, SPZ or glb splat file.
    progress
        Told about the splats read.

    Returns
    -------
    Splats
        The splats, checked finite.
    """
    kind = format_of(path)
    if kind == ".ply":
        layout = ply.read_layout(path)
        check_memory(estimate_read(layout.count, layout.degree, ".ply"),
                     f"reading {layout.count} splats", path)
        return concatenate([s for _, s in _chunks(layout, progress, "reading splats")])
    with stage(progress, "reading splats"):
        s = spz.read(path) if kind == ".spz" else gltf.read(path)
    s.check_finite(os.fspath(path))
    return s


def write(path: str | os.PathLike[str], splats: Splats, overwrite: bool = False,
          progress: Progress | None = None) -> Path:
    """Write splats (PLY in the trainer's layout, SPZ or glb) atomically; non-finite values
    are refused before anything is written.

    Parameters
    ----------
    path
        The output file; its suffix picks the format.
    splats
        The splats.
    overwrite
        Replace an existing file.
    progress
        Told about the splats written.

    Returns
    -------
    Path
        The file written.
    """
    kind = format_of(path)
    splats.check_finite(os.fspath(path))
    splats.check_rotations(os.fspath(path))
    check_memory(estimate_write(splats, path), f"writing {splats.count} splats", path)
    from ..files import atomic_output

    with stage(progress, "writing splats", total=splats.count) as bar:
        if kind == ".ply":
            dtype = ply.trainer_dtype(splats.degree, splats.log_scales.shape[1])
            with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
                f.write(ply.header(dtype, splats.count))
                for i in range(0, splats.count, ply.CHUNK):
                    part = splats.take(slice(i, i + ply.CHUNK))
                    ply.from_splats(part, dtype).tofile(f)
                    bar.advance(part.count)
        elif kind == ".spz":
            spz.write(path, splats, overwrite)
        else:
            gltf.write(path, splats, overwrite)
    return Path(path)


@dataclass(frozen=True)
class TransformSettings:
    """What [`transform_file`][shprobe.splats.transform_file] does.

    Parameters
    ----------
    similarity
        The move: rotation or reflection, uniform scale and translation.
    sh_degree
        The SH degree to truncate to (None: keep the file's).
    overwrite
        An existing output may be replaced.
    """

    similarity: Similarity = field(default_factory=Similarity.identity)
    sh_degree: int | None = None
    overwrite: bool = False


@dataclass(frozen=True)
class TransformResult:
    """What [`transform_file`][shprobe.splats.transform_file] did.

    Attributes
    ----------
    count
        Splats written.
    degree_in, degree_out
        The SH degree read and written.
    path
        The file written.
    """

    count: int
    degree_in: int
    degree_out: int
    path: Path

    def as_dict(self) -> dict[str, Any]:
        """What was written, as JSON-able values.

        Returns
        -------
        dict
            ``path``, ``count``, ``sh_degree_in``, ``sh_degree_out``.
        """
        return {"path": str(self.path), "count": self.count, "sh_degree_in": self.degree_in,
                "sh_degree_out": self.degree_out}

    def __repr__(self) -> str:
        return (f"TransformResult({self.count} splats, SH degree {self.degree_in}"
                f"{'' if self.degree_in == self.degree_out else f' → {self.degree_out}'}, "
                f"{self.path})")


def _degree(settings: TransformSettings, degree: int, where) -> int:
    d = settings.sh_degree
    if d is None:
        return degree
    check_degree(d, "sh_degree")
    if d > degree:
        raise ShprobeError(f"sh_degree {d} is above the file's SH degree {degree}", where)
    return d


def _stream_floats(layout: ply.PlyLayout, cols: dict[str, int], dtype: np.dtype,
                   sim: Similarity, f, progress: Progress | None) -> None:
    """PLY → PLY for all-float32 records: each chunk moved in place as an (N, F) matrix."""
    names = list(layout.dtype.names)
    k_in, k_out = (layout.degree + 1) ** 2 - 1, (ply.degree_of(dtype) + 1) ** 2 - 1

    def source(name: str) -> int:  # f_rest is channel-major: renumbered when truncated
        if not name.startswith("f_rest_"):
            return cols[name]
        c, j = divmod(int(name[7:]), k_out)
        return cols[f"f_rest_{c * k_in + j}"]

    keep = [source(n) for n in dtype.names]
    from threadpoolctl import threadpool_limits

    # one BLAS thread: the GEMMs of a chunk are a few ms, and idle BLAS threads spinning
    # between chunks cost more CPU than they save (5x the CPU time on a 2-core machine)
    with threadpool_limits(1, user_api="blas"), \
            stage(progress, "transforming splats", total=layout.count) as bar:
        done = 0
        for rec in ply.records(layout):
            a = rec.view(np.float32).reshape(rec.shape[0], len(names))
            ply.first_non_finite(a, names, layout.path, done)
            ply.transform_matrix(a, cols, layout.degree, sim)
            ply.first_non_finite(a, names, f"{layout.path} (after the transform)", done)
            ply.first_zero_rotation(a, cols, layout.path, done)
            (a if len(keep) == len(names) else a[:, keep]).tofile(f)
            done += rec.shape[0]
            bar.advance(rec.shape[0])


def transform_file(src: str | os.PathLike[str], dst: str | os.PathLike[str],
                   settings: TransformSettings, progress: Progress | None = None
                   ) -> TransformResult:
    """Read ``src``, move every splat by ``settings.similarity`` (SH included), truncate the
    SH if asked, write ``dst`` (any format to any). PLY → PLY is streamed in chunks, keeping
    properties the transform does not know (they are carried through unchanged).

    Parameters
    ----------
    src
        The splat file read (PLY, SPZ or glb).
    dst
        The splat file written (any of the three).
    settings
        The similarity, the SH degree to keep and whether to overwrite.
    progress
        Told about the splats done.

    Returns
    -------
    TransformResult
        The count, the SH degree in and out, the path written.
    """
    from ..files import atomic_output, check_output_path

    check_output_path(dst, settings.overwrite)
    out_kind = format_of(dst)
    if format_of(src) == ".ply" and out_kind == ".ply":
        layout = ply.read_layout(src)
        check_memory(estimate_stream(layout), f"transforming {layout.count} splats", src)
        degree = _degree(settings, layout.degree, src)
        dtype = ply.output_dtype(layout.dtype, degree)
        cols = ply.float_columns(layout.dtype.newbyteorder("="))
        with atomic_output(dst, settings.overwrite) as tmp, open(tmp, "wb") as f:
            f.write(ply.header(dtype, layout.count))
            if cols is not None:
                _stream_floats(layout, cols, dtype, settings.similarity, f, progress)
            else:
                for rec, s in _chunks(layout, progress, "transforming splats"):
                    moved = apply(s.truncated(degree), settings.similarity)
                    moved.check_finite(os.fspath(dst))
                    moved.check_rotations(os.fspath(dst))
                    ply.from_splats(moved, dtype, extra=rec).tofile(f)
        return TransformResult(layout.count, layout.degree, degree, Path(dst))
    s = read(src, progress)
    degree = _degree(settings, s.degree, src)
    check_memory(estimate_transform(s.count, degree, format_of(src), out_kind),
                 f"transforming {s.count} splats", src)
    with stage(progress, "transforming splats"):
        moved = apply(s.truncated(degree), settings.similarity)
    write(dst, moved, settings.overwrite, progress)
    return TransformResult(s.count, s.degree, degree, Path(dst))


@dataclass(frozen=True)
class SplatInfo:
    """What ``shprobe splat info`` prints: count, SH degree, kind, bounds of the positions and
    the energy of each SH band (mean over splats of Σ_m Σ_rgb coefficient², band 0 = f_dc).

    Attributes
    ----------
    path, format
        The file and its format.
    count
        Splats.
    degree
        SH degree.
    kind
        "3DGS" or "2DGS".
    bounds_min, bounds_max
        The positions' bounding box.
    band_energy
        Per SH band, the mean over splats of Σ_m Σ_rgb coefficient².
    """

    path: str
    format: str
    count: int
    degree: int
    kind: str
    bounds_min: tuple[float, float, float]
    bounds_max: tuple[float, float, float]
    band_energy: tuple[float, ...]

    def __repr__(self) -> str:
        return f"SplatInfo({self.count} {self.kind} splats, SH degree {self.degree})"

    def as_dict(self) -> dict:
        return {"path": self.path, "format": self.format, "count": self.count,
                "sh_degree": self.degree, "kind": self.kind,
                "bounds": {"min": list(self.bounds_min), "max": list(self.bounds_max)},
                "band_energy": list(self.band_energy)}


def _bands(degree: int) -> np.ndarray:
    return np.repeat(np.arange(degree + 1), 2 * np.arange(degree + 1) + 1)


def info(path: str | os.PathLike[str], progress: Progress | None = None) -> SplatInfo:
    """Summarise a splat file (a PLY is streamed).

    Parameters
    ----------
    path
        A splat file.
    progress
        Told about the splats read.

    Returns
    -------
    SplatInfo
        Its format, count, SH degree and bounds.
    """
    kind = format_of(path)
    if kind == ".ply":
        layout = ply.read_layout(path)
        parts = (s for _, s in _chunks(layout, progress, "reading splats"))
    else:
        parts = iter([read(path, progress)])
    lo, hi, energy, count, first = None, None, None, 0, None
    for s in parts:
        first = first or s
        band = np.zeros(s.degree + 1)
        np.add.at(band, _bands(s.degree), np.square(s.sh, dtype=np.float64).sum(axis=(0, 2)))
        energy = band if energy is None else energy + band
        mn, mx = s.positions.min(axis=0), s.positions.max(axis=0)
        lo = mn if lo is None else np.minimum(lo, mn)
        hi = mx if hi is None else np.maximum(hi, mx)
        count += s.count
    assert first is not None and energy is not None  # readers refuse empty files
    return SplatInfo(os.fspath(path), kind[1:], count, first.degree,
                     "2DGS" if first.log_scales.shape[1] == 2 else "3DGS",
                     tuple(float(v) for v in lo), tuple(float(v) for v in hi),
                     tuple(float(e) for e in energy / count))
