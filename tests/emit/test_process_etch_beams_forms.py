"""The etch on a beam conductor in every emitted form: the clamped-clamped beam of
tests/oracles/beam_etch (examples/cc_beam.toml, the electrode past the beam's sides, a_in) in the .lib
(ngspice 39 and 46), the _xspice.lib (ngspice 39), the .va through OSDI (ngspice 46), VACASK and the FMU.

The oracle is the beam's width law: with its length fixed, everything of a clamped-clamped beam that
the model carries is proportional to its width w (modal masses rho w t L c_v and stiffnesses E w t^3
/ L^3 c_v with width-independent mode shapes, the stretching energy E w t (int w'^2 / 2)^2 / 2L, the
a_in load rho w t int phi dx, and with fringe "none" over an electrode wider than the beam the
capacitance eps w int dx / (g - q phi)). So with a force scaled by r = (w - 2 etch) / w the beam
moves as the drawn beam does under the unscaled force, at every frequency and into the stretching
range, and its capacitance is r times the drawn one at the same state. Each deck holds one instance
per etch of tests/oracles/beam_etch.ETCHES and one at etch 0, with the force r F; the etched
instances are held to the etch-0 one of the same run.

Tolerances:
- static (.op, 12 uN on m1: 0.29 um, the stretching 2 % of the restoring force there): the laws'
  stated errors (mechanics and strain energy, each relative) plus the peak normalisation's round-off
  in m and k (tests/model/test_process_etch_beams.py: 2e-7) plus Newton's reltol 1e-10 and vntol
  1e-12 V (above the velocity nodes' rounding floor, docs/contact.md; 4e-12 of |x| >= 0.25 um): 2e-7 + the
  stated. Without the energy's etch ratio the etched instances are 2e-4 off.
- .ac at 50 and 300 kHz around that operating point: 1/H = k_t - m w^2, each relative error at most
  the above, amplified by (k_t + m w^2) / |k_t - m w^2| (2.5 at 300 kHz, f1 = 195 kHz): 3 x that.
- C at rest (.ac of the electrode current, the beam unbiased) over r against the etch-0 instance's:
  the capacitance law's stated error + 1e-9 (ngspice's AC solve to round-off); the etch-0 instance's
  C against eps w L / g within its fit's held-out error (the fit at rest).
- under SHOCK = 3e5 m/s^2 on a_in alone (-0.25 um; the load G ~ w, the mass's ratio): the same as
  the forced instances plus the load law's stated residual.
- the FMU (model exchange): at one state with the same scaled force and SHOCK on a_in the
  accelerations qdd equal the etch-0 instance's (m, k, the energy and the load all ~ w) within the
  static bound plus the load law's residual, and the charge over r at 1 V within the capacitance bound.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen import emit
from netgen.core.constants import EPS0
from netgen.emit import ngspice as emit_ngspice
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import run_vacask
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.beam_etch import ETCHES, beam_text, width_ratio
from tests.oracles.process_cases import control_block

FORCE = 12.0  # uN on m1 (1 V = 1 uN)
SHOCK = 3e5  # m/s^2 on a_in: G a about 10 uN on m1, -0.25 um
POINTS = (0.0, *ETCHES)
NORMALISATION = 2e-7  # the peak normalisation's round-off (tests/model/test_process_etch_beams.py)


@pytest.fixture(scope="module")
def model():
    return build_model(parse_structure(beam_text("cc_beam"), "cc_beam.toml"))


def bounds(model) -> tuple[float, float, float]:
    """(static, ac, capacitance) relative bounds (module docstring)."""
    p = model.process
    static = p["etch"]["max_rel_error"] + p["strain_energy"]["max_rel_error"] + NORMALISATION + 1e-10
    return static, 3 * static, p["etch"]["capacitance_max_rel_error"] + 1e-9


def load_error(model) -> float:
    """The a_in load law's stated residual (netgen.model.process_loads.acceleration_law)."""
    return model.process["etch"]["acceleration"]["max_rel_error"]


def instances(analysis: str) -> str:
    """Per etch point: a forced instance (r FORCE DC, r AC on f_m1, gravity on a_in) and, in the .ac
    deck, an unbiased one whose electrode current gives C."""
    out = ["Va a 0 DC 9.81", "Vd d 0 DC 0 AC 1", f"Vg g 0 DC {SHOCK!r}"]
    for i, e in enumerate(POINTS):
        r = width_ratio("cc_beam", e)
        out += [
            f"Xf{i} 0 0 f{i} xf{i} 0 xf2_{i} 0 xf3_{i} a cc_beam etch={e!r}",
            f"Vf{i} f{i} 0 DC {FORCE * r!r} AC {r!r}",
            f"Xg{i} 0 0 0 xg{i} 0 xg2_{i} 0 xg3_{i} g cc_beam etch={e!r}",
        ]
        if analysis == "ac":
            out += [f"Xc{i} d p{i} 0 xc{i} 0 xc2_{i} 0 xc3_{i} 0 cc_beam etch={e!r}", f"Vp{i} p{i} 0 0"]
    return "\n".join(out)


def deck(include: str, analysis: str, control: str = "") -> str:
    card = ".op" if analysis == "op" else ".ac lin 2 50k 300k"
    return f"* cc beam etch\n.include {include}\n{instances(analysis)}\n.options reltol=1e-10 vntol=1e-12 abstol=1e-20\n{card}\n{control}\n.end\n"


def check(model, op, ac) -> None:
    """The etched instances against the etch-0 one (module docstring)."""
    static, dynamic, cap = bounds(model)
    x0, g0 = float(np.real(op["v(xf0)"])[0]), float(np.real(op["v(xg0)"])[0])
    assert 0.2 < x0 < 0.4 and -0.4 < g0 < -0.1  # um: into the stretching range
    for i, e in enumerate(POINTS[1:], start=1):
        assert float(np.real(op[f"v(xf{i})"])[0]) == pytest.approx(x0, rel=static)
        assert float(np.real(op[f"v(xg{i})"])[0]) == pytest.approx(g0, rel=static + load_error(model))
        np.testing.assert_allclose(ac[f"v(xf{i})"], ac["v(xf0)"], rtol=dynamic)
        c = np.imag(ac[f"i(vp{i})"]) / (2 * np.pi * np.real(ac["frequency"]))
        c0 = np.imag(ac["i(vp0)"]) / (2 * np.pi * np.real(ac["frequency"]))
        np.testing.assert_allclose(c / width_ratio("cc_beam", e), c0, rtol=cap)
    c0 = abs(float(np.imag(ac["i(vp0)"])[0])) / (2 * np.pi * 50e3)
    assert c0 == pytest.approx(EPS0 * 50e-6 * 300e-6 / 1e-6, rel=model.capacitances[0].max_rel_error)


def test_lib(model, tmp_path, ngspice_version):
    (tmp_path / "cc_beam.lib").write_text(emit_ngspice.subcircuit(model))
    inc = str(tmp_path / "cc_beam.lib")
    check(model, run_ngspice(deck(inc, "op"), tmp_path / "op")[0], run_ngspice(deck(inc, "ac"), tmp_path / "ac")[0])


def test_xspice(model, tmp_path):
    xlib, control = sdn.xspice_library(model, tmp_path, sdn.code_models(False))
    inc = str(xlib.resolve())
    op = run_ngspice(deck(inc, "op", control_block(control, "op.raw")), tmp_path / "op")[0]
    check(model, op, run_ngspice(deck(inc, "ac", control_block(control, "ac.raw")), tmp_path / "ac")[0])


@pytest.fixture(scope="module")
def osdi(model, tmp_path_factory):
    folder = tmp_path_factory.mktemp("osdi")
    emit.write_outputs(model, folder, "osdi")
    return folder


def test_osdi(model, osdi, tmp_path, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    pre = [f"pre_osdi {osdi / 'cc_beam.osdi'}"]
    inc = str(osdi / "cc_beam_osdi.lib")
    op = run_ngspice(deck(inc, "op", control_block(pre, "op.raw")), tmp_path / "op")[0]
    check(model, op, run_ngspice(deck(inc, "ac", control_block(pre, "ac.raw")), tmp_path / "ac")[0])


def test_vacask(model, osdi, tmp_path):
    """The module in VACASK, etch on its model cards, one op: the static deflections as in the .lib."""
    lines = [f'load "{osdi / "cc_beam.osdi"}"', "model vsource vsource", "v_a (a 0) vsource dc=9.81"]
    lines += [f"v_g (g 0) vsource dc={SHOCK!r}"]
    for i, e in enumerate(POINTS):
        r = width_ratio("cc_beam", e)
        lines += [
            f"model m{i} cc_beam etch={e!r}",
            f"x{i} (0 0 f{i} xf{i} 0 xf2_{i} 0 xf3_{i} a) m{i}",
            f"v_f{i} (f{i} 0) vsource dc={FORCE * r!r}",
            f"y{i} (0 0 0 xg{i} 0 xg2_{i} 0 xg3_{i} g) m{i}",
        ]
    net = "cc beam etch\nground 0\n" + "\n".join(lines) + "\ncontrol\n  options reltol=1e-10\n  analysis op1 op\nendc\n"
    plot = run_vacask(net, tmp_path / "run", analysis="op1")
    x0, g0 = (float(np.real(np.atleast_1d(plot[n])[0])) for n in ("xf0", "xg0"))
    for i in range(1, len(POINTS)):
        assert float(np.real(np.atleast_1d(plot[f"xf{i}"])[0])) == pytest.approx(x0, rel=bounds(model)[0])
        g = float(np.real(np.atleast_1d(plot[f"xg{i}"])[0]))
        assert g == pytest.approx(g0, rel=bounds(model)[0] + load_error(model))


def test_fmu(model):
    """Model exchange at one state (xs = 0.3, 0.02, 0.05 of the touching amplitudes) with r FORCE on m1,
    SHOCK on a_in and 1 V on the electrode: qdd as at etch 0, the charge over r as at etch 0."""
    path = fmu.built(model)
    static, _, cap = bounds(model)
    scale = np.array([c.scale for c in model.coordinates])
    names = [f"qdd_{c.name}" for c in model.coordinates]
    out = []
    for e in POINTS:
        r = width_ratio("cc_beam", e)
        inst = fmu.Instance(path, cosim=False)
        inst.set({"etch": e, "f_m1": FORCE * r, "a_in": SHOCK, "V_drive": 1.0})
        inst.start()
        x = np.zeros(inst.md.numberOfContinuousStates)
        x[: len(scale)] = np.array([0.3, 0.02, 0.05]) * scale
        inst.set_states(x)
        out.append((inst.get(names), inst.get(["Q_drive"])[0] / r))
        inst.close()
    for qdd, q in out[1:]:
        np.testing.assert_allclose(qdd, out[0][0], rtol=static + load_error(model))
        assert q == pytest.approx(out[0][1], rel=cap)
