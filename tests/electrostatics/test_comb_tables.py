"""The comb cross-section tables the package ships (netgen.electrostatics.comb_section.SHIPPED):
the three-axis example builds from them on a clean clone without one 2-D solve, exactly the
tables its combs need (and its combs' at the etched widths of its etch law, at the thicknesses of its
tscale law and at the suite's rebuilds) are shipped, and a shipped value equals a fresh converged solve of the cell
(so a table left over from other settings or another cell cannot pass for this one)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.build import build
from netgen.core.constants import EPS0
from netgen.electrostatics import comb_section
from netgen.electrostatics.comb import CombCell
from netgen.geometry.layout import electrodes
from netgen.model.process import etch_points, etched, fit_points, scaled
from netgen.structure import load_structure, parse_structure
from netgen.structure.schema import Process
from tests.fixtures import ROOT
from tests.oracles.process_cases import (
    CROSS_CORNERS,
    CROSS_INSIDE,
    CROSS_PROCESS,
    CROSS_REBUILDS,
    PERFORATED_ETCHES,
    field2d_text,
    xyz_text,
)


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


def etched_cells() -> set:
    """The cells of accelerometer_xyz's combs at the etched finger widths its etch law and the suite's
    rebuilds read (tests/model/test_process_etch_field2d.py, netgen.model.etch_combs) and at the finger
    thicknesses of its tscale law over the default tscale_range (netgen.model.process.thickness_capacitance;
    the rebuilds at 0.9 and 1.1 of tests/model/test_process_tscale_combs.py are two of them), and those
    of the (tscale, etch) cross factor (tests/model/test_process_cross_field2d.py)."""
    text = xyz_text(process='[process]\nparameters = ["etch"]\n').replace('"textbook"', '"field2d"')
    s = parse_structure(text, "xyz.toml")
    structures = [etched(s, e) for e in etch_points(s.process) if e] + [
        parse_structure(xyz_text(e).replace('"textbook"', '"field2d"'), "xyz.toml") for e in PERFORATED_ETCHES
    ]
    structures += [scaled(s, t) for t in fit_points(Process(("tscale",))) if t != 1.0]  # the tscale law's
    cross = parse_structure(field2d_text(process=CROSS_PROCESS), "xyz.toml")  # the cross factor's corners and
    structures += [etched(scaled(cross, t), e) for t, e in CROSS_CORNERS + CROSS_INSIDE]  # held-out points,
    structures += [parse_structure(field2d_text(t, e), "xyz.toml") for t, e in CROSS_REBUILDS]  # its rebuilds
    eps = EPS0 * s.electrostatics.relative_permittivity
    out = set()
    for st in structures:
        for e in electrodes(st):
            c = e.shape
            if hasattr(c, "pitch"):  # a comb (netgen.electrostatics.comb.geometry's cell)
                out.add(comb_section.Geometry.of(CombCell(c.width, c.thickness, c.pitch / 2, c.substrate_gap, eps)))
    return out


def test_the_example_builds_from_the_shipped_tables_alone(example):
    """Every table of the example and of its etched combs is shipped, and nothing else is."""
    want = {f"{kind}-{g.key(kind)}.npz" for g in cells(example) | etched_cells() for kind in ("section", "end")}
    assert {p.name for p in comb_section.SHIPPED.glob("*.npz")} == want


def test_a_shipped_value_is_a_fresh_solve(example):
    """Shipped side C' at nodes of the table (the fingers 0.8 um below the fixed ones) against direct
    solves at the package's settings: a gap g below the nominal g0 is the right half of the solve at
    g and its mirror 2 g0 - g the left half of the same solve; the nominal gap (its own mirror) is
    the mean of the two halves, half the cell's mutual C' (comb_section.section_values; before
    VERSION 3 the left half, 2.8e-6 off the right one, overwrote it there). To 1e-9: the solve is a
    deterministic mesh and a direct sparse solve, whose charges carry about cond * eps ~ 1e6 * 2e-16
    of rounding on another CPU, well under the 2.8e-6 left-right split this separates."""
    (g,) = cells(example)
    gaps, offsets, _ = comb_section.grids(g)
    n, j = len(gaps), 2
    with np.load(comb_section.SHIPPED / f"section-{g.key('section')}.npz") as z:
        shipped = z["side"][:, j]
    assert offsets[j] == pytest.approx(-0.8e-6, abs=0)
    right, left, _ = comb_section.solve_cell(g, float(gaps[n // 2]), float(offsets[j]))
    assert abs(right / left - 1) > 1e-6  # the halves differ: the mean is what the node must hold
    assert shipped[n // 2] == pytest.approx((right + left) / 2, rel=1e-9, abs=0)
    right, left, _ = comb_section.solve_cell(g, float(gaps[3]), float(offsets[j]))
    assert [shipped[3], shipped[n - 4]] == pytest.approx([right, left], rel=1e-9, abs=0)
