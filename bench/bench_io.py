"""File decoding time (issue 3: reported separately from projection), and layout table setup.

Run: PYTHONPATH=src python bench/bench_io.py [--size 4096x2048] [--repeat 5]
Prints a markdown table. Peers in the same run: OpenImageIO's raw read_image (no checks, no
conversion) and shprobe's own numba RGBE decoder.
"""

from __future__ import annotations

import argparse
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

    from shprobe.probes.codecs import read_rgbe
    from shprobe.probes.images import read_image, write_image
    from shprobe.probes.layouts import get_layout

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
                b, m = best(lambda p=p: read_rgbe(p), args.repeat)
                rows.append(("peer: shprobe numba RGBE decoder .hdr", mb, b, m, None))

    print(f"### Decoding a {w}x{h} RGB float image (best / median of {args.repeat})\n")
    print("| reader | file MiB | best ms | median ms | write ms |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, mb, b, m, wt in rows:
        wts = f"{wt * 1e3:.0f}" if wt is not None else ""
        print(f"| {name} | {mb:.1f} | {b * 1e3:.1f} | {m * 1e3:.1f} | {wts} |")

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


if __name__ == "__main__":
    main()
