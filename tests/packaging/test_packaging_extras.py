"""The light core and its extras: ``import shprobe`` imports none of the optional packages, and a
command whose extra is missing says which one in one line (simulated here by blocking the
modules in a fresh interpreter; tests/packaging/test_packaging.py checks a real core-only
install)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from shprobe.cli.extras import EXTRAS

SRC = Path(__file__).resolve().parents[2] / "src"
OPTIONAL = sorted({m for mods in EXTRAS.values() for m in mods} | {"torch", "jax", "anyio"})


def run_blocked(blocked: list[str], code: str, tmp_path: Path) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter in which ``blocked`` modules cannot be imported."""
    prelude = f"import sys\nfor _m in {blocked!r}:\n    sys.modules[_m] = None\n"
    env = {"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin", "SHPROBE_CACHE_DIR": str(tmp_path)}
    return subprocess.run([sys.executable, "-c", prelude + code], capture_output=True,
                          text=True, cwd=tmp_path, env=env, timeout=300)


def test_import_shprobe_and_every_public_name_imports_no_extra(tmp_path):
    code = ("import shprobe\n"
            "for n in shprobe._EXPORTS: getattr(shprobe, n)\n"
            "import shprobe.cli.main\n"
            f"print(sorted(m for m in {OPTIONAL!r} if m in sys.modules))\n")
    r = subprocess.run([sys.executable, "-c", "import sys\n" + code], capture_output=True,
                       text=True, cwd=tmp_path, env={"PYTHONPATH": str(SRC)}, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_the_core_runs_with_every_extra_blocked(tmp_path):
    r = run_blocked(OPTIONAL, "import shprobe, numpy as np\n"
                    "from shprobe.cli.main import main\n"
                    "L = shprobe.project(shprobe.procedural_env(64, 32), lmax=2)\n"
                    "E = shprobe.irradiance(L, np.array([[0.0, 1.0, 0.0]]))\n"
                    "assert E.shape == (1, 3) and np.isfinite(E).all()\n"
                    "sys.exit(main(['sh', 'eval', '--dir', '0,0,1', '--lmax', '1']))\n", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "0.488602512" in r.stdout  # y1,0 at +Z: sqrt(3 / 4π)


@pytest.mark.parametrize(("extra", "argv"), [
    ("batch", ["batch", "probe.hdr", "-o", "t.parquet"]),
    ("viewer", ["view", "--preset", "grace", "--no-browser"]),
])
def test_a_command_whose_extra_is_missing_names_it_in_one_line(extra, argv, tmp_path):
    r = run_blocked(list(EXTRAS[extra]), "from shprobe.cli.main import main\n"
                    f"sys.exit(main({argv!r}))\n", tmp_path)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert f"pip install 'shprobe[{extra}]'" in lines[0]
    assert lines[0].startswith(f"shprobe: error: shprobe {argv[0]} needs")
    assert not list(tmp_path.glob("t.parquet*"))


def test_missing_names_only_what_is_absent(tmp_path):
    r = run_blocked(["xxhash"], "from shprobe.cli.extras import missing\n"
                    "print(missing('batch'), missing('viewer'))\n", tmp_path)
    assert r.stdout.split("] [")[0] == "['xxhash'"
    assert r.stdout.strip().endswith("[]")
