"""The bench scripts stand on the installed package: each bench/*.py imports only netgen, the
standard library, third-party packages, bench/support.py and its sibling scripts, never `tests`
or a test module, and never edits sys.path (`.venv/bin/python bench/x.py` has the script's folder
on sys.path already; the test oracles come through support, loaded by file path). The checker is
tested on synthetic sources first, so these tests can fail."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from tests.fixtures import ROOT

BENCH = ROOT / "bench"


def _is_sys_path(node: ast.AST) -> bool:
    """`sys.path` (an attribute `path` of the name `sys`)."""
    return (
        isinstance(node, ast.Attribute)
        and node.attr == "path"
        and isinstance(node.value, ast.Name)
        and node.value.id == "sys"
    )


def _test_module(name: str) -> bool:
    """The package `tests`, a module of it, or a test module (a component named test_*)."""
    parts = name.split(".")
    return parts[0] == "tests" or any(p.startswith("test_") for p in parts)


def violations(source: str) -> list[tuple[int, str]]:
    """(line, what) of every sys.path mutation and every import of tests or a test module."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, f"imports {a.name}") for a in node.names if _test_module(a.name)]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if _test_module(node.module):
                out.append((node.lineno, f"imports from {node.module}"))
            elif node.module == "sys" and any(a.name == "path" for a in node.names):
                out.append((node.lineno, "imports sys.path by name"))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and _is_sys_path(node.func.value):
            out.append((node.lineno, f"calls sys.path.{node.func.attr}"))
        elif isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if _is_sys_path(t) or (isinstance(t, ast.Subscript) and _is_sys_path(t.value)):
                    out.append((node.lineno, "assigns sys.path"))
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            called = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            if called in ("import_module", "__import__") and _test_module(str(node.args[0].value)):
                out.append((node.lineno, f"imports {node.args[0].value} by name"))
    return sorted(out)


@pytest.mark.parametrize(
    "source, line",
    [
        ("import sys\nsys.path.insert(0, 'x')\n", 2),
        ("import sys\n\nsys.path.append('x')\n", 3),
        ("import sys\nsys.path[:0] = ['x']\n", 2),
        ("import sys\nsys.path += ['x']\n", 2),
        ("import sys\nsys.path = ['x']\n", 2),
        ("from sys import path\n", 1),
        ("from tests.fixtures import ROOT\n", 1),
        ("import tests.va_scan\n", 1),
        ("def f():\n    from test_bem_sampling import reduced\n", 2),
        ("from tests.sim.test_ngspice import reference_transient\n", 1),
        ("import importlib\nimportlib.import_module('tests.oracles')\n", 2),
    ],
)
def test_checker_flags_path_edits_and_test_imports(source, line):
    """Each form of the two faults is found, on its line."""
    assert [n for n, _ in violations(source)] == [line]


def test_checker_passes_the_allowed_imports():
    """netgen, the standard library, third-party packages, support and sibling scripts; reading sys.path is fine."""
    source = (
        "import sys\nimport numpy as np\nfrom support import ROOT, closed_forms\nimport sigma_delta as bench\n"
        "from baselines import BASELINES\nfrom netgen.testbench import sigma_delta as sd\nprint(sys.path[0])\n"
        "from netgen.electrostatics.sampling import sample_grid\n"
    )
    assert violations(source) == []


def test_no_bench_script_edits_sys_path_or_imports_tests():
    """Every bench/*.py: file and line of each fault."""
    found = [
        f"{p.relative_to(ROOT)}:{line}: {what}"
        for p in sorted(BENCH.glob("*.py"))
        for line, what in violations(p.read_text(encoding="utf-8"))
    ]
    assert found == [], "\n".join(found)


def test_support_loads_every_oracle_by_its_path():
    """support.oracle loads each module it names from tests/oracles in a fresh interpreter started in
    bench/ (as a script's folder is on sys.path) with no `tests` package importable."""
    from_support = "import support; print(' '.join(m for m in support.MODULES if support.oracle(m)))"
    proc = subprocess.run(
        [sys.executable, "-I", "-c", f"import sys; sys.path.insert(0, '.'); {from_support}; import tests"],
        cwd=BENCH,
        capture_output=True,
        text=True,
        timeout=120,
    )
    modules = sorted(p.stem for p in (ROOT / "tests" / "oracles").glob("*.py") if p.stem != "__init__")
    assert proc.stdout.split() == modules, proc.stderr[-3000:]
    assert "No module named 'tests'" in proc.stderr  # the oracles came by path, not as tests.oracles
