"""The comb cross-section tables the package ships (netgen.electrostatics.comb_section.SHIPPED):
the three-axis example builds from them on a clean clone without one 2-D solve, exactly the
tables its combs need are shipped, and a shipped value equals a fresh converged solve of the cell
(so a table left over from other settings or another cell cannot pass for this one)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.build import build
from netgen.electrostatics import comb_section
from netgen.structure import load_structure
from tests.fixtures import ROOT


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """examples/accelerometer_xyz.toml built in an empty cache with the solver disabled."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(tmp_path_factory.mktemp("empty")))
        mp.setattr(comb_section, "_TABLES", {})
        mp.setattr(comb_section, "solve", lambda *a, **k: pytest.fail("solved a table the package ships"))
        b = build(load_structure(ROOT / "examples" / "accelerometer_xyz.toml"))
        mp.setattr(comb_section, "_TABLES", {})
    return b


def cells(b) -> set:
    """The distinct cross-section geometries of a build's combs."""
    combs = next(p for _, p in b.prepared.parts if hasattr(p, "geoms"))
    return {comb_section.Geometry.of(g.cell) for g in combs.geoms}


def test_the_example_builds_from_the_shipped_tables_alone(example):
    """Every table of the example is shipped, and nothing else is."""
    want = {f"{kind}-{g.key(kind)}.npz" for g in cells(example) for kind in ("section", "end")}
    assert {p.name for p in comb_section.SHIPPED.glob("*.npz")} == want


def test_a_shipped_value_is_a_fresh_solve(example):
    """The shipped side C' at a node of the table (the nominal gap, the fingers 0.8 um below the
    fixed ones) against one direct solve at the package's settings, within the solve's convergence
    tol (the table holds the solves' values at its nodes; a fresh solve differs by 2.8e-6 on the AMD
    EPYC, more than rounding, so the stated 1e-6 did not hold)."""
    (g,) = cells(example)
    gaps, offsets, _ = comb_section.grids(g)
    i, j = len(gaps) // 2, 2
    with np.load(comb_section.SHIPPED / f"section-{g.key('section')}.npz") as z:
        shipped = float(z["side"][i, j])
    assert offsets[j] == pytest.approx(-0.8e-6, abs=0)
    fresh = comb_section.solve_cell(g, float(gaps[i]), float(offsets[j]))[0]
    assert shipped == pytest.approx(fresh, rel=comb_section.SETTINGS["tol"], abs=0)
