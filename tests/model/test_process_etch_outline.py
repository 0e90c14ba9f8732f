"""The lateral etch bias on the proof mass's outline and etch holes (netgen.model.process.etched): the
perforated mass of examples/accelerometer_xyz on crab legs between its z plates
(tests/oracles/process_cases.perforated) against the full rebuild of the file rewritten at three etch
values across the default range (side 405 - 2 etch, hole 4 + 2 etch, beams 3 - 2 etch, in um), and
against closed forms of the etched mass and inertia.

Tolerances:
- mass and inertia: m = rho t ((L - 2e)^2 - N (h + 2e)^2) and the second moments are polynomials of
  degree 2 and 4 in e whose cubic fit over five points is exact but for the least squares' round-off
  (Vandermonde of etch / 1 um over +-0.1 um, condition near 1e4, times 1e-16): 1e-9 for the mass; the
  fourth-degree inertia misses its cubic by the quartic's share, (2 e)^4 / L^4 < 1e-14, so also 1e-9.
- modal frequencies f ~ sqrt(k / m): the laws carry the stated etch error (the cubics' largest
  residual at the re-run points, a relative error of k or m), so f is off by at most half of it; held
  to the brief's 1e-4 or that, whichever is larger (as tests/model/test_process_etch.py).
- capacitances: the nominal fits times each electrode's etch ratio (a cubic from the extractor at
  rest, checked against the extractor over the box at the range's ends: the stated
  capacitance_max_rel_error, the fill factor's gap dependence) against the rebuild's fits: each fit
  is within its max_rel_error of its extractor, so the two differ by at most the sum of the two fit
  errors (bounded by twice the larger) plus the stated ratio error (between the range's ends the
  ratio's cubic interpolates a smooth fill factor: its error there is below the ends').
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.model.process import capacitance_at, coordinate_values
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import PERFORATED_ETCHES, PERFORATED_RANGE, perforated

RHO, T = 2330.0, 2e-6


@pytest.fixture(scope="module")
def nominal():
    return build_model(parse_structure(perforated(process=PERFORATED_RANGE), "px.toml"))


@pytest.fixture(scope="module", params=PERFORATED_ETCHES)
def rebuilt(request):
    return request.param, build_model(parse_structure(perforated(request.param), "px.toml"))


def etched_inertia(etch: float) -> tuple[float, float]:
    """(mass, tilt_x moment of inertia) of the etched perforated square, hole by hole."""
    side, hole, n = 405e-6 - 2 * etch, 4e-6 + 2 * etch, 40
    centres = (np.arange(n) - (n - 1) / 2) * 10e-6
    area = side**2 - n * n * hole**2
    iy = side**4 / 12 - n * sum(hole**2 * y**2 + hole**4 / 12 for y in centres)
    mass = RHO * T * area
    return mass, RHO * T * iy + mass * T**2 / 12


def test_mass_and_inertia_closed_form(nominal, rebuilt):
    """The laws' mass (z) and tilt_x inertia against the closed forms at the etched sizes, and the
    rebuild's against the same."""
    etch, model = rebuilt
    mass, inertia = etched_inertia(etch)
    names = [c.name for c in nominal.coordinates]
    z, tx = names.index("z"), names.index("tilt_x")
    assert coordinate_values(nominal.process, z, etch=etch)[0] == pytest.approx(mass, rel=1e-9, abs=0)
    assert coordinate_values(nominal.process, tx, etch=etch)[0] == pytest.approx(inertia, rel=1e-9, abs=0)
    assert model.coordinates[z].mass == pytest.approx(mass, rel=1e-9, abs=0)
    assert model.coordinates[tx].mass == pytest.approx(inertia, rel=1e-9, abs=0)


def test_frequencies_against_rebuild(nominal, rebuilt):
    """Every modal frequency from the laws against the rebuild's."""
    etch, model = rebuilt
    err = nominal.process["etch"]["max_rel_error"]
    for v, ref in enumerate(model.coordinates):
        m, k, _ = coordinate_values(nominal.process, v, etch=etch)
        assert math.sqrt(k / m) / math.sqrt(ref.stiffness / ref.mass) == pytest.approx(1.0, abs=max(1e-4, err / 2))


def test_capacitances_against_rebuild(nominal, rebuilt):
    """C at 100 points of the fit box: the nominal model times the etch ratio (capacitance_at) against
    the rebuild, within the ratio's stated error plus the two models' fit errors."""
    etch, model = rebuilt
    stated = nominal.process["etch"]["capacitance_max_rel_error"]
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    assert [c.scale for c in model.coordinates] == pytest.approx(
        [c.scale for c in nominal.coordinates], rel=1e-12, abs=0
    )
    q = np.random.default_rng(11).uniform(-0.2, 0.2, (100, len(nominal.coordinates)))
    got, ref = capacitance_at(nominal, q, etch), model.capacitance(q)
    np.testing.assert_allclose(got, ref, rtol=2 * max(errs) + stated)
