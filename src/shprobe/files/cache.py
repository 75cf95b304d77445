"""shprobe's on-disk cache: entries derived from input files, keyed by their content, stored
with a digest and pruned least recently used first; a cache is never an error."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ShprobeError
from .outputs import atomic_output

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
