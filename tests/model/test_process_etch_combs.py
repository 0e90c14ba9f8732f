"""The lateral etch bias on comb fingers (netgen.model.process.capacitance_laws: the fits read at the
state shifted by the gap's and the overlap's change, times a ratio) with the mass outline, holes and
crab legs of examples/accelerometer_xyz (textbook comb form, hole pitch 9.98 um:
tests/oracles/process_cases.xyz_text), against the full rebuild of the file rewritten at three etch
values across the default range, and against closed forms.

Tolerances:
- capacitances at 100 points: the nominal fits read at the shifted state times the ratio
  (capacitance_at) against the rebuild's fits at the same physical displacement (the touching
  amplitudes change with the comb gap, so the scaled points differ): each fit is within its
  max_rel_error of its extractor, so the two differ by at most twice the larger fit error plus the
  law's stated capacitance_max_rel_error (its check over the fit box at the range's ends, shifted
  points and all: the shift reads a fit up to 0.13 of the touching amplitude beyond its box).
- a comb's capacitance at rest against the textbook closed form N eps t (L0 - 2 etch) / (g + 2 etch)
  (one face per finger, no tip term): the shift is exact for that form, so within the fit error
  at rest (at most max_rel_error) and the stated law error.
- modal frequencies against the rebuild: half the stated etch error of the mechanics laws or the
  brief's 1e-4, whichever is larger (the crab legs at w = t = 2 um hit the kink of the torsion
  constant's fit, netgen.mechanics.frame.torsion_constant: the stated error is 1.7e-3 there).
- the mass against rho t ((L - 2 etch)^2 - 1600 (h + 2 etch)^2 + 80 (w_f - 2 etch) L_f) (the 80 moving
  fingers, 2 x 40 um, narrowed and as long beyond the receding edge): a quadratic in etch, exact in the
  cubic but for the least squares' round-off, 1e-9.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from netgen.core.constants import EPS0
from netgen.core.errors import ModelError
from netgen.model import MacroModel
from netgen.model.process import capacitance_at, coordinate_values
from netgen.structure import parse_structure
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import ETCH_PROCESS, PERFORATED_ETCHES, xyz_text

PROCESS = ETCH_PROCESS


@pytest.fixture(scope="module")
def nominal():
    return build_model(parse_structure(xyz_text(process=PROCESS), "xyz.toml"))


@pytest.fixture(scope="module", params=PERFORATED_ETCHES)
def rebuilt(request):
    return request.param, build_model(parse_structure(xyz_text(request.param), "xyz.toml"))


def test_capacitances_against_rebuild(nominal, rebuilt):
    etch, model = rebuilt
    stated = nominal.process["etch"]["capacitance_max_rel_error"]
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, len(nominal.coordinates)))
    phys = x * nominal.scales
    got, ref = capacitance_at(nominal, x, etch), model.capacitance(phys / model.scales)
    np.testing.assert_allclose(got, ref, rtol=2 * max(errs) + stated)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_comb_closed_form(nominal, etch):
    """xp_t at rest: 20 fingers, one face each, eps t (30 um - 2 etch) / (1.5 um + 2 etch)."""
    k = [f.electrode for f in nominal.capacitances].index("xp_t")
    got = capacitance_at(nominal, np.zeros((1, len(nominal.coordinates))), etch)[0, k]
    ref = 20 * EPS0 * 2e-6 * (30e-6 - 2 * etch) / (1.5e-6 + 2 * etch)
    tol = nominal.capacitances[k].max_rel_error + nominal.process["etch"]["capacitance_max_rel_error"]
    assert got == pytest.approx(ref, rel=tol, abs=0)


def test_frequencies_and_mass(nominal, rebuilt):
    etch, model = rebuilt
    err = nominal.process["etch"]["max_rel_error"]
    for v, ref in enumerate(model.coordinates):
        m, k, _ = coordinate_values(nominal.process, v, etch=etch)
        assert math.sqrt(k / m) / math.sqrt(ref.stiffness / ref.mass) == pytest.approx(1.0, abs=max(1e-4, err / 2))
    z = [c.name for c in nominal.coordinates].index("z")
    mass = 2330 * 2e-6 * ((400e-6 - 2 * etch) ** 2 - 1600 * (4e-6 + 2 * etch) ** 2 + 80 * (2e-6 - 2 * etch) * 40e-6)
    assert coordinate_values(nominal.process, z, etch=etch)[0] == pytest.approx(mass, rel=1e-9, abs=0)


@pytest.mark.parametrize(
    ("change", "where"),
    [
        ({"electrode": "nope"}, "process.etch.capacitance[0].electrode"),
        ({"ratio": [1.0, 0.0]}, "process.etch.capacitance[0]"),
        ({"shift": {"rot_z": 2.0}}, "process.etch.capacitance[0].shift"),
        ({"shift": {"x": "2"}}, "process.etch.capacitance[0].shift.x"),
    ],
)
def test_bad_capacitance_law_in_json(nominal, change, where):
    """An edited model JSON whose etch law names an unknown electrode or coordinate, or has a short
    ratio or a text shift: a ModelError naming the key (the emitters would write it into the netlist)."""
    d = copy.deepcopy(nominal.to_dict())  # to_dict shares the model's process record
    d["process"]["etch"]["capacitance"][0].update(change)
    with pytest.raises(ModelError) as exc:
        MacroModel.from_dict(d, "xyz.json")
    assert where in str(exc.value)
