"""The package as a user gets it: built from a clean checkout with no Node on PATH, checked as
an index would, installed into fresh virtual environments (the core alone, then with
``[viewer]`` and ``[batch]``) and used there — the demo, a library snippet, the viewer's page
in headless Chromium, a two-probe batch and every README tour line, run as written in a shell
whose venv is activated.

The build is done once per test run (a lock shares it between xdist workers); installs use
pip's cache, so after the first CI run nothing is downloaded.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import shlex
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

from shprobe._version import __version__
from tests.conftest import REPO, one_line_error, shared_dir

pytestmark = pytest.mark.slow

NAME = f"shprobe-{__version__}"
#: what a fresh venv runs with: its own bin, the system's tools, no Node
BASE_PATH = "/usr/local/bin:/usr/bin:/bin"
#: the headless Chromium flags of the project (Debian's browser, never a downloaded one)
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader-webgl"]


def run(cmd: list[str] | str, *, timeout: float = 900, ok: bool = True,
        **kw) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kw)
    if ok:
        shown = cmd if isinstance(cmd, str) else shlex.join(map(str, cmd))
        assert r.returncode == 0, f"{shown}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


def no_node_path(tmp: Path) -> str:
    """A PATH holding the test's Python (for ``python -m build``) and no Node."""
    bindir = tmp / "bin"
    bindir.mkdir(exist_ok=True)
    for exe in ("python", "python3"):
        link = bindir / exe
        if not link.exists():
            link.symlink_to(sys.executable)
    assert shutil.which("node", path=str(bindir)) is None
    return str(bindir)


def clean_checkout(dest: Path) -> Path:
    """The tracked files of this checkout (what a fresh clone holds) copied to ``dest``."""
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout: the packaging checks build from the tracked files")
    names = run(["git", "ls-files", "-z"], cwd=REPO).stdout.split("\0")
    for name in filter(None, names):
        src = REPO / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


@contextlib.contextmanager
def locked(path: Path):
    with open(path, "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="module")
def dists(tmp_path_factory) -> dict[str, Path]:
    """sdist, the wheel built from it, and a wheel built straight from the checkout."""
    root = tmp_path_factory.getbasetemp()
    shared = root.parent if os.environ.get("PYTEST_XDIST_WORKER") else root
    out = shared / "shprobe-dists"
    with locked(shared / "shprobe-dists.lock"):
        done = out / "done"
        if not done.exists():
            shutil.rmtree(out, ignore_errors=True)
            out.mkdir()
            src = clean_checkout(out / "checkout")
            env = dict(os.environ, PATH=no_node_path(out))
            # `python -m build`: the sdist, then the wheel from the unpacked sdist
            run([sys.executable, "-m", "build", "--outdir", str(out / "dist"), str(src)],
                env=env)
            run([sys.executable, "-m", "build", "--wheel", "--outdir", str(out / "direct"),
                 str(src)], env=env)
            done.touch()
    return {"sdist": out / "dist" / f"{NAME}.tar.gz",
            "wheel": out / "dist" / f"{NAME}-py3-none-any.whl",
            "direct": out / "direct" / f"{NAME}-py3-none-any.whl"}


def wheel_files(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n: z.read(n) for n in z.namelist() if not n.endswith("/RECORD")}


def test_sdist_and_wheel_build_without_node_hold_the_viewer_and_agree(dists):
    from_sdist, direct = wheel_files(dists["wheel"]), wheel_files(dists["direct"])
    assert sorted(from_sdist) == sorted(direct)
    assert [n for n in from_sdist if from_sdist[n] != direct[n]] == []
    vendor = REPO / "src" / "shprobe" / "viewer" / "static" / "vendor"
    for f in vendor.rglob("*"):
        if f.is_file():
            name = "shprobe/viewer/static/vendor/" + f.relative_to(vendor).as_posix()
            assert from_sdist[name] == f.read_bytes(), name
    for name in ("shprobe/viewer/static/index.html", "shprobe/py.typed",
                 f"{NAME}.dist-info/licenses/LICENSE"):
        assert name in from_sdist, name
    meta = from_sdist[f"{NAME}.dist-info/METADATA"].decode()
    assert "Provides-Extra: viewer" in meta and "Provides-Extra: batch" in meta
    assert re.search(r"^Requires-Dist: dask.*extra == \"batch\"", meta, re.M)
    assert not re.search(r"^Requires-Dist: (dask|starlette|uvicorn|pyarrow)[^;]*$", meta, re.M)
    with tarfile.open(dists["sdist"]) as t:
        names = set(t.getnames())
    for name in ("LICENSE", "CHANGELOG.md", "tools/js/package-lock.json",
                 "tools/js/vendor.sha256", "tools/vendor_js.sh", "mkdocs.yml",
                 "src/shprobe/viewer/static/vendor/three/three.min.js"):
        assert f"{NAME}/{name}" in names, name


def test_twine_check_passes(dists):
    r = run([sys.executable, "-m", "twine", "check", "--strict", str(dists["sdist"]),
             str(dists["wheel"])])
    assert r.stdout.count("PASSED") == 2, r.stdout
    meta = wheel_files(dists["wheel"])[f"{NAME}.dist-info/METADATA"].decode()
    assert "Classifier: Programming Language :: Python :: 3" in meta
    assert "Project-URL: Documentation" in meta
    assert "Description-Content-Type: text/markdown" in meta


def venv_env(venv: Path, tmp: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.update(PATH=f"{venv / 'bin'}:{BASE_PATH}", PIP_DISABLE_PIP_VERSION_CHECK="1",
               PIP_NO_INPUT="1", HOME=os.environ.get("HOME", str(tmp)))
    env.pop("SHPROBE_TEST_DATA", None)  # the viewer's default mesh: the sphere
    return env


def pip_install(venv: Path, spec: str, env: dict[str, str]) -> None:
    run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", spec], env=env)


SNIPPET = """
import sys
import numpy as np
import shprobe
env = shprobe.procedural_env(64, 32)
L = shprobe.project(env, lmax=2)
n = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
E = shprobe.irradiance(L, n)
np.testing.assert_allclose(E, shprobe.irradiance_quadratic(L, n), rtol=1e-9)
R = shprobe.from_euler_zyz(0.3, 0.5, 0.7)
np.testing.assert_allclose(shprobe.irradiance(shprobe.rotate(L, R), n @ R.T), E, rtol=1e-9)
assert not {"dask", "pyarrow", "starlette", "uvicorn"} & set(sys.modules)
print(shprobe.__version__, shprobe.__file__)
"""


def first_frame(url: str) -> list[str]:
    """Open ``url`` in headless Chromium, wait for the viewer's first lit frame; the page's
    console errors (none expected)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True,
                                     args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
            page.goto(url)
            page.wait_for_function("() => window.__shprobe && window.__shprobe.firstFrameAt",
                                   timeout=180_000)
            assert page.locator("canvas").count() >= 1
            size = page.evaluate("() => { const c = document.querySelector('canvas');"
                                 " return [c.width, c.height]; }")
            assert min(size) > 0
            return errors
        finally:
            browser.close()


def tour_lines() -> list[str]:
    from tests.docs.test_readme import tour_lines as lines

    return lines()


@pytest.mark.browser
def test_installed_wheel_core_then_viewer_then_batch_then_the_tour(dists, tmp_path):
    venv = tmp_path / "venv"
    run([sys.executable, "-m", "venv", str(venv)])  # fresh: no system site-packages
    env = venv_env(venv, tmp_path)
    wheel = str(dists["wheel"])
    py, shprobe = str(venv / "bin" / "python"), str(venv / "bin" / "shprobe")

    # the core: no extra installed, the main job and the library work
    pip_install(venv, wheel, env)
    for mod in ("dask", "pyarrow", "starlette", "uvicorn"):
        assert run([py, "-c", f"import {mod}"], env=env, ok=False).returncode != 0, mod
    assert run([shprobe, "--version"], env=env).stdout.split()[-1] == __version__
    work = tmp_path / "work"
    work.mkdir()
    run([shprobe, "demo"], env=env, cwd=work)
    assert (work / "shprobe-demo").is_dir() and any((work / "shprobe-demo").glob("*.png"))
    out = run([py, "-c", SNIPPET], env=env, cwd=work).stdout
    assert str(venv) in out  # the installed package, not the checkout
    for extra, argv in (("viewer", ["view", "--preset", "grace", "--no-browser"]),
                        ("batch", ["batch", "a.hdr", "-o", "t.parquet"])):
        r = run([shprobe, *argv], env=env, cwd=work, ok=False)
        assert r.returncode == 1, r.stderr
        one_line_error(r.stderr, f"pip install 'shprobe[{extra}]'")

    # [viewer] and [batch] added (the viewer's page is opened last)
    pip_install(venv, f"{wheel}[viewer]", env)
    pip_install(venv, f"{wheel}[batch]", env)
    skipped = []

    # [batch]: a two-probe batch, its rows the library's own numbers
    run([py, "-c", "import shprobe\n"
         "for i, w in enumerate((64, 32)):\n"
         "    shprobe.write_env(f'p{i}.hdr', shprobe.procedural_env(w, w // 2))\n"],
        env=env, cwd=work)
    run([shprobe, "batch", "p0.hdr", "p1.hdr", "-j", "1", "-o", "t.parquet"], env=env,
        cwd=work)
    run([py, "-c", "import numpy as np, shprobe, pyarrow.parquet as pq\n"
         "t = pq.read_table('t.parquet').to_pylist()\n"
         "assert len(t) == 2 and all(r['failure'] is None for r in t), t\n"
         "for r in t:\n"
         "    L = shprobe.project(shprobe.load_env(r['path']), lmax=2)\n"
         "    np.testing.assert_allclose(np.asarray(r['coefficients']), L, rtol=1e-5)\n"],
        env=env, cwd=work)

    # every README tour line, as written, in a shell whose venv is activated
    data = shared_dir()
    files = {"grace.hdr": data / "probes" /
             "grace.hdr", "ennis.hdr": data / "probes" / "ennis.hdr",
             "bunny.obj": data / "meshes" / "bunny.obj"}
    if all(f.is_file() for f in files.values()):
        tour = tmp_path / "tour"
        tour.mkdir()
        for name, f in files.items():
            shutil.copy(f, tour / name)
        for line in tour_lines():
            r = run(["bash", "-c", f". {venv}/bin/activate && {line}"], env=env, cwd=tour,
                    ok=False)
            assert r.returncode == 0 and "Traceback" not in r.stderr, f"{line}\n{r.stderr}"
        for name in ("c.json", "irr.exr", "bunny.png", "basis/basis.png", "edited.json",
                     "h.npz", "nm.png", "t.npz", "frames/f_000.png", "frames/f_035.png",
                     "ball.png", "fitted.json", "report.html", "probes.parquet"):
            assert (tour / name).is_file(), name
    else:
        skipped.append(f"the README tour: test data not found under {data} (set "
                       "SHPROBE_TEST_DATA)")

    # [viewer]: the served page opens in headless Chromium with a lit canvas, no errors
    if os.access("/usr/bin/chromium", os.X_OK) and _has_playwright():
        p = subprocess.Popen([shprobe, "view", "--preset", "grace", "--no-browser"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=env, cwd=work)
        try:
            line = p.stdout.readline()
            assert line.startswith("shprobe view: http://127.0.0.1:"), line + p.stderr.read()
            assert first_frame(line.split()[-1]) == []
        finally:
            p.terminate()
            p.wait(30)
    else:
        skipped.append("the viewer's page: /usr/bin/chromium or playwright not installed "
                       "(apt install chromium)")
    if skipped:
        pytest.skip("; ".join(skipped))


def _has_playwright() -> bool:
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return False
    return True
