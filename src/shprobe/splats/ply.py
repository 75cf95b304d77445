"""3DGS PLY files, read and written in chunks.

The reference trainer's layout (graphdeco-inria/gaussian-splatting ``save_ply``): one binary
little-endian ``vertex`` element of float properties ``x y z nx ny nz f_dc_0..2
f_rest_0..(3·(K−1)−1) opacity scale_0..2 rot_0..3``. ``f_rest`` is channel-major: all red
coefficients k = 1..K−1, then green, then blue; ``opacity`` is a logit, ``scale_*`` natural
logs, ``rot_*`` a quaternion with w first. 2D Gaussian splatting writes two scales. Properties
other than these (e.g. ``nx ny nz``, a confidence) are carried through unchanged.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..errors import ShprobeError
from .cloud import Splats

#: Splats per chunk of a streamed read or write (about 16 MB of degree-3 records).
CHUNK = 1 << 16
#: Largest PLY header read (the trainer's is under 2 kB).
MAX_HEADER = 1 << 20

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
          "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
          "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
          "float64": "f8"}
_NAMES = {"f4": "float", "f8": "double", "i1": "char", "u1": "uchar", "i2": "short",
          "u2": "ushort", "i4": "int", "u4": "uint"}
_DEGREE_OF_REST = {0: 0, 9: 1, 24: 2, 45: 3}


@dataclass(frozen=True)
class PlyLayout:
    """What a splat PLY's header says: record type, count, where the data starts."""

    path: str
    count: int
    dtype: np.dtype
    offset: int
    degree: int
    scales: int

    def __repr__(self) -> str:
        return (f"PlyLayout({self.count} splats, degree {self.degree}, {self.scales} scales, "
                f"{self.dtype.itemsize} B each)")


def _fail(path, msg: str):
    raise ShprobeError(msg, path)


def read_layout(path: str | os.PathLike[str]) -> PlyLayout:
    """Parse and check a splat PLY's header (nothing else is read); one line per problem."""
    p = os.fspath(path)
    from ..files import open_regular

    with open_regular(p, "splat file") as f:  # a FIFO or /dev/zero: refused, never read
        size = os.fstat(f.fileno()).st_size
        try:
            head = f.read(MAX_HEADER)
        except OSError as e:
            raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if not head.startswith(b"ply"):
        _fail(p, "not a PLY file (no 'ply' magic)")
    end = re.search(rb"end_header\r?\n", head)
    if end is None:
        _fail(p, "PLY header has no end_header (truncated or not a PLY)")
    try:
        lines = head[: end.start()].decode("ascii").splitlines()
    except UnicodeDecodeError:
        _fail(p, "PLY header is not ASCII text")
    fmt, elements = None, []
    for raw in lines[1:]:
        t = raw.split()
        if not t or t[0] in ("comment", "obj_info"):
            continue
        if t[0] == "format" and len(t) >= 2:
            fmt = t[1]
        elif t[0] == "element" and len(t) == 3:
            try:
                elements.append((t[1], int(t[2]), []))
            except ValueError:
                _fail(p, f"PLY element {t[1]!r} has a non-integer count {t[2]!r}")
        elif t[0] == "property" and elements:
            elements[-1][2].append(t[1:])
        else:
            _fail(p, f"unexpected PLY header line {raw.strip()[:60]!r}")
    if fmt not in ("binary_little_endian", "binary_big_endian"):
        _fail(p, f"PLY format {fmt!r} is not supported: splat files are binary "
                 "(binary_little_endian, as the 3DGS trainer writes them)")
    if not elements or elements[0][0] != "vertex":
        _fail(p, "PLY has no vertex element first: not a Gaussian-splat file")
    _, count, props = elements[0]
    faces = any(name == "face" and n > 0 for name, n, _ in elements[1:])
    names = [pr[-1] for pr in props]
    needed = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1",
              "rot_0", "rot_1", "rot_2", "rot_3"]
    missing = [n for n in needed if n not in names]
    if missing:
        what = "a mesh (vertices and faces)" if faces else "a point cloud"
        _fail(p, f"PLY is {what}, not Gaussian splats: no {', '.join(missing[:4])}"
                 f"{' …' if len(missing) > 4 else ''} properties")
    end_ch = ">" if fmt == "binary_big_endian" else "<"
    fields = []
    for pr in props:
        if pr[0] == "list":
            _fail(p, f"PLY vertex property {pr[-1]!r} is a list: not the 3DGS layout")
        if len(pr) != 2 or pr[0] not in _TYPES:
            _fail(p, f"PLY vertex property {' '.join(pr)!r} has an unknown type")
        code = _TYPES[pr[0]]
        if code[0] != "f" and (pr[1] in needed or pr[1].startswith(("f_rest_", "scale_"))):
            _fail(p, f"PLY property {pr[1]!r} is {pr[0]}, expected float (the 3DGS layout)")
        fields.append((pr[1], end_ch + code))
    if len(set(names)) != len(names):
        _fail(p, "PLY vertex element names a property twice")
    dtype = np.dtype(fields)
    rest = sum(1 for n in names if n.startswith("f_rest_"))
    if rest == 72:
        _fail(p, "SH degree 4 (72 f_rest properties): the 3DGS renderer evaluates degree ≤ 3; "
                 "no degree-4 layout is read")
    if rest not in _DEGREE_OF_REST or any(f"f_rest_{i}" not in names for i in range(rest)):
        _fail(p, f"PLY has {rest} f_rest properties: expected 0, 9, 24 or 45 "
                 "(f_rest_0 … consecutive, SH degree 0–3)")
    scales = 3 if "scale_2" in names else 2
    if count == 0:
        _fail(p, "PLY holds no splats (element vertex 0)")
    if count < 0:
        _fail(p, f"PLY declares a negative splat count {count}")
    offset = end.end()
    need = offset + count * dtype.itemsize
    if size < need:
        _fail(p, f"truncated: the header declares {count} splats ({need} bytes with the "
                 f"header) but the file holds {size} bytes")
    if size > need and not elements[1:]:
        _fail(p, f"PLY has {size - need} bytes after its {count} splats (not the layout its "
                 "header declares)")
    return PlyLayout(p, count, dtype, offset, _DEGREE_OF_REST[rest], scales)


def records(layout: PlyLayout, chunk: int | None = None) -> Iterator[np.ndarray]:
    """The vertex records, ``chunk`` (default `CHUNK`) at a time (structured arrays,
    native byte order)."""
    from ..files import open_regular

    chunk = CHUNK if chunk is None else chunk
    with open_regular(layout.path, "splat file") as f:
        f.seek(layout.offset)
        left = layout.count
        while left:
            n = min(chunk, left)
            a = np.fromfile(f, dtype=layout.dtype, count=n)
            if a.shape[0] != n:
                raise ShprobeError("truncated while reading splats", layout.path)
            left -= n
            yield a if layout.dtype.isnative else a.astype(layout.dtype.newbyteorder("="))


def _stack(rec: np.ndarray, names: list[str]) -> np.ndarray:
    out = np.empty((rec.shape[0], len(names)), dtype=np.float32)
    for i, n in enumerate(names):
        out[:, i] = rec[n]
    return out


def to_splats(rec: np.ndarray, layout: PlyLayout) -> Splats:
    """Records → [`Splats`][shprobe.splats.Splats] (f_rest un-interleaved to (N, K, 3))."""
    k = (layout.degree + 1) ** 2
    sh = np.empty((rec.shape[0], k, 3), dtype=np.float32)
    for c in range(3):
        sh[:, 0, c] = rec[f"f_dc_{c}"]
        for j in range(k - 1):
            sh[:, j + 1, c] = rec[f"f_rest_{c * (k - 1) + j}"]
    names = rec.dtype.names or ()
    normals = _stack(rec, ["nx", "ny", "nz"]) if "nx" in names else None
    return Splats(_stack(rec, ["x", "y", "z"]),
                  _stack(rec, [f"scale_{i}" for i in range(layout.scales)]),
                  _stack(rec, ["rot_0", "rot_1", "rot_2", "rot_3"]),
                  rec["opacity"].astype(np.float32), sh, normals)


def output_dtype(layout_dtype: np.dtype, degree: int) -> np.dtype:
    """The little-endian record type written for ``degree``: the input's properties in their
    order, f_rest beyond the degree dropped, normals stored as integers written as float."""
    keep = 3 * ((degree + 1) ** 2 - 1)
    fields = []
    for name in layout_dtype.names:
        if name.startswith("f_rest_") and int(name[7:]) >= keep:
            continue
        code = layout_dtype[name].str[1:]
        if name in ("nx", "ny", "nz") and code[0] != "f":
            code = "f4"  # a moved normal has negative components: no integer type holds it
        fields.append((name, "<" + code))
    return np.dtype(fields)


def degree_of(dtype: np.dtype) -> int:
    """The SH degree of a record type, from its f_rest count."""
    return _DEGREE_OF_REST[sum(1 for n in dtype.names if n.startswith("f_rest_"))]


def trainer_dtype(degree: int, scales: int = 3) -> np.dtype:
    """The reference trainer's record type for ``degree`` (normals included, as it writes)."""
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(3 * ((degree + 1) ** 2 - 1))]
    names += ["opacity"] + [f"scale_{i}" for i in range(scales)]
    names += [f"rot_{i}" for i in range(4)]
    return np.dtype([(n, "<f4") for n in names])


def from_splats(s: Splats, dtype: np.dtype, extra: np.ndarray | None = None) -> np.ndarray:
    """[`Splats`][shprobe.splats.Splats] → records of ``dtype``; properties not in the splats come
    from ``extra`` (the input records) where it has them, else zero."""
    out = np.zeros(s.count, dtype=dtype)
    names = set(dtype.names)
    if extra is not None:
        for n in (extra.dtype.names or ()):
            if n in names:
                out[n] = extra[n]
    for i, n in enumerate("xyz"):
        out[n] = s.positions[:, i]
    if s.normals is not None and "nx" in names:
        for i, n in enumerate(("nx", "ny", "nz")):
            out[n] = s.normals[:, i]
    for i in range(s.log_scales.shape[1]):
        out[f"scale_{i}"] = s.log_scales[:, i]
    for i in range(4):
        out[f"rot_{i}"] = s.rotations[:, i]
    out["opacity"] = s.opacity
    k = s.sh.shape[1]
    for c in range(3):
        out[f"f_dc_{c}"] = s.sh[:, 0, c]
        for j in range(k - 1):
            out[f"f_rest_{c * (k - 1) + j}"] = s.sh[:, j + 1, c]
    return out


def header(dtype: np.dtype, count: int) -> bytes:
    """A binary little-endian PLY header for ``count`` records of ``dtype``."""
    lines = ["ply", "format binary_little_endian 1.0", "comment written by shprobe",
             f"element vertex {count}"]
    lines += [f"property {_NAMES[dtype[n].str[1:]]} {n}" for n in dtype.names]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def float_columns(dtype: np.dtype) -> dict[str, int] | None:
    """Column index of every property when all are float32 (the trainer's layout: the records
    are then an (N, F) float32 matrix), else None."""
    if any(dtype[n] != np.dtype("f4") for n in dtype.names) or dtype.itemsize != 4 * len(
            dtype.names):
        return None
    cols = {n: i for i, n in enumerate(dtype.names)}
    rest = sorted(int(n[7:]) for n in cols if n.startswith("f_rest_"))
    if rest and any(cols[f"f_rest_{i}"] != cols["f_rest_0"] + i for i in rest):
        return None  # f_rest not stored in order: the general path
    return cols


def first_non_finite(a: np.ndarray, names, where, offset: int = 0) -> None:
    """Refuse an (N, F) record matrix with a NaN or Inf, naming the splat and property."""
    if not np.isfinite(a).all():
        i, j = np.argwhere(~np.isfinite(a))[0]
        raise ShprobeError(f"splat {offset + int(i)} has a non-finite value (NaN or Inf) in "
                           f"property {names[int(j)]!r}", where)


def first_zero_rotation(a: np.ndarray, cols: dict[str, int], where, offset: int = 0) -> None:
    """Refuse an (N, F) record matrix holding a zero quaternion (no rotation), naming the
    splat.

    Parameters
    ----------
    a : numpy.ndarray
        (N, F) float32 records.
    cols : dict
        Column of each property.
    where : str
        The file named in the message.
    offset : int
        Number of the first record here.
    """
    rot = a[:, [cols[f"rot_{i}"] for i in range(4)]]
    zero = ~np.any(rot != 0, axis=1)
    if zero.any():
        raise ShprobeError(f"splat {offset + int(np.argmax(zero))} has a zero rotation "
                           "quaternion (no rotation: nothing written)", where)


def transform_matrix(a: np.ndarray, cols: dict[str, int], degree: int, sim) -> None:
    """Move the splats of an (N, F) float32 record matrix in place (the fast path of
    [`shprobe.splats.transform.apply`][shprobe.splats.apply] for all-float layouts: one GEMM for the
    SH); values beyond float32 become inf, refused after the transform (no numpy warning).

    Parameters
    ----------
    a : numpy.ndarray
        (N, F) float32 records, changed in place.
    cols : dict
        Column of each property.
    degree : int
        The SH degree of the records.
    sim : shprobe.splats.Similarity
        The transform.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        _transform_matrix(a, cols, degree, sim)


def _transform_matrix(a: np.ndarray, cols: dict[str, int], degree: int, sim) -> None:
    from .transform import X180, quat_from_matrix, quat_multiply, sh_matrix

    q = np.asarray(sim.linear, dtype=np.float64)
    mirror_ = np.linalg.det(q) < 0
    xyz = [cols[c] for c in "xyz"]
    a[:, xyz] = (a[:, xyz].astype(np.float64) @ (sim.scale * q).T + sim.translation)
    if "nx" in cols:
        nrm = [cols["nx"], cols["ny"], cols["nz"]]
        a[:, nrm] = a[:, nrm] @ q.T.astype(np.float32)
    scales = [cols[n] for n in ("scale_0", "scale_1", "scale_2") if n in cols]
    a[:, scales] += np.float32(np.log(sim.scale))
    rot = [cols[f"rot_{i}"] for i in range(4)]
    r = quat_multiply(quat_from_matrix(-q if mirror_ else q), a[:, rot])
    a[:, rot] = quat_multiply(r, X180) if mirror_ else r
    k = (degree + 1) ** 2
    if k > 1:
        first = cols["f_rest_0"]
        m = sh_matrix(q, degree)[1:, 1:].T.astype(np.float32)
        rest = a[:, first : first + 3 * (k - 1)].reshape(-1, k - 1)
        a[:, first : first + 3 * (k - 1)] = (rest @ m).reshape(a.shape[0], -1)
