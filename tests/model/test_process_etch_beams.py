"""The lateral etch on beam conductors (netgen.model.process.etched_beam): a cantilever's or a
clamped-clamped beam's width w - 2 etch, the cantilever's free tip back by etch (length L - etch; its
clamp, the anchor's edge, stays), against the Euler-Bernoulli closed forms and full rebuilds of the
structure file rewritten at the etched width and length (tests/oracles/beam_etch: the examples with
the electrode drawn past the beam, so that with fringe "none" the facing area is the whole etched
beam at every etch of the range).

Tolerances:
- frequencies: the peak-normalised modes are functions of x / L alone, so f ~ 1 / L^2 whatever the
  width (the clamped-clamped beam's unchanged, the cantilever's times (L / (L - etch))^2); a Hermite
  mesh of a fixed element count is self-similar in L, so the re-runs follow that to round-off. The law
  is sqrt(k / m) of two cubics fitted to the re-runs: within their stated residual (the mechanics'
  max_rel_error) and, between the fit points, the cubic's truncation of (1 - etch / L)^-3, whose
  fourth-order term 15 (etch / L)^4 is below 2.4e-10 over the range: stated + 1e-9. The brief's
  acceptance is 1e-4.
- modal mass and stiffness, m ~ w L and k ~ w / L^3: each re-run's mode is normalised to a peak of 1,
  so its eigenvector's round-off enters m and k (not f, a Rayleigh quotient of the same vector):
  eigh's backward error on this pencil shows as its eigenvalues' 1e-7 disagreement with the Rayleigh
  quotients (netgen.mechanics.beam.beam_modes), an eigenvector error of at most that order, twice
  that in a quadratic form: stated + 2e-7.
- capacitances: C(q; etch) = pc(etch) C(q; 0) (no shift for a beam: netgen.model.process.
  capacitance_laws). With fringe "none" and the electrode past the beam, C = eps w' int dx / (g - q
  phi(x / L')) over the beam: exactly (w' L') / (w L) times the drawn C at the same modal amplitudes,
  so pc at rest against that within the stated capacitance error (the law against the extractor) plus
  1e-12; at 100 points of the fit box against a rebuild's fit within the two fits' held-out errors
  plus the stated error (the law's value error, first order).
- the cantilever's pull-in against a rebuild: V^2 = 2 k s / C'(s), and C(q; etch) = pc C(q; 0), so
  V_law = V(nominal fit, law stiffnesses) / sqrt(pc). Half the stiffness law's stated error plus the
  fits' slope error: a fit residual |r| <= e C on the box |q| <= R (R m1's sampling range) has a
  relative slope error <= 4 e / R (Markov's inequality, as in tests/model/test_process_pull_in.py),
  halved by the square root, for the nominal's fit, the rebuild's fit and the law's stated error:
  2 (e_0 + e_1 + e_c) / R + 1e-9 (8e-4 here, inside the brief's 0.2 %).
- the stretching energy (clamped-clamped): U = E w' t (int w'^2 / 2)^2 / 2L with the modes unchanged
  (L fixed): the law's etch ratio R(etch) against (w - 2 etch) / w within its stated error + 1e-9 (a
  linear law: the cubic carries it to round-off).
- the a_in load G = rho t w' int phi dx ~ w' L' (the modal mass's ratio): within the load law's stated
  residual + 2e-7 (the peak normalisation, as the mass).

examples/cantilever.toml as drawn (beam_etch.drawn_text: the electrode's edges on the beam's), where an
under-etched beam overhangs the electrode:
- at rest with fringe "none" the facing area is the electrode's (w L) under-etched and the beam's (w -
  2 etch)(L - etch) over-etched, so the knotted ratio (two polynomial pieces joined at 0, each exact
  for its side's polynomial) gives C / C_drawn exactly: within the stated capacitance error + 1e-12.
- at 100 points of the fit box the law against the extractor re-run on the rebuilt (etched) structure
  (the field solution, not the rebuild's fit: at -0.2 um that fit is itself 9.7e-4 off its extractor
  over the box while stating 1.1e-4, bench/process_etch_beams.py): the drawn fit's held-out error plus
  the law's stated error (first order) + 1e-12.
- the pull-in from the law (its stiffnesses, its capacitance with the state factor: process_balance.
  LawAt) against the rebuild's, the bound above: 0.5 e_k + 2 (e_0 + e_1 + e_c) / R + 1e-9.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.build import build_model, electrodes, extractor, plate_outline
from netgen.build import mechanics as run_mechanics
from netgen.core.errors import StructureError
from netgen.mechanics import mechanics
from netgen.model.etch_knots import edge_knots, tip_knots
from netgen.model.process import capacitance_at, coordinate_values, etched, process_laws, ratio_value
from netgen.structure import parse_structure
from netgen.sweep.point import at_point
from tests.oracles.beam_etch import ETCHES, beam_text, drawn_text, length_ratio, modal_ratios, width_ratio
from tests.oracles.process_balance import LawAt, pull_in

NAMES = ("cantilever", "cc_beam")
NORMALISATION = 2e-7  # the peak normalisation's round-off in m and k (module docstring)


@pytest.fixture(scope="module")
def models():
    return {n: build_model(parse_structure(beam_text(n), f"{n}.toml")) for n in NAMES}


@pytest.fixture(scope="module")
def rebuilds():
    return {
        (n, e): build_model(parse_structure(beam_text(n, e, process=""), f"{n}.toml")) for n in NAMES for e in ETCHES
    }


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("etch", ETCHES)
def test_modes_against_euler_bernoulli(models, name, etch):
    """Each mode's mass, stiffness and frequency from the laws against m ~ w L, k ~ w / L^3, f ~ 1 / L^2
    (the clamped-clamped beam's frequencies unchanged by the width: within the stated error + 1e-9)."""
    model = models[name]
    law = model.process
    stated = law["etch"]["max_rel_error"]
    rm, rk, rf = modal_ratios(name, etch)
    for v, c in enumerate(model.coordinates):
        mass, k, _ = coordinate_values(law, v, etch=etch)
        assert mass / c.mass == pytest.approx(rm, rel=stated + NORMALISATION)
        assert k / c.stiffness == pytest.approx(rk, rel=stated + NORMALISATION)
        f = math.sqrt(k / mass) / (2 * math.pi)
        assert f / c.frequency_hz == pytest.approx(rf, rel=stated + 1e-9)
    if name == "cc_beam":
        assert rf == 1.0


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("etch", ETCHES)
def test_against_rebuild(models, rebuilds, name, etch):
    """The law's frequencies against the rebuild's (stated + 1e-9); pc against (w' L') / (w L) and the
    capacitances at 100 points of the fit box against the rebuild's fit (module docstring)."""
    model, ref = models[name], rebuilds[(name, etch)]
    law = model.process
    for v, c in enumerate(ref.coordinates):
        mass, k, _ = coordinate_values(law, v, etch=etch)
        f = math.sqrt(k / mass) / (2 * math.pi)
        assert f == pytest.approx(c.frequency_hz, rel=law["etch"]["max_rel_error"] + 1e-9)
    (cap,) = law["etch"]["capacitance"]
    assert "shift" not in cap
    stated = law["etch"]["capacitance_max_rel_error"]
    pc = ratio_value(cap["ratio"], etch)
    assert pc == pytest.approx(width_ratio(name, etch) * length_ratio(name, etch), rel=stated + 1e-12)
    assert np.allclose(model.scales, ref.scales, rtol=1e-12)  # the same touching amplitudes: the same points
    box = np.array(
        [model.sampling.get("coordinate_range", {}).get(c.name, model.sampling["range"]) for c in model.coordinates]
    )
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (100, model.ncoords)) * box
    errs = model.capacitances[0].max_rel_error + ref.capacitances[0].max_rel_error
    np.testing.assert_allclose(pc * model.capacitance(x), ref.capacitance(x), rtol=errs + stated + 1e-12)


@pytest.mark.parametrize("etch", ETCHES)
def test_cantilever_pull_in_against_rebuild(models, rebuilds, etch):
    """The etched cantilever's pull-in from the laws (law stiffnesses, the nominal fit times pc) against
    the rebuild's, within the module docstring's bound (below the brief's 0.2 %)."""
    model, ref = models["cantilever"], rebuilds[("cantilever", etch)]
    law = model.process["etch"]
    k = [coordinate_values(model.process, v, etch=etch)[1] for v in range(model.ncoords)]
    pc = ratio_value(law["capacitance"][0]["ratio"], etch)
    v_law = pull_in(model, k) / math.sqrt(pc)
    v_ref = pull_in(ref, [c.stiffness for c in ref.coordinates])
    r = model.sampling.get("coordinate_range", {}).get("m1", model.sampling["range"])
    fits = model.capacitances[0].max_rel_error + ref.capacitances[0].max_rel_error
    bound = 0.5 * law["max_rel_error"] + 2 * (fits + law["capacitance_max_rel_error"]) / r + 1e-9
    print(
        f"etch {etch:+.1e}: pull-in {v_law:.6f} V, rebuilt {v_ref:.6f} V ({v_law / v_ref - 1:+.1e}, bound {bound:.1e})"
    )
    assert bound < 2e-3
    assert v_law == pytest.approx(v_ref, rel=bound)


def test_stretching_energy_ratio(models):
    """The clamped-clamped beam's stretching energy law times R(etch) = (w - 2 etch) / w."""
    u = models["cc_beam"].process["strain_energy"]
    assert u["a"] == [0.0, 0.0, 0.0, 0.0] and u["b"] == [1.0, 0.0, 0.0, 0.0]  # etch alone: no modulus law
    for etch in ETCHES:
        assert ratio_value(u["etch"], etch) == pytest.approx(
            width_ratio("cc_beam", etch), rel=u["max_rel_error"] + 1e-9
        )


@pytest.mark.parametrize("name", NAMES)
def test_acceleration_load(models, name):
    """The a_in load's etch ratio against the etched beam's rho t w' L' (the modal mass's ratio); an
    antisymmetric mode of the clamped-clamped beam has no load (G = 0, ratio 1)."""
    model = models[name]
    law = model.process["etch"]["acceleration"]
    loaded = [abs(g) > 1e-9 * max(map(abs, model.acceleration)) for g in model.acceleration]
    assert loaded == [True, name == "cantilever", True]
    for etch in ETCHES:
        rm = modal_ratios(name, etch)[0]
        for r in (r for r, on in zip(law["ratio"], loaded) if on):
            assert ratio_value(r, etch) == pytest.approx(rm, rel=law["max_rel_error"] + NORMALISATION)


def test_laws_without_a_build():
    """The model stage alone (process_laws, no extractor) on the clamped-clamped beam with etch and
    tscale: the product law at the box's corners is exact (k ~ w t^3, m ~ w t): stated error below 1e-8."""
    text = beam_text(
        "cc_beam", process='[process]\nparameters = ["etch", "tscale"]\netch_range = ["-0.2 um", "0.3 um"]\n'
    )
    s = parse_structure(text, "cc.toml")
    m = mechanics(s)
    law = process_laws(s, m, mechanics, [], 0.0, 0.3)
    assert law["etch"]["max_rel_error"] < 1e-8
    mass, k, _ = coordinate_values(law, 0, tscale=1.1, etch=0.3e-6)
    assert k / m.stiffnesses[0] == pytest.approx(1.1**3 * width_ratio("cc_beam", 0.3e-6), rel=1e-8 + NORMALISATION)
    assert mass / m.masses[0] == pytest.approx(1.1 * width_ratio("cc_beam", 0.3e-6), rel=1e-8 + NORMALISATION)


def test_narrow_beam_refused():
    """A beam 8 um wide with etch up to 3 um per edge (6 of its 8 um): exit 2 at process.etch_range."""
    text = beam_text("cantilever", process='[process]\nparameters = ["etch"]\netch_range = ["-1 um", "3 um"]\n')
    text = text.replace('width = "50 um"', 'width = "8 um"')
    with pytest.raises(StructureError) as exc:
        parse_structure(text, "cantilever.toml")
    assert "process.etch_range" in str(exc.value) and "beam" in str(exc.value)


def test_sweep_point_scales_the_energy(models):
    """A sweep's model at a process point (netgen.sweep.point.at_point, the loop design's numbers)
    carries the stretching energy times (w - 2 etch) / w, as the emitted pu does (it was left at the
    drawn beam's, under tscale, escale and temp too): within the energy law's stated error + 1e-9."""
    model = models["cc_beam"]
    u = model.process["strain_energy"]
    nominal = np.array(model.nonlinear["energy_J"]["coeffs"])
    for etch in ETCHES:
        moved = np.array(at_point(model, {"etch": etch}).nonlinear["energy_J"]["coeffs"])
        np.testing.assert_allclose(moved, nominal * width_ratio("cc_beam", etch), rtol=u["max_rel_error"] + 1e-9)


@pytest.fixture(scope="module")
def drawn():
    return build_model(parse_structure(drawn_text(), "cantilever.toml"))


def test_drawn_ratio_at_rest(drawn):
    """The knot at etch 0 and the facing area at rest on each side of it (module docstring)."""
    law = drawn.process["etch"]
    assert law["knots"] == [0.0] and law["capacitance"][0]["state"]["below"] == 0.0
    rest = np.zeros((1, drawn.ncoords))
    c0 = drawn.capacitance(rest)[0, 0]
    for etch in (-0.2e-6, -0.1e-6, -0.05e-6, 0.05e-6, 0.1e-6, 0.3e-6):
        area = 1.0 if etch < 0 else width_ratio("cantilever", etch) * length_ratio("cantilever", etch)
        got = capacitance_at(drawn, rest, etch)[0, 0] / c0
        assert got == pytest.approx(area, rel=law["capacitance_max_rel_error"] + 1e-12)


@pytest.mark.parametrize("etch", ETCHES)
def test_drawn_against_extractor(drawn, etch):
    """The law (knotted ratio, the tip's state factor) at 100 points of the fit box against the field
    solution on the etched structure (module docstring)."""
    s = etched(parse_structure(drawn_text(), "cantilever.toml"), etch)
    plate = plate_outline(s)
    prepared = extractor(s, plate).prepare(electrodes(s), plate, run_mechanics(s).basis)
    box = np.array(
        [drawn.sampling.get("coordinate_range", {}).get(c.name, drawn.sampling["range"]) for c in drawn.coordinates]
    )
    x = np.random.default_rng(3).uniform(-1.0, 1.0, (100, drawn.ncoords)) * box
    ref = np.asarray(prepared.capacitance(x * drawn.scales), dtype=float)[:, 0]
    tol = drawn.capacitances[0].max_rel_error + drawn.process["etch"]["capacitance_max_rel_error"] + 1e-12
    np.testing.assert_allclose(capacitance_at(drawn, x, etch)[:, 0], ref, rtol=tol)


@pytest.mark.parametrize("etch", ETCHES)
def test_drawn_pull_in(drawn, etch):
    """The drawn cantilever's pull-in from the law against a rebuild's (module docstring's bound)."""
    ref = build_model(parse_structure(drawn_text(etch, process=""), "cantilever.toml"))
    law = drawn.process["etch"]
    k = [coordinate_values(drawn.process, v, etch=etch)[1] for v in range(drawn.ncoords)]
    v_law = pull_in(LawAt(drawn, etch), k)
    v_ref = pull_in(ref, [c.stiffness for c in ref.coordinates])
    r = drawn.sampling.get("coordinate_range", {}).get("m1", drawn.sampling["range"])
    fits = drawn.capacitances[0].max_rel_error + ref.capacitances[0].max_rel_error
    bound = 0.5 * law["max_rel_error"] + 2 * (fits + law["capacitance_max_rel_error"]) / r + 1e-9
    print(
        f"etch {etch:+.1e}: pull-in {v_law:.6f} V, rebuilt {v_ref:.6f} V ({v_law / v_ref - 1:+.1e}, bound {bound:.1e})"
    )
    assert bound < 2e-3
    assert v_law == pytest.approx(v_ref, rel=bound)


def test_drawn_sweep_point(drawn):
    """A sweep's model at an etch (netgen.sweep.point.at_point) reads the knotted ratio: at rest (the
    tip's state factor 1 there) the facing area's ratio, as test_drawn_ratio_at_rest."""
    rest = np.zeros((1, drawn.ncoords))
    c0 = drawn.capacitance(rest)[0, 0]
    for etch in ETCHES:
        area = 1.0 if etch < 0 else width_ratio("cantilever", etch) * length_ratio("cantilever", etch)
        got = at_point(drawn, {"etch": etch}).capacitance(rest)[0, 0] / c0
        assert got == pytest.approx(area, rel=drawn.process["etch"]["capacitance_max_rel_error"] + 1e-12)


def test_edge_knots():
    """Where the etched beam's edges (sides +-(w - 2 etch) / 2, the tip L - etch) meet the electrode's:
    the drawn cantilever's at etch 0 (sides and tip), an electrode narrower by 0.1 um a side at 0.1 um
    (the sides), none with the electrode past the beam (tests/oracles/beam_etch)."""
    lo, hi = -0.2e-6, 0.3e-6
    s = parse_structure(drawn_text(), "cantilever.toml")
    assert edge_knots(s, lo, hi) == (0.0,) and tip_knots(s, lo, hi) == {"drive": 0.0}
    narrow = parse_structure(drawn_text().replace('y = ["-25 um", "25 um"]', 'y = ["-24.9 um", "24.9 um"]'), "c.toml")
    assert edge_knots(narrow, lo, hi) == pytest.approx((0.0, 0.1))
    assert edge_knots(parse_structure(beam_text("cantilever"), "c.toml"), lo, hi) == ()
