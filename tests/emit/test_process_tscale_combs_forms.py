"""tscale's capacitance law on textbook comb fingers (netgen.model.process.thickness_capacitance:
pc_<electrode> a cubic in tscale, exactly tscale for eps t / g) in every emitted form: the .lib (ngspice
39 and 46), the _xspice.lib (netgen_es code model, ngspice 39 as installed), the .va through OSDI
(ngspice 46), the same module in VACASK and the FMU, on examples/accelerometer_xyz with textbook
combs (tests/oracles/process_cases.xyz_thick, comb xp_t).

Tolerances:
- C at rest of xp_t from .ac of its current (no DC bias: no force, the mass still) against the
  textbook form 20 eps (2 um tscale) 30 um / 1.5 um: within the fit's max_rel_error at rest plus the
  law's stated error (as tests/model/test_process_tscale_combs.py); and against the Python model's law
  (capacitance_at, the arithmetic the forms render): ngspice's linear AC solve, round-off, 1e-9.
- the forces: COMB_VOLTS on xp_t; the comb's force ~ t (eps t / g) and the in-plane stiffness of the
  legs ~ t (bending in plane and stretching; the laws exact: the model test's 5.7e-11), and the textbook
  comb has no vertical force, so the static state is the same at every tscale. The FMU's balance
  (model exchange, q'' = 0 at rest, solved to 1e-15) at tscale against the FMU's at 1: relative to the
  largest scaled deflection, cond(J) (2 x 1e-12 + d) (the forces' round-off, tests/emit/test_fmu.py),
  d the in-plane stiffness laws' own departure from k t (the cubic's least-squares round-off,
  netgen.model.process.power_fit: about 1e-10; read from the laws, coordinate_values). ngspice's .op of the .lib against the FMU at the same tscale: cond(J)
  (RELTOL + 1e-12), Newton's test (as tests/emit/test_fmu_process.py). The FMU's charge against the
  model's law at its state times the voltage: 1e-12. VACASK's op of the OSDI module at reltol RELTOL
  and vntol 1e-12 V: its x against the FMU's at the same tscale, the same Newton bound. vntol 1e-12 V
  (above the velocity nodes' rounding floor at rest, docs/contact.md) is 1e-10 of the largest
  deflection (x_x ~ 0.01 um: 9.9e-11 textbook, 7.2e-11 field2d), so the step Newton last tested is
  within RELTOL + 1e-10 of it, and the state it returns within a constant times that step squared. Without the law the force were tscale times too
  small: the deflection 10 % off at 0.9 and 1.1.

The same example with its own field2d combs (the `field2d` tests; pc_xp_t 0.933 at 0.9, not tscale:
the fringe does not grow with t), whose combs carry the state factor 1 + u P1(xs) + u^2 P2(xs), u =
tscale - 1 (netgen.model.etch_state; 1 at rest, so checked at a displaced state, with the helpers and
bounds of tests/emit/test_process_etch_field2d_forms.py at tscale 0.9: xp_t's C there against the
Python law, 1e-9; the forces on x, y, rot_z against a five-point difference of the law's C,
F2D_TOL 4.2e-11, derived there for the same comb cells and fits' degree; the FMU's charge 1e-12 and
forces; the law without the factor is seen); under COMB_VOLTS the fingers also lift the mass (levitation),
so the state moves with tscale: the FMU's charge at its balance against the law there, 1e-12, and the
.lib's .op (ngspice 39) and VACASK's op against the FMU's balance, Newton's bound as above.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen import emit
from netgen.core.constants import EPS0
from netgen.emit import ngspice as emit_ngspice
from netgen.model.process import capacitance_at, coordinate_values
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import run_vacask
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.emit.test_process_etch_field2d_forms import check_state, check_state_fmu, state_deck
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles import fmu_process as fp
from tests.oracles.process_cases import control_block, osdi_form, xyz_thick

TSCALES = (0.9, 1.1)  # the default tscale_range's ends
STATE_TSCALE = 0.9  # the field2d combs' state factor's check: a range end (|u| largest)


@pytest.fixture(scope="module")
def xyz():
    return build_model(parse_structure(xyz_thick(process='\n[process]\nparameters = ["tscale"]\n'), "xyz.toml"))


def deck(include: str, tscale: float, control: str = "") -> str:
    """.ac of comb xp_t's current at rest (the other electrodes and the plate at 0 V)."""
    pins = "d 0 0 0 0 0 0 0 0 0 p " + " ".join(f"0 x{k}" for k in range(6)) + " 0 0 0"
    return f"""* comb cap
.include {include}
Vd d 0 DC 0 AC 1
Vp p 0 0
X1 {pins} accelerometer_xyz tscale={tscale!r}
.ac lin 1 1k 1k
{control}
.end
"""


def check(xyz, plot, tscale: float) -> None:
    """xp_t's C at rest against the textbook form and the model's law (module docstring)."""
    cap = abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    tol = xyz.capacitances[k].max_rel_error + xyz.process["tscale"]["capacitance_max_rel_error"]
    assert cap == pytest.approx(20 * EPS0 * 2e-6 * tscale * 30e-6 / 1.5e-6, rel=tol, abs=0)
    law = capacitance_at(xyz, np.zeros((1, xyz.ncoords)), tscale=tscale)[0, k]
    assert cap == pytest.approx(law, rel=1e-9, abs=0)


@pytest.mark.parametrize("tscale", TSCALES)
def test_lib(xyz, tmp_path, ngspice_version, tscale):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check(xyz, run_ngspice(deck(str(tmp_path / "xyz.lib"), tscale), tmp_path)[0], tscale)


@pytest.mark.parametrize("tscale", TSCALES)
def test_xspice(xyz, tmp_path, tscale):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    check(xyz, run_ngspice(deck(str(xlib.resolve()), tscale, control_block(control, "ac.raw")), tmp_path)[0], tscale)


@pytest.mark.parametrize("tscale", TSCALES)
def test_osdi(xyz, tmp_path, monkeypatch, tscale):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)
    net = deck(inc, tscale, control_block(pre, "ac.raw"))
    check(xyz, run_ngspice(net, tmp_path / "run")[0], tscale)


def plane(xyz) -> list:
    """(index, coordinate) of the in-plane coordinates, the ones the comb moves (x, y, rot_z)."""
    return [(v, c) for v, c in enumerate(xyz.coordinates) if c.name in ("x", "y", "rot_z")]


@pytest.fixture(scope="module")
def built(xyz, tmp_path_factory):
    lib = tmp_path_factory.mktemp("tscale_combs") / "xyz.lib"
    lib.write_text(emit_ngspice.subcircuit(xyz))
    path = fmu.built(xyz)
    return lib, path, fp.comb_balance(xyz, path, 1.0, "tscale")


@pytest.mark.parametrize("tscale", TSCALES)
def test_forces_fmu_and_lib(xyz, built, tmp_path, tscale):
    """The static state under COMB_VOLTS on xp_t at tscale: the FMU's the same as at 1, the .lib's .op
    the FMU's, the FMU's charge the law's (module docstring)."""
    lib, path, (q1, _, cond1) = built
    q, charge, cond = fp.comb_balance(xyz, path, tscale, "tscale")
    scale = np.array([c.scale for c in xyz.coordinates])
    big = np.max(np.abs(q) / scale)
    d = max(
        abs(coordinate_values(xyz.process, v, tscale=tscale)[1] / (tscale * c.stiffness) - 1) for v, c in plane(xyz)
    )
    assert float(np.max(np.abs(q - q1) / scale) / big) <= max(cond, cond1) * (2e-12 + d)
    op = fp.comb_op(xyz, lib, tscale, tmp_path, "tscale")
    assert float(np.max(np.abs(q - op) / scale) / big) <= cond * (fp.RELTOL + 1e-12)
    k = [f.electrode for f in xyz.capacitances].index(fp.COMB)
    ref = capacitance_at(xyz, (q / scale)[None, :], tscale=tscale)[0, k] * fp.COMB_VOLTS
    assert charge == pytest.approx(ref, rel=1e-12, abs=0)


@pytest.mark.parametrize("tscale", TSCALES)
def test_forces_vacask(xyz, built, tmp_path, tscale):
    """The OSDI module in VACASK, tscale on its model card, COMB_VOLTS on xp_t: its static x (um at
    x_x) against the FMU's balance at the same tscale (module docstring)."""
    _, path, _ = built
    q, _, cond = fp.comb_balance(xyz, path, tscale, "tscale")
    scale = np.array([c.scale for c in xyz.coordinates])
    x = vacask_x(xyz, tmp_path, tscale)
    assert abs(x - q[0]) / scale[0] <= cond * (fp.RELTOL + 1e-12) * np.max(np.abs(q) / scale)


def vacask_x(xyz, tmp_path, tscale: float) -> float:
    """x (m) of VACASK's op of the OSDI module, tscale on its model card, COMB_VOLTS on xp_t (reltol
    RELTOL, vntol 1e-12 V)."""
    emit.write_outputs(xyz, tmp_path, "osdi")
    outs = " ".join(f"0 x_{c.name}" for c in xyz.coordinates)
    net = f"""xyz comb
ground 0
load "{tmp_path / "accelerometer_xyz.osdi"}"
model mems accelerometer_xyz tscale={tscale!r}
model vsource vsource
x1 (d 0 0 0 0 0 0 0 0 0 0 {outs} 0 0 0) mems
v_d (d 0) vsource dc={fp.COMB_VOLTS!r}
control
  options reltol={fp.RELTOL!r} vntol=1e-12
  analysis op1 op
endc
"""
    plot = run_vacask(net, tmp_path / "run", analysis="op1")
    return float(np.atleast_1d(plot["x_x"])[0]) * 1e-6  # x_x in um


@pytest.fixture(scope="module")
def xyz2d():
    """accelerometer_xyz with its own field2d combs and tscale declared (the 2-D section tables at the
    law's five thicknesses ship: netgen/electrostatics/comb_tables)."""
    text = xyz_thick(process='\n[process]\nparameters = ["tscale"]\n')
    return build_model(parse_structure(text.replace('comb_model = "textbook"', 'comb_model = "field2d"'), "xyz.toml"))


def test_field2d_law_is_not_tscale(xyz2d):
    """The case exercises what the textbook one cannot: the field2d comb's ratio departs from tscale (the
    fringe and the substrate's share do not grow with t), by more than a form's 1e-9 round-off could hide."""
    ratio = {r["electrode"]: r["ratio"] for r in xyz2d.process["tscale"]["capacitance_laws"]}["xp_t"]
    assert abs(float(np.dot(ratio, [1.0, 0.9, 0.81, 0.729])) / 0.9 - 1) > 1e-3


def test_field2d_has_state_factors(xyz2d):
    """Every comb of the field2d case carries a state factor (u = tscale - 1), and the stated error
    with it is below the one without (the law's own check points, held out of the fit)."""
    t = xyz2d.process["tscale"]
    assert all("state" in r for r in t["capacitance_laws"] if r["electrode"][0] in "xy")
    assert t["capacitance_max_rel_error"] < t["capacitance_stateless_max_rel_error"]


def test_field2d_state_lib(xyz2d, tmp_path, ngspice_version):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz2d))

    def run(xs, bias):
        deck = state_deck(str(tmp_path / "xyz.lib"), xyz2d, STATE_TSCALE, xs, bias, param="tscale")
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz2d, run, STATE_TSCALE, "tscale")


def test_field2d_state_xspice(xyz2d, tmp_path):
    xlib, control = sdn.xspice_library(xyz2d, tmp_path, sdn.code_models(False))

    def run(xs, bias):
        deck = state_deck(
            str(xlib.resolve()), xyz2d, STATE_TSCALE, xs, bias, control_block(control, "s.raw"), param="tscale"
        )
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz2d, run, STATE_TSCALE, "tscale")


def test_field2d_state_osdi(xyz2d, tmp_path, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz2d, tmp_path)

    def run(xs, bias):
        deck = state_deck(
            inc,
            xyz2d,
            STATE_TSCALE,
            xs,
            bias,
            control_block(pre, "s.raw"),
            param="tscale",
        )
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz2d, run, STATE_TSCALE, "tscale")


def test_field2d_state_fmu(xyz2d):
    """The FMU at the displaced state: charge and forces against the law (check_state_fmu's bounds)."""
    check_state_fmu(xyz2d, STATE_TSCALE, "tscale")


@pytest.mark.parametrize("tscale", TSCALES)
def test_field2d_forces(xyz2d, tmp_path, tscale):
    """COMB_VOLTS on xp_t at tscale (the field2d comb also lifts the mass: levitation): the FMU's charge
    at its balance against the law there (1e-12), the .lib's .op in ngspice 39 and the OSDI module's op
    in VACASK against the FMU's balance, Newton's bound cond(J) (RELTOL + 1e-12) (module docstring)."""
    lib = tmp_path / "xyz.lib"
    lib.write_text(emit_ngspice.subcircuit(xyz2d))
    q, charge, cond = fp.comb_balance(xyz2d, fmu.built(xyz2d), tscale, "tscale")
    scale = np.array([c.scale for c in xyz2d.coordinates])
    big = np.max(np.abs(q) / scale)
    k = [f.electrode for f in xyz2d.capacitances].index(fp.COMB)
    assert charge == pytest.approx(
        capacitance_at(xyz2d, (q / scale)[None, :], tscale=tscale)[0, k] * fp.COMB_VOLTS, rel=1e-12, abs=0
    )
    op = fp.comb_op(xyz2d, lib, tscale, tmp_path, "tscale")
    assert float(np.max(np.abs(q - op) / scale) / big) <= cond * (fp.RELTOL + 1e-12)
    x = vacask_x(xyz2d, tmp_path, tscale)
    assert abs(x - q[0]) / scale[0] <= cond * (fp.RELTOL + 1e-12) * big
