"""The etch's capacitance laws (netgen.model.process.capacitance_laws) in every emitted form, the .lib
(ngspice 39 and 46), the _xspice.lib (netgen_es code model, ngspice 39 as installed) and the .va
through OSDI (ngspice 46): the ratio pc_<electrode> on the proof mass on four clamped-guided beams
over a plate wider than the mass (tests/oracles/process_cases.GUIDED), whose facing area is the
etched outline (200 um - 2 etch)^2, and the combs' shifted states on examples/accelerometer_xyz with
textbook combs (tests/oracles/process_cases.xyz_text, C at rest of comb xp_t).

Tolerances:
- C at rest from .ac of the electrode current (I = j w C V, the mass still: no DC bias, no force)
  against eps (200 um - 2 etch)^2 / g: fringe "none" makes the 1/P fit exact to round-off and the
  ratio ((L - 2 etch) / L)^2 a quadratic the cubic carries exactly; ngspice's linear AC solve is exact
  to round-off: 1e-9.
- the static deflection at 10 V (56 % of the 17.8 V pull-in) from .op against the root
  of k(etch) z = eps A(etch) V^2 / (2 (g - z)^2), with k_z(etch) = k_z (1 - 2 etch / w) (a beam's
  axial and vertical stiffness ~ w, the law exact: tests/model/test_process_etch.py): the model's
  force is exact as above, so the error is Newton's last step at reltol 1e-12 and vntol 1e-12 V (above
  the velocity nodes' rounding floor, PUSH_OPTIONS; 1e-11 of an x_z of ~0.1 um read in um): 1e-7
  covers the quadratic convergence's last correction by decades.
- the static deflection under a_in = 1 g (the guided mass with the port a_in) in the .lib, the
  _xspice.lib, OSDI and VACASK against -m(etch) g / k(etch), the load of the etched mass
  (netgen.model.process_loads; the derivation next to the tests).
- accelerometer_xyz pushed onto xp_t's sidewall stop, against the model's rest (rest_exact) in every
  form (PUSH_OPTIONS, STOP_REL, REST_REL and FULL_REL: the derivations next to them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from netgen import emit
from netgen.core.constants import EPS0
from netgen.emit import ngspice as emit_ngspice
from netgen.model.process import capacitance_at
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import run_vacask
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn
from tests.fixtures import NGSPICE
from tests.fixtures import shared_model as build_model
from tests.oracles.process_cases import (
    ETCHES,
    PERFORATED_ETCHES,
    RANGE,
    control_block,
    guided,
    pushed_rest,
    xyz_etch_text,
)

GAP, SIDE, VOLTS = 2e-6, 200e-6, 10.0
OPTIONS = ".options reltol=1e-12 vntol=1e-12 abstol=1e-20"
ETCHES_COMB = PERFORATED_ETCHES  # across the default etch_range of the comb case


@pytest.fixture(scope="module")
def model():
    return build_model(parse_structure(guided(process='[process]\nparameters = ["etch"]' + RANGE), "cg.toml"))


def area(etch: float) -> float:
    return (SIDE - 2 * etch) ** 2


def deflection(model, etch: float) -> float:
    """The closed-form static z (m, toward the plate below: negative) at VOLTS."""
    k = model.coordinates[0].stiffness * (1 - 2 * etch / 2e-6)
    return brentq(lambda z: k * z + EPS0 * area(etch) * VOLTS**2 / (2 * (GAP + z) ** 2), -GAP / 3, 0.0, xtol=1e-22)


def decks(include: str, etch: float, control: str = "") -> tuple[str, str]:
    """(.ac deck of C at rest, .op deck of the deflection at VOLTS) around one instance at `etch`."""
    ac = f"""* cap
.include {include}
Vd d 0 DC 0 AC 1
Vp p 0 0
X1 d p 0 xz cg etch={etch!r}
.ac lin 1 1k 1k
{control}
.end
"""
    op = f"""* op
.include {include}
Vd d 0 DC {VOLTS}
X1 d 0 0 xz cg etch={etch!r}
{OPTIONS}
.op
{control}
.end
"""
    return ac, op


def check(model, ac_plot, op_plot, etch: float) -> None:
    """C at rest and the deflection against the closed forms (module docstring)."""
    cap = abs(float(np.imag(ac_plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    assert cap == pytest.approx(EPS0 * area(etch) / GAP, rel=1e-9, abs=0)
    z = float(np.real(op_plot["v(xz)"])[0]) * 1e-6  # x_z in um
    assert z == pytest.approx(deflection(model, etch), rel=1e-7, abs=0)


@pytest.mark.parametrize("etch", ETCHES)
def test_lib(model, tmp_path, ngspice_version, etch):
    (tmp_path / "cg.lib").write_text(emit_ngspice.subcircuit(model))
    ac, op = decks(str(tmp_path / "cg.lib"), etch)
    check(model, run_ngspice(ac, tmp_path / "ac")[0], run_ngspice(op, tmp_path / "op")[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_xspice(model, tmp_path, etch):
    xlib, control = sdn.xspice_library(model, tmp_path, sdn.code_models(False))
    ac, _ = decks(str(xlib.resolve()), etch, control_block(control, "ac.raw"))
    _, op = decks(str(xlib.resolve()), etch, control_block(control, "op.raw"))
    check(model, run_ngspice(ac, tmp_path / "ac")[0], run_ngspice(op, tmp_path / "op")[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_osdi(model, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(model, tmp_path, "osdi")
    pre = [f"pre_osdi {tmp_path / 'cg.osdi'}"]
    ac, _ = decks(str(tmp_path / "cg_osdi.lib"), etch, control_block(pre, "ac.raw"))
    _, op = decks(str(tmp_path / "cg_osdi.lib"), etch, control_block(pre, "op.raw"))
    check(model, run_ngspice(ac, tmp_path / "ac")[0], run_ngspice(op, tmp_path / "op")[0], etch)


@pytest.fixture(scope="module")
def xyz():
    """examples/accelerometer_xyz with the textbook combs and etch declared (tests/oracles/process_cases.xyz_text)."""
    return build_model(parse_structure(xyz_etch_text(), "xyz.toml"))


def comb_deck(include: str, etch: float, control: str = "") -> str:
    """.ac of comb xp_t's current at rest (the other electrodes and the plate at 0 V: only xp_t's charge
    moves; no DC bias, so no force and the mass stays)."""
    pins = "d 0 0 0 0 0 0 0 0 0 p " + " ".join(f"0 x{k}" for k in range(6)) + " 0 0 0"
    return f"""* comb cap
.include {include}
Vd d 0 DC 0 AC 1
Vp p 0 0
X1 {pins} accelerometer_xyz etch={etch!r}
.ac lin 1 1k 1k
{control}
.end
"""


def check_comb(xyz, plot, etch: float) -> None:
    """The comb's C at rest against the textbook closed form, within the fit's error at rest and the
    law's stated error (as tests/model/test_process_etch_combs.py; the simulators add round-off)."""
    cap = abs(float(np.imag(plot["i(vp)"])[0])) / (2 * math.pi * 1e3)
    k = [f.electrode for f in xyz.capacitances].index("xp_t")
    tol = xyz.capacitances[k].max_rel_error + xyz.process["etch"]["capacitance_max_rel_error"]
    assert cap == pytest.approx(20 * EPS0 * 2e-6 * (30e-6 - 2 * etch) / (1.5e-6 + 2 * etch), rel=tol, abs=0)
    # and exactly the Python model's law (the emitters render its arithmetic): round-off
    assert cap == pytest.approx(capacitance_at(xyz, np.zeros((1, xyz.ncoords)), etch)[0, k], rel=1e-9, abs=0)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_lib(xyz, tmp_path, ngspice_version, etch):
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    check_comb(xyz, run_ngspice(comb_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_xspice(xyz, tmp_path, etch):
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    deck = comb_deck(str(xlib.resolve()), etch, control_block(control, "ac.raw"))
    check_comb(xyz, run_ngspice(deck, tmp_path)[0], etch)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_osdi(xyz, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(xyz, tmp_path, "osdi")
    deck = comb_deck(
        str(tmp_path / "accelerometer_xyz_osdi.lib"),
        etch,
        control_block([f"pre_osdi {tmp_path / 'accelerometer_xyz.osdi'}"], "ac.raw"),
    )
    check_comb(xyz, run_ngspice(deck, tmp_path / "run")[0], etch)


PUSH = 20.0  # uN on f_x: 3.1 um of the 6.4 N/m legs' travel, past xp_t's finger stop
# The push's Newton test. The velocity nodes u_q are 0 at rest, but ngspice computes them as the LU's
# rounding of the u rows, sums of scaled forces up to the push's 0.128 x 20 = 2.6 over fewer than 100
# terms (the .lib's Bu rows read 73 nodes): |u| <~ 100 x 2.2e-16 x 2.6 = 5.8e-14 V (2.7e-15 to 7.1e-15 on the
# test machine). vntol = 1e-15 V lay under that floor: Newton then passed only when two iterates
# rounded alike, and where they did not, gmin and source stepping failed and the transient op ran
# (18k-25k iterations, up to the hour's timeout, at a rest up to 2.3 % off; docs/contact.md). vntol =
# 1e-12 V is above the floor by 17x and below reltol x |xs| (2e-12 for the stop's xs ~ 2), so the
# moving nodes still converge to reltol 1e-12: every form then takes 4-20 iterations (docs/contact.md).
PUSH_OPTIONS = ".options reltol=1e-12 vntol=1e-12 abstol=1e-20"
# The rests against rest_exact (the model's laws at the etch, the stop in its linear part: a 2 x 2 solve).
# ngspice reads every number inside a B-source expression (numparam's {...} results too) to 11
# significant digits (0.1276231078066803 reads 0.12762310781; a G element's value keeps all 17): each
# such coefficient of the .lib is within 5e-11 relative of the model's. The rest's B-source
# coefficients are the push's gain, the two springs (pk x K) and the stop's offset 2 etch / L; the sum
# of |d ln q / d ln c| over them is at most 1.52 for x and 4.69 for rot_z over the three etches (4.69
# with the stop's gain; `.venv/bin/python bench/stop_newton.py --sensitivity`): 4.69 x 5e-11 = 2.3e-10,
# plus FULL_REL.
REST_REL = 2.5e-10
# The _xspice.lib (mechanics in G elements, stops in the code model), OSDI and VACASK keep all digits.
# Newton's last step lands on the rest to round-off (every element is linear there), and the solve's
# backward error is at most 3 n eps per coefficient for n equations (211 in the .lib, 111 in the
# _xspice.lib, 33 through OSDI; growth 1 assumed), so with a summed sensitivity below 6 (4.69 over the
# rest's parts; 5.62 with the stop's x and rot_z gains perturbed apart): 3 x 211 x 1.1e-16 x 6 = 4.2e-13;
# 1e-12 also covers the model's own arithmetic (a few eps per gain).
FULL_REL = 1e-12
# The .lib's stop node at rest (push 0): sg = -1 - {2 etch / L_x}, the offset read to 11 digits (5e-11 of
# 0.133 over 1.13: 5.9e-12) with L_x = 1.5 um (1 + 6.6e-14) (8e-15); the .op of a linear circuit is
# one exact step: 1e-11.
STOP_REL = 1e-11


def push_deck(include: str, etch: float, control: str = "", push: float = PUSH) -> str:
    """.op of the mass pushed along +x by `push` (uN) onto xp_t's sidewall stop (no voltages)."""
    pins = "0 0 0 0 0 0 0 0 0 0 0 fx x0 0 x1 0 x2 0 x3 0 x4 0 x5 0 0 0"
    return f"""* push
.include {include}
Vf fx 0 DC {push}
X1 {pins} accelerometer_xyz etch={etch!r}
{PUSH_OPTIONS}
.op
{control}
.end
"""


def sidewall_stop(xyz) -> int:
    """The index of xp_t's sidewall stop (its direction along x)."""
    names = [c.name for c in xyz.coordinates]
    pts = xyz.contact["points"]
    return next(j for j, p in enumerate(pts) if p["electrode"] == "xp_t" and p["a"][names.index("x")] != 0.0)


def rest_x(plot) -> float:
    """x (um) and rot_z (mrad) of the pushed mass."""
    return float(np.real(plot["v(x0)"])[0]), float(np.real(plot["v(x2)"])[0])


def rest_exact(model, etch: float) -> tuple[float, float]:
    """The model's rest under PUSH (tests/oracles/process_cases.pushed_rest: a 2 x 2 solve)."""
    return pushed_rest(model, etch, PUSH * 1e-6)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_stop_pushed_lib(xyz, tmp_path, ngspice_version, etch):
    """The .lib pushed onto xp_t's sidewall stop rests at rest_exact within its 11-digit coefficients
    (REST_REL)."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    got = rest_x(run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=REST_REL, abs=0)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_stop_lib(xyz, tmp_path, ngspice_version, etch):
    """xp_t's sidewall stop at rest: its penetration node sg_j = a_j . xs - 1 reads -(1.5 um + 2 etch) /
    1.5 um (the stop at the widened gap; x's touching amplitude is the drawn 1.5 um gap), within
    STOP_REL."""
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    plot = run_ngspice(push_deck(str(tmp_path / "xyz.lib"), etch, push=0.0), tmp_path)[0]
    sg = float(np.real(plot[f"v(x1.sg_{sidewall_stop(xyz) + 1})"])[0])
    assert sg == pytest.approx(-(1.5e-6 + 2 * etch) / 1.5e-6, rel=STOP_REL, abs=0)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_stop_xspice(xyz, tmp_path, etch):
    """The _xspice.lib (its stops in the code model, reading the etch columns) pushed in ngspice 39
    rests at rest_exact (FULL_REL)."""
    xlib, control = sdn.xspice_library(xyz, tmp_path, sdn.code_models(False))
    got = rest_x(run_ngspice(push_deck(str(xlib.resolve()), etch, control_block(control, "op.raw")), tmp_path)[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_stop_osdi(xyz, tmp_path, monkeypatch, etch):
    """The .va through OSDI (ngspice 46) pushed rests at rest_exact (FULL_REL)."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(xyz, tmp_path, "osdi")
    pre = [f"pre_osdi {tmp_path / 'accelerometer_xyz.osdi'}"]
    deck = push_deck(str(tmp_path / "accelerometer_xyz_osdi.lib"), etch, control_block(pre, "op.raw"))
    got = rest_x(run_ngspice(deck, tmp_path / "run")[0])
    assert got == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


@pytest.mark.parametrize("etch", ETCHES_COMB)
def test_comb_stop_vacask(xyz, tmp_path, etch):
    """The same module in VACASK at its default tolerances (reltol 1e-3) rests at rest_exact: the rest
    lies where every element is linear (the stop past its ramp, p = 5.8 to 7.7 delta), so the Newton
    step from an iterate there lands on it to round-off and the step test only confirms it: FULL_REL."""
    assert vacask_rest(xyz, tmp_path, etch) == pytest.approx(rest_exact(xyz, etch), rel=FULL_REL, abs=0)


def vacask_rest(model, folder, etch: float) -> tuple[float, float]:
    """x (um) and rot_z (mrad) of accelerometer_xyz's module pushed by PUSH in VACASK's op."""
    emit.write_outputs(model, folder, "osdi")
    va = (folder / "accelerometer_xyz.va").read_text()
    start = va.index("module accelerometer_xyz(") + len("module accelerometer_xyz(")
    pins = va[start : va.index(")", start)].replace(",", " ").split()
    net = "\n".join(
        [
            "push",
            "ground 0",
            f'load "{folder / "accelerometer_xyz.osdi"}"',
            f"model mems accelerometer_xyz etch={etch!r}",
            "model vsource vsource",
            f"x1 ({' '.join(pins)}) mems",
            *[f"v_{p} ({p} 0) vsource dc=0" for p in pins if not p.startswith("x_") and p != "f_x"],
            f"v_f_x (f_x 0) vsource dc={PUSH!r}",
            "control",
            "  analysis op1 op",
            "endc",
            "",
        ]
    )
    plot = run_vacask(net, folder / "run", analysis="op1")
    return float(np.ravel(plot["x_x"])[0]), float(np.ravel(plot["x_rot_z"])[0])


# the a_in load under etch (netgen.model.process_loads) in every form: the guided mass with the port a_in
# under 1 g, its static deflection -m(etch) g / k(etch) against the closed form m = rho (200 um - 2 etch)^2 t,
# k = 4 E (w - 2 etch) t^3 / L^3 (tests/oracles/fmu_process.closed_form); the .op is one linear solve
# (no voltage), exact to round-off, and its Newton test at reltol 1e-12 / vntol 1e-12 V against an x_z of
# ~1e-4 V (1e-8 of it): 1e-7 as above. Before, the load stayed at the drawn mass's: off by 4 etch / 200 um
# (2e-3 at 0.1 um).
G = 9.81


@pytest.fixture(scope="module")
def loaded():
    text = guided(process='[process]\nparameters = ["etch"]' + RANGE).replace(
        'rigid = ["z"]', 'rigid = ["z"]\ninertial = ["a_z"]'
    )
    return build_model(parse_structure(text, "cg.toml"))


def gravity_deck(include: str, etch: float, control: str = "") -> str:
    return f"""* 1 g
.include {include}
Va a 0 DC {G!r}
X1 0 0 0 xz a cg etch={etch!r}
{OPTIONS}
.op
{control}
.end
"""


def check_gravity(plot, etch: float) -> None:
    m = 2330.0 * (SIDE - 2 * etch) ** 2 * 5e-6
    k = 4 * 160e9 * (2e-6 - 2 * etch) * 5e-6**3 / 150e-6**3
    z = float(np.real(plot["v(xz)"])[0]) * 1e-6  # x_z in um
    assert z == pytest.approx(-m * G / k, rel=1e-7, abs=0)


@pytest.mark.parametrize("etch", ETCHES)
def test_gravity_lib(loaded, tmp_path, ngspice_version, etch):
    (tmp_path / "cg.lib").write_text(emit_ngspice.subcircuit(loaded))
    check_gravity(run_ngspice(gravity_deck(str(tmp_path / "cg.lib"), etch), tmp_path)[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_gravity_xspice(loaded, tmp_path, etch):
    xlib, control = sdn.xspice_library(loaded, tmp_path, sdn.code_models(False))
    deck = gravity_deck(str(xlib.resolve()), etch, control_block(control, "op.raw"))
    check_gravity(run_ngspice(deck, tmp_path)[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_gravity_osdi(loaded, tmp_path, monkeypatch, etch):
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])
    emit.write_outputs(loaded, tmp_path, "osdi")
    deck = gravity_deck(
        str(tmp_path / "cg_osdi.lib"), etch, control_block([f"pre_osdi {tmp_path / 'cg.osdi'}"], "op.raw")
    )
    check_gravity(run_ngspice(deck, tmp_path / "run")[0], etch)


@pytest.mark.parametrize("etch", ETCHES)
def test_gravity_vacask(loaded, tmp_path, etch):
    """The same module in VACASK, etch on its model card (its op at VACASK's default tolerances,
    reltol 1e-3 of a linear solve: one Newton step, exact to round-off)."""
    emit.write_outputs(loaded, tmp_path, "osdi")
    net = f"""cg gravity
ground 0
load "{tmp_path / "cg.osdi"}"
model mems cg etch={etch!r}
model vsource vsource
x1 (bot plate fz xz a) mems
v_bot (bot 0) vsource dc=0
v_plate (plate 0) vsource dc=0
v_fz (fz 0) vsource dc=0
v_a (a 0) vsource dc={G!r}
control
  analysis op1 op
endc
"""
    plot = run_vacask(net, tmp_path / "run", analysis="op1")
    check_gravity({"v(xz)": np.atleast_1d(plot["xz"])}, etch)
