"""Safe output files: written to a temporary name beside the target, then renamed.

Nothing is half-written and an existing file is only replaced when the caller asks; several
outputs commit together or not at all (``transaction``).
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

from ..errors import ShprobeError


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
