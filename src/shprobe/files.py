"""Safe output files: written to a temporary name beside the target, then renamed.

Nothing is half-written and an existing file is only replaced when the caller asks.
"""

from __future__ import annotations

import json
import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ShprobeError


def read_text(path: str | os.PathLike[str], what: str = "text file") -> str:
    """The UTF-8 text of an input file, or one line naming it (missing, a folder, unreadable,
    not text)."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as f:
            return f.read()
    except FileNotFoundError:
        raise ShprobeError("no such file", p) from None
    except IsADirectoryError:
        raise ShprobeError("is a directory, not a file", p) from None
    except UnicodeDecodeError:
        raise ShprobeError(f"not a {what}", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None


def check_output_path(path: str | os.PathLike[str], overwrite: bool = False) -> Path:
    """Refuse, before any work, an output that could not be written: an existing file (or
    link, even a dangling one) unless ``overwrite``, a folder, a parent that is a file or a
    folder that is not writable. Missing parent folders are fine: they are made when the file
    is written (every command makes its output folders the same way)."""
    p = Path(path)
    if len(os.fsencode(p.name)) > 255:
        raise ShprobeError("file name is longer than 255 bytes", p)
    if p.is_dir():
        raise ShprobeError("is a directory, not a file", p)
    if os.path.lexists(p) and not stat.S_ISREG(os.lstat(p).st_mode) and not p.is_symlink():
        raise ShprobeError("is not a regular file (a device, pipe or socket): shprobe writes "
                           "its outputs as files only", p)
    if os.path.lexists(p) and not overwrite:
        raise ShprobeError("already exists (pass --force / overwrite=True to replace it)", p)
    parent = p.parent
    while not parent.exists():
        if parent == parent.parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        raise ShprobeError(f"{parent} is not a folder", p)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ShprobeError(f"folder {parent} is not writable", p)
    return p


@contextmanager
def atomic_output(path: str | os.PathLike[str], overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); move it to ``path`` on success.

    Missing parent folders are made. Without ``overwrite`` the move is a hard link that fails
    if ``path`` appeared meanwhile (no race with another writer); with it, an atomic rename.
    On any error — or SIGTERM / SIGHUP in the CLI, which raise SystemExit — the temporary
    file is removed and ``path`` is left as it was. Errors name ``path``, not the temporary.
    """
    p = check_output_path(path, overwrite)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ShprobeError(f"cannot make folder {p.parent}: {e.strerror or e}", p) from None
    tmp = p.with_name(f".shprobe-{os.getpid()}-{secrets.token_hex(4)}.tmp{p.suffix}")
    try:
        try:
            yield tmp
        except OSError as e:  # e.g. no space left on device: name the target
            raise ShprobeError(f"cannot write: {e.strerror or e}", p) from None
        if not tmp.exists():
            raise ShprobeError("nothing was written", p)
        if overwrite:
            os.replace(tmp, p)
        else:
            try:
                os.link(tmp, p)
            except FileExistsError:
                raise ShprobeError("already exists (pass --force / overwrite=True to replace "
                                   "it)", p) from None
            except OSError:  # a file system without hard links: check, then rename
                if os.path.lexists(p):
                    raise ShprobeError("already exists (pass --force / overwrite=True to "
                                       "replace it)", p) from None
                os.replace(tmp, p)
    finally:
        if os.path.lexists(tmp):
            tmp.unlink()


def write_text(path: str | os.PathLike[str], text: str, overwrite: bool = False) -> Path:
    """Write ``text`` atomically."""
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json(path: str | os.PathLike[str], obj: Any, overwrite: bool = False) -> Path:
    """Write ``obj`` as indented JSON atomically."""
    return write_text(path, json.dumps(obj, indent=2) + "\n", overwrite)


def save_npz(path: str | os.PathLike[str], overwrite: bool = False, **arrays: Any) -> Path:
    """``np.savez_compressed`` atomically, to a ``.npz`` name only (so a bake never replaces,
    say, the mesh it was made from); non-finite float arrays are refused."""
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
    a missing, empty, truncated or corrupt archive is one line naming it."""
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
    """Arrays of an ``.npz`` archive, read safely: the headers (:func:`npz_headers`) are read
    and the total inflated size checked against the memory limit *before* anything is
    inflated (a small compressed file cannot expand to gigabytes unasked), then each member's
    stored size against its header; one line naming the file on any problem. ``names``
    limits the arrays read (all by default; a missing one is not an error here)."""
    from .limits import check_memory

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
