"""Comb electrodes on the 2-D field solver (comb_model = "field2d", netgen.electrostatics.comb_section):
the lateral comb's dC/dx from the extractor against direct 2-D solves of the finger cell and the
finger end times the finger count, and ngspice's static force against (1/2) V^2 dC/dx of the
Python model. Coarse tables in a private cache (one mesh per solve; bench/comb_textbook.py has
the converged figures)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.build import build
from netgen.electrostatics import comb_section
from netgen.electrostatics.field2d import solve
from netgen.emit import ngspice as emit_ngspice
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from tests.electrostatics.test_comb import LATERAL, K, N
from tests.fixtures import Bench

FIELD = LATERAL.replace('comb_model = "textbook"', 'comb_model = "field2d"')
UM = 1e-6


@pytest.fixture(scope="module")
def lateral(tmp_path_factory):
    """The lateral comb of test_comb built on coarse field2d tables (restored afterwards)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(tmp_path_factory.mktemp("cache")))
        mp.setattr(comb_section, "GRID", {"gaps": 5, "offsets": 4, "ends": 4})
        mp.setattr(comb_section, "SETTINGS", {"tol": 5e-3, "max_levels": 1, "mesh_scale": 1.0, "order": 2})
        mp.setattr(comb_section, "_TABLES", {})
        yield build(parse_structure(FIELD, "comb.toml"))


def test_lateral_dcdx_is_the_finger_count_times_the_2d_solves(lateral):
    """dC/dx at rest = n (2 C'_face + 2 w |dC'_end/de|): the cell's two faces per moving finger (one
    direct solve at the nominal gap) and the two finger ends whose clearance closes (central
    difference of direct end-section solves at e0 -+ 1 um), within 1 %; above the textbook."""
    combs = [p for _, p in lateral.prepared.parts if hasattr(p, "geoms")]
    g = comb_section.Geometry.of(combs[0].geoms[0].cell)
    assert (g.width, g.thickness, g.gap, g.substrate_gap) == (2 * UM, 2 * UM, 2 * UM, float("inf"))
    face = comb_section.solve_cell(g, g.gap, 0.0)[0]
    e0, h = 20 * UM, 1 * UM
    ends = [
        solve(comb_section.end_problem(g, e, 0.0), **comb_section.SETTINGS).mutual("moving", "fixed")
        for e in (e0 - h, e0 + h)
    ]
    expect = N * (2 * face - 2 * g.width * (ends[1] - ends[0]) / (2 * h))
    dcdx = lateral.prepared.gradient(np.zeros(2))[0, 0]
    assert dcdx == pytest.approx(expect, rel=0.01, abs=0)
    assert dcdx > 1.2 * 2 * N * g.eps * g.thickness / g.gap  # fringe at t/g = 1


def test_fitted_force_along_the_fingers_in_ngspice(lateral, tmp_path):
    """The fitted model's dC/dx within 1 % of the extractor's, and ngspice's static deflection under
    V gives k x = (1/2) V^2 dC/dx of the Python model within 0.5 %."""
    model = lateral.model
    assert model.capacitance_gradient(np.zeros((1, 2)))[0, 0, 0] == pytest.approx(
        lateral.prepared.gradient(np.zeros(2))[0, 0], rel=0.01, abs=0
    )
    lib = tmp_path / "comb.lib"
    lib.write_text(emit_ngspice.subcircuit(model))
    v = 25.0
    bench = Bench(model, lib, sources={"drive": f"DC {v}", "plate": "0"})
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    xs = float(plot["x1.xs_x"][0])
    force = 0.5 * v**2 * model.capacitance_gradient(np.array([[xs, 0.0]]))[0, 0, 0]
    assert K * xs * model.coordinates[0].scale == pytest.approx(force, rel=0.005, abs=0)
    assert xs > 1e-3


def test_motion_outside_the_tables_is_a_structure_error_naming_the_electrode(lateral):
    """A finger gap the section table does not span (y closing the 2 um gap to 0.1 um, below the
    table's lower edge of 0.1 gap) is a StructureError naming the file, the electrode and the fix,
    not a ValueError that would exit 70 as an internal error."""
    from netgen.core.errors import StructureError

    combs = [p for _, p in lateral.prepared.parts if hasattr(p, "geoms")]
    with pytest.raises(StructureError) as err:
        combs[0].capacitance(np.array([0.0, 1.9 * UM]))
    text = str(err.value)
    assert "comb.toml" in text and "electrode drive" in text and 'comb_model = "textbook"' in text
