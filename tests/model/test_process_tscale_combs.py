"""tscale on a proof mass with textbook comb fingers (netgen.model.process.thickness_capacitance: each
electrode's capacitance times a cubic in tscale) with the perforated mass, crab legs and z plates of
examples/accelerometer_xyz (textbook comb form: tests/oracles/process_cases.xyz_thick), against full
rebuilds of the file rewritten at 0.9, 1.0 and 1.1 times the 2 um layer, and against the closed form.

Tolerances:
- capacitances at 100 points: the nominal fits times the ratio (capacitance_at) against the
  rebuild's fits at the same physical displacement: each fit is within its max_rel_error of its
  extractor and the law within its stated capacitance_max_rel_error of the extractor at the range's
  ends (over the fit box; the ratio exact at 1), so the two differ by at most twice the larger fit
  error plus the stated law error.
- a comb's capacitance at rest against the textbook form 20 eps (2 um tscale) 30 um / 1.5 um (one face
  per finger): the model's fit at rest is within its max_rel_error of the extractor, which is that
  form; the ratio's error adds the stated law error (0 for combs: eps t / g is linear in t).
- the in-plane (comb) modes x, y, rot_z against the rebuild within the brief's 1e-4: in-plane
  bending and stretching of the legs ~ t, the rigid mass and inertia about z ~ t, so their laws are
  power laws (the cubic's round-off). The out-of-plane modes (z, tilts: the legs' torsion, w = t at
  the kink of netgen.mechanics.frame.torsion_constant) within half the stated tscale error.

The same example with its own field2d combs (the `field2d` tests; the 2-D section tables at the five
thicknesses ship): the 100 points within the same bound (the stated error is then the ratio's spread
over the fit box, the fringe's share moving with the gap and the out-of-plane offset, that the combs'
state factor carries), the modes as above. And the perforated plates' law against the fill factor's closed form at rest (fringe none), a
bound far under the plates' change (test_plate_law_is_the_hole_walls).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.core.constants import EPS0
from netgen.electrostatics.perforation import PERFORATION_LN_A, PERFORATION_STRENGTH, PERFORATION_WALL_SHARE
from netgen.model.process import capacitance_at, coordinate_values, scaled
from netgen.structure import parse_structure
from netgen.sweep.point import at_point
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import TSCALES, Drawn, fresh_extractor, fresh_points, xyz_mass, xyz_thick

PROCESS = '\n[process]\nparameters = ["tscale"]\n'
IN_PLANE = ("x", "y", "rot_z")


@pytest.fixture(scope="module")
def nominal():
    return build_model(parse_structure(xyz_thick(process=PROCESS), "xyz.toml"))


@pytest.fixture(scope="module", params=TSCALES)
def rebuilt(request):
    return request.param, build_model(parse_structure(xyz_thick(request.param), "xyz.toml"))


def test_capacitances_against_rebuild(nominal, rebuilt):
    tscale, model = rebuilt
    stated = nominal.process["tscale"]["capacitance_max_rel_error"]
    errs = [f.max_rel_error for f in nominal.capacitances + model.capacitances]
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, len(nominal.coordinates)))
    got, ref = capacitance_at(nominal, x, tscale=tscale), model.capacitance(x * nominal.scales / model.scales)
    np.testing.assert_allclose(got, ref, rtol=2 * max(errs) + stated)


@pytest.mark.parametrize("tscale", TSCALES)
def test_comb_closed_form(nominal, tscale):
    """xp_t at rest: 20 fingers, one face each, eps (2 um tscale) 30 um / 1.5 um."""
    k = [f.electrode for f in nominal.capacitances].index("xp_t")
    got = capacitance_at(nominal, np.zeros((1, len(nominal.coordinates))), tscale=tscale)[0, k]
    ref = 20 * EPS0 * 2e-6 * tscale * 30e-6 / 1.5e-6
    tol = nominal.capacitances[k].max_rel_error + nominal.process["tscale"]["capacitance_max_rel_error"]
    assert got == pytest.approx(ref, rel=tol, abs=0)


def test_frequencies(nominal, rebuilt):
    tscale, model = rebuilt
    err = nominal.process["tscale"]["max_rel_error"]
    for v, ref in enumerate(model.coordinates):
        m, k, _ = coordinate_values(nominal.process, v, tscale=tscale)
        bound = 1e-4 if ref.name in IN_PLANE else max(1e-4, err / 2)
        assert math.sqrt(k / m) / math.sqrt(ref.stiffness / ref.mass) == pytest.approx(1.0, abs=bound), ref.name


@pytest.mark.parametrize("tscale", (0.9, 1.1))
def test_sweep_point_model(nominal, tscale):
    """A sweep's model at the process point (netgen.sweep.point.at_point: the fits' c_ref times the
    ratio) reads the capacitances capacitance_at renders: the same products in another order, 1e-12."""
    x = np.random.default_rng(6).uniform(-0.15, 0.15, (20, len(nominal.coordinates)))
    got = at_point(nominal, {"tscale": tscale}).capacitance(x)
    np.testing.assert_allclose(got, capacitance_at(nominal, x, tscale=tscale), rtol=1e-12, atol=0)


@pytest.mark.parametrize("tscale", TSCALES)
def test_in_plane_participation_is_the_moving_mass(nominal, tscale):
    """The a_x / a_y participation under tscale (netgen.model.process_loads.inertial_law: X ((1 - f)
    tscale + f tscale^3)) against the hand moving mass at the scaled layer, rho (2 um tscale) ((400 um)^2
    - 1600 (4 um)^2 + 80 x 2 um x 40 um) (the plate, its holes and the 80 fingers beyond its edge: the
    fingers scale with the layer): an in-plane translation's participation is that mass, exact but for
    the sums' round-off, 1e-12."""
    f = nominal.process["inertial"]["t3_fraction"]["participation"]
    mass = xyz_mass(0.0) * tscale
    for kind, v in (("a_x", 0), ("a_y", 1)):
        p = nominal.inertial.participation[kind][v]
        got = p * ((1 - f[kind][v]) * tscale + f[kind][v] * tscale**3)
        assert got == pytest.approx(mass, rel=1e-12, abs=0)


def field2d(tscale: float = 1.0, process: str = "") -> str:
    """xyz_thick with accelerometer_xyz's own field2d combs (the 2-D section tables at the tscale law's
    five thicknesses ship: netgen/electrostatics/comb_tables; the rebuilds at 0.9 and 1.1 are two)."""
    return xyz_thick(tscale, process).replace('comb_model = "textbook"', 'comb_model = "field2d"')


@pytest.fixture(scope="module")
def nominal2d():
    return build_model(parse_structure(field2d(process=PROCESS), "xyz.toml"))


@pytest.fixture(scope="module", params=TSCALES)
def rebuilt2d(request):
    return request.param, build_model(parse_structure(field2d(request.param), "xyz.toml"))


def test_field2d_capacitances_against_rebuild(nominal2d, rebuilt2d):
    """The field2d combs' law against rebuilds at 100 points: the bound of test_capacitances_against_rebuild
    (2 x the larger fit error + the stated law error: the ratio times the combs' state factor, u = tscale
    - 1, netgen.model.etch_state, for the fringe's and the substrate's share varying with the gap and the
    out-of-plane offset)."""
    test_capacitances_against_rebuild(nominal2d, rebuilt2d)


@pytest.mark.parametrize("tscale", (0.9, 0.95, 1.1))
def test_field2d_stated_error_bounds_fresh_points(nominal2d, tscale):
    """The stated capacitance_max_rel_error (rest, 32 random points and the box's 64 corners at the law's
    thicknesses: netgen.model.etch_cross.check_sets) bounds the law's error against a fresh field solution
    (the scaled structure's extractor; the law over the drawn one, process_cases.Drawn: no fit error) at
    300 fresh points of the fit box (seed 11, not the laws' check points): the claim under test."""
    s = parse_structure(field2d(process=PROCESS), "xyz.toml")
    extract = fresh_extractor(s, nominal2d.scales)
    xs = fresh_points(s.sampling, 300, len(nominal2d.coordinates), 11)
    got, ref = capacitance_at(Drawn(nominal2d, s, extract), xs, tscale=tscale), extract(scaled(s, tscale), xs)
    ok = np.isfinite(got) & np.isfinite(ref)
    assert np.max(np.abs(got[ok] / ref[ok] - 1.0)) <= nominal2d.process["tscale"]["capacitance_max_rel_error"]


def test_field2d_frequencies(nominal2d, rebuilt2d):
    """The modes with field2d combs: as test_frequencies (the combs' form does not enter the mechanics)."""
    test_frequencies(nominal2d, rebuilt2d)


@pytest.fixture(scope="module")
def sheer():
    """xyz_thick with [electrostatics] fringe = "none": a z plate's capacitance at rest is then eps F A / g
    alone (the electrode lies under the mass's perforated middle), its tscale ratio the fill factor's."""
    text = xyz_thick(process=PROCESS).replace("[electrostatics]", '[electrostatics]\nfringe = "none"')
    return build_model(parse_structure(text, "xyz.toml"))


@pytest.mark.parametrize("tscale", (0.9, 0.95, 1.05, 1.1))
def test_plate_law_is_the_hole_walls(sheer, tscale):
    """pc_zs against the closed form F(g; tscale t) / F(g; t) of the perforated plate
    (netgen.electrostatics.perforation, written out here: F = 1 - (1 - phi) ((h - 2 d) / p)^2, the walls'
    share phi = beta (1 - exp(-k t)), k = sqrt(2) pi / h, d = (B g / pi) ln(1 + A h / g)) at rest: no fit
    error enters (the law is fitted at rest). The law changes by 3.6e-4 at 0.9, so the bound must be far
    below that to catch a missing plate law (the 100-point test's 2 x fit error + stated cannot). Bound:
    the cubic's truncation, the Taylor remainder max|f''''| (0.1)^4 / 4! of f(tscale) = F / F(1) over the
    range (f'''' = beta s^2 (k t)^4 exp(-k t tscale) / F, largest at 0.9), times 3 for the five-point
    least-squares fit's points against its maximum and the rescale to 1 at 1: 5.4e-7, under a
    three-hundredth of the change at 0.95."""
    h, p, g, t = 4e-6, 9.98e-6, 2e-6, 2e-6
    k = math.sqrt(2) * math.pi / h
    s2 = ((h - 2 * PERFORATION_STRENGTH * g / math.pi * math.log1p(math.exp(PERFORATION_LN_A) * h / g)) / p) ** 2

    def fill(tau: float) -> float:
        return 1 - (1 - PERFORATION_WALL_SHARE * -math.expm1(-k * t * tau)) * s2

    ratio = {r["electrode"]: r["ratio"] for r in sheer.process["tscale"]["capacitance_laws"]}["zs"]
    got = float(np.dot(ratio, [1.0, tscale, tscale**2, tscale**3]))
    fourth = PERFORATION_WALL_SHARE * s2 * (k * t) ** 4 * math.exp(-0.9 * k * t) / fill(1.0)
    bound = 3 * fourth * 0.1**4 / 24
    assert abs(fill(tscale) / fill(1.0) - 1) > 100 * bound  # the change a missing law would leave
    assert got == pytest.approx(fill(tscale) / fill(1.0), rel=bound, abs=0)
