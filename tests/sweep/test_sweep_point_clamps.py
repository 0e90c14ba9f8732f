"""A sweep's process-point model (netgen.sweep.point.at_point) clamps its plate terms where the
emitted forms do: at the knee and floor of the NOMINAL term at rest. The forms take a gap offset dg
as a shift of the polynomial's argument, P(xs_z - sign dg / L_z), with the clamp's constants from
the nominal fit; the point model re-expands the shifted polynomial, whose own P(0) is another
number (0.9 of the nominal at dg = -0.2 um on examples/piston_process.toml), so a clamp read from
it would start elsewhere: 11 % off in C past the knee."""

from __future__ import annotations

import json

import numpy as np
import pytest

from netgen.model import MacroModel
from netgen.sweep.point import at_point
from tests.fixtures import ROOT

EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def piston() -> MacroModel:
    path = ROOT / "netlists" / "piston_process" / "piston_process.json"
    return MacroModel.from_dict(json.loads(path.read_text()), str(path))


@pytest.mark.parametrize("dg", [-0.2e-6, 0.2e-6])
def test_point_model_clamps_at_the_nominal_rest_term(piston, dg):
    """C of the point model at xs equals the nominal model's at the shifted argument xs + delta, from
    rest through the knee into the floor. Tolerance (derived): the re-expanded polynomial differs
    from the shifted one by rounding, at most 4 eps sum_k |c_k| (|xs| + |delta|)^k (the binomial
    sums, degree <= 1 here: a few operations each), relative to the smallest unclamped term P the
    scan reaches, the clamp's floor times P(0)."""
    gap = piston.process["gaps"][0]
    z = [c.name for c in piston.coordinates].index("z")
    delta = -gap["sign"] * dg / piston.coordinates[z].scale
    point = at_point(piston, {f"dg_{gap['set']}": dg})
    assert point.term_clamps() == piston.term_clamps()

    xs = np.zeros((41, piston.ncoords))
    xs[:, z] = np.linspace(0.0, -1.2, 41)  # rest, the knee (P = 0.05 P(0)) and past it
    shifted = xs.copy()
    shifted[:, z] += delta
    p0 = [p for f in piston.capacitances for p in f.polys]
    reach = max(float(np.sum(np.abs(p.coeffs))) for p in p0) * (1.2 + abs(delta))
    tol = 4 * EPS * reach / piston.contact["floor"]
    got, want = point.capacitance(xs), piston.capacitance(shifted)
    assert np.max(np.abs(got / want - 1)) <= tol
    knee = piston.term_clamps()[0][0][0]
    assert np.min(p0[0](shifted)) < knee  # the scan does pass the knee
