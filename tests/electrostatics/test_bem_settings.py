"""BEM settings from the structure file's [electrostatics.bem] table (netgen.structure.bem_table,
netgen.electrostatics.bem.settings_of): the values written reach the solver and are recorded in
every sample; bad keys exit 2 naming the file, the line, the key and the fix."""

from __future__ import annotations

import contextlib
import importlib.util
import io

import numpy as np
import pytest

from netgen.cli.commands import main
from netgen.electrostatics import bem
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure import parse_structure
from tests.fixtures import SMALL_BEM_DISK

DISK = SMALL_BEM_DISK
SETTINGS = """[electrostatics.bem]
element_to_gap = 2.0
edge_to_gap = 1.0
element_to_size = 0.5
max_levels = 2
tolerance = 1.0
quadrature_order = 12
singular_order = 5
refinement = 1.5
memory_budget_gb = 0.5
"""


def structure(extra: str = SETTINGS, extractor: str = "bem"):
    """The small disk with an [electrostatics] extra (the [electrostatics.bem] table by default)."""
    return parse_structure(DISK.format(extractor=extractor, extra=extra), "small_bem.toml")


def test_table_values_reach_the_settings():
    """Every key written is the BemSettings field (memory in bytes); absent keys keep the defaults."""
    st = bem.settings_of(structure())
    want = {
        "element_to_gap": 2.0,
        "edge_to_gap": 1.0,
        "element_to_size": 0.5,
        "max_levels": 2,
        "tolerance": 1.0,
        "quadrature_order": 12,
        "singular_order": 5,
        "refinement": 1.5,
        "memory_budget": 0.5e9,
    }
    for key, value in want.items():
        assert getattr(st, key) == value, key
    assert st.levels == bem.BemSettings().levels and st.growth == bem.BemSettings().growth
    assert bem.settings_of(structure("")) == bem.BemSettings()


@pytest.mark.skipif(importlib.util.find_spec("bempp_cl") is None, reason="needs bempp-cl")
def test_settings_are_used_and_recorded_in_the_samples():
    """A solve on the file's settings: the quadrature order written (12, where the rule gives 4 for
    elements of 2 gaps) is the one used, and the sample records every setting."""
    from netgen.electrostatics.bem_sampling import sample_maxwell

    s = structure()
    m, plate = mechanics(s), plate_outline(s)
    prepared = bem.from_structure(s, plate).prepare(electrodes(s), plate, m.basis)
    samples = sample_maxwell(prepared, np.zeros((1, len(m.names))))
    assert samples.order.tolist() == [12]
    for key in ("element_to_gap", "edge_to_gap", "quadrature_order", "singular_order", "memory_budget", "tolerance"):
        assert samples.settings[key] == getattr(prepared.settings, key), key
    solve = prepared.maxwell(np.zeros(len(m.names)))
    assert [x["order"] for x in solve.settings["solves"]] == [12, 12]
    assert solve.settings["refinement"] == 1.5 and solve.settings["singular_order"] == 5
    assert "quadrature 12/5" in bem.from_structure(s, plate).description


def build(tmp_path, text: str) -> tuple[int, str]:
    """`netgen build` of text in tmp_path: exit code and stderr."""
    (tmp_path / "small_bem.toml").write_text(text)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.chdir(tmp_path):
        code = main(["build", "small_bem.toml", "-o", "out", "-q"])
    return code, err.getvalue()


BAD = {
    "unknown key": (
        "[electrostatics.bem]\ntolerence = 0.01\n",
        "bem",
        "electrostatics.bem.tolerence",
        "did you mean 'tolerance'",
    ),
    "not a number": (
        '[electrostatics.bem]\ntolerance = "small"\n',
        "bem",
        "electrostatics.bem.tolerance",
        "not a number in (0, 1]",
    ),
    "levels not integer": (
        "[electrostatics.bem]\nlevels = 2.5\n",
        "bem",
        "electrostatics.bem.levels",
        "not an integer in 2..6",
    ),
    "growth 1": ("[electrostatics.bem]\ngrowth = 1.0\n", "bem", "electrostatics.bem.growth", "number above 1"),
    "max below levels": (
        "[electrostatics.bem]\nlevels = 3\nmax_levels = 2\n",
        "bem",
        "electrostatics.bem.max_levels",
        "make max_levels at least levels",
    ),
    "no BEM solve": (
        "[electrostatics.bem]\ntolerance = 0.01\n",
        "parallel_plate",
        "electrostatics.bem",
        "drop [electrostatics.bem]",
    ),
    "beyond quadrature": (
        "[electrostatics.bem]\nelement_to_gap = 12.0\n",
        "bem",
        "electrostatics.bem.element_to_gap",
        "element_to_gap = 8 or less",
    ),
    "quadrature too low": (
        "[electrostatics.bem]\nelement_to_gap = 4.0\nquadrature_order = 4\n",
        "bem",
        "electrostatics.bem.quadrature_order",
        "quadrature_order = 8 or more",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_bem_tables_exit_2(tmp_path, case):
    """Each bad table: exit 2, the file, the key and its fix; a line where the parser knows it; no output."""
    extra, extractor, key, fix = BAD[case]
    text = DISK.format(extractor=extractor, extra=extra)
    code, err = build(tmp_path, text)
    assert code == 2, err
    assert "small_bem.toml" in err and key in err and fix in err and "fix:" in err, err
    assert "Traceback" not in err and not (tmp_path / "out").exists()
    if case not in ("beyond quadrature", "quadrature too low"):  # the parser's own errors have the line
        line = next(
            i
            for i, t in enumerate(text.splitlines(), 1)
            if t.startswith(key.split(".")[-1] + " =")
            or t.startswith("[electrostatics.bem]")
            and key == "electrostatics.bem"
        )
        assert f"small_bem.toml:{line}:" in err, err
