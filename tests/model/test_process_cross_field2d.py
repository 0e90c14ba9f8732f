"""tscale and etch together on accelerometer_xyz's own field2d combs (netgen.model.etch_cross.cross_capacitance):
each comb's C is the etch law (its fit read at the etch-shifted state, times pc_e(etch) and the etch state
factor) times the tscale law (pc_t(tscale) and the tscale state factor), each fitted with the other
parameter nominal, times the cross factor 1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs)), u = etch / 1 um
(netgen.model.etch_state.cross_laws), fitted at the four corners of the (tscale, etch) box for what the
product misses (the finger's fringe share moves with its width and thickness together: the plain
product is 4.3e-3 off at (0.9, -0.1 um) and (1.1, -0.1 um), bench/process_cross.py). The 2-D section
tables of the cross cells (the corners, and the points inside the box used here) ship with the package
(netgen/electrostatics/comb_tables), so nothing is solved here.

Tolerances:
- the law against the field solution (the extractor of the structure scaled and etched there; the
  law reads the drawn structure's extractor instead of the fits, tests/oracles/process_cases.Drawn, so
  no fit error enters) at 200 fresh points of the fit box (seed 11, not the laws' check points) at the
  box's corners and at two points inside it (held out of the cross fit, which has only the corners):
  within the stated capacitance_max_rel_error of the etch record, the claim under test (it covers the
  corners' check points and the box's corners).
- capacitances at 100 points against full rebuilds at a corner and inside: twice the larger fit error
  plus the stated law error (tests/model/test_process_etch_field2d.py).
- a sweep's model at the point (netgen.sweep.point.at_point) against capacitance_at: the same products
  in another order, 1e-12.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from netgen.core.errors import ModelError
from netgen.model import MacroModel
from netgen.model.process import capacitance_at, etched, scaled
from netgen.structure import parse_structure
from netgen.sweep.point import at_point
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import (
    CROSS_CORNERS,
    CROSS_INSIDE,
    CROSS_PROCESS,
    CROSS_REBUILDS,
    Drawn,
    field2d_text,
    fresh_extractor,
    fresh_points,
)

CORNERS, INSIDE, PROCESS = CROSS_CORNERS, CROSS_INSIDE, CROSS_PROCESS
text = field2d_text


@pytest.fixture(scope="module")
def drawn():
    return parse_structure(text(process=PROCESS), "xyz.toml")


@pytest.fixture(scope="module")
def nominal(drawn):
    return build_model(drawn)


@pytest.fixture(scope="module")
def field(drawn, nominal):
    """The field solution at fresh points: (structure -> capacitances, the points, the law over it)."""
    extract = fresh_extractor(drawn, nominal.scales)
    return extract, fresh_points(drawn.sampling, 200, len(nominal.coordinates), 11), Drawn(nominal, drawn, extract)


def test_every_comb_has_a_cross_factor(nominal):
    """The case exercises the cross factor: every comb has one (the plain product misfits past the
    state laws' FLOOR at the corners), and the stated error with it is below the plain product's."""
    e = nominal.process["etch"]
    assert all("cross" in r for r in e["capacitance"] if r["electrode"][0] in "xy")
    assert e["capacitance_cross_max_rel_error"] < e["capacitance_product_max_rel_error"]
    assert e["capacitance_max_rel_error"] >= e["capacitance_cross_max_rel_error"]


@pytest.mark.parametrize(("tscale", "etch"), CORNERS + INSIDE)
def test_law_against_field_solution(drawn, nominal, field, tscale, etch):
    """The law (the fits replaced by the drawn extractor) against the extractor of the structure scaled
    and etched at the point, at 200 fresh points: within the stated error (module docstring)."""
    extract, xs, law = field
    got = capacitance_at(law, xs, etch=etch, tscale=tscale)
    ref = extract(etched(scaled(drawn, tscale), etch), xs)
    ok = np.isfinite(got) & np.isfinite(ref)  # a touching point: nan in both
    assert np.max(np.abs(got[ok] / ref[ok] - 1.0)) <= nominal.process["etch"]["capacitance_max_rel_error"]


@pytest.fixture(scope="module", params=CROSS_REBUILDS)
def rebuilt(request):
    tscale, etch = request.param
    return request.param, build_model(parse_structure(text(tscale, etch), "xyz.toml"))


def test_capacitances_against_rebuild(nominal, rebuilt):
    """100 points against the rebuild's fits at the same physical displacement (module docstring)."""
    (tscale, etch), model = rebuilt
    stated = nominal.process["etch"]["capacitance_max_rel_error"]
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, len(nominal.coordinates)))
    got = capacitance_at(nominal, x, etch=etch, tscale=tscale)
    np.testing.assert_allclose(got, model.capacitance(x * nominal.scales / model.scales), rtol=2 * max(errs) + stated)


def test_sweep_point_model(nominal):
    """netgen.sweep.point.at_point carries the cross factor as capacitance_at does (1e-12)."""
    x = np.random.default_rng(6).uniform(-0.15, 0.15, (20, len(nominal.coordinates)))
    point = {"tscale": 0.9, "etch": -1e-7}
    got = at_point(nominal, point).capacitance(x)
    np.testing.assert_allclose(got, capacitance_at(nominal, x, **point), rtol=1e-12, atol=0)


def test_cross_law_validated_on_load(nominal):
    """A comb's cross factor, which every form writes as monomials, is checked on load like a state
    factor (netgen.model.validate.check_state_law), its constant row allowed: a ModelError naming the
    key for a bad entry, never a netlist with it."""
    d = copy.deepcopy(nominal.to_dict())
    law = next(r for r in d["process"]["etch"]["capacitance"] if "cross" in r)
    assert sum(law["cross"]["exponents"][0]) == 0  # Q1, Q2 keep their constant
    MacroModel.from_dict(copy.deepcopy(d), "xyz.json")
    law["cross"]["coeffs"][1][0] = "1e-3"
    with pytest.raises(ModelError) as exc:
        MacroModel.from_dict(d, "xyz.json")
    assert "cross.coeffs[1][0]" in str(exc.value)
