"""Batch throughput against decode-only throughput, RGBE decoders, prefilter latency, and the
peak memory of a streamed 16384x8192 float EXR projection (issue 11).

Run: PYTHONPATH=src python bench/bench_batch.py [--n 16] [--size 2048x1024] [--repeat 3]
     [--big 16384x8192 | --big 0] [--dir DIR]
Prints markdown tables. All figures come from one run; decode-only and batch passes are
interleaved. Peers: OpenImageIO's raw RGBE read, shprobe's numba RGBE decoder and OpenCV's
imread on the same .hdr; the whole-image projection's peak memory beside the streamed one.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _machine import machine

PY = sys.executable


def probe_image(h: int, w: int, seed: int, y0: int = 0, rows: int | None = None):
    """A probe-like image (rows y0..y0+rows of an h×w map): sky gradient × noise, a sun."""
    rows = h - y0 if rows is None else rows
    rng = np.random.default_rng([seed, y0])
    yy = ((y0 + np.arange(rows, dtype=np.float32)) / h)[:, None, None]
    img = (0.2 + (1 - yy) * np.array([0.5, 0.6, 1.0], np.float32)) * (
        1 + 0.3 * rng.random((rows, w, 3), dtype=np.float32))
    sy, sx = int(0.3 * h), int((0.2 + 0.05 * seed) % 1 * w)  # a 2-pixel-radius sun
    r = max(2, h // 512)
    a, b = max(sy - r, y0), min(sy + r, y0 + rows)
    if a < b:
        img[a - y0:b - y0, max(sx - r, 0):sx + r] = 2.0e4
    return img


def make_files(d: Path, n: int, w: int, h: int) -> list[Path]:
    from shprobe.probes.images import write_image

    files = []
    for i in range(n):
        img = probe_image(h, w, i)
        for ext in ("hdr", "exr"):
            p = d / f"probe{i:03d}.{ext}"
            if not p.exists():
                write_image(p, img)
            files.append(p)
    return files


def best_median(times):
    return min(times), float(np.median(times))


# ----------------------------------------------------------------------------- decoders


def bench_decoders(hdr: Path, repeat: int) -> list[str]:
    """Wall and CPU time (the box is shared: CPU time is the steadier figure)."""
    import OpenImageIO as oiio

    from shprobe.probes.codecs import read_oiio, rgbe_half_step
    from shprobe.probes.images import read_image

    ref = read_image(hdr)

    def oiio_raw():
        inp = oiio.ImageInput.open(str(hdr))
        a = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
        inp.close()
        return a

    readers = [
        ("shprobe.read_image (numba RGBE decoder, (m + 0.5) step built in)",
         lambda: read_image(hdr)),
        ("before: OpenImageIO + half-step pass (read_image until this issue)",
         lambda: rgbe_half_step(read_oiio(hdr)[0])),
        ("peer: OpenImageIO read_image (m·2^k, no half step)", oiio_raw)]
    try:
        import cv2

        readers.append(("peer: OpenCV imread", lambda: cv2.imread(
            str(hdr), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)[:, :, ::-1]))
    except ImportError:
        pass
    wall = {name: [] for name, _ in readers}
    cpu = {name: [] for name, _ in readers}
    out = {}
    for _ in range(repeat):  # interleaved
        for name, fn in readers:
            t, c = time.perf_counter(), time.process_time()
            out[name] = fn()
            wall[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - c)
    rows = ["| reader | wall best ms | wall median ms | CPU best ms | CPU median ms | "
            "max rel. diff vs (m+0.5)·2^(e−136) |",
            "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for name, _ in readers:
        a = np.asarray(out[name], np.float32)
        rel = float(np.max(np.abs(a - ref) / np.maximum(ref, 1e-30)))
        b, m = best_median(wall[name])
        cb, cm = best_median(cpu[name])
        rows.append(f"| {name} | {1e3 * b:.1f} | {1e3 * m:.1f} | {1e3 * cb:.1f} | "
                    f"{1e3 * cm:.1f} | {rel:.2e} |")
    return rows


# ----------------------------------------------------------------------------- throughput


def _warm_decoder() -> None:
    """Decode-only workers get what batch workers get: the same heap setting (buffers reused;
    it makes decoding faster, so the baseline is the fastest we have) and warm decoders."""
    from shprobe.batch.engine import _keep_heap, _warm

    _keep_heap()
    _warm()


def _decode(p: str) -> int:
    from shprobe.probes.images import read_image

    return read_image(p).nbytes


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and every child process: the driver, the
    Dask scheduler (it runs in the driver), the nannies' workers and the decode pool."""
    import psutil

    me = psutil.Process()
    total = sum(me.cpu_times()[:2])
    for c in me.children(recursive=True):
        try:
            total += sum(c.cpu_times()[:2])
        except psutil.Error:
            pass
    return total


def bench_throughput(files: list[Path], repeat: int, workers: int) -> tuple[list[str], dict]:
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from distributed import Client

    from shprobe.batch import BatchOptions, Engine, run_batch
    from shprobe.batch.engine import _local_cluster

    paths = [str(p) for p in files]
    mb = sum(p.stat().st_size for p in files) / 1e6
    pool = ProcessPoolExecutor(workers, mp_context=get_context("spawn"),
                               initializer=_warm_decoder)
    list(pool.map(_decode, paths[: 2 * workers]))  # start and warm the pool
    cluster = _local_cluster(workers)  # the cluster `shprobe batch` starts
    client = Client(cluster)
    run_batch(paths[:workers], None, engine=Engine(client=client))  # warm plugin + first tasks
    wall: dict[str, list[float]] = {"dec": [], "bat": [], "now": []}
    cpu: dict[str, list[float]] = {"dec": [], "bat": [], "now": []}
    decoded = 0
    table = None

    def timed(key, fn):
        c, t = cpu_seconds(), time.perf_counter()
        out = fn()
        wall[key].append(time.perf_counter() - t)
        cpu[key].append(cpu_seconds() - c)
        return out

    for _ in range(repeat):  # interleaved passes
        decoded = timed("dec", lambda: sum(pool.map(_decode, paths)))
        table = timed("bat", lambda: run_batch(paths, None, engine=Engine(client=client)).table)
        timed("now", lambda: run_batch(paths, None, options=BatchOptions(window=False),
                                       engine=Engine(client=client)).table)
    client.close()
    cluster.close()
    pool.shutdown()
    n = len(paths)
    assert table is not None and table.column("failure").null_count == n
    secs = np.asarray(table.column("seconds"))
    windows = table.column("window").to_pylist()
    names = {"dec": f"decode only (read_image in {workers} processes)",
             "bat": f"shprobe batch (warm LocalCluster, {workers} workers × 1 thread)",
             "now": "shprobe batch --no-window (same cluster)"}
    rows = ["| pass | files | wall best s | wall median s | files/s (best) | file MB/s | "
            "decoded MB/s | CPU s, all processes (best) | CPU ms per file (best) |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for k, name in names.items():
        b, m = best_median(wall[k])
        rows.append(f"| {name} | {n} | {b:.2f} | {m:.2f} | {n / b:.1f} | {mb / b:.0f} | "
                    f"{decoded / 1e6 / b:.0f} | {min(cpu[k]):.2f} | "
                    f"{1e3 * min(cpu[k]) / n:.1f} |")
    bd, md = best_median(wall["dec"])
    bb, mbat = best_median(wall["bat"])
    bn, mnow = best_median(wall["now"])
    info = {"ratio_best": bd / bb, "ratio_median": md / mbat, "ratio_now_best": bd / bn,
            "ratio_now_median": md / mnow,
            "ratio_cpu": min(cpu["dec"]) / min(cpu["bat"]),
            "ratio_cpu_median": float(np.median(cpu["dec"]) / np.median(cpu["bat"])),
            "ratio_pass": [d / b for d, b in zip(wall["dec"], wall["bat"], strict=True)],
            "row_median_s": float(np.median(secs)), "wall_per_probe": bb / n * workers,
            "windows": {k: windows.count(k) for k in set(windows)}, "mb": mb}
    return rows, info


def _sha256(path) -> str:
    """The content hash before issue 11's speed pass (SHA-256), for the record."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        while b := f.read(1 << 20):
            h.update(b)
    return h.hexdigest()


def bench_cpu(files: list[Path], repeat: int) -> list[str]:
    """CPU time per probe in this process (steadier than wall time on a shared box): decode
    only, and a batch row's parts, for the first .hdr and .exr."""
    from shprobe.batch import probe_row
    from shprobe.batch.rows import HASH, content_hash
    from shprobe.lighting.projection import project_file
    from shprobe.probes.images import read_image

    rows = [f"| format | read_image ms | content hash ({HASH}) ms | before: SHA-256 ms | "
            "project_file (streamed decode + projection) ms | whole batch row ms | "
            "decode / row |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for ext in (".hdr", ".exr"):
        p = next(f for f in files if f.suffix == ext)
        fns = {"read": lambda p=p: read_image(p), "hash": lambda p=p: content_hash(p),
               "sha": lambda p=p: _sha256(p),
               "proj": lambda p=p: project_file(p, 2), "row": lambda p=p: probe_row(str(p))}
        for fn in fns.values():
            fn()
        cpu = {k: [] for k in fns}
        for _ in range(2 * repeat + 1):  # interleaved
            for k, fn in fns.items():
                c = time.process_time()
                fn()
                cpu[k].append(time.process_time() - c)
        b = {k: 1e3 * min(v) for k, v in cpu.items()}
        rows.append(f"| {ext} | {b['read']:.1f} | {b['hash']:.1f} | {b['sha']:.1f} | "
                    f"{b['proj']:.1f} | {b['row']:.1f} | {100 * b['read'] / b['row']:.0f} % |")
    return rows


def bench_cold_cli(files: list[Path], d: Path, workers: int) -> float:
    out = d / "cold.parquet"
    if out.exists():
        out.unlink()
    t = time.perf_counter()
    subprocess.run([PY, "-m", "shprobe", "batch", *map(str, files), "-o", str(out), "-j",
                    str(workers)], check=True, capture_output=True)
    return time.perf_counter() - t


def bench_latency(hdr: Path, repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        subprocess.run([PY, "-m", "shprobe", "prefilter", str(hdr), "-F", "json"], check=True,
                       capture_output=True)
        times.append(time.perf_counter() - t)
    return best_median(times)


# ----------------------------------------------------------------------------- 16k


def write_big(path: Path, w: int, h: int) -> None:
    """A float EXR written a band of rows at a time (zip compression, 16-row blocks)."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(w, h, 3, oiio.FLOAT)
    spec.attribute("compression", "zip")
    assert out.open(str(path), spec), out.geterror()
    band = 256
    for y0 in range(0, h, band):
        rows = min(band, h - y0)
        assert out.write_scanlines(y0, y0 + rows, 0, probe_image(h, w, 7, y0, rows)), \
            out.geterror()
    out.close()


_PEAK = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
         "r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
         "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, "
         "time.perf_counter() - t, r.returncode); print(r.stdout[-400:], r.stderr[-400:])")


def peak_rss(cmd: list[str]) -> tuple[float, float, str]:
    """(peak RSS MiB, seconds, output tail) of a command run alone in a fresh process."""
    r = subprocess.run([PY, "-c", _PEAK, *cmd], capture_output=True, text=True, check=True)
    first, *rest = r.stdout.splitlines()
    kb, secs, rc = first.split()
    if rc != "0":
        raise RuntimeError(f"{cmd} failed: {' '.join(rest)}")
    return int(kb) / 1024, float(secs), "\n".join(rest)


def bench_big(d: Path, w: int, h: int) -> list[str]:
    big = d / f"big{w}x{h}.exr"
    if not big.exists():
        t = time.perf_counter()
        tmp = big.with_name(".tmp-" + big.name)
        write_big(tmp, w, h)
        tmp.replace(big)  # a run cut short leaves no half-written probe behind
        print(f"(wrote {big.name}: {big.stat().st_size / 2**20:.0f} MiB in "
              f"{time.perf_counter() - t:.0f} s)", file=sys.stderr)
    streamed = ("import sys, numpy as np; from shprobe.lighting.projection import project_file; "
                "np.save(sys.argv[2], project_file(sys.argv[1], 2).coeffs)")
    whole = ("import sys, numpy as np; from shprobe.lighting import project; "
             "from shprobe.probes.env import load_env; "
             "np.save(sys.argv[2], project(load_env(sys.argv[1]), 2))")
    rows = ["| what (one process each) | peak RSS MiB | wall s |", "| --- | ---: | ---: |"]
    res = {}
    for name, cmd in [
            ("baseline: python + import shprobe.lighting.projection",
             [PY, "-c", "import shprobe.lighting.projection, numpy"]),
            ("project_file (streamed, 16 MB blocks)",
             [PY, "-c", streamed, str(big), str(d / "s.npy")]),
            ("shprobe prefilter (streams above 256 MB decoded)",
             [PY, "-m", "shprobe", "prefilter", str(big), "-F", "json"]),
            ("shprobe batch --scheduler inline (one row)",
             [PY, "-m", "shprobe", "batch", str(big), "-o", str(d / "big.parquet"), "--force",
              "--scheduler", "inline"]),
            ("peer: project(load_env(...)) (whole image)",
             [PY, "-c", whole, str(big), str(d / "w.npy")])]:
        mib, secs, _ = peak_rss(cmd)
        res[name] = mib
        rows.append(f"| {name} | {mib:.0f} | {secs:.1f} |")
    a, b = np.load(d / "s.npy"), np.load(d / "w.npy")
    rows.append("")
    rows.append(f"File {big.stat().st_size / 2**20:.0f} MiB on disk, {w * h * 12 / 2**20:.0f} MiB "
                f"decoded. Streamed vs whole coefficients: max |Δ| = "
                f"{np.abs(a - b).max():.2e} (max |L| {np.abs(b).max():.3g}).")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=16, help="probes per format")
    ap.add_argument("--size", default="2048x1024")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big", default="16384x8192", help="WxH of the big EXR, 0 to skip")
    ap.add_argument("--dir", help="keep the generated files here (default: a temp dir)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    print(machine())
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(args.dir or tmp)
        d.mkdir(parents=True, exist_ok=True)
        files = make_files(d, args.n, w, h)
        hdr = files[0]
        print(f"\n### RGBE decoders on one {w}x{h} .hdr ({hdr.stat().st_size / 1e6:.1f} MB), "
              f"best / median of {2 * args.repeat + 1}\n")
        print("\n".join(bench_decoders(hdr, 2 * args.repeat + 1)))
        rows, info = bench_throughput(files, args.repeat, args.workers)
        print(f"\n### Throughput, {len(files)} probes {w}x{h} ({args.n} .hdr + {args.n} .exr, "
              f"{info['mb']:.0f} MB), all cores, best / median of {args.repeat}\n")
        print("\n".join(rows))
        passes = ", ".join(f"{100 * r:.0f} %" for r in info["ratio_pass"])
        print(f"\n**RATIO batch / decode-only throughput (target >= 80 %): "
              f"{100 * info['ratio_best']:.0f} % (wall, best pass of each), "
              f"{100 * info['ratio_median']:.0f} % (wall, median)**; pass by pass {passes}; "
              f"in CPU time of all processes {100 * info['ratio_cpu']:.0f} % (best), "
              f"{100 * info['ratio_cpu_median']:.0f} % (median). With --no-window "
              f"{100 * info['ratio_now_best']:.0f} % (best), {100 * info['ratio_now_median']:.0f}"
              f" % (median). Windows chosen: {info['windows']}.")
        print("\n### CPU time per probe, one process (best of "
              f"{2 * args.repeat + 1}, interleaved)\n")
        print("\n".join(bench_cpu(files, args.repeat)))
        cold = bench_cold_cli(files, d, args.workers)
        lb, lm = bench_latency(hdr, args.repeat)
        print("\n### Per-probe latency\n")
        print("| what | s |\n| --- | ---: |")
        print(f"| `shprobe prefilter X.hdr -F json` as a process (start-up included), best | "
              f"{lb:.2f} |")
        print(f"| the same, median | {lm:.2f} |")
        print(f"| in batch: worker time per probe (median of the `seconds` column) | "
              f"{info['row_median_s']:.3f} |")
        print(f"| in batch: wall × workers / probes (warm cluster) | "
              f"{info['wall_per_probe']:.3f} |")
        print(f"| cold `shprobe batch` of the {len(files)} files, end to end (cluster start, "
              f"warm-up, Parquet) | {cold:.1f} total |")
        print(f"\nLoad average at the end: {' / '.join(f'{v:.2f}' for v in os.getloadavg())}")
        if args.big not in ("0", ""):
            bw, bh = (int(v) for v in args.big.split("x"))
            print(f"\n### Peak memory, {bw}x{bh} float EXR\n")
            print("\n".join(bench_big(d, bw, bh)))


if __name__ == "__main__":
    main()
