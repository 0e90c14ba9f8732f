"""The process instance parameters of the FMU (netgen.emit.fmu_process), driven through fmpy: a
proof mass on four clamped-guided beams 2 um above one plate (tests/oracles/fmu_process: all five
parameters declared, Rayleigh alpha = 2e5 1/s so that a run settles within 300 us: damping ratio
0.25..0.45 over the parameters, decay rate alpha / 2), at three values of each parameter across its
valid range.

References:
- closed forms of the structure: k = 4 E w t^3 / L^3 (Euler-Bernoulli beams, guided ends) with
  t = 5 um tscale, E = 160 GPa escale (1 + tc (T - T0)) (tc the declared -60 ppm/K, T0 = 300 K the
  structure's temperature), w = 2 um - 2 etch; m = rho (200 um - 2 etch)^2 t (the rigid plate,
  etched); b = alpha m; the step response of m x'' + b x' + k x = F from rest (resonance and static
  deflection F / k); under a
  voltage V on the plate below, the equilibrium k z = -eps0 A V^2 / (2 (g + dg + z)^2) and the
  charge eps0 A V / (g + dg + z) (fringe "none": the 1/P fit is exact); a step on a_in loads the
  plate with -m a_in (the a_in gain times tscale and, under etch, the etched mass's ratio);
- the same mass damped by its squeeze film alone, at -40, 25 and 125 C: the damping's ratio to the
  nominal against the film's viscosity law (Sutherland, Veijola's rarefaction) computed in
  tests/oracles/fmu_process.viscosity_ratio;
- ngspice 39's transient (or .ac) of the emitted .lib with the same instance parameters (second
  solver).

Tolerances:
- FMU against the closed form: the laws' stated error (model.process max_rel_error, <= 1e-11 here)
  times 10 (bounds the step response's sensitivity to a relative stiffness error at damping ratio
  >= 0.25: |d x / d ln k| <= (1 + 1 / zeta) peak); plus twice the FMU's integration error, taken as
  the distance of the run (DP45 at tolerance 1e-10) from the same run at 1e-13 (the global error
  scales as tol^0.8, so the difference is the coarse run's error within 1 %); plus 1e-12 for the
  round-off of ~1e4 steps of 1e-16 each. The static value at 300 us also carries the transient's
  remainder exp(-alpha T / 2) / sqrt(1 - zeta^2) < 1e-12.
- the FMU's static value at 300 us against ngspice's .op of the .lib: its Newton test at reltol 1e-9
  (one linear solve for a force load) plus the FMU's bound above.
- FMU against ngspice over ngspice's first 100 us (the resonance: 3.6 to 6.2 periods, 10 decay
  times): the budget of tests/emit/test_fmu.py (the trapezoidal phase error at the 2 ns step cap,
  Newton's reltol 1e-9 accumulated over the steps, interpolation, the FMU's own error), asserted
  below 1e-5 of the peak; the comparison is held to 1e-5.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen.model import MacroModel
from netgen.model.process import capacitance_at
from netgen.sim import fmu
from tests.fixtures import NETLISTS
from tests.fixtures import shared_model as build_model
from tests.oracles import fmu_process as fp
from tests.oracles import process_forms as pf

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # noqa: E402  (fmpy's FMI 2.0 calls raise it too)
from fmpy.validation import validate_fmu  # noqa: E402

CASES = [(name, v) for name, vals in fp.VALUES.items() for v in vals]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The model, its .lib and its FMU."""
    return fp.build(tmp_path_factory.mktemp("fmu_process"))


def law_error(model) -> float:
    """The largest stated relative error of the model's process laws."""
    p = model.process
    laws = (p["tscale"], p["escale"], p["etch"], p["etch"]["acceleration"])
    return max(law["max_rel_error"] for law in laws)


@pytest.mark.parametrize("name,value", CASES, ids=[f"{n}={v:g}" for n, v in CASES])
def test_step_response_against_closed_form_and_ngspice(built, tmp_path, name, value):
    """A step force on z: the whole response (resonance and the static deflection F / k) against
    the closed form at the process point, and against ngspice's .lib at the same parameters."""
    model, lib, path = built
    got = fp.step_case(model, lib, path, name, value, tmp_path)
    assert 0.25 <= got["zeta"] <= 0.45 and got["tail"] < 1e-12
    bound = 10 * law_error(model) + 2 * got["integ"] + 1e-12
    assert got["err"] <= bound, got
    assert got["static"] <= bound + got["tail"], got
    assert fp.ngspice_budget(model) < 1e-5
    assert got["ngspice"] <= 1e-5, got
    assert got["op"] <= fp.RELTOL + bound + got["tail"], got


@pytest.mark.parametrize("tscale", fp.VALUES["tscale"])
def test_acceleration_step_scales_with_the_thickness(built, tmp_path, tscale):
    """A step acceleration on a_in: the load -m a_in grows with the thickness (the a_in gain times
    tscale), the static deflection -m a / k as t^-2; against the closed form and ngspice as above."""
    model, lib, path = built
    got = fp.step_case(model, lib, path, "tscale", tscale, tmp_path, load="a_in")
    bound = 10 * law_error(model) + 2 * got["integ"] + 1e-12
    assert got["err"] <= bound and got["static"] <= bound + got["tail"], got
    assert got["ngspice"] <= 1e-5, got
    assert got["op"] <= fp.RELTOL + bound + got["tail"], got


@pytest.mark.parametrize("etch", fp.VALUES["etch"])
def test_acceleration_step_follows_the_etched_mass(built, tmp_path, etch):
    """A step acceleration on a_in at an etch bias: the load -m a_in of the etched plate, m = rho
    (200 um - 2 etch)^2 t (the a_in gain times the etched body's ratio, netgen.model.process_loads; it
    stayed at the drawn plate's, -6e-3 at 0.3 um), against the closed form and ngspice as above."""
    model, lib, path = built
    got = fp.step_case(model, lib, path, "etch", etch, tmp_path, load="a_in")
    bound = 10 * law_error(model) + 2 * got["integ"] + 1e-12
    assert got["err"] <= bound and got["static"] <= bound + got["tail"], got
    assert got["ngspice"] <= 1e-5, got
    assert got["op"] <= fp.RELTOL + bound + got["tail"], got


@pytest.fixture(scope="module")
def film(tmp_path_factory):
    """The guided mass damped by its squeeze film alone: model, .lib and FMU."""
    return fp.film_build(tmp_path_factory.mktemp("fmu_film"))


@pytest.mark.parametrize("temp", fp.FILM_TEMPS)
def test_squeeze_film_damping_follows_the_viscosity_law(film, tmp_path, temp):
    """At -40, 25 and 125 C the FMU's damping over the nominal against the film's viscosity ratio
    (Sutherland's law with Veijola's rarefaction, computed here): within the law's stated
    polynomial misfit (model.process temp.viscosity.max_rel_error) plus 1e-12 of round-off; and
    the .lib's damping from ngspice's .ac at the same temp against the FMU's: ngspice's linear solve
    and the three-point fit, 1e-9 (tests/emit/test_process_ngspice.py)."""
    model, lib, path = film
    got = fp.film_case(model, lib, path, temp, tmp_path)
    misfit = model.process["temp"]["viscosity"]["max_rel_error"]
    assert got["ratio"] <= misfit + 1e-12, got
    assert got["ngspice"] <= 1e-9, got


@pytest.mark.parametrize("dg", fp.DG)
def test_gap_offset_static_deflection_and_charge(built, tmp_path, dg):
    """VOLTS stepped onto the plate below: the static deflection and the plate's charge at 300 us
    against the parallel-plate equilibrium across the gap g + dg, and the transient against ngspice."""
    model, lib, path = built
    got = fp.gap_case(model, lib, path, dg, tmp_path)
    assert got["tail"] < 1e-12
    laws = 10 * law_error(model)  # pk at the nominal point: the laws' round-off (d ln z / d ln k < 2 here)
    assert got["z"] <= laws + 2 * got["z_integ"] + 1e-12 + got["tail"], got
    assert got["q"] <= laws + 2 * got["q_integ"] + 1e-12 + got["tail"], got
    assert got["ngspice"] <= 1e-5, got
    assert got["op"] <= fp.RELTOL + laws + 2 * got["z_integ"] + 1e-12 + got["tail"], got


@pytest.mark.parametrize("dg", (-2e-7, 0.0, 3e-7))
def test_stop_follows_the_gap_offset(dg):
    """The committed piston_process model pushed by -10 uN through f_z past its electrode: the FMU's
    static balance (model exchange: the root of q''(z) at q' = 0, by brentq) against the balance of
    spring, force and the stop's penalty with the electrode's surface at -(g + dg)
    (tests/oracles/process_forms.resting, the penalty written out from its definition). The model's
    stop is stated in its z scale, which is the gap to its round-off (1.99999999999985e-06 m: 7.5e-14
    relative), so the penetration differs by 7.5e-14 and the rest point by 1.5e-19 m; both roots to
    brentq's 1e-15 relative (2e-21 m), the force's round-off (1e-16 of 1e-5 N over a slope >= 2 N/m)
    < 1e-21 m: 1e-17 m. Without the offset the plate would rest dg (>= 2e-7 m) away."""
    model = MacroModel.load_json(NETLISTS / "piston_process" / "piston_process.json")
    inst = fmu.Instance(fmu.built(model), cosim=False)
    inst.set({"dg_drive": dg, "f_z": pf.FORCE})
    inst.start()

    def qdd(z: float) -> float:
        inst.set_states(np.array([z, 0.0]))
        return float(inst.get(["qdd_z"])[0])

    z = brentq(qdd, -(pf.GAP + dg) * 1.5, -(pf.GAP + dg) * 0.9, xtol=1e-22, rtol=1e-15)
    inst.close()
    assert abs(z - pf.resting(model, dg)) <= 1e-17
    assert -z > pf.GAP + dg  # on the stop, pressed into it


# ----------------------------------------------------------------------------- description, refusals


def test_parameters_in_the_model_description(built):
    """Every declared parameter is an FMI parameter (variability fixed) with start = nominal, min/max =
    the range the model's process record states, its unit (temp degC, etch and dg m, ratios none)
    and a description naming the range; the FMU passes fmpy's validator."""
    model, _, path = built
    assert validate_fmu(str(path)) == []
    md = fmpy.read_model_description(str(path))
    var = {v.name: v for v in md.modelVariables}
    p = model.process
    want = {
        "tscale": (1.0, p["tscale"]["range"], None),
        "escale": (1.0, p["escale"]["range"], None),
        "temp": (p["temperature_C"], p["temp"]["range_C"], "degC"),
        "etch": (0.0, p["etch"]["range_m"], "m"),
        "dg_bot": (0.0, [-p["gaps"][0]["max_m"], p["gaps"][0]["max_m"]], "m"),
    }
    for name, (start, (lo, hi), unit) in want.items():
        v = var[name]
        assert (v.causality, v.variability, v.initial) == ("parameter", "fixed", "exact")
        assert float(v.start) == pytest.approx(start, rel=1e-12, abs=0.0)  # temp: the .lib's 6 digits of T0
        assert float(v.min) == float(f"{lo:.12g}") and float(v.max) == float(f"{hi:.12g}")  # round-off dropped
        assert v.unit == unit
        assert f"valid {lo:.6g}..{hi:.6g}" in v.description


def outside(model) -> list[tuple[str, float]]:
    """Per parameter a value just below its range and one just above (1e-6 of the span outside)."""
    p = model.process
    ranges = {
        "tscale": p["tscale"]["range"],
        "escale": p["escale"]["range"],
        "temp": p["temp"]["range_C"],
        "etch": p["etch"]["range_m"],
        "dg_bot": [-p["gaps"][0]["max_m"], p["gaps"][0]["max_m"]],
    }
    out = []
    for name, (lo, hi) in ranges.items():
        d = 1e-6 * (hi - lo)
        out += [(name, lo - d), (name, hi + d)]
    return out + [("tscale", math.nan)]


def test_out_of_range_refused_at_initialization(built, capsys):
    """A value outside its valid range (or NaN) makes fmi2ExitInitializationMode return fmi2Error
    with a logged error naming the parameter, its value and its range; the range's ends themselves
    initialize as a user writes them (dg_bot = -1.5e-7, the range's -1.4999999999998874e-07 to round-off);
    and a process parameter set after initialization is refused (variability fixed)."""
    model, _, path = built
    for name, value in outside(model):
        inst = fmu.Instance(path)
        inst.set({name: value})
        with pytest.raises(FMICallException, match="fmi2ExitInitializationMode"):
            inst.start()
        log = capsys.readouterr().out
        assert f"process parameter {name} = " in log and "outside its valid range" in log, log
        inst.fmu.freeInstance()
    ends = {"tscale": 0.9, "escale": 1.5, "temp": -40.0, "etch": 0.3e-6, "dg_bot": -1.5e-7}  # as a user writes them
    inst = fmu.Instance(path)
    inst.set(ends)
    inst.start()
    with pytest.raises(FMICallException, match="fmi2SetReal"):
        inst.set({"tscale": 1.0})
    assert "process parameter tscale is fixed after initialization" in capsys.readouterr().out
    inst.close()


@pytest.mark.parametrize("etch", fp.ETCH_CAPS)
def test_etch_capacitance_ratio_static_deflection_and_charge(built, tmp_path, etch):
    """VOLTS stepped onto the plate below at the lateral etch: the FMU's capacitance carries the etch's
    ratio pc_bot ((200 um - 2 etch) / 200 um)^2 (netgen.model.process.capacitance_laws), so the static
    deflection and the charge at 300 us match the parallel-plate equilibrium with k(etch) and the
    etched area, and the deflection ngspice's .op of the .lib at the same etch (the same law).
    Tolerances as test_gap_offset_static_deflection_and_charge: the laws' stated error times 10 (pk and
    pc, exact quadratics here), twice the FMU's integration error, 1e-12 round-off and the transient's
    remainder; against the .op also its Newton test at reltol 1e-9. Without the ratio the force would
    be off by 4 etch / 200 um = 2e-3 at |etch| = 0.1 um, decades above the bound."""
    model, lib, path = built
    got = fp.etch_case(model, lib, path, etch, tmp_path)
    assert got["tail"] < 1e-12
    laws = 10 * law_error(model)
    assert got["z"] <= laws + 2 * got["z_integ"] + 1e-12 + got["tail"], got
    assert got["q"] <= laws + 2 * got["q_integ"] + 1e-12 + got["tail"], got
    assert got["op"] <= fp.RELTOL + laws + 2 * got["z_integ"] + 1e-12 + got["tail"], got


@pytest.fixture(scope="module")
def combs(tmp_path_factory):
    """examples/accelerometer_xyz with textbook combs and etch declared, its .lib and its FMU."""
    return fp.comb_build(tmp_path_factory.mktemp("fmu_combs"), build_model)


@pytest.mark.parametrize("etch", fp.ETCH_CAPS)
def test_etch_shifts_the_combs_static_deflection_and_charge(combs, tmp_path, etch):
    """fp.COMB_VOLTS on comb xp_t of accelerometer_xyz at the lateral etch: its fingers' terms read the
    state shifted by shift / L etch (netgen.model.process.capacitance_laws: the gap 1.5 um + 2 etch).
    The FMU's static balance (model exchange, q'' = 0 at rest) against ngspice's .op of the .lib at the
    same etch instance parameter (the same law rendered): Newton's test at reltol fp.RELTOL (vntol
    1e-12 V: 9.4e-11 of x_x's 0.01 um, under it) bounds the .op's relative state error, and the FMU's
    root is solved to 1e-15; a force error maps to the state
    through the scaled balance's Jacobian, so the bound is cond(J) (RELTOL + 1e-12), 1e-12 the forces'
    round-off (tests/emit/test_fmu.py), relative to the largest scaled deflection. The charge against
    the MacroModel's own law at the FMU's state (netgen.model.process.capacitance_at, times the
    voltage): 1e-12, the terms summed in another order (tests/emit/test_fmu.py). With the drawn
    capacitances (the FMU before the law) the deflection was off by 0.24..0.35 at |etch| = 0.1 um."""
    model, lib, path = combs
    q, charge, cond = fp.comb_balance(model, path, etch)
    scale = np.array([c.scale for c in model.coordinates])
    op = fp.comb_op(model, lib, etch, tmp_path)
    err = float(np.max(np.abs(q - op) / scale) / np.max(np.abs(q) / scale))
    assert err <= cond * (fp.RELTOL + 1e-12), (err, cond)
    k = [f.electrode for f in model.capacitances].index(fp.COMB)
    ref = capacitance_at(model, (q / scale)[None, :], etch)[0, k] * fp.COMB_VOLTS
    assert charge == pytest.approx(ref, rel=1e-12, abs=0)


@pytest.mark.parametrize("etch", fp.ETCH_CAPS)
def test_inertial_loads_follow_the_etched_body(combs, etch):
    """accelerometer_xyz's FMU at rest (model exchange) under a_x, a_y and a_in at the lateral etch: each
    translation's acceleration q'' equals the one under its force input loaded instead with the etched
    moving mass's hand sum -M(etch) a (the plate with its holes and the 80 fingers,
    tests/oracles/process_cases.xyz_mass; the same mass divides both, so only the load is compared):
    the etch ratios' round-off (1e-11, tests/model/test_process_loads) plus the laws' stated residuals
    plus the forces' round-off 1e-12."""
    from tests.oracles.process_cases import xyz_mass

    model, _, path = combs
    law = model.process
    tol = 1e-11 + law["etch"]["acceleration"]["max_rel_error"] + law["inertial"]["etch"]["max_rel_error"] + 1e-12
    for port, q in (("a_x", "x"), ("a_y", "y"), ("a_in", "z")):
        got = []
        for inputs in ({port: 9.81}, {f"f_{q}": -xyz_mass(etch) * 9.81}):
            inst = fmu.Instance(path, cosim=False)
            inst.set({"etch": etch} | inputs)
            inst.start()
            got.append(float(inst.get([f"qdd_{q}"])[0]))
            inst.close()
        assert got[0] == pytest.approx(got[1], rel=tol, abs=0), (port, got)


@pytest.fixture(scope="module")
def rotating():
    """accelerometer_xyz with etch declared and the rate w_z (tests/oracles/process_cases.xyz_structure), its FMU."""
    from tests.oracles.process_cases import xyz_structure

    model = build_model(xyz_structure())
    return model, fmu.built(model)


@pytest.mark.parametrize("etch", fp.ETCH_CAPS)
def test_coriolis_load_follows_the_etched_body(rotating, etch):
    """accelerometer_xyz's FMU at rest but moving along x at 1 mm/s under w_z = 100 rad/s (model
    exchange): y's acceleration equals the one under f_y loaded instead with the Coriolis force of the
    etched moving mass's hand sum, 2 M(etch) w_z v (its sign the model's), M the plate, holes and 80
    fingers (tests/oracles/process_cases.xyz_mass; the same mass divides both). With q = 0 the
    centrifugal terms on y vanish by symmetry. Tolerance as test_inertial_loads_follow_the_etched_body."""
    from tests.oracles.process_cases import xyz_mass

    model, path = rotating
    names = [c.name for c in model.coordinates]
    ix, iy = names.index("x"), names.index("y")
    sign = np.sign(model.inertial.gyroscopic["z"][iy][ix])
    w, v = 100.0, 1e-3
    state = np.zeros(2 * model.ncoords + sum(len(c.film) for c in model.coordinates))
    state[model.ncoords + ix] = v
    got = []
    for inputs in ({"w_z": w}, {"f_y": -w * sign * 2 * xyz_mass(etch) * v}):
        inst = fmu.Instance(path, cosim=False)
        inst.set({"etch": etch} | inputs)
        inst.start()
        inst.set_states(state)
        got.append(float(inst.get(["qdd_y"])[0]))
        inst.close()
    tol = 1e-11 + model.process["inertial"]["etch"]["max_rel_error"] + 1e-12
    assert got[0] != 0.0
    assert got[0] == pytest.approx(got[1], rel=tol, abs=0), got


@pytest.mark.parametrize("etch", fp.ETCH_CAPS)
def test_etch_moves_the_combs_stops(combs, etch):
    """Comb xp_t's finger stop follows the etch as its terms do (netgen.emit.process.stop_offsets: the
    finger gap 1.5 um + 2 etch, process_cases.xyz_text): the FMU's q''_x / x along x alone (no voltage,
    no force) 20 nm before and after the etched gap against its value at 0.1 um. The model's springs
    are linear (no strain energy; asserted), so before contact the ratio is the springs' to round-off,
    1e-12 (tests/emit/test_fmu.py's n eps); 20 nm into the stop its penalty (stiffness x penetration
    20 nm / 1.5 um) is of the order of the spring's force: > 0.1 of it. With the drawn stop (the FMU
    before the law) the contact began 200 nm early or late: one side or the other fails."""
    model = combs[0]
    assert model.nonlinear_energy_polynomial() is None
    before, after = fp.comb_stop_onset(model, combs[2], etch, 1.5e-6, 20e-9)
    assert before <= 1e-12, (before, after)
    assert after > 0.1, (before, after)
