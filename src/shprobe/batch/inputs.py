"""What ``shprobe batch`` reads: files, folders (recursive), globs, and lists of paths (.txt,
.csv, .parquet), expanded to ``(absolute path, layout)`` pairs in a stable order."""

from __future__ import annotations

import csv
import fnmatch
import glob
import os
from collections.abc import Iterable
from pathlib import Path

from ..errors import ShprobeError
from ..files import read_text
from ..probes.images import READ_EXTENSIONS
from ..probes.layouts import LAYOUT_NAMES

#: Extensions of path lists (one probe per line / row).
LIST_EXTENSIONS = (".txt", ".lst", ".list", ".csv", ".parquet")
_GLOB_CHARS = set("*?[")

__all__ = ["LIST_EXTENSIONS", "expand_inputs"]


def _check_layout(name: str | None, where: str) -> str:
    name = (name or "auto").strip().lower() or "auto"
    if name != "auto" and name not in LAYOUT_NAMES:
        raise ShprobeError(f"unknown layout {name!r}; choose auto or one of "
                           + ", ".join(LAYOUT_NAMES), where)
    return name


def _images_under(folder: Path) -> list[Path]:
    out = []
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        out += [Path(root, f) for f in sorted(files)
                if not f.startswith(".") and Path(f).suffix.lower() in READ_EXTENSIONS]
    return out


def _match(parts: list[str], names: list[str]) -> bool:
    """Whether the path components ``names`` match the pattern components ``parts`` (``**``:
    zero or more folders; a leading dot only matched by a pattern's leading dot, as glob)."""
    if not parts:
        return not names
    if parts[0] == "**":
        return any(_match(parts[1:], names[i:]) for i in range(len(names) + 1)
                   if not any(n.startswith(".") for n in names[:i]))
    return (bool(names) and (parts[0].startswith(".") or not names[0].startswith("."))
            and fnmatch.fnmatchcase(names[0], parts[0]) and _match(parts[1:], names[1:]))


def _glob(pattern: str) -> list[str]:
    """Paths matching ``pattern`` (``**`` recursive): `glob.glob` where the pattern has
    no ``**``; otherwise a walk below the pattern's fixed folder that follows links to folders
    but enters each folder (device, inode) once, so links to ``.`` or to a parent give each
    file once and end (glob's own ``**`` follows them until the path is too long)."""
    if "**" not in pattern:
        return glob.glob(pattern)
    parts = pattern.split(os.sep)
    k = next(i for i, c in enumerate(parts) if _GLOB_CHARS & set(c))
    root = os.sep.join(parts[:k]) or ("/" if pattern.startswith(os.sep) else ".")
    rest = parts[k:]
    out: list[str] = []
    seen: set[tuple[int, int]] = set()
    for top, dirs, files in os.walk(root, followlinks=True):
        try:
            st = os.stat(top)
        except OSError:
            dirs[:] = []
            continue
        if (st.st_dev, st.st_ino) in seen:
            dirs[:] = []
            continue
        seen.add((st.st_dev, st.st_ino))
        dirs.sort()
        rel = os.path.relpath(top, root)
        base = [] if rel == "." else rel.split(os.sep)
        for name in sorted(files) + dirs:
            if _match(rest, [*base, name]):
                out.append(os.path.join(top, name))
    return out


def _read_list(p: Path) -> list[tuple[str, str | None]]:
    """(path, layout or None) rows of a list file; relative paths are taken from the list's
    folder."""
    ext = p.suffix.lower()
    rows: list[tuple[str, str | None]] = []
    if ext == ".parquet":
        import pyarrow.parquet as pq

        try:
            t = pq.read_table(p)
        except Exception as e:  # pyarrow raises several types for bad files
            raise ShprobeError(f"cannot read path list: {' '.join(str(e).split())[:200]}",
                               p) from None
        if "path" not in t.column_names:
            raise ShprobeError("a Parquet path list needs a 'path' column", p)
        paths = t.column("path").to_pylist()
        lays = t.column("layout").to_pylist() if "layout" in t.column_names else [None] * len(
            paths)
        rows = [(str(a), b) for a, b in zip(paths, lays, strict=True) if a]
    elif ext == ".csv":
        text = read_text(p, "CSV file")
        reader = csv.DictReader(text.splitlines())
        if reader.fieldnames is None or "path" not in reader.fieldnames:
            raise ShprobeError("a CSV path list needs a header row with a 'path' column", p)
        rows = [(r["path"].strip(), r.get("layout")) for r in reader if (r["path"] or "").strip()]
    else:
        for line in read_text(p, "text file").splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                rows.append((line, None))
    base = p.parent
    return [(a if os.path.isabs(a) else os.fspath(base / a), b) for a, b in rows]


def expand_inputs(inputs: str | os.PathLike[str] | Iterable[str | os.PathLike[str]],
                  layout: str = "auto") -> list[tuple[str, str]]:
    """Expand INPUTS to ``[(absolute path, layout), ...]``, duplicates dropped, order kept.

    Each input is a folder (every image under it, recursively, hidden entries skipped, in
    sorted order), an image file, a list of paths (``.txt``/``.lst``: one per line, ``#``
    comments; ``.csv`` with a ``path`` and optional ``layout`` column; ``.parquet`` likewise;
    relative paths are relative to the list's folder) or a glob (``**`` recursive). A path
    that does not exist is kept (its row will carry the error); a glob matching nothing is
    an error. ``layout`` applies where a list gives none; ``auto`` detects it per file.

    Parameters
    ----------
    inputs
        Folders, image files, path lists (.txt, .lst, .csv, .parquet) or globs.
    layout
        The layout where a list gives none ("auto" detects it).

    Returns
    -------
    list of tuple
        (absolute path, layout) per probe, duplicates dropped, order kept.
    """
    if isinstance(inputs, str | os.PathLike):
        inputs = [inputs]
    default = _check_layout(layout, "--layout")
    out: dict[str, str] = {}

    def add(path: str | os.PathLike[str], lay: str | None, where: str) -> None:
        key = os.path.abspath(os.fspath(path))
        out.setdefault(key, _check_layout(lay, where) if lay else default)

    for item in inputs:
        s = os.fspath(item)
        p = Path(s)
        if p.is_dir():
            for f in _images_under(p):
                add(f, None, s)
        elif p.suffix.lower() in LIST_EXTENSIONS and p.is_file():
            for a, b in _read_list(p):
                add(a, b, s)
        elif not p.exists() and _GLOB_CHARS & set(s):
            hits = sorted(_glob(s))
            hits = [h for h in hits if Path(h).suffix.lower() in READ_EXTENSIONS
                    and not Path(h).is_dir()]
            if not hits:
                raise ShprobeError("no image files match this pattern", s)
            for h in hits:
                add(h, None, s)
        else:
            add(s, None, s)
    return list(out.items())

