"""Speed of lighting from photos (issue 14): a 4k (3840×2160) grey-ball photo.

Run: ``PYTHONPATH=src python bench/bench_fitting.py [--quick]`` — prints a markdown table.

The photo: the renderer's unit sphere (orthographic, ball radius 900 px) under grace's R&H
Fig. 2 coefficients, albedo 0.5, 1 % noise, a cast shadow over 10 % of the ball, on a grey
backdrop, float32 in memory (decoding a 4k EXR is measured in bench_io: ~0.1–0.25 s). Timed,
interleaved, best and median of N:

- ``fit_grey_ball`` with detection (the whole `shprobe fit grey-ball` computation after the
  read): detect_circle + ball_pixels + the robust fit;
- its parts: ``detect_circle``; ``ball_pixels``; ``fit_samples`` robust (MM-estimator) and
  plain (one weighted least-squares pass);
- peer: ``numpy.linalg.lstsq`` on the full design matrix (the textbook one-liner, no
  robustness), same pixels.

Wall time and CPU time (``time.process_time``) are both printed: on the shared 2-core box the
wall time grows with the load average, the CPU time of one thread much less. Run it with
``OPENBLAS_NUM_THREADS=1`` so that the CPU time is one thread's.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from shprobe.fitting import ball_pixels, detect_circle, fit_grey_ball, fit_samples  # noqa: E402
from shprobe.fitting.solve import design_factors  # noqa: E402
from shprobe.probes.presets import get_preset  # noqa: E402
from shprobe.sh import sh_basis  # noqa: E402


def photo(W: int = 3840, H: int = 2160, r: float = 900.0):
    from shprobe.scene import Camera, render

    L = get_preset("grace")
    cam = Camera(W, H, "orthographic", ortho_height=2.0 * H / (2 * r), margin=1.0)
    res = render(None, L, cam, albedo=0.5, background=[0.2, 0.2, 0.2])
    img = res.image
    rng = np.random.default_rng(0)
    img += 0.01 * float(res.radiance[res.mask].mean()) * rng.standard_normal(
        img.shape, dtype=np.float32)
    jj, ii = np.ogrid[0:H, 0:W]
    shadow = ((ii - W / 2 - 500) ** 2 + (jj - H / 2 + 300) ** 2 < 450 ** 2) & res.mask
    img[shadow] *= 0.3
    return np.maximum(img, 0), L, float(shadow.sum() / res.mask.sum())


def main() -> None:
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    quick = "--quick" in sys.argv
    n = 3 if quick else 7
    print(f"machine: {machine()}")
    t = time.perf_counter()
    img, L, shadow = photo()
    print(f"photo {img.shape[1]}x{img.shape[0]} made in {time.perf_counter() - t:.1f} s, "
          f"shadow {100 * shadow:.1f} % of the ball")
    c = detect_circle(img)
    px = ball_pixels(c, img.shape[:2], inset=1.0, mirror=False)
    vals = img[px.rows, px.cols]
    print(f"detected {c!r} (true 1920, 1080, 900); {px.rows.size} ball pixels")
    f = fit_grey_ball(img, albedo=0.5)
    err = np.abs(f.coeffs - L).max() / L[0].max()
    print(f"fit: max |ΔL| / L00 = {err:.4f}; {f.summary()}")
    fac = design_factors("diffuse")

    def lstsq():
        a = sh_basis(px.normals, 2) * fac
        return np.linalg.lstsq(a, vals, rcond=None)[0]

    cases = {
        "fit_grey_ball (detect + pixels + robust fit)": lambda: fit_grey_ball(img, albedo=0.5),
        "  detect_circle": lambda: detect_circle(img),
        "  ball_pixels": lambda: ball_pixels(c, img.shape[:2], inset=1.0, mirror=False),
        "  fit_samples robust (MM-estimator)": lambda: fit_samples(px.normals, vals),
        "  fit_samples plain least squares": lambda: fit_samples(px.normals, vals,
                                                                 robust=False),
        "peer: numpy.linalg.lstsq on the design matrix": lstsq,
    }
    for fn in cases.values():  # warm-up (numba compile)
        fn()
    times: dict[str, list[float]] = {k: [] for k in cases}
    cpu: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(n):  # interleaved
        for k, fn in cases.items():
            t, c0 = time.perf_counter(), time.process_time()
            fn()
            times[k].append(time.perf_counter() - t)
            cpu[k].append(time.process_time() - c0)
    print(f"\n4k grey ball, {px.rows.size} pixels, best / median of {n} (interleaved), "
          f"load {os.getloadavg()[0]:.2f} at end\n")
    print("| step | wall best ms | wall median ms | CPU best ms | CPU median ms |\n"
          "| --- | ---: | ---: | ---: | ---: |")
    for k, ts in times.items():
        cs = cpu[k]
        print(f"| {k} | {1000 * min(ts):.0f} | {1000 * statistics.median(ts):.0f} | "
              f"{1000 * min(cs):.0f} | {1000 * statistics.median(cs):.0f} |")


if __name__ == "__main__":
    main()
