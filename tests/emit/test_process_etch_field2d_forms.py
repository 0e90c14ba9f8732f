"""accelerometer_xyz's own (2-D cell, field2d) combs under etch in the emitted forms: the .lib (ngspice
39 and 46), the _xspice.lib (netgen_es code model, ngspice 39) and the .va through OSDI (ngspice 46).
Each comb's fit is read at the state shifted by the geometric 2 etch plus a fitted effective part
across its fingers (netgen.model.etch_combs); its contact stops follow the geometric shift alone
(stop_shift: nodes of their own in the code model, offsets in the .lib and the .va).

Tolerances:
- comb xp_t's C at rest from .ac of its current (no bias: no force, the mass still) against the Python
  law (netgen.model.process.capacitance_at, the arithmetic the emitters render): the forms evaluate
  the same polynomial at the same shifted state, round-off: 1e-9.
- xp_t's sidewall stop at rest in the .lib: its penetration node reads -(1.5 um + 2 etch) / 1.5 um
  (the geometric shift, not the effective one, which would put it 0.14 etch nearer), within STOP_REL
  (1e-11: the offset read to 11 digits); the mass pushed onto it at the model's rest (rest_exact),
  the .lib within REST_REL (2.5e-10: its B-source coefficients read to 11 digits), the _xspice.lib,
  OSDI and VACASK (at its default tolerances: the rest is where every element is linear) within
  FULL_REL (1e-12); the mechanics and stops are the textbook case's, so are the derivations in
  tests/emit/test_process_etch_forms.py, next to the constants.

The combs' state factor 1 + u P1(xs) + u^2 P2(xs) (netgen.model.etch_state) is 1 at rest, so it is
checked at a displaced state (in the forms above, the FMU, and the forces in VACASK) (z, tilt_x, tilt_y moved by force inputs, x, y, rot_z left free):
- C of xp_t there from .ac without bias against the Python law at the .op's state: round-off, 1e-9
  (as at rest).
- the electrostatic forces on x, y, rot_z with 5 V on xp_t: the form's K(etch) q (the .op balances
  them; netgen.model.process.coordinate_values) against 1/2 V^2 dC/dq of the Python law's C by a
  five-point central difference of step h = 1e-3 in xs (an independent reference for the product rule
  pc (pr dC0 + C0 dpr)). Compared as dW/dxs (J, one unit for the three) relative to their largest:
  truncation h^4/30 |C^(5)| / |C'| <= h^4 120 / (30 0.6^4) = 3.1e-11 (C of a gap 1 - x closing to
  0.6 at the box's edge); round-off 1.5 eps_C / h with eps_C <= 28 terms x 2.1 (the fit's
  sum |terms| / |P| over the box) x 1.1e-16 = 6.5e-15: 9.8e-12; the .op at reltol 1e-12, vntol 1e-12 V
  (above the rest's rounding floor on the velocity nodes, docs/contact.md): the step Newton last tested
  is within reltol |v| + vntol, 1e-12 + 7.9e-11 of the largest force here (x at 0.0126 um), and the
  iterate it returns within a constant times that step squared (quadratic convergence: the forms'
  Jacobians are analytic), so the state is round-off, 1e-12 kept; 4.2e-11 in all. The law without the state factor is 7e-4 .. 7e-3 off there.
- energy: the form's own force against 1/2 V^2 dC/dxs_x of the form's own charge (C from .ac at
  xs -+ h, -+ 2h along x, set by force inputs without bias; h = 1e-2): the .ac's C within the rest
  check's 1e-9 gives 1.5e-9 / h = 1.5e-7 relative, truncation (1e-2)^4 120 / (30 0.6^4) = 3.1e-7:
  4.6e-7 (the charge is the energy's, the force its slope: a product rule dropped in the force or the
  charge fails by 7e-4).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from netgen import emit
from netgen.emit import ngspice as emit_ngspice
from netgen.emit.etch_state import RECORDS
from netgen.model.process import capacitance_at, coordinate_values
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.emit.test_process_etch_forms import (
    FULL_REL,
    REST_REL,
    STOP_REL,
    comb_deck,
    push_deck,
    rest_exact,
    rest_x,
    sidewall_stop,
    vacask_rest,
)
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import PERFORATED_ETCHES, control_block, osdi_form, xyz_etch_text


@pytest.fixture(scope="module")
def xyz():
    """accelerometer_xyz with its field2d combs and etch declared (the etched cells' tables ship)."""
    text = xyz_etch_text().replace('comb_model = "textbook"', 'comb_model = "field2d"')
    return build_model(parse_structure(text, "xyz.toml"))


def check_rest(xyz, plot, etch: float) -> None:
    """xp_t's C at rest against the Python law (round-off)."""
    cap = abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    assert cap == pytest.approx(capacitance_at(xyz, np.zeros((1, xyz.ncoords)), etch)[0, k], rel=1e-9, abs=0)


def test_law_has_effective_shift(xyz):
    """The case exercises what the forms must render apart: a fitted shift beside the stops' geometric one."""
    law = next(r for r in xyz.process["etch"]["capacitance"] if r["electrode"] == "xp_t")
    assert law["stop_shift"] == {"x": -2.0, "y": -2.0} and law["shift"]["x"] != -2.0


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_lib(xyz, tmp_path, ngspice_version, etch):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check_rest(xyz, run_ngspice(comb_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_xspice(xyz, tmp_path, etch):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    check_rest(
        xyz, run_ngspice(comb_deck(str(xlib.resolve()), etch, control_block(control, "ac.raw")), tmp_path)[0], etch
    )


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_rest_osdi(xyz, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)
    deck = comb_deck(inc, etch, control_block(pre, "ac.raw"))
    check_rest(xyz, run_ngspice(deck, tmp_path / "run")[0], etch)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_lib(xyz, tmp_path, ngspice_version, etch):
    """xp_t's sidewall stop at rest at the geometric widened gap (STOP_REL)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    plot = run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch, push=0.0), tmp_path)[0]
    sg = float(np.real(plot[f"v(x1.sg_{sidewall_stop(xyz) + 1})"])[0])
    assert sg == pytest.approx(-(1.5e-6 + 2 * etch) / 1.5e-6, rel=STOP_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_pushed_lib(xyz, tmp_path, ngspice_version, etch):
    """The .lib pushed onto the stop rests at rest_exact (REST_REL: its 11-digit coefficients)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    got = rest_x(run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=REST_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_xspice(xyz, tmp_path, etch):
    """The code model's stops read their own geometric-shift columns: rest_exact in ngspice 39 (FULL_REL)."""
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    got = rest_x(run_ngspice(push_deck(str(xlib.resolve()), etch, control_block(control, "op.raw")), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_osdi(xyz, tmp_path, monkeypatch, etch):
    """The .va through OSDI (ngspice 46) pushed rests at rest_exact (FULL_REL)."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)
    deck = push_deck(inc, etch, control_block(pre, "op.raw"))
    got = rest_x(run_ngspice(deck, tmp_path / "run")[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", PERFORATED_ETCHES)
def test_stop_vacask(xyz, tmp_path, etch):
    """The same module in VACASK (its default tolerances: the rest is where every element is linear,
    tests/emit/test_process_etch_forms.test_comb_stop_vacask) rests at rest_exact (FULL_REL)."""
    assert vacask_rest(xyz, tmp_path, etch) == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


# ------------------------------------------------------------------ the state factor at a displaced state

STATE_ETCH, VOLTS = -1e-7, 5.0  # the range's end where the factor is largest, xp_t's bias
OUT_OF_PLANE = {"z": 0.1, "tilt_x": -0.08, "tilt_y": 0.09}  # scaled states set by force inputs
F2D_TOL, ENERGY_TOL = 4.2e-11, 4.6e-7


def point(param: str | dict, value: float) -> dict[str, float]:
    """The process point of the helpers below: {param: value}, or `param` itself where it is a point
    (tscale and etch together: tests/emit/test_process_cross_field2d_forms.py; `value` unread)."""
    return dict(param) if isinstance(param, dict) else {param: value}


def state_deck(
    include: str, model, etch: float, xs: dict[str, float], bias: float, control: str = "", param: str | dict = "etch"
) -> str:
    """.op (and .ac with no bias) of accelerometer_xyz with force inputs holding the coordinates of
    `xs` (scaled) at K(etch) L xs and `bias` V on xp_t (the other electrodes and the plate at 0 V);
    `param`: the process parameter `etch` is the value of (tscale: tests/emit/test_process_tscale_combs_forms;
    a point: point)."""
    srcs = []
    for k, c in enumerate(model.coordinates):
        stiff = coordinate_values(model.process, k, **point(param, etch))[1]
        srcs.append(f"Vf{k} f{k} 0 DC {float(stiff * c.scale * xs.get(c.name, 0.0) / c.port_units[3])!r}")
    pins = "d 0 0 0 0 0 0 0 0 0 p " + " ".join(f"f{k} x{k}" for k in range(6)) + " 0 0 0"
    return "\n".join(
        [
            "* state",
            f".include {include}",
            f"Vd d 0 DC {bias!r} AC 1",
            "Vp p 0 0",
            *srcs,
            f"X1 {pins} accelerometer_xyz " + " ".join(f"{k}={v!r}" for k, v in point(param, etch).items()),
            ".options reltol=1e-12 vntol=1e-12 abstol=1e-20",
            ".op",
            ".ac lin 1 1k 1k" if bias == 0.0 else "",
            control,
            ".end",
        ]
    )


def plot_of(plots, kind: str):
    return next(p for p in plots if kind in p.name)


def state_of(model, plot) -> np.ndarray:
    """The scaled state of the .op from the x_<q> ports (1 V = one displacement unit)."""
    return np.array(
        [float(np.real(plot[f"v(x{k})"])[0]) * c.port_units[1] / c.scale for k, c in enumerate(model.coordinates)]
    )


def law_slopes(model, xs: np.ndarray, etch: float, h: float = 1e-3, param: str | dict = "etch") -> np.ndarray:
    """dC_xp_t/dxs (F) of the Python law at xs (`param` = etch) by a five-point central difference of step h."""
    k = [f.electrode for f in model.capacitances].index("xp_t")
    out = np.zeros(len(xs))
    for v in range(len(xs)):
        e = np.eye(len(xs))[v] * h
        c = [capacitance_at(model, (xs + j * e)[None], **point(param, etch))[0, k] for j in (-2, -1, 1, 2)]
        out[v] = (c[0] - 8 * c[1] + 8 * c[2] - c[3]) / (12 * h)
    return out


def form_slopes(model, xs: np.ndarray, etch: float, param: str | dict = "etch") -> np.ndarray:
    """The form's electrostatic dW/dxs = F L on x, y, rot_z at the .op: K(etch) L^2 xs (no force input)."""
    return np.array(
        [
            coordinate_values(model.process, v, **point(param, etch))[1] * model.coordinates[v].scale ** 2 * xs[v]
            for v in range(3)
        ]
    )


def stateless(model, param: str | dict = "etch"):
    """The model without its combs' state factors (what the law was before netgen.model.etch_state; a
    point's parameters' factors, and the cross factors, all)."""
    other = copy.deepcopy(model)
    for name in point(param, 0.0):
        for r in other.process[name][RECORDS[name]]:
            r.pop("state", None)
            r.pop("cross", None)
    return other


def check_state(model, run, etch: float = STATE_ETCH, param: str | dict = "etch") -> None:
    """C at the displaced state without bias, and the forces with VOLTS on xp_t, against the Python law
    (`param` = etch: the process parameter's value)."""
    plots = run(OUT_OF_PLANE, 0.0)
    xs = state_of(model, plot_of(plots, "Operating"))
    cap = abs(float(np.imag(plot_of(plots, "AC")["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in model.capacitances].index("xp_t")
    assert cap == pytest.approx(capacitance_at(model, xs[None], **point(param, etch))[0, k], rel=1e-9, abs=0)
    xs = state_of(model, plot_of(run(OUT_OF_PLANE, VOLTS), "Operating"))
    got, ref = form_slopes(model, xs, etch, param), 0.5 * VOLTS**2 * law_slopes(model, xs, etch, param=param)[:3]
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(got - ref)) <= F2D_TOL * scale, (got, ref)
    bare = 0.5 * VOLTS**2 * law_slopes(stateless(model, param), xs, etch, param=param)[:3]
    assert np.max(np.abs(bare - ref)) > 1e3 * F2D_TOL * scale  # the check sees the factor


def test_law_has_state_factors(xyz):
    """Every comb of the field2d case carries a state factor, and the stated error with it is below the
    one without (the law's own check points, held out of the fit)."""
    e = xyz.process["etch"]
    assert all("state" in r for r in e["capacitance"] if r["electrode"][0] in "xy")
    assert e["capacitance_max_rel_error"] < e["capacitance_stateless_max_rel_error"]


def test_state_lib(xyz, tmp_path, ngspice_version):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))

    def run(xs, bias):
        return run_ngspice(state_deck(str(tmp_path / "xyz.lib"), xyz, STATE_ETCH, xs, bias), tmp_path / f"r{bias}")

    check_state(xyz, run)


def test_state_xspice(xyz, tmp_path):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))

    def run(xs, bias):
        deck = state_deck(str(xlib.resolve()), xyz, STATE_ETCH, xs, bias, control_block(control, "s.raw"))
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz, run)


def test_state_osdi(xyz, tmp_path, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)

    def run(xs, bias):
        deck = state_deck(inc, xyz, STATE_ETCH, xs, bias, control_block(pre, "s.raw"))
        return run_ngspice(deck, tmp_path / f"r{bias}")

    check_state(xyz, run)


def test_state_energy_lib(xyz, tmp_path, ngspice_version):
    """The .lib's force on x at the biased state against the slope of its own charge (module doc)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    lib = str(tmp_path / "xyz.lib")
    xs = state_of(
        xyz, plot_of(run_ngspice(state_deck(lib, xyz, STATE_ETCH, OUT_OF_PLANE, VOLTS), tmp_path / "b"), "Operating")
    )
    h, caps = 1e-2, []
    for j in (-2, -1, 1, 2):
        at = {c.name: float(x) for c, x in zip(xyz.coordinates, xs + j * h * np.eye(6)[0])}
        plot = plot_of(run_ngspice(state_deck(lib, xyz, STATE_ETCH, at, 0.0), tmp_path / f"c{j}"), "AC")
        caps.append(abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3))
    slope = 0.5 * VOLTS**2 * (caps[0] - 8 * caps[1] + 8 * caps[2] - caps[3]) / (12 * h)
    assert form_slopes(xyz, xs, STATE_ETCH)[0] == pytest.approx(slope, rel=ENERGY_TOL, abs=0)


def test_state_fmu(xyz):
    """The FMU (model exchange, states set directly): its charge of xp_t at the displaced state against
    the Python law (1e-12: the terms summed in another order, tests/emit/test_fmu.py) and its forces
    M (q''(V) - q''(0)) as dW/dxs against the law's slopes (F2D_TOL: the difference's truncation and
    round-off as above; the FMU's forces to 1e-12)."""
    check_state_fmu(xyz, STATE_ETCH)


def check_state_fmu(xyz, etch: float, param: str | dict = "etch") -> None:
    """The FMU's charge and forces at the displaced state against the law (test_state_fmu; `param` = etch)."""
    pytest.importorskip("fmpy")
    from netgen.sim import fmu

    inst = fmu.Instance(fmu.built(xyz), cosim=False)
    inst.set(point(param, etch))
    inst.start()
    xs = np.array([0.03, -0.02, 0.04] + list(OUT_OF_PLANE.values()))
    x = np.zeros(inst.md.numberOfContinuousStates)
    x[:6] = xs * xyz.scales
    names = [f"qdd_{c.name}" for c in xyz.coordinates]
    inst.set_states(x)
    free = inst.get(names)
    inst.set({"V_xp_t": VOLTS})
    inst.set_states(x)
    pulled, charge = inst.get(names), inst.get(["Q_xp_t"])[0]
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    assert charge == pytest.approx(capacitance_at(xyz, xs[None], **point(param, etch))[0, k] * VOLTS, rel=1e-12, abs=0)
    mass = np.array([coordinate_values(xyz.process, v, **point(param, etch))[0] for v in range(6)])
    got, ref = mass * (pulled - free) * xyz.scales, 0.5 * VOLTS**2 * law_slopes(xyz, xs, etch, param=param)
    assert np.max(np.abs(got - ref)) <= (F2D_TOL + 1e-12) * np.max(np.abs(ref)), (got, ref)


def test_state_vacask(xyz, tmp_path):
    """The same .va module in VACASK (its op at reltol 1e-12, vntol 1e-12 as the ngspice decks): the
    forces with VOLTS on xp_t at the displaced state against the law's slopes (F2D_TOL)."""
    check_state_vacask(xyz, tmp_path, STATE_ETCH)


def check_state_vacask(xyz, tmp_path, etch: float, param: str | dict = "etch") -> None:
    """test_state_vacask at a process point (`param`, point)."""
    from netgen.core.paths import vacask_string
    from netgen.sim.vacask import run_vacask

    at = point(param, etch)
    emit.write_outputs(xyz, tmp_path, "osdi")
    ports = " ".join(["d", *["0"] * 9, "p"] + [f"f{k} x{k}" for k in range(6)] + ["0", "0", "0"])
    srcs = [f"v_d (d 0) vsource dc={VOLTS!r}", "v_p (p 0) vsource dc=0"]
    for k, c in enumerate(xyz.coordinates):
        stiff = coordinate_values(xyz.process, k, **at)[1]
        force = stiff * c.scale * OUT_OF_PLANE.get(c.name, 0.0) / c.port_units[3]
        srcs.append(f"v_f{k} (f{k} 0) vsource dc={float(force)!r}")
    net = "\n".join(
        [
            "xyz state",
            "ground 0",
            f"load {vacask_string(tmp_path / 'accelerometer_xyz.osdi', tmp_path / 'run')}",
            "model mems accelerometer_xyz " + " ".join(f"{k}={v!r}" for k, v in at.items()),
            "model vsource vsource",
            f"x1 ({ports}) mems",
            *srcs,
            "control",
            "  options reltol=1e-12 vntol=1e-12",
            "  analysis op1 op",
            "endc",
            "",
        ]
    )
    plot = run_vacask(net, tmp_path / "run", analysis="op1")
    xs = np.array(
        [float(np.atleast_1d(plot[f"x{k}"])[0]) * c.port_units[1] / c.scale for k, c in enumerate(xyz.coordinates)]
    )
    got, ref = form_slopes(xyz, xs, etch, param), 0.5 * VOLTS**2 * law_slopes(xyz, xs, etch, param=param)[:3]
    assert np.max(np.abs(got - ref)) <= F2D_TOL * np.max(np.abs(ref)), (got, ref)
