"""Safe output files: written to a temporary name beside the target, then renamed.

Nothing is half-written and an existing file is only replaced when the caller asks.
"""

from __future__ import annotations

import contextvars
import json
import os
import re
import secrets
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ShprobeError


def read_text(path: str | os.PathLike[str], what: str = "text file") -> str:
    """The UTF-8 text of an input file, or one line naming it (missing, folder, not text)."""
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


def regular_file(path: str | os.PathLike[str], what: str = "file") -> os.stat_result:
    """The ``stat`` of an input that must be a regular file, or one line naming it: a FIFO,
    a device (``/dev/zero``), a socket or a folder is refused at once (reading one would
    block forever or never end).

    Parameters
    ----------
    path : str or os.PathLike
        The input file (links are followed).
    what : str
        What the file should be, for the messages ("splat file", "probe").

    Returns
    -------
    os.stat_result
        The file's status.
    """
    p = os.fspath(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise ShprobeError(f"no such {what}", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if stat.S_ISDIR(st.st_mode):
        raise ShprobeError("is a directory, not a file", p)
    if not stat.S_ISREG(st.st_mode):
        raise ShprobeError(f"is not a regular file (a device, pipe or socket): a {what} must "
                           "be a file", p)
    return st


def open_regular(path: str | os.PathLike[str], what: str = "file"):
    """Open an input for binary reading once [`regular_file`][shprobe.files.regular_file] accepts
    it, without blocking and checked again on the descriptor (a FIFO swapped in is never waited on).

    Parameters
    ----------
    path : str or os.PathLike
        The input file.
    what : str
        What the file should be, for the messages.

    Returns
    -------
    io.BufferedReader
        The open file.
    """
    p = os.fspath(path)
    regular_file(p, what)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise ShprobeError(f"is not a regular file: a {what} must be a file", p)
    return open(fd, "rb")


def check_output_path(path: str | os.PathLike[str], overwrite: bool = False,
                      inputs: tuple = ()) -> Path:
    """Refuse, before any work, an output that could not be written: an existing file (or
    link, even a dangling one) unless ``overwrite``, one of the ``inputs`` (by any name), a
    folder, a parent that is a file or a folder that is not writable. Missing parent folders
    are fine: they are made when the file is written (by every command the same way).

    Parameters
    ----------
    path : str or os.PathLike
        The output file.
    overwrite : bool
        Whether an existing file may be replaced (``--force``).
    inputs : tuple of str or os.PathLike
        The files the output is made from.

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    if any(os.path.exists(p) and os.path.exists(i) and os.path.samefile(i, p) for i in inputs):
        raise ShprobeError("is this command's input: the output must be another file", p)
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


#: Temporary outputs: ``.shprobe-<pid>-<8 hex>.tmp<suffix>`` beside their target.
_TMP_NAME = re.compile(r"\.shprobe-([0-9]+)-[0-9a-f]{8}\.tmp(\.[^/]*)?")
#: A dead writer's temporary file is removed only when it has not changed for this long:
#: the PID in its name is of this machine's process table, and a folder shared with another
#: machine or container may hold a live writer's file under a PID that is free here.
STALE_SECONDS = 60.0


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):  # someone else's live process, or cannot tell
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike[str],
                             min_age: float = STALE_SECONDS) -> list[Path]:
    """Remove the temporary outputs that writers killed outright (SIGKILL, power loss) left in
    ``folder``: only files named as shprobe names them (``.shprobe-<pid>-<hex>.tmp…``),
    regular files, whose PID is no running process and that have not changed for
    ``min_age`` seconds. Never an error (a file another process removes first is fine).

    Parameters
    ----------
    folder
        The folder to clean.
    min_age
        Seconds a temporary must have been left unchanged.

    Returns
    -------
    list of Path
        The files removed.
    """
    gone: list[Path] = []
    now = time.time()
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return gone
    for e in entries:
        m = _TMP_NAME.fullmatch(e.name)
        if not m or int(m.group(1)) == os.getpid() or _alive(int(m.group(1))):
            continue
        try:
            st = e.stat(follow_symlinks=False)
            if stat.S_ISREG(st.st_mode) and now - st.st_mtime >= min_age:
                os.unlink(e.path)
                gone.append(Path(e.path))
        except OSError:
            pass
    return gone


@dataclass
class _Pending:
    tmp: Path
    target: Path
    overwrite: bool


@dataclass
class Transaction:
    """Outputs written by [`atomic_output`][shprobe.files.atomic_output] inside
    [`transaction`][shprobe.files.transaction]: each is written to its temporary file as usual, but
    moved into place only when the whole block succeeds."""

    pending: list[_Pending] = field(default_factory=list)

    def commit(self) -> None:
        """Move every output into place; if one fails, undo the ones already moved (a
        replaced file is restored) and raise.

        Raises
        ------
        OSError
            When an output cannot be moved into place (the others are undone first).
        """
        done: list[tuple[Path, Path | None]] = []  # (target, backup of what it replaced)
        try:
            for w in self.pending:
                backup = None
                if w.overwrite and os.path.lexists(w.target):
                    backup = w.tmp.with_name(w.tmp.name + ".old")
                    try:
                        os.link(w.target, backup, follow_symlinks=False)
                    except OSError:
                        backup = None
                _place(w.tmp, w.target, w.overwrite)
                done.append((w.target, backup))
        except BaseException:
            for target, backup in reversed(done):
                try:
                    if backup is not None:
                        os.replace(backup, target)
                    else:
                        target.unlink()
                except OSError:
                    pass
            raise
        finally:
            for w in self.pending:
                for q in (w.tmp, w.tmp.with_name(w.tmp.name + ".old")):
                    if os.path.lexists(q):
                        q.unlink()


_TRANSACTION: contextvars.ContextVar[Transaction | None] = contextvars.ContextVar(
    "shprobe_output_transaction", default=None)


@contextmanager
def transaction() -> Iterator[Transaction]:
    """Commit several outputs together or not at all: every
    [`atomic_output`][shprobe.files.atomic_output] (and so every writer of shprobe) inside the block
    writes its temporary file, and all are renamed into place when the block ends without an error;
    on any error — a full disk on the last file, Ctrl-C — none of them appears and nothing is
    replaced. Nested blocks join the outermost one.

    Yields
    ------
    Transaction
        The block's commit of every output written inside it.
    """
    if _TRANSACTION.get() is not None:
        yield _TRANSACTION.get()  # type: ignore[misc]
        return
    t = Transaction()
    token = _TRANSACTION.set(t)
    try:
        yield t
    except BaseException:
        _TRANSACTION.reset(token)
        for w in t.pending:
            if os.path.lexists(w.tmp):
                w.tmp.unlink()
        raise
    _TRANSACTION.reset(token)
    t.commit()


def _place(tmp: Path, p: Path, overwrite: bool) -> None:
    """Move the written ``tmp`` to ``p``: an atomic rename with ``overwrite``, else a hard link
    that fails if ``p`` appeared meanwhile."""
    if overwrite:
        os.replace(tmp, p)
        return
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


@contextmanager
def atomic_output(path: str | os.PathLike[str], overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); move it to ``path`` on success.

    Missing parent folders are made. Without ``overwrite`` the move is a hard link that fails
    if ``path`` appeared meanwhile (no race with another writer); with it, an atomic rename.
    On any error — or SIGTERM / SIGHUP in the CLI, which raise SystemExit — the temporary
    file is removed and ``path`` is left as it was. Errors name ``path``, not the temporary.
    Inside [`transaction`][shprobe.files.transaction] the move waits for the end of the block.
    Temporary files that killed writers left in the folder are removed first
    ([`remove_stale_temporaries`][shprobe.files.remove_stale_temporaries]).

    Parameters
    ----------
    path
        The output file.
    overwrite
        An existing file may be replaced.

    Yields
    ------
    Path
        The temporary file to write.
    """
    p = check_output_path(path, overwrite)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ShprobeError(f"cannot make folder {p.parent}: {e.strerror or e}", p) from None
    remove_stale_temporaries(p.parent)
    tmp = p.with_name(f".shprobe-{os.getpid()}-{secrets.token_hex(4)}.tmp{p.suffix}")
    txn = _TRANSACTION.get()
    kept = False
    try:
        try:
            yield tmp
        except OSError as e:  # e.g. no space left on device: name the target
            raise ShprobeError(f"cannot write: {e.strerror or e}", p) from None
        if not tmp.exists():
            raise ShprobeError("nothing was written", p)
        if txn is not None:
            if any(w.target == p for w in txn.pending):
                raise ShprobeError("is written twice by one command", p)
            txn.pending.append(_Pending(tmp, p, overwrite))
            kept = True
        else:
            _place(tmp, p, overwrite)
    finally:
        if not kept and os.path.lexists(tmp):
            tmp.unlink()


def write_text(path: str | os.PathLike[str], text: str, overwrite: bool = False) -> Path:
    """Write ``text`` atomically.

    Parameters
    ----------
    path
        The output file.
    text
        The text (UTF-8).
    overwrite
        An existing file may be replaced.

    Returns
    -------
    Path
        The file written.
    """
    with atomic_output(path, overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json(path: str | os.PathLike[str], obj: Any, overwrite: bool = False) -> Path:
    """Write ``obj`` as indented JSON atomically.

    Parameters
    ----------
    path
        The output file.
    obj
        A JSON-able object.
    overwrite
        An existing file may be replaced.

    Returns
    -------
    Path
        The file written.
    """
    return write_text(path, json.dumps(obj, indent=2) + "\n", overwrite)


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


# ----------------------------------------------------------------------------- on-disk cache

#: Environment variable naming the folder of shprobe's caches; ``off`` keeps none.
CACHE_ENV = "SHPROBE_CACHE_DIR"
#: Entries kept per kind of cache (the oldest beyond are removed when one is written).
CACHE_KEEP = 16
_DIGEST = 32  # bytes of BLAKE2b stored after each entry's data


def cache_dir() -> Path | None:
    """The folder of shprobe's on-disk caches: ``$SHPROBE_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/shprobe``, else ``~/.cache/shprobe``; None when ``$SHPROBE_CACHE_DIR``
    is ``off``. What is kept there is derived from input files (keyed by their content) and
    may be deleted at any time.

    Returns
    -------
    Path or None
        The cache folder, or None when caching is off.
    """
    env = os.environ.get(CACHE_ENV)
    if env is not None and env.strip():
        return None if env.strip().lower() == "off" else Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "shprobe"


def file_digest(path: str | os.PathLike[str], *extra: str | bytes) -> str:
    """Hex BLAKE2b (128-bit) of a file's bytes and of ``extra`` (e.g. the versions of the code
    that derives something from it): a cache key that changes with the content, not the name
    or the time stamp.

    Parameters
    ----------
    path
        The file.
    *extra
        More strings or bytes hashed after its content.

    Returns
    -------
    str
        The digest, hex.
    """
    import hashlib

    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    for x in extra:
        h.update(b"\0" + (x.encode() if isinstance(x, str) else x))
    return h.hexdigest()


def _cache_entry(kind: str, key: str) -> Path | None:
    root = cache_dir()
    if root is None or not kind.isidentifier() or not key.isalnum():
        return None
    return root / kind / f"{key}.bin"


def read_cache(kind: str, key: str) -> bytes | None:
    """The bytes [`write_cache`][shprobe.files.write_cache] stored under ``kind`` / ``key``, checked
    against their stored digest; None when absent, unreadable or damaged (a cache is never an
    error).

    Parameters
    ----------
    kind
        The cache's kind (a sub-folder).
    key
        The entry's key.

    Returns
    -------
    bytes or None
        The stored bytes, or None.
    """
    import hashlib

    p = _cache_entry(kind, key)
    if p is None:
        return None
    try:
        raw = p.read_bytes()
    except OSError:
        return None
    data, digest = raw[:-_DIGEST], raw[-_DIGEST:]
    if len(raw) <= _DIGEST or hashlib.blake2b(data, digest_size=_DIGEST).digest() != digest:
        return None
    try:
        os.utime(p)  # recently used: kept longest
    except OSError:
        pass
    return data


def write_cache(kind: str, key: str, data: bytes, keep: int = CACHE_KEEP) -> bool:
    """Store ``data`` under ``kind`` / ``key`` (written to a temporary name and renamed, with
    its digest, so a reader never sees half an entry) and remove the least recently used
    entries of ``kind`` beyond ``keep``; False, silently, where the cache folder cannot be
    written (a cache is never an error).

    Parameters
    ----------
    kind
        The cache's kind (a sub-folder).
    key
        The entry's key.
    data
        The bytes.
    keep
        Entries of ``kind`` kept, least recently used removed first.

    Returns
    -------
    bool
        Whether the entry was stored.
    """
    import hashlib

    p = _cache_entry(kind, key)
    if p is None:
        return False
    try:
        with atomic_output(p, overwrite=True) as tmp, open(tmp, "wb") as f:
            f.write(data)
            f.write(hashlib.blake2b(data, digest_size=_DIGEST).digest())
    except (ShprobeError, OSError):
        return False
    try:  # another process may be pruning too
        entries = sorted((q for q in p.parent.glob("*.bin") if not q.name.startswith(".")),
                         key=lambda q: q.stat().st_mtime_ns)
        for old in entries[:max(0, len(entries) - keep)]:
            old.unlink(missing_ok=True)
    except OSError:
        pass
    return True
