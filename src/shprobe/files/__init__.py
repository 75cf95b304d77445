"""Files in and out: inputs checked before reading (``inputs``), safe outputs written to a
temporary name and renamed into place (``outputs``), checked ``.npz`` archives (``npz``) and
the on-disk cache (``cache``). Every public name is importable from ``shprobe.files``, the
constants too (``__all__``, which the manual lists, holds the functions and classes)."""

from .cache import CACHE_ENV as CACHE_ENV
from .cache import CACHE_KEEP as CACHE_KEEP
from .cache import cache_dir, file_digest, read_cache, write_cache
from .inputs import open_regular, read_text, regular_file
from .npz import load_npz, npz_headers, save_npz
from .outputs import STALE_SECONDS as STALE_SECONDS
from .outputs import (
    Transaction,
    atomic_output,
    check_output_path,
    remove_stale_temporaries,
    transaction,
    write_json,
    write_text,
)

__all__ = [
    "Transaction",
    "atomic_output",
    "cache_dir",
    "check_output_path",
    "file_digest",
    "load_npz",
    "npz_headers",
    "open_regular",
    "read_cache",
    "read_text",
    "regular_file",
    "remove_stale_temporaries",
    "save_npz",
    "transaction",
    "write_cache",
    "write_json",
    "write_text",
]
