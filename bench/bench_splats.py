"""`shprobe splat transform` against PlayCanvas splat-transform on the same PLY, same run.

Run: PYTHONPATH=src python bench/bench_splats.py [--splats 1000000 6000000] [--repeat 3]

For each size it writes a degree-3 trainer-layout PLY (248 bytes a splat: 1M splats is
248 MB) to a temporary folder, then times the whole command of each tool — process start
included — rotating it PLY → PLY, and reads each child's peak resident memory from the kernel
(``wait4``). The files are deleted after each size. splat-transform is the one pinned in
tests/consumers (``npm ci`` there); without node it is skipped and said so.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CLI = ROOT / "tests" / "consumers" / "node_modules" / "@playcanvas" / "splat-transform" / \
    "bin" / "cli.mjs"
CHUNK = 1 << 18


def write_ply(path: Path, n: int, seed: int = 0) -> None:
    """A degree-3 PLY in the reference trainer's layout, written chunk by chunk."""
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(45)] + ["opacity", "scale_0", "scale_1", "scale_2"]
    names += ["rot_0", "rot_1", "rot_2", "rot_3"]
    dtype = np.dtype([(nm, "<f4") for nm in names])
    rng = np.random.default_rng(seed)
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {n}"]
    head += [f"property float {nm}" for nm in names] + ["end_header"]
    with open(path, "wb") as f:
        f.write(("\n".join(head) + "\n").encode())
        for i in range(0, n, CHUNK):
            m = min(CHUNK, n - i)
            a = rng.normal(size=(m, len(names))).astype(np.float32)
            a[:, 3:6] = 0.0
            a[:, 9:54] *= 0.2
            a[:, 55:58] -= 4.0
            f.write(a.view(dtype).tobytes())


def run(cmd: list[str]) -> tuple[float, float, float]:
    """(wall seconds, peak resident MB, CPU seconds user + system) of one command."""
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:3])} … failed: {err[-500:]}")
    return wall, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--splats", type=int, nargs="+", default=[1_000_000, 6_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--dir", default=None, help="Folder for the temporary files.")
    ap.add_argument("--write", nargs=2, metavar=("PATH", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.write:
        write_ply(Path(args.write[0]), int(args.write[1]))
        return
    sys.path.insert(0, str(Path(__file__).parent))
    from _machine import machine

    node = shutil.which("node")
    peer = node is not None and CLI.is_file()
    env_py = [sys.executable, "-m", "shprobe", "-q", "splat", "transform"]
    print(f"machine: {machine()}")
    if peer:
        ver = subprocess.run([node, str(CLI), "--version"], capture_output=True, text=True)
        nv = subprocess.run([node, "--version"], capture_output=True, text=True).stdout.strip()
        print(f"peer: @playcanvas/splat-transform {(ver.stdout + ver.stderr).strip()} on "
              f"node {nv}")
    else:
        print("peer: splat-transform not installed (node or tests/consumers/node_modules "
              "missing): skipped")
    print()
    print("| splats | file | shprobe wall best / median | CPU | peak RSS | splat-transform wall "
          "best / median | CPU | peak RSS | wall ratio (median) | CPU ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in args.splats:
        with tempfile.TemporaryDirectory(dir=args.dir) as d:
            src, out = Path(d) / "in.ply", Path(d) / "out.ply"
            # written by a child process: a child's peak RSS (wait4) starts from its parent's
            # at spawn, so the parent stays small
            subprocess.run([sys.executable, __file__, "--write", str(src), str(n)], check=True)
            ours, theirs = [], []
            for _ in range(args.repeat):
                out.unlink(missing_ok=True)
                ours.append(run([*env_py, str(src), "-o", str(out), "--rotate",
                                 "1,2,3:40"]))
                out.unlink(missing_ok=True)
                if peer:
                    theirs.append(run([node, str(CLI), "-q", "-w", str(src), "-r",
                                       "10,20,30", str(out)]))
            size = src.stat().st_size / 1e6

        def cells(rows):
            w = sorted(r[0] for r in rows)
            return (f" {w[0]:.2f} / {np.median(w):.2f} s | {np.median([r[2] for r in rows]):.2f}"
                    f" s | {max(r[1] for r in rows):.0f} MB |")

        row = f"| {n:,} | {size:.0f} MB |" + cells(ours)
        if peer:
            ratio = np.median([r[0] for r in ours]) / np.median([r[0] for r in theirs])
            cpu = np.median([r[2] for r in ours]) / np.median([r[2] for r in theirs])
            row += cells(theirs) + f" {ratio:.2f} | {cpu:.2f} |"
        else:
            row += " – | – | – | – | – |"
        print(row, flush=True)


if __name__ == "__main__":
    main()
