"""``.npz`` archives: written atomically with finite values only, read with their headers and
sizes checked against the memory limit before anything is inflated."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ShprobeError
from .outputs import atomic_output


def save_npz(path: str | os.PathLike[str], overwrite: bool = False, **arrays: Any) -> Path:
    """``np.savez_compressed`` atomically, to a ``.npz`` name only (so a bake never replaces,
    say, the mesh it was made from); non-finite float arrays are refused.

    Parameters
    ----------
    path
        The ``.npz`` file.
    overwrite
        An existing file may be replaced.
    **arrays
        The arrays by name.

    Returns
    -------
    Path
        The file written.
    """
    if Path(path).suffix.lower() != ".npz":
        raise ShprobeError("an .npz output must be named *.npz", path)
    for k, a in arrays.items():
        a = np.asarray(a)
        if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
            raise ShprobeError(f"refusing to write non-finite values ({k})", path)
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)
    return Path(path)


def npz_headers(path: str | os.PathLike[str], what: str = "file"
                ) -> dict[str, tuple[tuple[int, ...], np.dtype, bool]]:
    """(shape, dtype, stored size matches the header) of every array of an ``.npz``, read from
    the ``.npy`` headers alone (nothing is inflated); object arrays are refused (no pickles);
    a missing, empty, truncated or corrupt archive is one line naming it.

    Parameters
    ----------
    path
        The ``.npz`` archive.
    what
        What the file is, named in errors.

    Returns
    -------
    dict
        Per array: (shape, dtype, whether its stored size matches the header).
    """
    import zipfile

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ShprobeError(f"no such {what}", p)
    if not zipfile.is_zipfile(p):
        raise ShprobeError(f"not a {what} (not an .npz archive: empty, truncated or another "
                           "format)", p)
    out = {}
    try:
        with zipfile.ZipFile(p) as z:
            for info in z.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                name = info.filename[:-4]
                with z.open(info) as f:
                    fmt = np.lib.format
                    read = (fmt.read_array_header_1_0 if fmt.read_magic(f) == (1, 0)
                            else fmt.read_array_header_2_0)
                    shape, _, dtype = read(f)
                    start = f.tell()
                if dtype.hasobject:
                    raise ShprobeError(f"array {name!r} holds Python objects (refused)", p)
                size = start + int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                out[name] = (tuple(shape), dtype, info.file_size == size)
    except ShprobeError:
        raise
    except Exception as e:  # zipfile / numpy raise many types on damaged archives
        raise ShprobeError(f"cannot read {what} (not an .npz, truncated or malformed): "
                           f"{' '.join(str(e).split())[:200]}", p) from None
    return out


def load_npz(path: str | os.PathLike[str], names: Any = None,
             what: str = "file") -> dict[str, np.ndarray]:
    """Arrays of an ``.npz`` archive, read safely: the headers
    ([`npz_headers`][shprobe.files.npz_headers]) are read and the total inflated size checked
    against the memory limit *before* anything is inflated (a small compressed file cannot expand to
    gigabytes unasked), then each member's stored size against its header; one line naming the file
    on any problem. ``names`` limits the arrays read (all by default; a missing one is not an error
    here).

    Parameters
    ----------
    path
        The ``.npz`` archive.
    names
        The arrays to read (default: all).
    what
        What the file is, named in errors.

    Returns
    -------
    dict of str to ndarray
        The arrays by name.
    """
    from ..limits import check_memory

    p = os.fspath(path)
    heads = npz_headers(p, what)
    want = list(heads) if names is None else [n for n in names if n in heads]
    check_memory(sum(int(np.prod(heads[n][0], dtype=np.float64)) * heads[n][1].itemsize
                     for n in want), f"reading the arrays of this {what}", p)
    bad = [n for n in want if not heads[n][2]]
    if bad:
        raise ShprobeError(f"array {bad[0]!r} is not the size its header says (truncated or "
                           "malformed)", p)
    try:
        with np.load(p, allow_pickle=False) as d:
            return {n: d[n] for n in want}
    except Exception as e:  # CRC errors, truncated streams
        raise ShprobeError(f"cannot read {what} (truncated or corrupt): "
                           f"{' '.join(str(e).split())[:200]}", p) from None
