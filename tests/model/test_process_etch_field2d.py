"""The lateral etch bias on accelerometer_xyz's own combs, the 2-D finger cell
(netgen.electrostatics.comb_section: fringe, far gap, out-of-plane offset), against the full
rebuild of the file rewritten at three etch values across the default range
(tests/oracles/process_cases.xyz_text with comb_model "field2d"). The cell's tables at the etched
finger widths ship with the package (netgen/electrostatics/comb_tables), so nothing is solved here.

The law (netgen.model.process.capacitance_laws) reads each comb's fit at the state shifted across
its fingers by the geometric 2 etch plus a fitted effective part (netgen.model.etch_combs: the far
gap and the fringe of the narrower finger), times the ratio pc(etch) and the comb's state factor
1 + u P1(xs) + u^2 P2(xs) (netgen.model.etch_state: what depends on the state beyond the shift).

Tolerances:
- capacitances at 100 points: the nominal fits read at the shifted state times the ratio against
  the rebuild's fits at the same physical displacement; each fit is within its max_rel_error of its
  extractor, the law within its stated capacitance_max_rel_error of the etched extractor: twice the
  larger fit error plus the stated law error (as tests/model/test_process_etch_combs.py).
- the effective shift: the geometric one is the near gap's exact shift; the fitted part is what the
  cell's far gap and fringe add, a fraction of it: between 0 and the geometric 2 etch (the fitted
  part is 0 to round-off for the textbook form, tests/model/test_process_etch_combs.py).
- the contact stops follow the geometric shift (stop_shift: exactly -+2 per metre of etch).
- the law over the drawn extractor against the etched structure's at 300 fresh points: within the
  stated capacitance_max_rel_error, the claim under test (it covers the box's corners).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from netgen.core.errors import ModelError
from netgen.model import MacroModel
from netgen.model.process import capacitance_at, comb_shifts, etched
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import ETCH_PROCESS, PERFORATED_ETCHES, Drawn, fresh_extractor, fresh_points, xyz_text

PROCESS = ETCH_PROCESS


def field2d(text: str) -> str:
    """The structure text with accelerometer_xyz's own comb form (the 2-D cell)."""
    return text.replace('comb_model = "textbook"', 'comb_model = "field2d"')


@pytest.fixture(scope="module")
def nominal():
    return build_model(parse_structure(field2d(xyz_text(process=PROCESS)), "xyz.toml"))


@pytest.fixture(scope="module", params=PERFORATED_ETCHES)
def rebuilt(request):
    return request.param, build_model(parse_structure(field2d(xyz_text(request.param)), "xyz.toml"))


def test_capacitances_against_rebuild(nominal, rebuilt):
    etch, model = rebuilt
    stated = nominal.process["etch"]["capacitance_max_rel_error"]
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, len(nominal.coordinates)))
    got, ref = capacitance_at(nominal, x, etch), model.capacitance(x * nominal.scales / model.scales)
    np.testing.assert_allclose(got, ref, rtol=2 * max(errs) + stated)


def test_effective_shift_and_stops(nominal):
    """Each comb's fitted shift across its fingers lies between 0 and the geometric one, on its side;
    its stops follow the geometric shift exactly."""
    from netgen.structure import parse_structure as parse

    names = [c.name for c in nominal.coordinates]
    geometric = comb_shifts(parse(field2d(xyz_text(process=PROCESS)), "xyz.toml"), names)
    laws = {r["electrode"]: r for r in nominal.process["etch"]["capacitance"]}
    for e, shift in geometric.items():
        assert laws[e]["stop_shift"] == shift
        across = "x" if e.startswith("x") else "y"
        assert 0.0 < laws[e]["shift"][across] / shift[across] < 1.0
        assert laws[e]["shift"][("y" if across == "x" else "x")] == shift[("y" if across == "x" else "x")]


@pytest.fixture(scope="module")
def field(nominal):
    """The drawn structure, its fresh extractor, 300 fresh points of the fit box (seed 11: not the laws'
    check points) and the model's law over the extractor (process_cases.Drawn: no fit error)."""
    s = parse_structure(field2d(xyz_text(process=PROCESS)), "xyz.toml")
    extract = fresh_extractor(s, nominal.scales)
    return s, extract, fresh_points(s.sampling, 300, len(nominal.coordinates), 11), Drawn(nominal, s, extract)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stated_error_bounds_fresh_points(nominal, field, etch):
    """The stated capacitance_max_rel_error (rest, 32 random points and the box's 64 corners at the law's
    etch points: netgen.model.etch_cross.check_sets) bounds the law's error against a fresh field solution
    (the etched structure's extractor) at 300 fresh points (the claim under test; on the 32 random points
    alone it was 8.1e-4 against 9.6e-4 held out)."""
    s, extract, xs, law = field
    got, ref = capacitance_at(law, xs, etch), extract(etched(s, etch), xs)
    ok = np.isfinite(got) & np.isfinite(ref)
    assert np.max(np.abs(got[ok] / ref[ok] - 1.0)) <= nominal.process["etch"]["capacitance_max_rel_error"]


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda s: s["exponents"][0].__setitem__(0, -1), "exponents"),  # not a monomial
        (lambda s: s["exponents"].__setitem__(0, [0] * len(s["exponents"][0])), "exponents"),  # pc's constant
        (lambda s: s["coeffs"].pop(), "coeffs"),  # P2 missing
        (lambda s: s["coeffs"][1].__setitem__(0, "1e-3"), "coeffs[1][0]"),  # text in a netlist's number
    ],
)
def test_state_law_validated_on_load(nominal, edit, key):
    """A comb's state factor (netgen.model.etch_state), which every form writes as monomials, is checked
    on load: a ModelError naming the key, never a netlist with it."""
    d = copy.deepcopy(nominal.to_dict())
    law = next(r for r in d["process"]["etch"]["capacitance"] if "state" in r)
    edit(law["state"])
    with pytest.raises(ModelError) as exc:
        MacroModel.from_dict(d, "xyz.json")
    assert f"state.{key}" in str(exc.value)
