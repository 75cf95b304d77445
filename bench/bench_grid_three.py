"""three.js's own GPU bake of a probe grid: ``LightProbeGridWebGL.bake`` (three r187) of a 7×4×7
grid of the closed room on the open ground (``grids.scenes.room_on_ground``) and of the bunny
(scaled 1.5 tall) on a ground, under the grace probe, in headless Chromium — WebGL2 on
SwiftShader here, a CPU rasteriser, not a GPU. What three.js's bake sees is in
bench/three_grid_bake.py. Per scene: the first bake (shader compiles included) and the median of
the later ones, each ending with the atlas read back (so the GPU work is finished); for the room
also the leak three.js's grid shows (mean irradiance on the cavity floor / on the open ground
around the room, plain trilinear sampling).

    SHPROBE_TEST_DATA=../shared PYTHONPATH=src python bench/bench_grid_three.py [--runs 4]
        [--cubemap 8 64]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "src"))
from _machine import machine  # noqa: E402
from shprobe.grids.scenes import bunny_on_ground, room_on_ground  # noqa: E402
from shprobe.lighting import project  # noqa: E402
from shprobe.probes.env import load_env  # noqa: E402
from three_grid_bake import (  # noqa: E402
    CONSUMERS,
    bake_job,
    grid_from_three,
    run_bakes,
)

#: the flags of the tests' Chromium (tests/support/browser.py): WebGL2 on SwiftShader
FLAGS = ["--no-sandbox", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-dev-shm-usage", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader"]
DATA = Path(os.environ.get("SHPROBE_TEST_DATA", HERE.parent.parent / "shared"))


def bake_in_chromium(jobs: dict[str, dict]) -> dict[str, dict]:
    """The jobs baked in headless /usr/bin/chromium, tests/consumers/ served over HTTP on a
    local port for the page's ES modules."""
    import functools
    import http.server
    import threading
    from typing import ClassVar

    from playwright.sync_api import sync_playwright

    base = http.server.SimpleHTTPRequestHandler

    class Quiet(base):
        extensions_map: ClassVar[dict[str, str]] = {
            **base.extensions_map, ".js": "text/javascript", ".mjs": "text/javascript"}

        def log_message(self, *args) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(CONSUMERS))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                         args=FLAGS)
            page = browser.new_page()
            page.goto(f"http://127.0.0.1:{server.server_address[1]}/grid.html")
            out = run_bakes(jobs, page)
            browser.close()
        return out
    finally:
        server.shutdown()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=4, help="bakes per scene (the first is cold)")
    ap.add_argument("--cubemap", type=int, nargs="+", default=[8, 64],
                    help="cube map face sizes (three.js's default is 8)")
    args = ap.parse_args()
    print(machine())
    env = load_env(DATA / "probes" / "grace.hdr")
    L = project(env, 2)
    room = room_on_ground()
    bunny, bunny_bounds = bunny_on_ground()
    jobs = {}
    for size in args.cubemap:
        for name, mesh, bounds in (("room", room.mesh(), room.bounds),
                                   ("bunny", bunny, bunny_bounds)):
            job = bake_job(mesh, bounds, env, L, runs=args.runs)
            job["cubemapSize"] = size
            jobs[f"{name}, cube {size}"] = job
    t = time.perf_counter()
    results = bake_in_chromium(jobs)
    info = next(iter(results.values()))["info"]
    print(f"Chromium WebGL2 renderer: {info['renderer']}; three r{info['version']}; "
          f"{time.perf_counter() - t:.1f} s in all")
    print(f"{'scene':<18}{'faces':>7}{'first bake s':>14}{'later bakes s (median)':>24}"
          f"{'leak in/out':>13}")
    for key, res in results.items():
        s = res["seconds"]
        later = statistics.median(s[1:]) if len(s) > 1 else float("nan")
        leak = ""
        if key.startswith("room"):
            lk = room.leak(grid_from_three(res, jobs[key]), leak_control=False)
            leak = f"{lk.floor_ratio:.3f}"
        print(f"{key:<18}{len(jobs[key]['faces']) // 3:>7}{s[0]:>14.2f}{later:>24.2f}"
              f"{leak:>13}")


if __name__ == "__main__":
    main()
