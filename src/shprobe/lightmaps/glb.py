"""The GLB container (glTF 2.0 binary): JSON chunk, BIN chunk; read, encode, written
atomically."""

from __future__ import annotations

import json
import os
import struct
from typing import Any

from ..errors import ShprobeError

__all__ = ["encode_glb", "parse_glb", "read_glb", "write_glb"]

_GLB, _JSON, _BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


def _pad4(b: bytes | bytearray, fill: bytes = b"\0") -> bytes:
    return bytes(b) + fill * (-len(b) % 4)


def encode_glb(doc: dict, binary: bytes | bytearray) -> bytes:
    """The .glb bytes of a glTF JSON document and its BIN chunk.

    Parameters
    ----------
    doc : dict
        The glTF JSON (its buffer 0, if any, is the BIN chunk).
    binary : bytes
        The BIN chunk.

    Returns
    -------
    bytes
        The GLB container.
    """
    js = _pad4(json.dumps(doc, separators=(",", ":")).encode("utf-8"), b" ")
    parts = [js]
    chunks = [struct.pack("<II", len(js), _JSON), js]
    if binary:
        b = _pad4(binary)
        chunks += [struct.pack("<II", len(b), _BIN), b]
        parts.append(b)
    total = 12 + sum(8 + len(p) for p in parts)
    return b"".join([struct.pack("<III", _GLB, 2, total), *chunks])


def parse_glb(raw: bytes, where: Any = None) -> tuple[dict, bytes]:
    """(glTF JSON, BIN chunk) of .glb bytes; one line naming the file on any damage.

    Parameters
    ----------
    raw : bytes
        The file's bytes.
    where : str, optional
        The file, for error messages.

    Returns
    -------
    tuple of (dict, bytes)
        The JSON document and the BIN chunk (empty if none).
    """
    if len(raw) < 20 or struct.unpack_from("<I", raw)[0] != _GLB:
        raise ShprobeError("not a binary glTF (.glb) file", where)
    _, version, total = struct.unpack_from("<III", raw)
    if version != 2 or total > len(raw):
        raise ShprobeError(f"glb version {version} or length {total} is wrong (truncated?)",
                           where)
    jlen, jtype = struct.unpack_from("<II", raw, 12)
    if jtype != _JSON or 20 + jlen > total:
        raise ShprobeError("glb has no JSON chunk first", where)
    try:
        doc = json.loads(raw[20:20 + jlen])
    except ValueError:
        raise ShprobeError("glb JSON chunk is not JSON", where) from None
    pos, binary = 20 + jlen, b""
    if pos + 8 <= total:
        blen, btype = struct.unpack_from("<II", raw, pos)
        if btype == _BIN:
            binary = bytes(raw[pos + 8:pos + 8 + blen])
    return doc, binary


def read_glb(path: str | os.PathLike[str]) -> tuple[dict, bytes]:
    """(glTF JSON, BIN chunk) of a .glb file.

    Parameters
    ----------
    path : str or PathLike
        The file.

    Returns
    -------
    tuple of (dict, bytes)
        As `parse_glb`.
    """
    p = os.fspath(path)
    try:
        with open(p, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise ShprobeError("no such file", p) from None
    except OSError as e:
        raise ShprobeError(f"cannot read: {e.strerror or e}", p) from None
    return parse_glb(raw, p)


def write_glb(path: str | os.PathLike[str], doc: dict, binary: bytes | bytearray,
              overwrite: bool = False) -> None:
    """Write a .glb atomically (a temporary file renamed into place; see shprobe.files).

    Parameters
    ----------
    path : str or PathLike
        The output.
    doc : dict
        The glTF JSON.
    binary : bytes
        The BIN chunk.
    overwrite : bool
        Replace an existing file.
    """
    from ..files import atomic_output

    data = encode_glb(doc, binary)
    with atomic_output(path, overwrite) as tmp, open(tmp, "wb") as f:
        f.write(data)
