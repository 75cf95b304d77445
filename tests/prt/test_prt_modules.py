"""The PRT package as a newcomer reads it: its modules import each other without a cycle (also
through function-level imports), no function takes more than 12 parameters, the package says
which modules it has, and the source states the present (no "issue N" / "run N")."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import shprobe.prt as prt

PRT = Path(prt.__file__).parent
CLI = PRT.parent / "cli" / "prt.py"


def local_imports(path: Path) -> set[str]:
    """The sibling modules a prt module imports, at any depth of the file."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.add(node.module.split(".")[0])
            else:
                out.update(a.name for a in node.names)
    return out


def test_no_import_cycle_inside_prt():
    graph = {p.stem: local_imports(p) for p in PRT.glob("*.py") if p.stem != "__init__"}
    state: dict[str, int] = {}

    def visit(m, path):
        if state.get(m) == 1:
            raise AssertionError("import cycle: " + " -> ".join([*path, m]))
        if state.get(m) == 2:
            return
        state[m] = 1
        for n in sorted(graph.get(m, ())):
            visit(n, [*path, m])
        state[m] = 2

    for m in sorted(graph):
        visit(m, [])
    # the check itself finds a cycle
    graph["geometry"] = graph["geometry"] | {"trace"}
    state.clear()
    try:
        visit("trace", [])
    except AssertionError as e:
        assert "trace -> " in str(e)
    else:
        raise AssertionError("the cycle check missed a cycle")


def test_package_names_its_modules_and_the_source_states_the_present():
    doc = prt.__doc__
    for p in PRT.glob("*.py"):
        if p.stem not in ("__init__", "_kernels"):
            assert f"`shprobe.prt.{p.stem}`" in doc or f":mod:`.{p.stem}`" in doc, p.stem
    for p in [*PRT.glob("*.py"), CLI]:
        text = p.read_text()
        assert not re.search(r"\b(issue|run) \d+", text), p.name
