"""Cost of saying no: wall time and peak resident memory of each refusal class of the bad-input
issue, each in a fresh process (`shprobe ...` as a user runs it; start-up included, and shown
alone as the first row).

Run: ``python bench/bench_refusals.py`` (``SHPROBE_TEST_DATA`` for the shared probes). Prints a
markdown table; the target is < 1 s and < 200 MB above the start-up row for every refusal.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine

SHARED = Path(os.environ.get("SHPROBE_TEST_DATA",
                             Path(__file__).resolve().parents[1].parent / "shared"))


def _files(d: Path) -> dict[str, Path]:
    import numpy as np

    f = {}
    f["huge.hdr"] = d / "huge.hdr"
    f["huge.hdr"].write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n"
                              + b"\x02\x02\x00\x00" * 4)
    f["bomb.npz"] = d / "bomb.npz"
    with zipfile.ZipFile(f["bomb.npz"], "w", zipfile.ZIP_DEFLATED) as z, \
            z.open("traced.npy", "w") as out:
        import io

        buf = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            buf, {"descr": "<f8", "fortran_order": False, "shape": (40000, 40000)})
        out.write(buf.getvalue() + bytes(1 << 20))
    f["deep.json"] = d / "deep.json"
    f["deep.json"].write_text("[" * 100_000 + "]" * 100_000)
    os.mkfifo(d / "fifo.spz")  # nobody writes to it: a reader that opens it blocks forever
    f["fifo.spz"] = d / "fifo.spz"
    os.symlink("/dev/zero", d / "zero.glb")  # endless
    f["zero.glb"] = d / "zero.glb"
    import json
    import struct

    js = json.dumps([{"asset": {"version": "2.0"}}]).encode()  # a list as the document
    js += b" " * (-len(js) % 4)
    f["list.glb"] = d / "list.glb"
    f["list.glb"].write_bytes(struct.pack("<III", 0x46546C67, 2, 20 + len(js))
                              + struct.pack("<II", len(js), 0x4E4F534A) + js)
    meta = json.dumps({"format": "shprobe-grid", "version": "1"}).encode()
    f["grid.npz"] = d / "grid.npz"
    np.savez(f["grid.npz"], meta=np.frombuffer(meta, np.uint8),
             coeffs=np.zeros((2, 2, 2, 9, 3), np.float32),
             bounds=np.array([[-1.0, -1, -1], [1, 1, 1]]))
    return f


def _run(argv: list[str]) -> tuple[float, float, int]:
    """(wall seconds, peak RSS MB of this child alone, exit code)."""
    cmd = argv[1:] if argv[0] == "-c" else ["-m", "shprobe", *argv]
    if argv[0] == "-c":
        cmd = ["-c", argv[1]]
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, *cmd], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    dt = time.perf_counter() - t0
    return dt, usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status)


def main() -> None:
    grace = SHARED / "probes" / "grace.hdr"
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        f = _files(d)
        cases = [
            ("start-up only (`shprobe --version`)", ["--version"]),
            ("71-byte .hdr declaring 100000x100000", ["prefilter", str(f["huge.hdr"])]),
            ("4.9 kB .npz declaring 12.8 GB", ["prt", "render", str(f["bomb.npz"]), "--preset",
                                               "grace", "-o", str(d / "x.png")]),
            ("JSON nested 100000 deep", ["prefilter", "--coeffs", str(f["deep.json"])]),
            ("irradiance --size 40000x20000", ["irradiance", "--preset", "grace", "--size",
                                              "40000x20000", "-o", str(d / "i.exr")]),
            ("render --size 30000x30000", ["render", "--preset", "grace", "--sphere", "--size",
                                          "30000x30000", "-o", str(d / "r.png")]),
            ("project(env, 1024) (library)",
             ["-c", f"import shprobe\ntry: shprobe.project(shprobe.load_env({str(grace)!r}), "
                    "1024)\nexcept shprobe.ShprobeError: raise SystemExit(1)"]),
            ("sh_basis(3000 dirs, 1024) (library)",
             ["-c", "import numpy as np, shprobe\ntry: shprobe.sh_basis(np.tile([0, 0, 1.0], "
                    "(3000, 1)), 1024)\nexcept shprobe.ShprobeError: raise SystemExit(1)"]),
            ("sh eval --lmax 100000", ["sh", "eval", "--dir", "0,0,1", "--lmax", "100000"]),
            ("a FIFO named x.spz", ["splat", "info", str(f["fifo.spz"])]),
            ("a .glb linked to /dev/zero", ["splat", "info", str(f["zero.glb"])]),
            ("a .glb whose JSON is a list", ["splat", "info", str(f["list.glb"])]),
            ("a grid file whose version is a string",
             ["grid", "export", str(f["grid.npz"]), "--format", "godot", "-o",
              str(d / "g.tres")]),
            ("grid bake --bounds ±1e300",
             ["grid", "bake", "bunny", "--preset", "grace", "--resolution", "2,2,2",
              "--bounds", "-1e300,-1e300,-1e300,1e300,1e300,1e300", "-o", str(d / "g.npz")]),
        ]
        print(f"Machine: {machine()}\n")
        print("| refusal | wall (s) | peak RSS (MB) | exit |")
        print("|---|---:|---:|---:|")
        for name, argv in cases:
            dt, mb, rc = _run(argv)
            print(f"| {name} | {dt:.2f} | {mb:.0f} | {rc} |")


if __name__ == "__main__":
    main()
