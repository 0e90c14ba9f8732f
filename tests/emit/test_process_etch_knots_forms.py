"""The etch stiffness law's torsion knot (netgen.model.etch_knots) in every emitted form: the .lib
(ngspice 39 and 46: ek_1 = (x + abs(x)) / 2 in .param), the _xspice.lib (ngspice 39; the springs are
netlist elements scaled by the same .param), the .va through OSDI (ngspice 46) and the FMU's runtime
(its etch_ratio branch), on examples/accelerometer_xyz with textbook combs (tests/oracles/
process_cases.xyz_text): 2 um legs on a 2 um layer, the kink at etch 0, probed on both sides of it.

References:
- the mechanics re-run at the etched sizes (the frame solve, not the law): z's stiffness k_z, and
  k_z / m_z for the FMU;
- the MacroModel's own law (netgen.model.process.coordinate_values): the arithmetic the forms render.

Tolerances:
- the .op's x_z = F / k_z (no voltage: no electrostatic force; springs linear: no strain energy;
  0.5 um against a 2 um stop's amplitude: no contact) to Newton's convergence at reltol 1e-12 and
  vntol 1e-12 V (above the velocity nodes' rounding floor, docs/contact.md; 2e-12 of x_z's 0.5 V)
  (quadratic: its last correction far below) and the printed 16-17 digits of the coefficients: 1e-9
  against the law; against the re-run the law's stated error times 3 (tests/model/
  test_process_etch_knots.py derives the factor) plus that 1e-9.
- the FMU's q''_z / x_z = -k_z / m_z at a state 10 nm off rest (linear springs, no forces): the
  runtime's round-off, 1e-12 (tests/emit/test_fmu.py's n eps), against the law; against the re-run
  the law's stated error times 3 for k and for m (the ratio's error adds).
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen.emit import ngspice as emit_ngspice
from netgen.mechanics import mechanics
from netgen.model.process import coordinate_values
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import control_block, osdi_form, xyz_etch_text, xyz_text

ETCHES = (-0.02e-6, -0.002e-6, 0.002e-6, 0.02e-6)  # m: both sides of the kink at 0
FORCE = 1.0  # uN on f_z (1 V = 1 uN): x_z ~ 0.54 um at 1.85 N/m
Z = 3  # z's index (x, y, rot_z, z, tilt_x, tilt_y)


@pytest.fixture(scope="module")
def xyz():
    model = build_model(parse_structure(xyz_etch_text(), "xyz.toml"))
    assert [c.name for c in model.coordinates][Z] == "z" and model.nonlinear_energy_polynomial() is None
    assert model.process["etch"]["knots"] == [0.0]
    return model


@pytest.fixture(scope="module")
def reruns():
    """etch -> the re-run's (mass, stiffness) of z."""
    out = {}
    for e in ETCHES:
        m = mechanics(parse_structure(xyz_text(e), "xyz.toml"))
        out[e] = (float(m.masses[Z]), float(m.stiffnesses[Z]))
    return out


def deck(include: str, etch: float, control: str = "") -> str:
    """.op of FORCE on f_z, no voltages."""
    pins = "0 0 0 0 0 0 0 0 0 0 0 0 x0 0 x1 0 x2 fz x3 0 x4 0 x5 0 0 0"
    return f"""* kink
.include {include}
Vf fz 0 DC {FORCE!r}
X1 {pins} accelerometer_xyz etch={etch!r}
.options reltol=1e-12 vntol=1e-12 abstol=1e-20
.op
{control}
.end
"""


def check(xyz, reruns, plot, etch: float) -> None:
    """x_z of the .op against F / k_z of the law and of the re-run (module docstring)."""
    x = float(np.real(plot["v(x3)"])[0]) * 1e-6
    law = coordinate_values(xyz.process, Z, etch=etch)[1]
    assert x == pytest.approx(FORCE * 1e-6 / law, rel=1e-9, abs=0)
    stated = xyz.process["etch"]["max_rel_error"]
    assert x == pytest.approx(FORCE * 1e-6 / reruns[etch][1], rel=3 * stated + 1e-9, abs=0)


@pytest.mark.parametrize("etch", ETCHES)
def test_lib(xyz, reruns, tmp_path, ngspice_version, etch):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check(xyz, reruns, run_ngspice(deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_xspice(xyz, reruns, tmp_path, etch):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    check(
        xyz, reruns, run_ngspice(deck(str(xlib.resolve()), etch, control_block(control, "op.raw")), tmp_path)[0], etch
    )


@pytest.mark.parametrize("etch", ETCHES)
def test_osdi(xyz, reruns, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    inc, pre = osdi_form(xyz, tmp_path)
    net = deck(inc, etch, control_block(pre, "op.raw"))
    check(xyz, reruns, run_ngspice(net, tmp_path / "run")[0], etch)


def test_fmu(xyz, reruns):
    """q''_z / x_z = -k_z / m_z of the FMU's runtime at each etch (module docstring)."""
    path, stated = fmu.built(xyz), xyz.process["etch"]["max_rel_error"]
    for etch in ETCHES:
        inst = fmu.Instance(path, cosim=False)  # etch is fixed after initialization: one instance each
        inst.set({"etch": etch})
        inst.start()
        s = np.zeros(inst.md.numberOfContinuousStates)
        s[Z] = 1e-8
        inst.set_states(s)
        rate = -float(inst.get(["qdd_z"])[0]) / 1e-8
        inst.close()
        m, k, _ = coordinate_values(xyz.process, Z, etch=etch)
        assert rate == pytest.approx(k / m, rel=1e-12, abs=0)
        assert rate == pytest.approx(reruns[etch][1] / reruns[etch][0], rel=6 * stated, abs=0)
