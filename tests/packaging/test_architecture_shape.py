"""The shape every workflow shares, checked on the source: no function outside the CLI takes
more than eight parameters (a workflow's settings travel as one settings object), and no
click command is defined inside another function (commands live at module level, where they
can be read, imported and introspected)."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "shprobe"
MAX_PARAMETERS = 8
#: Compiled kernels take flat arrays and scalars (numba cannot take the settings objects the
#: Python layer passes), so decorators from numba exempt a function.
NUMBA_DECORATORS = {"njit", "jit", "generated_jit", "vectorize", "guvectorize", "cfunc",
                    "stencil"}


def _functions(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield node


def _decorator_name(d: ast.expr) -> str:
    if isinstance(d, ast.Call):
        d = d.func
    if isinstance(d, ast.Attribute):
        return d.attr
    return d.id if isinstance(d, ast.Name) else ""


def parameter_count(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Parameters of ``fn``, self/cls not counted; *args and **kwargs count one each."""
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + (a.vararg is not None) + (a.kwarg is not None)


def _modules():
    for p in sorted(SRC.rglob("*.py")):
        yield p.relative_to(SRC), ast.parse(p.read_text(encoding="utf-8"))


def test_parameter_count_counts_what_a_caller_passes():
    tree = ast.parse("class C:\n    def m(self, a, b=1, *c, d, **e): pass\n"
                     "def f(a, /, b, *, c): pass\n")
    counts = {f.name: parameter_count(f) for f in _functions(tree)}
    assert counts == {"m": 5, "f": 3}


def test_no_function_outside_the_cli_takes_more_than_eight_parameters():
    over = []
    for rel, tree in _modules():
        if rel.parts[0] == "cli":
            continue
        for fn in _functions(tree):
            if {_decorator_name(d) for d in fn.decorator_list} & NUMBA_DECORATORS:
                continue
            n = parameter_count(fn)
            if n > MAX_PARAMETERS:
                over.append(f"{rel}:{fn.lineno} {fn.name} ({n})")
    assert not over, "functions over 8 parameters (pass a settings object): " + ", ".join(over)


def _is_click_command(d: ast.expr) -> bool:
    """``@x.command(...)``, ``@x.group(...)``, ``@click.command``, ``@click.group``."""
    if isinstance(d, ast.Call):
        d = d.func
    return isinstance(d, ast.Attribute) and d.attr in ("command", "group")


def test_no_click_command_is_defined_inside_a_function():
    nested = []
    for rel, tree in _modules():
        for outer in _functions(tree):
            for inner in _functions(outer):
                if inner is not outer and any(_is_click_command(d)
                                              for d in inner.decorator_list):
                    nested.append(f"{rel}:{inner.lineno} {inner.name} in {outer.name}")
    assert not nested, "click commands defined inside functions: " + ", ".join(nested)


def test_the_checks_see_what_they_look_for():
    """A nested command and a nine-parameter function are found (the tests can fail)."""
    tree = ast.parse("def register(g):\n    @g.command('x')\n    def x(): pass\n"
                     "def f(a, b, c, d, e, f, g, h, i): pass\n")
    fns = {f.name: f for f in _functions(tree)}
    assert any(_is_click_command(d) for d in fns["x"].decorator_list)
    assert parameter_count(fns["f"]) == 9
