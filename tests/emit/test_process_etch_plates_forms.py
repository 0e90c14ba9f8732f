"""The etch on a plate in every emitted form: the piston of tests/oracles/plate_etch (examples/
piston.toml, fringe "none", its electrode the whole plate) in the .lib (ngspice 39 and 46), the
_xspice.lib (ngspice 39), the .va through OSDI (ngspice 46), VACASK and the FMU.

The oracle is the area law: with fringe "none" C(z; etch) = r eps A / (g - z), r = (L - 2 etch)(W -
2 etch) / (L W), the mass r m and the spring k given. So an etched instance driven at V / sqrt(r)
feels r F_0(z, V / sqrt(r)) = F_0(z, V): it rests where the etch-0 instance at V does (.op, one real
pull-in-side equilibrium at 2.4 V of the 3.66 V pull-in); unbiased, its force response is 1 / (k - r m
w^2) and its capacitance r times the etch-0 one. Each deck holds one instance per etch of
tests/oracles/plate_etch.ETCHES and one at etch 0.

Tolerances:
- .op: the laws' stated errors (mass, capacitance; 0 here: exact) plus Newton's reltol 1e-10 and vntol
  1e-12 V, amplified by k / (k - dF/dz) = 1 / (1 - 2 z / (g - z)) <= 2 for |z| <= g / 5 (asserted):
  2 (stated + 1e-9).
- .ac of the force input at 5 and 40 kHz (f0 = 16.5 kHz): against 1 / (k - r m w^2) of the nominal
  model's m and k, the mass law's stated error amplified by (k + r m w^2) / |k - r m w^2| (<= 1.5 at
  these frequencies) plus ngspice's AC solve to round-off: 1.5 stated + 1e-9.
- C at rest (.ac of the electrode current) over r against the etch-0 instance's: the capacitance law's
  stated error + 1e-9; the etch-0 instance's C against eps A / g within its fit's held-out error.
- the FMU (model exchange) at one state (z = -0.1 g) with 1 V / sqrt(r) on the electrode: r qdd_z
  equals the etch-0 instance's at 1 V (the same force over the mass r m) within the static bound,
  the charge at 1 V over r within the capacitance bound.
- the rigid disk of tests/oracles/plate_etch (its electrodes' state factor: tilts move the rim strip's
  weight) in the FMU at a displaced state (z, tilt_x, tilt_y at -0.2, 0.25, -0.15 of the touching
  amplitudes): the charges at 1 V against the Python law (netgen.model.process.capacitance_at: ratio,
  z shift, state factor) at the three etches, the same arithmetic in the runtime's order: 1e-12.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen import emit
from netgen.core.constants import EPS0
from netgen.emit import ngspice as emit_ngspice
from netgen.model.process import capacitance_at
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import run_vacask
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.plate_etch import ETCHES, GAP, SIDE, STIFFNESS, area_ratio, disk_text, piston_text
from tests.oracles.process_cases import control_block

VOLTS = 2.4  # V on the etch-0 instance (pull-in 3.66 V)
POINTS = (0.0, *ETCHES)
FREQS = (5e3, 40e3)


@pytest.fixture(scope="module")
def model():
    return build_model(parse_structure(piston_text(), "piston.toml"))


def bounds(model) -> tuple[float, float, float]:
    """(static, ac, capacitance) relative bounds (module docstring)."""
    e = model.process["etch"]
    static = 2 * (e["max_rel_error"] + e["capacitance_max_rel_error"] + 1e-9)
    return static, 1.5 * e["max_rel_error"] + 1e-9, e["capacitance_max_rel_error"] + 1e-9


def instances(analysis: str) -> str:
    """Per etch point: a biased instance (V / sqrt(r)) in the .op deck; in the .ac deck a force-driven
    one (AC 1 on f_z) and an unbiased one whose electrode current gives C."""
    out = ["Vd d 0 DC 0 AC 1"] if analysis == "ac" else []
    for i, e in enumerate(POINTS):
        if analysis == "op":
            out += [f"Xb{i} b{i} 0 0 xb{i} piston etch={e!r}", f"Vb{i} b{i} 0 DC {VOLTS / math.sqrt(area_ratio(e))!r}"]
        else:
            out += [f"Xf{i} 0 0 f{i} xf{i} piston etch={e!r}", f"Vf{i} f{i} 0 DC 0 AC 1"]
            out += [f"Xc{i} d p{i} 0 xc{i} piston etch={e!r}", f"Vp{i} p{i} 0 0"]
    return "\n".join(out)


def deck(include: str, analysis: str, control: str = "") -> str:
    card = ".op" if analysis == "op" else f".ac lin 2 {FREQS[0]!r} {FREQS[1]!r}"
    return f"* piston etch\n.include {include}\n{instances(analysis)}\n.options reltol=1e-10 vntol=1e-12 abstol=1e-20\n{card}\n{control}\n.end\n"


def check_op(model, op) -> None:
    """The etched instances rest where the etch-0 one does (module docstring)."""
    x0 = float(np.real(op["v(xb0)"])[0])
    assert -GAP / 5 * 1e6 < x0 < -0.1  # um, towards the electrode below, |z| <= g / 5
    for i in range(1, len(POINTS)):
        assert float(np.real(op[f"v(xb{i})"])[0]) == pytest.approx(x0, rel=bounds(model)[0])


def check_ac(model, ac) -> None:
    """The force response against 1 / (k - r m w^2), C over r against the etch-0 one and eps A / g."""
    _, dynamic, cap = bounds(model)
    w = 2 * np.pi * np.real(ac["frequency"])
    m = model.coordinates[0].mass
    c0 = np.imag(ac["i(vp0)"]) / w
    for i, e in enumerate(POINTS):
        closed = 1.0 / (STIFFNESS - area_ratio(e) * m * w**2)  # um per uN
        np.testing.assert_allclose(np.real(ac[f"v(xf{i})"]), closed, rtol=dynamic)
        np.testing.assert_allclose(np.imag(ac[f"i(vp{i})"]) / w / area_ratio(e), c0, rtol=cap)
    assert abs(c0[0]) == pytest.approx(EPS0 * SIDE**2 / GAP, rel=model.capacitances[0].max_rel_error)


def test_lib(model, tmp_path, ngspice_version):
    (tmp_path / "piston.lib").write_text(emit_ngspice.subcircuit(model))
    inc = str(tmp_path / "piston.lib")
    check_op(model, run_ngspice(deck(inc, "op"), tmp_path / "op")[0])
    check_ac(model, run_ngspice(deck(inc, "ac"), tmp_path / "ac")[0])


def test_xspice(model, tmp_path):
    xlib, control = sdn.xspice_library(model, tmp_path, sdn.code_models(False))
    inc = str(xlib.resolve())
    check_op(model, run_ngspice(deck(inc, "op", control_block(control, "op.raw")), tmp_path / "op")[0])
    check_ac(model, run_ngspice(deck(inc, "ac", control_block(control, "ac.raw")), tmp_path / "ac")[0])


@pytest.fixture(scope="module")
def osdi(model, tmp_path_factory):
    folder = tmp_path_factory.mktemp("osdi")
    emit.write_outputs(model, folder, "osdi")
    return folder


def test_osdi(model, osdi, tmp_path, monkeypatch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    pre = [f"pre_osdi {osdi / 'piston.osdi'}"]
    inc = str(osdi / "piston_osdi.lib")
    check_op(model, run_ngspice(deck(inc, "op", control_block(pre, "op.raw")), tmp_path / "op")[0])
    check_ac(model, run_ngspice(deck(inc, "ac", control_block(pre, "ac.raw")), tmp_path / "ac")[0])


def test_vacask(model, osdi, tmp_path):
    """The module in VACASK, etch on its model cards, one op: the equilibria as in the .lib."""
    lines = [f'load "{osdi / "piston.osdi"}"', "model vsource vsource"]
    for i, e in enumerate(POINTS):
        lines += [
            f"model m{i} piston etch={e!r}",
            f"x{i} (b{i} 0 0 xb{i}) m{i}",
            f"v_b{i} (b{i} 0) vsource dc={VOLTS / math.sqrt(area_ratio(e))!r}",
        ]
    net = "piston etch\nground 0\n" + "\n".join(lines) + "\ncontrol\n  options reltol=1e-10\n  analysis op1 op\nendc\n"
    plot = run_vacask(net, tmp_path / "run", analysis="op1")
    x0 = float(np.real(np.atleast_1d(plot["xb0"])[0]))
    assert -GAP / 5 * 1e6 < x0 < -0.1
    for i in range(1, len(POINTS)):
        assert float(np.real(np.atleast_1d(plot[f"xb{i}"])[0])) == pytest.approx(x0, rel=bounds(model)[0])


def test_fmu(model):
    """Model exchange at z = -0.1 g with 1 V / sqrt(r): r qdd_z and the charge over r as at etch 0."""
    path = fmu.built(model)
    static, _, cap = bounds(model)
    scale = model.coordinates[0].scale
    out = []
    for e in POINTS:
        r = area_ratio(e)
        inst = fmu.Instance(path, cosim=False)
        inst.set({"etch": e, "V_drive": 1.0 / math.sqrt(r)})
        inst.start()
        x = np.zeros(inst.md.numberOfContinuousStates)
        x[0] = -0.1 * scale
        inst.set_states(x)
        qdd = inst.get(["qdd_z"])[0] * r
        inst.set({"V_drive": 1.0})
        out.append((qdd, inst.get(["Q_drive"])[0] / r))
        inst.close()
    assert out[0][0] != 0.0
    for qdd, q in out[1:]:
        assert qdd == pytest.approx(out[0][0], rel=static)
        assert q == pytest.approx(out[0][1], rel=cap)


def test_disk_fmu_state_factor():
    """The disk's charges at a displaced state against the Python law (module docstring)."""
    model = build_model(parse_structure(disk_text(), "disk.toml"))
    laws = model.process["etch"]["capacitance"]
    assert laws and all("state" in r for r in laws)  # every sector's rim strip moves with the tilts
    path = fmu.built(model)
    xs = np.array([[-0.2, 0.25, -0.15]])
    names = [f.electrode for f in model.capacitances]
    for e in ETCHES:
        inst = fmu.Instance(path, cosim=False)
        inst.set({"etch": e} | {f"V_{n}": 1.0 for n in names})
        inst.start()
        x = np.zeros(inst.md.numberOfContinuousStates)
        x[: model.ncoords] = xs[0] * model.scales
        inst.set_states(x)
        q = np.array(inst.get([f"Q_{n}" for n in names]))
        inst.close()
        np.testing.assert_allclose(q, capacitance_at(model, xs, e)[0], rtol=1e-12)
