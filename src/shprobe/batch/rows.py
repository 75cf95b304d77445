"""One probe → one table row: the columns of ``shprobe batch``, their Arrow types and units,
and the function that computes a row (run in a worker process or in-process).

Every number is computed by the library functions shprobe's commands use: the streamed
projection `shprobe.lighting.projection.project_file` (R&H 2001 eq. 10),
[`irradiance_coeffs`][shprobe.lighting.irradiance_coeffs] (eq. 7),
[`irradiance_matrix`][shprobe.lighting.irradiance_matrix] (eq. 11–12),
[`min_irradiance`][shprobe.lighting.min_irradiance], [`auto_window`][shprobe.lighting.auto_window]
and [`error_report`][shprobe.lighting.error_report] (§3.1).
"""

from __future__ import annotations

import io
import math
import os
import time
import warnings
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ShprobeError

__all__ = ["COLUMNS", "SCHEMA_VERSION", "BatchOptions", "content_hash", "probe_row", "schema"]

CONVENTION = ("real orthonormal SH, R&H 2001 signs (no Condon-Shortley phase), k = l(l+1)+m, "
              "world +Y up (lat-long row 0 = +Y, u = 0.5 -> -Z); coefficients [k][R,G,B]; "
              "E(n) = sum_k irradiance_coefficients[k] y_k(n); E(n) = n~^T M[c] n~ with "
              "n~ = (x, y, z, 1) (R&H eq. 12)")

#: Version of the table layout, in the schema's ``shprobe`` metadata. 2: the failure message
#: column is ``failure`` (1, unversioned: ``error``); tables of version 1 are still read
#: (:func:`shprobe.batch.read_table` renames the column) and resumed.
SCHEMA_VERSION = 2
#: Columns renamed since version 1: old name -> new name.
RENAMED = {"error": "failure"}

#: Rec. 709 luminance weights used to combine RGB for the dominant direction.
LUMA = (0.2126, 0.7152, 0.0722)

#: name -> (arrow type name, unit, description): the documented columns, in table order.
COLUMNS: dict[str, tuple[str, str, str]] = {
    "path": ("string", "", "absolute path of the probe file"),
    "size_bytes": ("int64", "bytes", "file size"),
    "content_hash": ("string", "", "XXH3-128 of the file bytes, hex (resume key; the "
                     "algorithm is this field's 'algorithm' metadata)"),
    "layout": ("string", "", "latlong | angular | mirrorball | cube (detected or given)"),
    "width": ("int32", "pixels", "image width as stored in the file"),
    "height": ("int32", "pixels", "image height as stored in the file"),
    "lmax": ("int32", "", "highest SH band projected"),
    "coefficients": ("list<list3<float64>>", "radiance x sr",
                     "L_lm (R&H eq. 10), K=(lmax+1)^2 rows of [R, G, B]"),
    "irradiance_coefficients": ("list<list3<float64>>", "irradiance",
                                "E_lm = A_l L_lm (R&H eq. 7), K rows of [R, G, B]"),
    "M": ("list3<list4<list4<float64>>>", "irradiance",
          "R&H eq. 12 matrix per channel R, G, B (null when lmax < 2)"),
    "integral": ("list3<float64>", "radiance x sr",
                 "integral of L over the sphere per channel = sqrt(4 pi) L_00"),
    "dominant_direction": ("list3<float64>", "unit vector",
                           "direction of the band-1 vector (L_11, L_1-1, L_10) of the "
                           "Rec. 709 luminance (null when lmax < 1 or it is zero)"),
    "dominant_strength": ("float64", "0..1", "|band-1 luminance vector| / (sqrt(3) L_00): "
                          "1 for one directional light, 0 for uniform light"),
    "min_irradiance": ("list3<float64>", "irradiance",
                       "min over the sphere of E(n) per channel: the certified lower bound "
                       "for lmax <= 2, the numerical minimum above"),
    "min_irradiance_certified": ("bool", "", "min_irradiance is a proven lower bound"),
    "window": ("string", "", "window `auto` would choose: none | hann | lanczos | gaussian "
               "| laplacian (null with --no-window)"),
    "window_strength": ("float64", "", "its strength (0 for none)"),
    "reference_grid": ("int32", "", "N of the 2N x N normal grid of the reference (null "
                       "without --reference)"),
    "error_mean": ("float64", "fraction of integral", "R&H 2001 sec. 3.1 metric: mean "
                   "|E_SH - E_exact| / integral over the normals (null without --reference)"),
    "error_max": ("float64", "fraction of integral", "the same, maximum over the normals"),
    "thumbnail": ("binary", "PNG", "tone-mapped thumbnail of the file (null unless asked)"),
    "thumbnail_exposure": ("float64", "stops", "exposure applied to the thumbnail"),
    "warning": ("string", "", "one-line warning (e.g. an 8-bit image), else null"),
    "failure": ("string", "", "one-line message naming the file when the probe failed, else "
                "null (not to be confused with error_mean / error_max, the SH accuracy)"),
    "seconds": ("float64", "s", "time spent on the probe by its worker"),
}


def _arrow_type(name: str):
    import pyarrow as pa

    f64 = pa.float64()
    return {
        "string": pa.string(), "int64": pa.int64(), "int32": pa.int32(), "float64": f64,
        "bool": pa.bool_(), "binary": pa.binary(),
        "list3<float64>": pa.list_(f64, 3),
        "list<list3<float64>>": pa.list_(pa.list_(f64, 3)),
        "list3<list4<list4<float64>>>": pa.list_(pa.list_(pa.list_(f64, 4), 4), 3),
    }[name]


def schema(meta: dict[str, Any] | None = None):
    """The Arrow schema of a batch table; each field's metadata holds its ``unit`` and
    ``description``; the schema's ``shprobe`` key holds ``meta`` (JSON) with the convention.

    Parameters
    ----------
    meta
        The table's metadata (the options, the convention).

    Returns
    -------
    pyarrow.Schema
        The table's schema with units and descriptions.
    """
    import json

    import pyarrow as pa

    from .._version import __version__

    fields = [pa.field(n, _arrow_type(t), nullable=n not in ("path",),
                       metadata={"unit": u, "description": d}
                       | ({"algorithm": HASH} if n == "content_hash" else {}))
              for n, (t, u, d) in COLUMNS.items()]
    doc = {"shprobe_version": __version__, "schema_version": SCHEMA_VERSION,
           "convention": CONVENTION, **(meta or {})}
    return pa.schema(fields, metadata={"shprobe": json.dumps(doc)})


@dataclass(frozen=True)
class BatchOptions:
    """What each row computes.

    Parameters
    ----------
    lmax
        The coefficients' degree.
    clamp
        Clamp bad pixels instead of failing the row.
    window
        Fill the auto-window columns (False leaves them null: they cost more than decoding a
        2k probe when a window is needed).
    reference
        N: add the exact-irradiance error on a 2N×N normal grid.
    thumbnail
        The thumbnail's width in pixels (0: none).
    block_bytes
        The bytes of one streamed block of rows.
    """

    lmax: int = 2
    clamp: bool = False
    window: bool = True
    reference: int | None = None
    thumbnail: int = 0
    block_bytes: int = 16 << 20

    def key(self) -> dict[str, Any]:
        """The options a table's rows depend on (resume refuses a table made with others).

        Returns
        -------
        dict
            The options the rows depend on, by name.
        """
        d = asdict(self)
        d.pop("block_bytes")
        return d | {"hash": HASH}


#: The content hash: XXH3-128 (the ``xxhash`` package), ~30 GB/s on one core. It identifies
#: files for resume and de-duplication, not against an adversary, so a fast non-cryptographic
#: 128-bit hash is enough; SHA-256 (tables before this change) cost 6 ms of a 2048×1024 .hdr
#: row and 20 ms of a .exr one, XXH3-128 0.9 and 4 ms, mostly the read (bench/bench_batch.py).
#: Tables record it (schema options ``hash`` and the column's ``algorithm`` metadata); resuming
#: a table made with another hash is refused.
HASH = "xxh3_128"


def content_hash(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """XXH3-128 of a file's bytes, hex (`HASH`); a regular file only (opened without
    blocking, so a FIFO put in its place meanwhile is refused, not waited on).

    Parameters
    ----------
    path
        A regular file.
    chunk
        Bytes read at a time.

    Returns
    -------
    str
        XXH3-128 of the bytes, hex.
    """
    import xxhash

    h = xxhash.xxh3_128()
    buf = bytearray(chunk)
    view = memoryview(buf)
    from ..files import open_regular

    with open_regular(path, "probe") as f:
        while n := f.readinto(buf):
            h.update(view[:n])
    return h.hexdigest()


class _Thumb:
    """Area-averaged thumbnail of an image streamed a block of rows at a time."""

    def __init__(self, tw: int, w: int, h: int) -> None:
        self.tw = max(1, min(int(tw), w))
        self.th = max(1, min(h, round(self.tw * h / w)))
        self.w, self.h = w, h
        self.sum = np.zeros((self.th, self.tw, 3))
        self.cols = (np.arange(self.tw) * w) // self.tw  # first column of each bin
        self.count = np.zeros(self.th)

    def add(self, y0: int, blk: NDArray[np.float32]) -> None:
        colsum = np.add.reduceat(blk.astype(np.float64), self.cols, axis=1)  # (r, tw, 3)
        bins = ((y0 + np.arange(blk.shape[0])) * self.th) // self.h
        np.add.at(self.sum, bins, colsum)
        np.add.at(self.count, bins, 1)

    def png(self) -> tuple[bytes, float]:
        from PIL import Image

        from ..probes.tonemap import auto_exposure, tonemap

        widths = np.diff(np.append(self.cols, self.w))
        img = self.sum / (self.count[:, None, None] * widths[None, :, None])
        exposure = auto_exposure(img, 1.0)  # the one exposure rule
        buf = io.BytesIO()
        Image.fromarray(tonemap(img, exposure)).save(buf, format="PNG")
        return buf.getvalue(), exposure


def _one_line(e: BaseException, path: str) -> str:
    if isinstance(e, ShprobeError):
        msg = str(e) if e.path else f"{path}: {e}"
    elif isinstance(e, OSError):
        msg = f"{path}: {e.strerror or e}"
    else:
        msg = f"{path}: {type(e).__name__}: {e}"
    return " ".join(msg.split())[:500]


def empty_row(path: str) -> dict[str, Any]:
    """A row with every column null but ``path``."""
    return dict.fromkeys(COLUMNS) | {"path": path}


def probe_row(path: str, layout: str = "auto", options: BatchOptions | None = None,
              done: frozenset[str] | set[str] | None = None) -> dict[str, Any]:
    """Compute one row (a dict of the [`COLUMNS`][shprobe.batch.COLUMNS], plain Python values).

    Never raises for a bad probe: its one-line message goes to ``failure`` and the columns not
    reached stay null. When the file's content hash is in ``done`` the work is skipped and
    the row has only ``path``, ``size_bytes``, ``content_hash`` and ``"skipped": True``.

    Parameters
    ----------
    path
        The probe.
    layout
        Its layout, or "auto".
    options
        What the row computes (default: lmax 2).
    done
        Content hashes already in the table: their work is skipped.

    Returns
    -------
    dict
        The row's values by column name.
    """
    from ..lighting import (
        auto_window,
        error_report,
        irradiance_coeffs,
        irradiance_matrix,
        min_irradiance,
        pad_coeffs,
    )
    from ..lighting.projection import project_file
    from ..probes.images import LDRWarning

    opt = options or BatchOptions()
    t0 = time.perf_counter()
    row = empty_row(path)
    try:
        from ..files import regular_file

        st = regular_file(path, "probe")  # /dev/zero, a FIFO, a socket: reading never ends
        row["size_bytes"] = st.st_size
        row["content_hash"] = content_hash(path)
        if done is not None and row["content_hash"] in done:
            return {"path": path, "size_bytes": row["size_bytes"],
                    "content_hash": row["content_hash"], "skipped": True}
        thumb: list[_Thumb] = []

        def on_block(y0: int, blk: NDArray[np.float32]) -> None:
            if opt.thumbnail:
                if not thumb:
                    thumb.append(_Thumb(opt.thumbnail, im_w[0], im_h[0]))
                thumb[0].add(y0, blk)

        from ..probes.streaming import image_size

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LDRWarning)
            im_w, im_h = [0], [0]
            if opt.thumbnail:
                im_w[0], im_h[0] = image_size(path)
            fp = project_file(path, opt.lmax, layout, opt.clamp, opt.block_bytes,
                              on_block if opt.thumbnail else None)
        msgs = [str(w.message) for w in caught if issubclass(w.category, LDRWarning)]
        row["warning"] = " ".join(msgs[0].split())[:500] if msgs else None
        c = fp.coeffs
        row.update(layout=fp.layout, width=fp.width, height=fp.height, lmax=opt.lmax,
                   coefficients=c.tolist(), irradiance_coefficients=irradiance_coeffs(c).tolist(),
                   integral=(c[0] * math.sqrt(4.0 * math.pi)).tolist())
        if opt.lmax >= 2:
            row["M"] = irradiance_matrix(c).tolist()
        if opt.lmax >= 1:
            luma = np.asarray(LUMA)
            v = np.array([c[3] @ luma, c[1] @ luma, c[2] @ luma])  # (x, y, z) ∝ (L11, L1-1, L10)
            n = float(np.linalg.norm(v))
            l00 = float(c[0] @ luma)
            if n > 0:
                row["dominant_direction"] = (v / n).tolist()
            row["dominant_strength"] = n / (math.sqrt(3.0) * l00) if l00 > 0 else None
        c2 = pad_coeffs(c, 2) if opt.lmax < 2 else c
        mn = min_irradiance(c2)
        row["min_irradiance_certified"] = bool(mn.exact)
        row["min_irradiance"] = (mn.lower_bound if mn.exact else mn.minimum).tolist()
        try:
            win = auto_window(c2) if opt.window else None
            if win is not None:
                row["window"], row["window_strength"] = win.kind, float(win.strength)
        except ShprobeError:  # no window helps (L_00 ≤ 0): leave the columns null
            pass
        if opt.reference:
            from ..probes.env import load_env

            env = load_env(path, None if fp.layout is None else fp.layout, clamp=opt.clamp)
            doc = error_report(env, (opt.lmax,), normal_grid=opt.reference).as_dict()
            rep = doc["rows"][0]
            row.update(reference_grid=int(opt.reference), error_mean=rep["mean_frac"],
                       error_max=rep["max_frac"])
        if thumb:
            row["thumbnail"], row["thumbnail_exposure"] = thumb[0].png()
        for k in ("dominant_strength", "window_strength", "error_mean", "error_max"):
            if row[k] is not None and not math.isfinite(row[k]):
                row[k] = None  # never write a non-finite number
    except Exception as e:  # a bad probe is a row, never the end of the batch
        keep = {k: row[k] for k in ("path", "size_bytes", "content_hash")}
        row = empty_row(path) | keep | {"failure": _one_line(e, path),
                                        "layout": None if layout == "auto" else layout}
    row["seconds"] = time.perf_counter() - t0
    return row
