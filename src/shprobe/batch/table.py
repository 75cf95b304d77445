"""The batch table on disk: reading one (any schema version), the parts a running batch
writes atomically, and the rows of a previous run that a resumed batch keeps."""

from __future__ import annotations

import json
import os
import secrets
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..errors import ShprobeError
from ..files import atomic_output
from .rows import COLUMNS, RENAMED, SCHEMA_VERSION, schema

__all__ = ["ROW_BYTES", "parts_dir", "read_table", "table_meta"]


def parts_dir(output: str | os.PathLike[str]) -> Path:
    """Folder of the parts of ``output`` while a batch runs: ``<output>.parts``.

    Parameters
    ----------
    output
        The batch table's path.

    Returns
    -------
    Path
        ``<output>.parts``.
    """
    p = Path(output)
    return p.with_name(p.name + ".parts")


def table_meta(table: Any) -> dict[str, Any]:
    """The ``shprobe`` JSON metadata of a batch table ({} if absent)."""
    raw = (table.schema.metadata or {}).get(b"shprobe")
    return json.loads(raw) if raw else {}


def _upgrade(t: Any, path: Any):
    """A table (or part) of any schema version with today's column names (`RENAMED`);
    one made by a newer shprobe is refused."""
    version = table_meta(t).get("schema_version", 1)
    if not isinstance(version, int) or version > SCHEMA_VERSION:
        raise ShprobeError(f"is a batch table of schema version {version}; this shprobe reads "
                           f"versions up to {SCHEMA_VERSION} (upgrade shprobe)", path)
    names = [RENAMED.get(n, n) if version < 2 else n for n in t.column_names]
    if names == t.column_names:
        return t
    return t.rename_columns(names).replace_schema_metadata(t.schema.metadata)


def read_table(path: str | os.PathLike[str]):
    """A batch table (pyarrow.Table) with its metadata, columns named as today (a table of an
    older schema version has its renamed columns renamed); one line for a file that is not
    one.

    Parameters
    ----------
    path
        A batch table (``.parquet``).

    Returns
    -------
    pyarrow.Table
        The table with its metadata.
    """
    import pyarrow.parquet as pq

    if os.path.exists(path) and not os.path.isfile(path):
        raise ShprobeError("is not a regular file", path)
    try:
        t = pq.read_table(path)
    except FileNotFoundError:
        raise ShprobeError("no such file", path) from None
    except Exception as e:
        raise ShprobeError(f"not a Parquet table: {' '.join(str(e).split())[:200]}",
                           path) from None
    if "options" not in table_meta(t) or "content_hash" not in t.column_names:
        raise ShprobeError("not a shprobe batch table", path)
    return _upgrade(t, path)


def _rows_table(rows: list[dict[str, Any]], meta: dict[str, Any]):
    import pyarrow as pa

    clean = [{k: r.get(k) for k in COLUMNS} for r in rows]
    return pa.Table.from_pylist(clean, schema=schema(meta))


#: Bytes of a table row on disk, with room (a row is ~1 kB of numbers and strings, its
#: thumbnail a few kB of PNG), for the free-space check before a batch starts.
ROW_BYTES = 16 << 10


def _write_part(folder: Path, rows: list[dict[str, Any]], meta: dict[str, Any]) -> Path:
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    p = folder / f"part-{time.time_ns():020d}-{os.getpid()}-{secrets.token_hex(3)}.parquet"
    try:
        with atomic_output(p) as tmp:
            pq.write_table(_rows_table(rows, meta), tmp)
    except BaseException as e:
        try:  # a full disk on the first part: no empty parts folder left behind
            folder.rmdir()
        except OSError:
            pass
        if isinstance(e, ShprobeError):  # name the table, not a part of it
            raise ShprobeError(e.message, folder.with_name(folder.name[:-6])) from None
        raise
    return p


def _existing_rows(output: Path, meta: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows of a previous table and of parts left by an interrupted run (refused when they
    were made with other options)."""
    import pyarrow.parquet as pq

    tables = []
    if output.exists():
        tables.append((output, read_table(output)))
    folder = parts_dir(output)
    if folder.is_dir():
        for p in sorted(folder.glob("part-*.parquet")):
            try:
                t = pq.read_table(p)
            except Exception:  # a part is renamed into place whole; anything else is not ours
                continue
            tables.append((p, _upgrade(t, p)))
    rows: list[dict[str, Any]] = []
    for p, t in tables:
        have = table_meta(t).get("options")
        want = meta["options"]
        old_hash = (have or {}).get("hash")
        if isinstance(have, dict) and old_hash != want["hash"]:
            raise ShprobeError(f"its content hashes are {old_hash} and this shprobe makes "
                               f"{want['hash']}: they cannot be matched to resume; choose "
                               "another output or pass --force to start afresh", p)
        if have != want:
            raise ShprobeError(f"was made with other options ({have}, now {meta['options']}); "
                               "choose another output or pass --force to start afresh", p)
        rows += t.to_pylist()
    return rows


def _merge(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per path, the last one given winning; sorted by path."""
    by_path: dict[str, dict[str, Any]] = {}
    for r in rows:
        by_path[r["path"]] = r
    return [by_path[k] for k in sorted(by_path)]
