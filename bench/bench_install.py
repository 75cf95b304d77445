"""What installing shprobe costs: the disk size of the core and of ``[all]`` in fresh virtual
environments, and the time from ``pip install 'shprobe[viewer]'`` in a clean venv to the first
lit frame of ``shprobe view`` in headless Chromium (the first start compiles numba's kernels
into the fresh install's cache; a second start is timed too).

    python bench/bench_install.py                 # builds the wheel from this checkout
    python bench/bench_install.py --wheel dist/shprobe-X-py3-none-any.whl

pip's cache is used as it is (state it with the figures: warm after a first install, so the
figures are installing, not downloading). The browser is started before the clock (a user's
browser is already open); it runs Debian's /usr/bin/chromium with WebGL on SwiftShader.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FLAGS = ["--no-sandbox", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--use-angle=swiftshader-webgl"]


def tree_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def venv(path: Path) -> tuple[Path, dict[str, str]]:
    subprocess.run([sys.executable, "-m", "venv", str(path)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(PATH=f"{path / 'bin'}:/usr/bin:/bin", PIP_DISABLE_PIP_VERSION_CHECK="1")
    return path / "bin", env


def pip_install(bindir: Path, env: dict[str, str], spec: str) -> float:
    t = time.perf_counter()
    subprocess.run([str(bindir / "python"), "-m", "pip", "install", "-q", spec], check=True,
                   env=env)
    return time.perf_counter() - t


def build_wheel(out: Path) -> Path:
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(out), str(REPO)],
                   check=True, stdout=subprocess.DEVNULL)
    return next(out.glob("shprobe-*.whl"))


def first_frame(page, shprobe: Path, env: dict[str, str], cwd: Path, t0: float) -> float:
    """Start ``shprobe view``, open its URL in ``page``; seconds from ``t0`` to the first lit
    frame (the page's own ``firstFrameAt`` mark)."""
    p = subprocess.Popen([str(shprobe), "view", "--preset", "grace", "--no-browser"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         cwd=cwd)
    try:
        url = p.stdout.readline().split()[-1]
        page.goto(url)
        page.wait_for_function("() => window.__shprobe && window.__shprobe.firstFrameAt",
                               timeout=600_000)
        return page.evaluate("() => window.__shprobe.firstFrameAt") / 1000.0 - t0
    finally:
        p.terminate()
        p.wait(30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wheel", type=Path, help="the wheel to install (default: build one)")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    tmp = Path(tempfile.mkdtemp(prefix="shprobe-install-"))
    try:
        wheel = args.wheel or build_wheel(tmp / "dist")
        print(f"# install bench — {platform.machine()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}, load average {os.getloadavg()[0]:.2f} at start; "
              f"{wheel.name}, pip cache as found")
        venv(tmp / "bare")
        bare = tree_bytes(tmp / "bare")
        rows = []
        for extra in ("", "[all]"):
            bindir, env = venv(tmp / f"v{extra or 'core'}")
            secs = pip_install(bindir, env, f"{wheel}{extra}")
            size = tree_bytes(bindir.parent) - bare
            rows.append((f"shprobe{extra or ' (core)'}", size / 2**20, secs))
        print("\n| install into a fresh venv | MiB on disk | pip install s |")
        print("| --- | ---: | ---: |")
        for name, mib, secs in rows:
            print(f"| {name} | {mib:.0f} | {secs:.1f} |")

        bindir, env = venv(tmp / "viewer")
        env.pop("SHPROBE_TEST_DATA", None)
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                         args=FLAGS)
            page = browser.new_page()
            page.goto("about:blank")
            time.sleep(2.0)  # the new window's own start-up is over before the clock starts
            t0 = time.time()
            secs = pip_install(bindir, env, f"{wheel}[viewer]")
            cold = first_frame(page, bindir / "shprobe", env, tmp, t0)
            page = browser.new_page()
            t1 = time.time()
            warm = first_frame(page, bindir / "shprobe", env, tmp, t1)
            browser.close()
        print("\n| clean venv, `pip install 'shprobe[viewer]'` then `shprobe view --preset "
              "grace` | s |")
        print("| --- | ---: |")
        print(f"| pip install | {secs:.1f} |")
        print(f"| `pip install` → first lit frame (first start: numba compiles) | {cold:.1f} |")
        print(f"| of which `shprobe view` → first lit frame | {cold - secs:.1f} |")
        print(f"| a second `shprobe view` → first lit frame | {warm:.1f} |")
        print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
