"""The pipeline's layers as an enforced contract: import-linter's contracts from pyproject.toml
(the layers, and no import cycle inside a package) hold for the package, and fail on a copy of it
where a lower layer imports a higher one (at module level or inside a function) or where two
modules of one package import each other; numba is imported only by kernel modules
(``_kernels.py`` / ``_kernels_<topic>.py``), lazily; `import shprobe` loads no numba; and
docs/architecture.md lists every module of the tree in its layer."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
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
    assert "2 kept, 0 broken" in res.stdout, res.stdout


def _mutated_copy(tmp_path: Path, module: str, line: str, inside_function: bool) -> Path:
    """A copy of the package with ``line`` added to ``module``, at module level or in a
    function (as lazy imports are); returns the copy's src folder."""
    pkg = tmp_path / "src" / "shprobe"
    shutil.copytree(SRC, pkg, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    target = pkg / module
    added = f"\n\ndef _added():\n    {line}\n" if inside_function else f"\n{line}  # noqa\n"
    target.write_text(target.read_text() + added)
    return tmp_path / "src"


def _importer(module: str) -> str:
    return "shprobe." + module[:-3].replace("/", ".").removesuffix(".__init__")


@pytest.mark.parametrize("inside_function", [False, True], ids=["module-level", "in-function"])
@pytest.mark.parametrize(("module", "back_edge"), [
    ("sh/basis.py", "from ..lighting import coeffs"),  # SH maths importing lighting
    ("probes/layouts/latlong.py", "from ...scene import render"),  # probes importing the scene
    ("lighting/coeffs.py", "from ..cli import main"),  # lighting importing the CLI
    ("hbasis/basis.py", "from ..prt import relight"),  # siblings importing each other
])
def test_a_deliberate_back_edge_breaks_the_contract(tmp_path, module, back_edge,
                                                    inside_function):
    """The layers contract on a copy of the package with one upward import added must fail
    and name that import, whether the import is at module level or inside a function."""
    res = _lint(_mutated_copy(tmp_path, module, back_edge, inside_function),
                ROOT / "pyproject.toml")
    assert res.returncode != 0, res.stdout
    assert "shprobe pipeline layers BROKEN" in res.stdout, res.stdout
    assert _importer(module) in res.stdout, res.stdout


@pytest.mark.parametrize("inside_function", [False, True], ids=["module-level", "in-function"])
@pytest.mark.parametrize(("module", "line", "package", "edge"), [
    # images imports codecs: codecs importing images closes a cycle in shprobe.probes
    ("probes/codecs.py", "from .images import read_image", "shprobe.probes",
     ".codecs -> .images"),
    # normalmap imports frames: the way back is a cycle in shprobe.hbasis
    ("hbasis/frames.py", "from .normalmap import shade_h", "shprobe.hbasis",
     ".frames -> .normalmap"),
    # one level down: cube imports base
    ("probes/layouts/base.py", "from .cube import Cube", "shprobe.probes.layouts",
     ".base -> .cube"),
])
def test_a_cycle_inside_a_package_breaks_the_contract(tmp_path, module, line, package, edge,
                                                      inside_function):
    """Two modules of one package (same layer, so the layers contract cannot see it) that
    import each other break the acyclic-siblings contract, which names the package and an
    import that would break the cycle."""
    res = _lint(_mutated_copy(tmp_path, module, line, inside_function), ROOT / "pyproject.toml")
    assert res.returncode != 0, res.stdout
    assert "shprobe pipeline layers KEPT" in res.stdout, res.stdout
    assert "no import cycle inside a package BROKEN" in res.stdout, res.stdout
    assert f"No cycles are allowed in {package}." in res.stdout, res.stdout
    a, b = edge.split(" -> ")  # the contract names one import of the cycle to remove
    assert f"{a} -> {b}" in res.stdout or f"{b} -> {a}" in res.stdout, res.stdout


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


def _is_kernel_name(stem: str) -> bool:
    """The one naming rule: a package's main kernel module is ``_kernels``, any other
    ``_kernels_<topic>``."""
    return stem == "_kernels" or (stem.startswith("_kernels_") and len(stem) > len("_kernels_"))


def _is_kernel(path: Path) -> bool:
    return _is_kernel_name(path.stem)


def test_kernel_modules_follow_one_naming_rule():
    kernels = [p for p in SRC.rglob("*.py") if "kernel" in p.stem or "unrolled" in p.stem]
    assert len(kernels) >= 5
    misnamed = [str(p.relative_to(SRC)) for p in kernels if not _is_kernel(p)]
    assert not misnamed, f"kernel modules not named _kernels[_<topic>].py: {misnamed}"


def test_numba_only_in_kernel_modules_imported_lazily():
    modules = sorted(SRC.rglob("*.py"))
    assert any(_is_kernel(p) for p in modules)
    for p in modules:
        for name, top_level in _imports(p):
            leaf = name.rsplit(".", 1)[-1]
            if name.split(".")[0] in ("numba", "llvmlite"):
                assert _is_kernel(p), f"{p.relative_to(SRC)} imports {name}"
            if _is_kernel_name(leaf):
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


def _tree_modules() -> set[str]:
    """Every module of the package: each .py file, and each sub-package below a layer package
    (its ``__init__`` holds code of its own, e.g. the layout registry)."""
    out = set()
    for p in SRC.rglob("*.py"):
        rel = p.relative_to(SRC).with_suffix("")
        parts = rel.parts
        if parts[-1] == "__init__":
            if len(parts) <= 2:  # shprobe itself and the layer packages: re-exports only
                continue
            parts = parts[:-1]
        out.add(".".join(("shprobe", *parts)))
    return out


def _documented_modules() -> dict[str, str]:
    """module → layer from the 'Modules, layer by layer' table of docs/architecture.md."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split("## Modules, layer by layer", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[1].startswith("`shprobe"):
            name = cells[1].strip("`")
            assert name not in rows, f"{name} is listed twice"
            rows[name] = cells[0]
    return rows


def _contract_layers() -> list[list[str]]:
    """The layers contract of pyproject.toml, bottom first, each a list of packages."""
    import tomllib

    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    layers = next(c for c in conf["contracts"] if c["type"] == "layers")["layers"]
    return [[p.strip(" ()") for p in layer.split("|")] for layer in reversed(layers)]


def test_architecture_doc_lists_every_module_in_its_layer():
    documented = _documented_modules()
    tree = _tree_modules()
    missing, stale = sorted(tree - set(documented)), sorted(set(documented) - tree)
    assert not missing and not stale, (
        f"docs/architecture.md's module table: missing {missing}, no longer in the tree {stale}")
    rank = {pkg: str(i) for i, layer in enumerate(_contract_layers(), 1) for pkg in layer}
    wrong = {}
    for name, layer in documented.items():
        owner = next((p for p in rank if name == p or name.startswith(p + ".")), None)
        want = rank[owner] if owner else "—"
        if layer != want:
            wrong[name] = (layer, want)
    assert not wrong, f"modules documented in the wrong layer (documented, contract): {wrong}"


def test_bench_imports_nothing_from_tests():
    """Benchmarks stand on the library (and bench/ itself), never on the test suite."""
    for p in sorted((ROOT / "bench").glob("*.py")):
        for name, _ in _imports(p):
            assert name.split(".")[0] != "tests", f"bench/{p.name} imports {name}"


MAX_LINES = 500


def test_no_hand_written_module_over_500_lines():
    """One concept per module: none over 500 lines, every line counted (docstrings too), except
    generated ones (first line says GENERATED)."""
    over = []
    for p in sorted(SRC.rglob("*.py")):
        text = p.read_text()
        if text.startswith('"""GENERATED'):
            continue
        n = text.count("\n")
        if n > MAX_LINES:
            over.append(f"{p.relative_to(SRC)} ({n} lines)")
    assert not over, f"modules over {MAX_LINES} lines: {over}"


def _parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    n = (len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None)
         + (a.kwarg is not None))
    return n - (1 if a.args and a.args[0].arg in ("self", "cls") else 0)


def test_no_function_outside_the_cli_takes_more_than_12_parameters():
    """Functions take a settings object rather than a dozen keywords (the CLI's command
    functions take one parameter per option, as click hands them)."""
    over = []
    for p in SRC.rglob("*.py"):
        if p.relative_to(SRC).parts[0] == "cli":
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) \
                    and _parameters(node) > 12:
                over.append(f"{p.relative_to(SRC)}: {node.name} ({_parameters(node)})")
    assert not over, over


def test_the_parameter_count_sees_a_long_signature():
    fn = ast.parse("def f(self, a, b, c, d, e, f, g, h, i, j, k, l, *m, n=1, **o): pass").body[0]
    assert _parameters(fn) == 15
