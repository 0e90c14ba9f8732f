"""The adaptive design's fit matches the capacitance and its slopes at rest
(netgen.electrostatics.sampling.rest_of, netgen.fit.capacitance.fit_plates): a loop lives within a
fraction of a nanometre of rest, and its forces there are these slopes. The reference is the
parallel plate in closed form: a square plate of area A over its electrode, fringe off, has
dC/dz = eps A / g^2 at rest and no first-order change with either tilt (by symmetry)."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.build import build
from netgen.core.constants import EPS0
from netgen.electrostatics.sampling import rest_of
from netgen.fit.capacitance import REST_WEIGHT
from netgen.structure import parse_structure
from tests.fit.test_adaptive import GAP, PISTON, SIDE


@pytest.fixture(scope="module")
def adaptive_build():
    return build(parse_structure(PISTON.format(sampling='design = "adaptive"\npoints = 120'), "piston3.toml"))


def test_rest_gradient_is_the_parallel_plate_slope(adaptive_build):
    b = adaptive_build
    rest = rest_of(b.prepared, b.scales)
    slope = EPS0 * SIDE**2 / GAP**2 * b.scales[0]  # per unit of the scaled z
    assert rest.c[0] == pytest.approx(EPS0 * SIDE**2 / GAP, rel=1e-9, abs=0)
    assert abs(rest.grad[0, 0]) == pytest.approx(slope, rel=1e-9, abs=0)
    assert np.all(np.abs(rest.grad[0, 1:]) < 1e-9 * slope)


def test_the_fit_matches_the_rest_slopes(adaptive_build):
    b = adaptive_build
    f = b.fits[0]
    slope = EPS0 * SIDE**2 / GAP**2 * b.scales[0]
    g = f.gradient(np.zeros((1, 3)))[0]
    # the rest is a soft constraint (fit_plates: its residuals weigh REST_WEIGHT^2 times all the
    # samples together), so it holds to the samples' misfit over REST_WEIGHT^2, not exactly
    bound = f.grid_max_rel_error / REST_WEIGHT**2
    assert f.value(np.zeros((1, 3)))[0] == pytest.approx(EPS0 * SIDE**2 / GAP, rel=bound, abs=0)
    assert abs(g[0]) == pytest.approx(slope, rel=bound, abs=0)
    assert np.all(np.abs(g[1:]) < 1e-5 * slope)


@pytest.mark.parametrize("sampling", ["levels = 3", 'design = "sobol"\npoints = 64'])
def test_the_fixed_designs_carry_no_rest_data(sampling):
    """The paper's grid keeps its fits (and the committed netlists) as they were; the fixed
    designs keep their fits to the box."""
    b = build(parse_structure(PISTON.format(sampling=sampling), "piston3.toml"))
    assert b.grid.rest is None
