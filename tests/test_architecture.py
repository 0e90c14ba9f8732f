"""The house, read from the package's own AST: data flows one way through the layers.

- core (netgen/core: constants, errors, units, text, files, the TOML reader, templating, plots,
  options, the external-tool runner) imports nothing else of netgen;
- runtime (netgen/runtime: arguments, interrupts, folders, executor) imports only core;
- the command line (netgen/cli: the console entry and its subcommands) sits on top and may import
  every stage;
- no stage imports a later stage; only the runtime and the command line import argparse;
- no import circle between rooms, and no private name (`_x`) is imported from, or read as an
  attribute of, another package.
The checker is tested on synthetic module sets first, so these tests can fail.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.fixtures import ROOT

PACKAGE = ROOT / "netgen"
# the layers below the stages, in order: core imports only itself, runtime imports core
BASE = ("__init__", "core", "runtime")
BASE_IMPORTS = {"__init__": set(), "core": set(), "runtime": {"core", "__init__"}}
# the pipeline's order: a stage may import the base layers, itself and the stages before it; the
# command line (netgen/cli) comes last
STAGES = (
    "structure",
    "geometry",
    "mechanics",
    "electrostatics",
    "fit",
    "model",
    "build",
    "export",
    "emit",
    "sim",
    "testbench",
    "sweep",
    "cli",
)


def room(module: str) -> str:
    """The layer or stage a dotted netgen module belongs to: netgen.a.b -> a."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def module_name(path: Path, root: Path) -> str:
    """Dotted module name of a file under the package folder `root` (named like the package)."""
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(tree: ast.AST, module: str, is_package: bool) -> list[tuple[str, list[str], int]]:
    """(imported module, names taken from it, line) of every import in one module's AST, relative
    imports resolved; `from pkg import sub` lists pkg with the name sub."""
    base = module.split(".") if is_package else module.split(".")[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, [], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                target = ".".join(base[: len(base) - node.level + 1] + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.append((target, [a.name for a in node.names], node.lineno))
    return out


def private_attributes(tree: ast.AST, aliases: dict[str, str]) -> list[tuple[str, str, int]]:
    """(module, private attribute, line) where a name bound to an imported netgen module is read
    with a leading underscore, e.g. `modes_module._field`."""
    return [
        (aliases[n.value.id], n.attr, n.lineno)
        for n in ast.walk(tree)
        if isinstance(n, ast.Attribute)
        and isinstance(n.value, ast.Name)
        and n.value.id in aliases
        and n.attr.startswith("_")
        and not n.attr.startswith("__")
    ]


def read_package(root: Path) -> dict[str, tuple[ast.AST, bool]]:
    """module name -> (AST, is a package __init__) of every .py file under `root`."""
    return {
        module_name(p, root): (ast.parse(p.read_text(encoding="utf-8"), str(p)), p.name == "__init__.py")
        for p in sorted(root.rglob("*.py"))
    }


def problems(modules: dict[str, tuple[ast.AST, bool]], top: str = "netgen") -> dict[str, list[str]]:
    """The three kinds of problem in a set of modules (see the module docstring)."""
    edges: dict[str, set[str]] = {}
    found: dict[str, list[str]] = {"circles": [], "upward": [], "private": []}
    known = set(modules)
    for name, (tree, is_package) in modules.items():
        here = room(name)
        aliases = {}
        for target, names, line in imports(tree, name, is_package):
            if not (target == top or target.startswith(top + ".")):
                continue
            submodules = [f"{target}.{n}" for n in names if f"{target}.{n}" in known]
            for t in [target] + submodules:
                there = room(t)
                if there != here:
                    edges.setdefault(here, set()).add(there)
                    if not allowed(here, there):
                        found["upward"].append(f"{name}:{line} imports {t} ({here} -> {there})")
            for n in names:
                if f"{target}.{n}" in known:
                    aliases[n] = f"{target}.{n}"
                elif n.startswith("_") and not n.startswith("__") and room(target) != here:
                    found["private"].append(f"{name}:{line} imports {n} from {target}")
        for mod, attr, line in private_attributes(tree, aliases):
            if room(mod) != here:
                found["private"].append(f"{name}:{line} reads {mod}.{attr}")
    found["circles"] = [" -> ".join(c) for c in cycles(edges)]
    return found


def allowed(here: str, there: str) -> bool:
    """May room `here` import room `there`?"""
    if here in BASE:
        return there in BASE_IMPORTS[here]
    if there in BASE:
        return True
    if there not in STAGES or here not in STAGES:
        return False
    return STAGES.index(there) < STAGES.index(here)


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of a room graph (one per strongly connected set, as a closed path)."""
    out, state = [], {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = "open"
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == "open":
                out.append(path[path.index(nxt) :] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for start in sorted(edges):
        if start not in state:
            visit(start, [start])
    return out


def synthetic(tmp_path: Path, files: dict[str, str]) -> dict[str, tuple[ast.AST, bool]]:
    """A throwaway package named netgen with the given files (path -> source)."""
    root = tmp_path / "netgen"
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return read_package(root)


# ----------------------------------------------------------------------------- the checker can fail


def test_checker_finds_a_circle_between_subpackages(tmp_path):
    mods = synthetic(
        tmp_path,
        {
            "__init__.py": "",
            "structure/__init__.py": "from ..geometry import shapes\n",
            "geometry/__init__.py": "",
            "geometry/shapes.py": "from ..structure import x\n",
        },
    )
    found = problems(mods)
    assert found["circles"] == ["geometry -> structure -> geometry"]
    assert found["upward"] == [
        "netgen.structure:1 imports netgen.geometry (structure -> geometry)",
        "netgen.structure:1 imports netgen.geometry.shapes (structure -> geometry)",
    ]


def test_checker_finds_private_names_across_packages(tmp_path):
    mods = synthetic(
        tmp_path,
        {
            "__init__.py": "",
            "mechanics/__init__.py": "",
            "mechanics/fields.py": "_P2 = 1\n",
            "mechanics/free_disk.py": "from .fields import _P2\n",  # same package: fine
            "build.py": "from .mechanics.fields import _P2\nfrom .mechanics import fields\nfields._P2\n",
        },
    )
    found = problems(mods)
    assert found["private"] == [
        "netgen.build:1 imports _P2 from netgen.mechanics.fields",
        "netgen.build:3 reads netgen.mechanics.fields._P2",
    ]
    assert not found["circles"] and not found["upward"]


def test_checker_finds_an_import_of_a_later_stage_and_a_shared_module_importing_a_stage(tmp_path):
    mods = synthetic(
        tmp_path,
        {
            "__init__.py": "",
            "fit/__init__.py": "from ..emit import x\n",
            "emit/__init__.py": "",
            "core/__init__.py": "",
            "core/files.py": "from ..model import m\n",
            "model/__init__.py": "",
        },
    )
    assert sorted(problems(mods)["upward"]) == [
        "netgen.core.files:1 imports netgen.model (core -> model)",
        "netgen.fit:1 imports netgen.emit (fit -> emit)",
    ]


# ----------------------------------------------------------------------------- the house itself


@pytest.fixture(scope="module")
def house() -> dict[str, list[str]]:
    return problems(read_package(PACKAGE))


def test_every_room_is_a_stage_or_a_base_layer():
    rooms = {room(m) for m in read_package(PACKAGE)}
    assert rooms <= set(STAGES) | set(BASE), sorted(rooms - set(STAGES) - set(BASE))


def test_the_root_holds_only_the_pipeline():
    """Beside the subpackages the root holds __init__, build (the stage order) and export."""
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "build.py", "export.py"]


def test_core_imports_nothing_else_of_netgen(house):
    assert [u for u in house["upward"] if "(core ->" in u] == []


def test_only_the_runtime_and_the_command_line_import_argparse():
    users = [
        name
        for name, (tree, _) in read_package(PACKAGE).items()
        for target, _, _ in imports(tree, name, False)
        if target == "argparse" and not name.startswith(("netgen.runtime.", "netgen.cli"))
    ]
    assert users == []


def test_no_import_circles(house):
    assert house["circles"] == []


def test_no_stage_imports_a_later_stage(house):
    assert house["upward"] == []


def test_no_private_names_across_packages(house):
    assert house["private"] == []


def test_no_module_is_over_600_lines():
    long = {
        str(p.relative_to(ROOT)): n
        for p in PACKAGE.rglob("*.py")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > 600
    }
    assert long == {}
