"""The pipeline's layers as an enforced contract: import-linter's layers contract from
pyproject.toml holds for the package, and fails when a lower layer imports a higher one; numba
is imported only by kernel modules, lazily; `import shprobe` loads no numba."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "shprobe"
LINT = Path(sys.executable).with_name("lint-imports")

pytestmark = pytest.mark.skipif(not LINT.exists(), reason="import-linter not installed "
                                "(pip install -e .[dev])")


def _lint(src_root: Path, config: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(src_root)}
    return subprocess.run([str(LINT), "--config", str(config), "--no-cache", "--no-logo"],
                          capture_output=True, text=True, env=env, cwd=src_root, timeout=300)


def test_layers_contract_is_kept():
    res = _lint(ROOT / "src", ROOT / "pyproject.toml")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "1 kept, 0 broken" in res.stdout


@pytest.mark.parametrize(("module", "back_edge"), [
    ("sh/basis.py", "from ..lighting import coeffs"),  # SH maths importing lighting
    ("probes/layouts.py", "from ..scene import render"),  # probes importing the scene
    ("lighting/coeffs.py", "from ..cli import main"),  # lighting importing the CLI
    ("hbasis/basis.py", "from ..prt import relight"),  # siblings importing each other
])
def test_a_deliberate_back_edge_breaks_the_contract(tmp_path, module, back_edge):
    """The same contract on a copy of the package with one upward import added (inside a
    function, as lazy imports are) must fail and name that import."""
    pkg = tmp_path / "src" / "shprobe"
    shutil.copytree(SRC, pkg, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    target = pkg / module
    target.write_text(target.read_text() + f"\n\ndef _back_edge():\n    {back_edge}\n")
    res = _lint(tmp_path / "src", ROOT / "pyproject.toml")
    assert res.returncode != 0, res.stdout
    assert "BROKEN" in res.stdout
    importer = "shprobe." + module[:-3].replace("/", ".")
    assert importer in res.stdout, res.stdout


def _imports(path: Path) -> list[tuple[str, bool]]:
    """(imported module, at module level?) for every import in a file."""
    tree = ast.parse(path.read_text(), str(path))
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, id(node) in top) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = "." * node.level + (node.module or "")
            out += [(f"{base}.{a.name}" if not node.module else base, id(node) in top)
                    for a in node.names]
    return out


def _is_kernel(path: Path) -> bool:
    return path.stem.startswith("_kernels") or path.stem in {"_unrolled", "_rotation_kernels",
                                                             "_layout_kernels"}


def test_numba_only_in_kernel_modules_imported_lazily():
    modules = sorted(SRC.rglob("*.py"))
    assert any(_is_kernel(p) for p in modules)
    for p in modules:
        for name, top_level in _imports(p):
            leaf = name.rsplit(".", 1)[-1]
            if name.split(".")[0] in ("numba", "llvmlite"):
                assert _is_kernel(p), f"{p.relative_to(SRC)} imports {name}"
            if leaf.startswith("_kernels") or leaf in ("_unrolled", "_rotation_kernels",
                                                       "_layout_kernels"):
                if not _is_kernel(p):
                    assert not top_level, (f"{p.relative_to(SRC)} imports kernel module "
                                           f"{name} at module level (import it lazily)")


def test_import_shprobe_loads_no_numba():
    code = ("import sys, shprobe, shprobe.sh, shprobe.probes, shprobe.lighting, shprobe.scene, "
            "shprobe.hbasis, shprobe.prt, shprobe.cli.main; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'scipy', "
            "'trimesh')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert out.returncode == 0, out.stderr
    assert "numba" not in out.stdout, out.stdout
