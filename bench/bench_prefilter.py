"""Benchmarks of the main job (issue 3): projection (R&H eq. 10), decoding, and the R&H speed
claim (brute-force vs SH irradiance map). Prints markdown tables.

    PYTHONPATH=src python bench/bench_prefilter.py [--quick]

Peers in the same run: a plain separable numpy transform (cos/sin matrix product per row, then
scipy's associated Legendre functions per row), ducc0's SHT analysis on the same grid (if
installed), and a naive numpy projection (basis matrix × pixels) for the angular map.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from shprobe.lighting.irradiance import irradiance_map
from shprobe.lighting.projection import _project_latlong, project
from shprobe.lighting.reference import reference_irradiance
from shprobe.probes.env import Env
from shprobe.probes.layouts import get_layout
from shprobe.sh import sh_basis


def best_ms(fn, repeat: int = 7) -> float:
    fn()  # warm-up (numba compilation, cached tables)
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1e3 * min(ts)


def separable_numpy_peer(rad: np.ndarray, lmax: int) -> np.ndarray:
    """The plain separable transform, everything rebuilt per call: per row Σ_φ L cos/sin(mφ)
    by one matrix product, then Σ_θ with scipy's normalised associated Legendre functions.
    Coefficients in the frame whose pole is the lat-long's +Y axis (what the transform
    computes; shprobe adds the fixed per-band turn to world axes, which costs ~µs)."""
    from scipy.special import assoc_legendre_p_all

    h, w = rad.shape[:2]
    psi = 2 * np.pi * (np.arange(w) + 0.5) / w
    m = np.arange(-lmax, lmax + 1)
    trig = np.where(m[:, None] >= 0, np.cos(np.abs(m)[:, None] * psi),
                    np.sin(np.abs(m)[:, None] * psi)).astype(np.float32)
    f = np.matmul(trig[None], rad)  # (H, M, 3)
    theta = np.pi * (np.arange(h) + 0.5) / h
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    dw = (2 * np.pi / w) * (edges[:-1] - edges[1:])
    # [l, m, H], unit norm on [−1, 1], with the Condon–Shortley phase (removed below)
    p = assoc_legendre_p_all(lmax, lmax, np.cos(theta), norm=True)[0]
    out = np.zeros(((lmax + 1) ** 2, 3))
    for l in range(lmax + 1):
        for mm in range(-l, l + 1):
            a = abs(mm)
            norm = math.sqrt(1 / (2 * np.pi)) * (math.sqrt(2) if a else 1.0) * (-1) ** a
            out[l * l + l + mm] = (p[l, a] * dw * norm) @ f[:, mm + lmax]
    return out


def ducc0_peer(rad64: list[np.ndarray], lmax: int):
    import ducc0

    return [ducc0.sht.experimental.analysis_2d(map=c[None], spin=0, lmax=lmax,
                                               geometry="F1") for c in rad64]


def naive_angular_peer(env: Env, lmax: int) -> np.ndarray:
    d, L, dw = env.samples()
    return (sh_basis(d, lmax) * dw[:, None]).T @ L.astype(np.float64)


LAT_LMAXES = (2, 6, 10, 16, 20, 32)  # issue 16's degrees


def latlong_table(rng, sizes, lmaxes, repeat: int = 9,
                  dtypes=(np.float32, np.float64)) -> None:
    """shprobe.project (threads picked by size), its one-thread path and the separable numpy
    peer on random float32 lat-long images; each repeat runs the three in turn (interleaved),
    wall time, best / median; the ratio is of best times. Both radiance types; the peer computes
    in the radiance's type as numpy's matmul does."""
    print("### Lat-long projection (R&H eq. 10), float32 and float64 radiance, 3 channels\n")
    print("ms, best / median of interleaved repeats; × = shprobe.project / peer (best)\n")
    print("| size | dtype | lmax | shprobe.project | threads (at the end) | shprobe, one thread "
          "| separable numpy (peer) | × |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    from shprobe.lighting.projection import _latlong_threads

    for (w, h), dtype, lmax in ((s, d, lm) for s in sizes for d in dtypes for lm in lmaxes):
        if lmax == lmaxes[0]:
            rad = rng.random((h, w, 3)).astype(dtype)
            env = Env(rad, "latlong")
        calls = {"auto": lambda lm=lmax, e=env: project(e, lm),
                 "one": lambda lm=lmax, r=rad: _project_latlong(r, lm, threads=1),
                 "peer": lambda lm=lmax, r=rad: separable_numpy_peer(r, lm)}
        t = {k: [] for k in calls}
        for f in calls.values():
            f()
        for _ in range(repeat):
            for k, f in calls.items():
                t0 = time.perf_counter()
                f()
                t[k].append(1e3 * (time.perf_counter() - t0))
        nthr = _latlong_threads(h * w * 3 * (2 * lmax + 1))
        b = {k: (min(v), float(np.median(v))) for k, v in t.items()}
        print(f"| {w}×{h} | {np.dtype(dtype).name} | {lmax} "
              f"| {b['auto'][0]:.2f} / {b['auto'][1]:.2f} | {nthr} "
              f"| {b['one'][0]:.2f} / {b['one'][1]:.2f} "
              f"| {b['peer'][0]:.2f} / {b['peer'][1]:.2f} "
              f"| {b['auto'][0] / b['peer'][0]:.2f} |")
    print(f"\nload average after the table: {os.getloadavg()[0]:.2f}\n")


def main() -> None:
    quick = "--quick" in sys.argv
    from _machine import machine

    print(f"Machine: {machine()}\n")
    rng = np.random.default_rng(0)
    rows: list[tuple[str, str, float]] = []
    if "--latlong" in sys.argv:
        latlong_table(rng, ((512, 256), (1024, 512), (4096, 2048)), LAT_LMAXES)
        return

    # --- lat-long: three sizes, interleaved with the peers ----------------------------------
    sizes = ((512, 256), (1024, 512)) + (((2048, 1024),) if quick else ((4096, 2048),))
    h, w = sizes[-1][1], sizes[-1][0]
    latlong_table(rng, sizes, LAT_LMAXES)
    rad = rng.random((h, w, 3), dtype=np.float32)
    for lmax in (2, 8):
        try:
            chans = [np.ascontiguousarray(rad[..., c], dtype=np.float64) for c in range(3)]
            rows.append((f"lat-long {w}×{h} float32, lmax {lmax}",
                         "ducc0 analysis_2d F1, 3 channels (peer)",
                         best_ms(lambda lm=lmax, ch=chans: ducc0_peer(ch, lm), repeat=3)))
        except Exception as e:  # pragma: no cover - optional peer
            rows.append(("", f"ducc0 (unavailable: {type(e).__name__})", float("nan")))

    # --- angular 1500 x 1500 --------------------------------------------------------------
    n = 750 if quick else 1500
    lay = get_layout("angular")
    t0 = time.perf_counter()
    lay.solid_angles((n, n))
    tables_ms = 1e3 * (time.perf_counter() - t0)
    t0 = time.perf_counter()
    lay.solid_angles((n - 1, n - 1))  # another size: kernel loaded, tables not cached
    tables2_ms = 1e3 * (time.perf_counter() - t0)
    aenv = Env(rng.random((n, n, 3), dtype=np.float32), lay)
    rows.append((f"angular {n}×{n} float32, lmax 2", "shprobe.project",
                 best_ms(lambda: project(aenv, 2))))
    rows.append(("", "naive numpy basis matrix (peer)",
                 best_ms(lambda: naive_angular_peer(aenv, 2), repeat=3)))
    rows.append(("", "layout tables, first call in the process (cached after)", tables_ms))
    rows.append(("", f"layout tables, a second size ({n - 1}², not cached)", tables2_ms))

    # --- decoding ---------------------------------------------------------------------
    from shprobe.probes.images import read_image, write_image

    with tempfile.TemporaryDirectory() as tmp:
        big = (rng.random((h, w, 3)) * 4).astype(np.float32)
        for ext in (".hdr", ".exr", ".pfm"):
            p = Path(tmp) / f"probe{ext}"
            write_image(p, big)
            rows.append((f"decode {w}×{h} {ext}", "shprobe.probes.images.read_image",
                         best_ms(lambda p=p: read_image(p), repeat=3)))

    print("| case | implementation | time (ms, best of N) |")
    print("| --- | --- | ---: |")
    for case, impl, ms in rows:
        print(f"| {case} | {impl} | {ms:.1f} |")

    # --- R&H speed claim ----------------------------------------------------------------
    ph, pw = (256, 512) if quick else (512, 1024)
    probe_path = Path(__file__).resolve().parents[1].parent / "shared" / "probes" / "grace.hdr"
    if probe_path.is_file():
        g = read_image(probe_path)
        k = ph // g.shape[0]
        prad = np.repeat(np.repeat(g, k, axis=0), k, axis=1) if k > 1 else g
        src = f"grace.hdr upsampled ×{k}"
    else:
        prad = rng.random((ph, pw, 3), dtype=np.float32)
        src = "random"
    penv = Env(prad, "latlong")
    size = 64
    grid = get_layout("angular").grid_shape(size)
    valid = get_layout("angular").valid_mask(grid)
    nrm = get_layout("angular").pixel_directions(grid)[valid]
    sh_ms = best_ms(lambda: irradiance_map(project(penv, 2), "angular", size))
    reference_irradiance(penv, nrm[:8])  # compile
    t0 = time.perf_counter()
    ref = reference_irradiance(penv, nrm)
    brute_ms = 1e3 * (time.perf_counter() - t0)
    emap = irradiance_map(project(penv, 2), "angular", size).radiance[valid]
    tot = float(penv.solid_angles().ravel() @ penv.radiance[..., 1].ravel())
    t = int(valid.sum())
    print()
    print(f"R&H speed claim: {size}×{size} angular irradiance map ({t} normals) from a "
          f"{pw}×{ph} lat-long probe ({src}, S = {pw * ph} pixels)")
    print()
    print("| method | time (ms) |")
    print("| --- | ---: |")
    print(f"| SH: project (eq. 10) + map (eq. 7), lmax 2 | {sh_ms:.1f} |")
    print(f"| brute force Σ L max(0, n·ω) dω (numba, parallel) | {brute_ms:.1f} |")
    print(f"| **ratio brute / SH** | **{brute_ms / sh_ms:.0f}×** (R&H predict ≈ T/9 = "
          f"{t / 9:.0f}×) |")
    print(f"\nmax |E_SH − E_brute| / ∫L dω (green) = "
          f"{np.abs(emap[:, 1] - ref[:, 1]).max() / tot:.4f}")
    print(f"\nload average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
