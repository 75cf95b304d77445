"""Viewer speed, measured in the headless Chromium the tests use (Debian /usr/bin/chromium,
SwiftShader WebGL — no GPU on this machine).

Run: ``PYTHONPATH=src SHPROBE_TEST_DATA=../shared python bench/bench_viewer.py`` — prints
markdown tables.

1. Command to first lit frame: ``shprobe view PROBE --no-browser`` started as a subprocess with a
   2048×1024 .hdr probe (grace resampled) and the default object (the packaged bunny; ``--before``
   trees of older checkouts use theirs: the test data's bunny through $SHPROBE_TEST_DATA), the
   URL printed once the files are read, the browser already running with its tab open and
   idle (as a user's is: :func:`browser_settled` waits out the new window's own start-up); the
   clock runs from just before the process starts until the page has drawn the lit bunny
   (``window.__shprobe.firstFrameAt``; the URL carries ``&bench=1``, so the page waits for that
   frame to be finished by reading a pixel back). Numba's cache and the mesh payload cache are
   warmed by one run first.
2. A lighting drag: each pointer move on the probe is one ``/api/design`` call (the library's
   Wigner rotation, window and certificate) plus one frame; the time per move as the page sees
   it (request + redraw), and the frame alone (per-pixel bunny, 512×512).
3. PRT relighting of a 100k-vertex transfer at lmax 4 (unshadowed bake of a subdivided sphere):
   the page's per-vertex transfer · lighting loop plus the frame, per drag step.
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "bench"))

from _machine import machine  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
#: Chromium as it runs on a machine without a GPU: the page composited in software and WebGL on
#: SwiftShader — Chromium's "WebGL fallback" mode (docs/gpu/swiftshader.md in Chromium's source).
#: ``--gpu-compositing`` selects ``--use-angle=swiftshader`` instead, SwiftShader as the GL
#: driver of everything, compositing included (a test-bot mode: the compositor's frames then
#: cost 0.3–0.4 CPU-s of the first frame here).
FLAGS = ["--no-sandbox", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--use-angle=swiftshader-webgl", "--enable-unsafe-swiftshader"]


#: the page's benchmark flag: it reads a pixel back after each frame it times, so that the
#: times are of finished frames (a normal session never reads back: a GPU stall)
BENCH = "&bench=1"


def make_probe(folder: Path) -> Path:
    from shprobe.probes.env import load_env
    from shprobe.probes.images import write_image
    from shprobe.probes.layouts import LatLong

    data = Path(os.environ.get("SHPROBE_TEST_DATA", REPO.parent / "shared"))
    env = load_env(data / "probes" / "grace.hdr")
    big = env.sample(LatLong().pixel_directions((1024, 2048)))
    p = folder / "grace_2k.hdr"
    write_image(p, big)
    return p


def start(args: list[str], src: Path | None = None, cache: Path | None = None
          ) -> tuple[subprocess.Popen, str, float]:
    # SHPROBE_VIEW_STAMPS: the server records its loading stages' times (served by /api/init)
    env = dict(os.environ, PYTHONPATH=str(src or REPO / "src"), SHPROBE_VIEW_STAMPS="1")
    if cache is not None:  # shprobe's on-disk cache (the viewer's mesh payloads)
        env["SHPROBE_CACHE_DIR"] = str(cache)
    t0 = time.time()
    p = subprocess.Popen([sys.executable, "-m", "shprobe", "view", *args, "--no-browser"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    line = p.stdout.readline()
    m = re.search(r"http://\S+", line)
    if not m:
        p.kill()
        raise SystemExit(f"no URL: {line!r} {p.stderr.read()}")
    return p, m.group(0), t0


STAGES = [  # (label, start event, end event): the stages of the first lit frame
    ("python start + imports → `view` command", "t0", "cli"),
    ("command → URL printed (loader forked, socket bound, server built, files read)", "cli",
     "url"),
    ("probe read + projected to lmax 2 (resolve_lighting; loader process)", "load_start",
     "decoded"),
    ("probe checks, coefficients to the server", "decoded", "source_done"),
    ("mesh read + the page's arrays (load_mesh; loader process)", "load_start", "geometry_done"),
    ("command → files ready for the page (server)", "t0", "ready"),
    ("URL → page navigation starts (browser)", "url", "nav"),
    ("navigation → page HTML received", "nav", "html"),
    ("navigation → viewer.js runs (three.js fetched + parsed)", "nav", "script"),
    ("viewer.js → WebGL renderer + the first frame's programs built (drawn once)", "script",
     "gl"),
    ("→ /api/init answered (it waits for the files)", "gl", "init"),
    ("init → design answered", "init", "design"),
    ("init → mesh received", "init", "mesh"),
    ("design + mesh → first lit frame drawn", "data", "first"),
    ("first lit frame → probe and irradiance panels made and drawn", "first", "panels"),
    ("first lit frame → the probe's background texture drawn", "first", "background"),
]


def browser_cpu() -> float:
    """CPU seconds used so far by this process's Chromium children (the browser, its GPU
    process, renderers, utilities)."""
    import psutil

    total = 0.0
    for c in psutil.Process().children(recursive=True):
        try:
            if "chrom" in c.name():
                t = c.cpu_times()
                total += t.user + t.system
        except psutil.Error:
            pass
    return total


def browser_settled(quiet: float = 0.02, window: float = 0.25, limit: float = 8.0) -> float:
    """Wait until Chromium is idle (under ``quiet`` CPU-s per ``window`` s; at most ``limit``
    s); returns the seconds waited. A new browser context opens a window whose own WebUI
    (chrome://resources, the omnibox's search box) loads for about a second after
    ``new_page`` returns, 0.5–0.7 CPU-s on this machine (measured with psutil and a Chromium
    trace): without this wait that start-up ran inside the timed first frame, competing for
    the two cores, while a user's tab was opened long before."""
    t0 = time.time()
    prev = browser_cpu()
    while time.time() - t0 < limit:
        time.sleep(window)
        now = browser_cpu()
        if now - prev < quiet:
            break
        prev = now
    return time.time() - t0


def first_frame(browser, args: list[str], src: Path | None = None, cache: Path | None = None
                ) -> tuple[float, float, dict[str, float]]:
    """(seconds from command to first lit frame, seconds to the URL line, stage stamps in
    seconds since the command started); ``cache``: the server's SHPROBE_CACHE_DIR."""
    import resource

    ctx = browser.new_context(viewport={"width": 1100, "height": 900})
    page = ctx.new_page()  # a browser tab already open, as a user's is ...
    page.goto("about:blank")
    settled = browser_settled()  # ... and settled: a new window's start-up is not the viewer's
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    b0 = browser_cpu()
    p, url, t0 = start(args, src, cache)
    t_url = time.time() - t0
    try:
        page.goto(url + BENCH)
        page.wait_for_function("() => window.__shprobe && (window.__shprobe.ready || "
                               "window.__shprobe.lastError)", timeout=60000)
        err = page.evaluate("() => window.__shprobe.lastError")
        if err:
            raise SystemExit(err)
        at = page.evaluate("() => window.__shprobe.firstFrameAt") / 1000.0
        b1 = browser_cpu()  # a little after the first frame (the polling's own latency)
        info = page.evaluate("""() => { const a = window.__shprobe, o = performance.timeOrigin;
            const n = performance.getEntriesByType('navigation')[0];
            const m = {}; for (const [k, v] of Object.entries(a.marks)) m[k] = (o + v) / 1000;
            m.nav = o / 1000; m.html = (o + n.responseEnd) / 1000;
            return { marks: m, server: (a.init && a.init.timings) || {} }; }""")
        ctx.close()
    finally:
        p.terminate()
        p.wait(10)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)  # the server and the loaders it reaped
    st = {"t0": 0.0, "first": at - t0,
          "cpu": r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime,
          "browser_cpu": b1 - b0, "settled": settled}
    for k, v in {**info["server"], **info["marks"]}.items():
        st[k] = v - t0
    return at - t0, t_url, st


def breakdown(runs: list[dict[str, float]]) -> None:
    """The stages of the first lit frame: median start and end (s after the command) and
    median duration of each, over the runs."""
    med = statistics.median
    print("| stage | from s | to s | takes ms (median) |\n| --- | ---: | ---: | ---: |")
    for label, a, b in STAGES:
        xs = [r for r in runs if a in r and b in r]
        if not xs:
            continue
        print(f"| {label} | {med(r[a] for r in xs):.3f} | {med(r[b] for r in xs):.3f} | "
              f"{1000 * med(r[b] - r[a] for r in xs):.0f} |")
    print(f"| **first lit frame** | | {med(r['first'] for r in runs):.3f} | |")


def drag_times(browser, args: list[str], mode: str | None, steps: int = 40
               ) -> dict[str, list[float]]:
    """Per drag step (ms): ``first`` move → first new frame (in-page rotation for lmax ≤ 2,
    else the server's answer), ``step`` move → the server's answer drawn, ``design`` the
    /api/design round trip, ``frame`` the whole redraw (main view + the two panels),
    ``main`` the 512×512 view alone, ``prt`` the page's PRT loop."""
    p, url, _ = start(args)
    try:
        ctx = browser.new_context(viewport={"width": 1100, "height": 900})
        page = ctx.new_page()
        page.goto(url + BENCH)
        page.wait_for_function("() => window.__shprobe && window.__shprobe.ready",
                               timeout=120000)
        if mode:
            page.select_option("#mode", mode)
        box = page.locator("#probe").bounding_box()
        x, y = box["x"] + 100, box["y"] + 128
        step_ms, frame_ms, prt_ms, design_ms, main_ms, first_ms = [], [], [], [], [], []
        page.mouse.move(x, y)
        page.mouse.down()
        for i in range(steps):
            n0 = page.evaluate("() => window.__shprobe.frames")
            t = time.perf_counter()
            page.mouse.move(x + 4 * (i + 1), y + (i % 3))
            page.wait_for_function(f"() => window.__shprobe.frames > {n0}", polling=1)
            first_ms.append(1000 * (time.perf_counter() - t))
            page.evaluate("() => window.__shprobe.settled()")
            step_ms.append(1000 * (time.perf_counter() - t))
            frame_ms.append(page.evaluate("() => window.__shprobe.frameTimes().slice(-1)[0]"))
            prt_ms.append(page.evaluate("() => window.__shprobe.prtRelightMs || 0"))
            design_ms.append(page.evaluate("() => window.__shprobe.lastDesignMs"))
            main_ms.append(page.evaluate("() => window.__shprobe.mainFrameMs"))
        page.mouse.up()
        inpage = page.evaluate("() => window.__shprobe.moveToFrame || []")
        ctx.close()
    finally:
        p.terminate()
        p.wait(10)
    return {"step": step_ms, "frame": frame_ms, "prt": prt_ms, "design": design_ms,
            "main": main_ms, "first": first_ms, "inpage": inpage}


def prt_transfer(folder: Path) -> Path:
    """An unshadowed lmax-4 bake of a ~100k-vertex sphere (analytic: no rays)."""
    import trimesh

    from shprobe.prt import bake

    m = trimesh.creation.icosphere(subdivisions=7)  # 163842 vertices
    keep = m.vertices[:, 1] > -0.35  # trim to ~100k
    faces = m.faces[keep[m.faces].all(axis=1)]
    sub = trimesh.Trimesh(m.vertices, faces, process=True)
    sub.remove_unreferenced_vertices()
    mp = folder / "ball100k.obj"
    sub.export(mp)
    t = bake(str(mp), mode="unshadowed", lmax=4)
    p = folder / "ball100k.npz"
    t.save(p)
    return p


def stats(xs: list[float]) -> str:
    return f"{min(xs):.1f} | {statistics.median(xs):.1f}"


def main() -> None:
    import argparse

    from playwright.sync_api import sync_playwright

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="timed first-frame runs (default 5)")
    ap.add_argument("--first-only", action="store_true", help="only the first-frame figure")
    ap.add_argument("--gpu-compositing", action="store_true",
                    help="SwiftShader as the GL of everything, compositing included "
                         "(--use-angle=swiftshader) instead of the WebGL fallback mode")
    ap.add_argument("--cold-mesh", action="store_true",
                    help="also time this tree with an empty cache (the mesh read by trimesh)")
    ap.add_argument("--before", type=Path, default=None,
                    help="another checkout's src/ to time interleaved with this one (before/after)")
    a = ap.parse_args()
    print(f"Machine: {machine()}\n")
    with tempfile.TemporaryDirectory() as d, sync_playwright() as pw:
        folder = Path(d)
        probe = make_probe(folder)
        flags = [f.replace("swiftshader-webgl", "swiftshader") if a.gpu_compositing else f
                 for f in FLAGS]
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=flags)
        print(f"Chromium flags: {' '.join(flags)}\n")
        warm = folder / "cache"  # the servers' own cache, warmed below (not the user's)
        os.environ["SHPROBE_CACHE_DIR"] = str(warm)
        trees: dict[str, tuple[Path | None, bool]] = {"this tree": (None, False)}
        if a.before is not None:
            trees = {"before": (a.before.resolve(), False), **trees}
        if a.cold_mesh:  # every run with an empty cache: the mesh read by trimesh
            trees["this tree, mesh not cached"] = (None, True)
        for src, _ in trees.values():  # warm numba's cache, the mesh cache, the OS file cache
            first_frame(browser, [str(probe)], src, warm)
        load0 = os.getloadavg()[0]
        res: dict[str, list] = {k: [] for k in trees}
        for i in range(a.runs):  # interleaved, so that all see the same load
            for k, (src, cold) in trees.items():
                cache = folder / f"cold{i}" if cold else warm
                res[k].append(first_frame(browser, [str(probe)], src, cache))
        load1 = os.getloadavg()[0]
        print(f"### Command to first lit frame (2048×1024 .hdr probe, bunny, 512×512; "
              f"{a.runs} runs after a warm-up)\n")
        print("| | best s | median s |\n| --- | ---: | ---: |")
        for k, runs in res.items():
            ff, uu = [r[0] for r in runs], [r[1] for r in runs]
            cc = [r[2]["cpu"] for r in runs]
            print(f"| {k}: `shprobe view` → first lit frame | {min(ff):.2f} | "
                  f"{statistics.median(ff):.2f} |")
            print(f"| {k}: of which to the URL line | {min(uu):.2f} | "
                  f"{statistics.median(uu):.2f} |")
            print(f"| {k}: CPU time of the server's processes, whole run (not wall) | "
                  f"{min(cc):.2f} | {statistics.median(cc):.2f} |")
            bc = [r[2]["browser_cpu"] for r in runs]
            print(f"| {k}: CPU time of Chromium's processes, command → first frame | "
                  f"{min(bc):.2f} | {statistics.median(bc):.2f} |")
            sw = [r[2]["settled"] for r in runs]
            print(f"| {k}: wait for the new tab's browser to go idle, before the clock | "
                  f"{min(sw):.2f} | {statistics.median(sw):.2f} |")
        ff = [r[0] for r in res["this tree"]]
        print(f"\n**FIRST LIT FRAME: {min(ff):.2f} s best, {statistics.median(ff):.2f} s median** "
              f"(target ≤ 1.5 s; load average {load0:.2f} before the runs, {load1:.2f} after)\n")
        for k, runs in res.items():
            print(f"#### Where the time goes, {k} (seconds after the command; the browser tab "
                  "is open before the clock starts)\n")
            breakdown([r[2] for r in runs])
            print()
        if a.first_only:
            browser.close()
            return
        d = drag_times(browser, [str(probe)], None)
        print("### A lighting drag (per pointer move; ms, best | median of 40)\n")
        print("| | best ms | median ms |\n| --- | ---: | ---: |")
        print(f"| bunny: pointer event → frame drawn, timed in the page (rotation in the page) "
              f"| {stats(d['inpage'])} |")
        print(f"| bunny: move → first new frame, timed by Playwright | {stats(d['first'])} |")
        print(f"| bunny: move → library's answer drawn | {stats(d['step'])} |")
        print(f"| bunny: `/api/design` round trip (Wigner rotation) | {stats(d['design'])} |")
        print(f"| bunny: redraw, 512×512 view + two 512×256 panels | {stats(d['frame'])} |")
        print(f"| bunny: the 512×512 view alone (per pixel) | {stats(d['main'])} |")
        tp = prt_transfer(folder)
        d = drag_times(browser, ["--transfer", str(tp)], None)
        nv = int(np.load(tp)["vertices"].shape[0])
        print(f"| PRT {nv} vertices, lmax 4: move → new frame (server) | {stats(d['step'])} |")
        print(f"| PRT: pointer event → frame drawn, timed in the page | {stats(d['inpage'])} |")
        print(f"| PRT: `/api/design` round trip | {stats(d['design'])} |")
        print(f"| PRT: transfer · lighting loop in the page | {stats(d['prt'])} |")
        print(f"| PRT: redraw incl. the loop and the panels | {stats(d['frame'])} |")
        print(f"| PRT: the 512×512 view alone incl. the loop | {stats(d['main'])} |")
        browser.close()
    print(f"\nLoad average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
