"""File decoding time (issue 3: reported separately from projection), and layout table setup.

Run: PYTHONPATH=src python bench/bench_io.py [--size 4096x2048] [--repeat 5]
Prints markdown tables. Peers in the same run: OpenImageIO's raw read_image (no checks, no
conversion), and shprobe's two RGBE decoders alone: the NumPy one (``probes.rgbe_numpy``, what
``read_rgbe`` uses up to ``RGBE_NUMPY_MAX_PIXELS``) and the compiled one (numba). Then the first
decode in a fresh process, where the compiled decoder's start-up counts.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def best(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="4096x2048")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))

    import OpenImageIO as oiio

    from shprobe.probes.codecs import read_rgbe, rgbe_header, rgbe_rows
    from shprobe.probes.images import read_image, write_image
    from shprobe.probes.layouts import get_layout
    from shprobe.probes.rgbe_numpy import decode_rgbe_numpy

    rng = np.random.default_rng(0)
    # a probe-like image: smooth sky plus noise and a few hot pixels (RLE sees real data)
    yy = np.linspace(0, 1, h, dtype=np.float32)[:, None, None]
    img = (0.2 + yy * np.array([0.5, 0.6, 1.0], np.float32)) * (
        1 + 0.3 * rng.random((h, w, 3), dtype=np.float32))
    img[rng.integers(0, h, 50), rng.integers(0, w, 50)] = 5000.0
    rows = []
    with tempfile.TemporaryDirectory() as d:
        files = {}
        for name, kw in (("hdr", {}), ("exr", {}), ("exr-half", {"half": True}), ("pfm", {})):
            p = Path(d) / f"probe-{name}.{name.split('-')[0]}"
            t = time.perf_counter()
            write_image(p, img, **kw)
            files[name] = (p, time.perf_counter() - t)
        read_image(files["hdr"][0])  # warm-up (numba cache, OIIO plugins)
        read_rgbe(files["hdr"][0])

        def raw_oiio(p):
            inp = oiio.ImageInput.open(str(p))
            inp.read_image(oiio.FLOAT)
            inp.close()

        for name, (p, wt) in files.items():
            mb = p.stat().st_size / 2**20
            b, m = best(lambda p=p: read_image(p), args.repeat)
            rows.append((f"shprobe.read_image .{name}", mb, b, m, wt))
            if name != "pfm":
                b, m = best(lambda p=p: raw_oiio(p), args.repeat)
                rows.append((f"peer: OpenImageIO read_image .{name}", mb, b, m, None))
            if name == "hdr":
                raw = p.read_bytes()
                *_, n1, n2, off = rgbe_header(p, raw)
                body = np.frombuffer(raw, np.uint8, offset=off)
                out = np.empty((n1, n2, 3), np.float32)
                b, m = best(lambda body=body, out=out:
                            decode_rgbe_numpy(body, out), args.repeat)
                rows.append(("peer: shprobe NumPy RGBE decoder alone .hdr", mb, b, m, None))
                b, m = best(lambda body=body, out=out: rgbe_rows(body, 0, out), args.repeat)
                rows.append(("peer: shprobe compiled RGBE decoder alone .hdr", mb, b, m, None))
        cold = fresh_process(files["hdr"][0], Path(d), args.repeat, write_image, img)

    print(f"### Decoding a {w}x{h} RGB float image (best / median of {args.repeat})\n")
    print("| reader | file MiB | best ms | median ms | write ms |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, mb, b, m, wt in rows:
        wts = f"{wt * 1e3:.0f}" if wt is not None else ""
        print(f"| {name} | {mb:.1f} | {b * 1e3:.1f} | {m * 1e3:.1f} | {wts} |")

    print("\n### First decode in a fresh process (`read_rgbe`, after the imports; "
          f"best / median of {args.repeat} processes)\n")
    print("| image | decoder | best ms | median ms |")
    print("| --- | --- | ---: | ---: |")
    for size, name, b, m in cold:
        print(f"| {size} | {name} | {b * 1e3:.0f} | {m * 1e3:.0f} |")

    print("\n### Layout tables (first call; later calls are cached or cheap)\n")
    print("| layout | grid | solid angles ms | directions ms |")
    print("| --- | --- | ---: | ---: |")
    for name, size in (("latlong", h), ("angular", 1500), ("mirrorball", 1500), ("cube", 1024)):
        lay = get_layout(name)
        g = lay.grid_shape(size)
        t = time.perf_counter()
        lay.solid_angles(g)
        ts = time.perf_counter() - t
        t = time.perf_counter()
        lay.pixel_directions(g)
        td = time.perf_counter() - t
        print(f"| {name} | {'x'.join(map(str, g))} | {ts * 1e3:.0f} | {td * 1e3:.0f} |")


def fresh_process(big: Path, folder: Path, repeat: int, write_image, img
                  ) -> list[tuple[str, str, float, float]]:
    """``read_rgbe`` timed in new processes: NumPy (the default up to RGBE_NUMPY_MAX_PIXELS)
    and compiled (forced by a limit of 0), for a 2048×1024 probe and the benchmark's image."""
    small = folder / "probe-2k.hdr"
    write_image(small, img[::max(1, img.shape[0] // 1024), ::max(1, img.shape[1] // 2048)])
    code = ("import sys, time; from shprobe.probes import codecs, rgbe_numpy; "
            "rgbe_numpy.RGBE_NUMPY_MAX_PIXELS = int(sys.argv[2]); t = time.perf_counter(); "
            "codecs.read_rgbe(sys.argv[1]); print(time.perf_counter() - t)")
    res = []
    for p in (small, big):
        h, w = (int(v) for v in p.read_bytes().split(b"\n-Y ")[1].split(b"\n")[0]
                .split(b" +X "))
        for name, limit in (("NumPy", 1 << 40), ("compiled (numba)", 0)):
            ts = [float(subprocess.run([sys.executable, "-c", code, str(p), str(limit)],
                                       capture_output=True, text=True, check=True).stdout)
                  for _ in range(repeat)]
            res.append((f"{w}×{h}", name, min(ts), float(np.median(ts))))
    return res


if __name__ == "__main__":
    main()
