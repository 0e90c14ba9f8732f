"""The vibratory gyroscope's mechanics (examples/gyroscope_z.toml; netgen.mechanics.inertial and the
flexure's k_xy) in the emitted circuits, against the closed-form steady state of the sense mode.

Driven along x by a sine force at the x resonance w, with a constant rate Omega_z and the flexure's
x-y coupling k_xy, the sense coordinate obeys m y'' + b_y y' + (k_y - m Omega^2) y = -2 m Omega x'
- k_xy x (Coriolis force -2 m Omega x e_z x x' on y; centrifugal softening -m Omega^2 of the
in-plane motions), so its phasor against the simulated x phasor X is exactly

    Y / X = -(k_xy + 2 i m Omega w) / (k_y - m Omega^2 - m w^2 + i w b_y):

the Coriolis part in phase with the drive velocity, the quadrature part with the drive displacement.
Both are checked at once (m = rho t (L W - holes + fingers), k, b from the model's coordinates: the mass from
the structure's dimensions, independently of the model's matrices). The example's Q = 2000 is
lowered to 20 so the transient settles in a short run.

Tolerances (derived, the same in each simulator): the free response decays as e^(-t / tau) with
tau = 2 Q / w; after 30 tau it is e^-30 = 1e-13 of the start. The least-squares fit of cos, sin and
a constant over a whole number (10) of periods leaks nothing between them for an exact sinusoid
(orthogonal over whole periods); the residual transient adds e^-30. The integration: the trapezoidal
rule (ngspice; VACASK's default) at h = period / 200 shifts each oscillator's frequency by
(w h)^2 / 12 = 8.2e-5, i.e. its k - m w^2 by 2 (w h)^2 / 12 k = 5.5e-3 N/m, which near resonance is
amplified by k_y / |D| (9.2 here: k_y - m w^2 = 1.6 N/m, w b_y = 3.3 N/m at Q = 20), so the ratio is
off by about 1.5e-3 in magnitude and phase; bench/gyroscope_open_loop.py measures +5.7e-4 on the
Coriolis part and +4.3e-3 on the quadrature part (phase error x their ratio 1.6), the same to three
digits in ngspice 39, 46 and VACASK. The Coriolis part is asserted within 1 % (6x that bound), the
quadrature part within 5 %, the out-of-plane responses (z, k_z / |D_z| about 3 at Q = 5) within 1 %."""

from __future__ import annotations

import math

import numpy as np
import pytest

from netgen.build import build_model
from netgen.core.errors import StructureError
from netgen.emit.ngspice import subcircuit
from netgen.emit.veriloga import module
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import parse_structure
from tests.fixtures import ROOT, Bench
from tests.mechanics.test_frame_inputs import MASS, PROOF_MASS, sine_amplitude

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
OMEGA = 10.0  # rad/s: the Coriolis part 2 m Omega w = 7.9e-3 N/m, k_xy = 5e-3 N/m: both of the same order
FORCE = 0.01  # uN (the f_x port's unit), amplitude of the drive force
PERIODS = 10  # the fit window, whole periods
Q_TEST = 20


def example_text(q: int = Q_TEST) -> str:
    text = EXAMPLE.read_text()
    assert "q_factor = { x = 2000, y = 2000 }" in text
    return text.replace("q_factor = { x = 2000, y = 2000 }", f"q_factor = {{ x = {q}, y = {q} }}")


@pytest.fixture(scope="module")
def gyro() -> MacroModel:
    return build_model(parse_structure(example_text(), str(EXAMPLE)))


def mass_of_example() -> float:
    """rho t (L W - n^2 s^2 + N w_f L_f): the 500 um, 10 um thick mass with 50 x 50 holes of 4 um and
    its 80 moving comb fingers (4 lateral combs of 16, two differential transverse pairs of 8 sharing
    theirs), 2 um wide, each 30 um beyond the 250 um edge (tip at centre 270 + overlap 20 / 2 um)."""
    return 2330.0 * 10e-6 * (500e-6**2 - 50 * 50 * (4e-6) ** 2 + 80 * 2e-6 * 30e-6)


def coord(model: MacroModel, name: str):
    return next(c for c in model.coordinates if c.name == name)


def phasor(t: np.ndarray, y: np.ndarray, w: float) -> complex:
    """Complex amplitude of the component at w, y ~ Re(A e^{i w t}) (least squares on cos, sin, 1)."""
    a = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
    (c, s, _), *_ = np.linalg.lstsq(a, y, rcond=None)
    return complex(c, -s)


def timing(model: MacroModel) -> tuple[float, float, float]:
    """Drive frequency (the x resonance), step (period / 200) and stop (30 tau + the window)."""
    w = math.sqrt(coord(model, "x").stiffness / coord(model, "x").mass)
    period = 2 * math.pi / w
    return w, period / 200, 30 * 2 * Q_TEST / w + PERIODS * period


def check_sense_ratio(model: MacroModel, t: np.ndarray, x: np.ndarray, y: np.ndarray, w: float) -> None:
    """Y / X against -(k_xy + 2 i m Omega w) / D: the Coriolis part (imaginary) within 1 %, the
    quadrature part (real) within 5 %."""
    cy, m = coord(model, "y"), mass_of_example()
    last = t > t[-1] - PERIODS * 2 * math.pi / w
    ratio = phasor(t[last], y[last], w) / phasor(t[last], x[last], w)
    d = cy.stiffness - m * OMEGA**2 - m * w**2 + 1j * w * cy.damping
    got = -ratio * d  # = k_xy + 2 i m Omega w
    assert got.imag == pytest.approx(2 * m * OMEGA * w, rel=0.01)
    assert got.real == pytest.approx(5e-3, rel=0.05)  # the example's k_xy, N/m


def test_coriolis_and_quadrature_in_ngspice(gyro, ngspice_version, tmp_path):
    """The B-source .lib in ngspice 39 and 46 (module docstring)."""
    w, step, stop = timing(gyro)
    lib = tmp_path / "g.lib"
    lib.write_text(subcircuit(gyro))
    sources = {"w_z": repr(OMEGA), "f_x": f"SIN(0 {FORCE} {w / (2 * math.pi)!r})"}
    bench = Bench(gyro, lib, sources=sources)
    plot = run_ngspice(bench.netlist(f".tran {step!r} {stop!r} 0 {step!r} uic"), tmp_path)[0]
    t = np.asarray(plot["time"])
    x = np.asarray(plot["v(x1.xs_x)"]) * coord(gyro, "x").scale
    y = np.asarray(plot["v(x1.xs_y)"]) * coord(gyro, "y").scale
    check_sense_ratio(gyro, t, x, y, w)


def test_coriolis_and_quadrature_in_vacask(gyro, tmp_path):
    """The Verilog-A module compiled by OpenVAF (OSDI) in a VACASK transient (module docstring),
    maxstep = period / 200: left to its own step control VACASK took steps long enough to miss the
    Coriolis part by 6 %."""
    w, step, stop = timing(gyro)
    va = tmp_path / "g.va"
    va.write_text(module(gyro))
    osdi, _ = compile_va(va)
    sources = {"w_z": f"dc={OMEGA!r}", "f_x": f'type="sine" sinedc=0 ampl={FORCE!r} freq={w / (2 * math.pi)!r}'}
    bench = VacaskBench(gyro, osdi, sources=sources)
    plot = run_vacask(
        bench.netlist(f'analysis tran1 tran step={step!r} stop={stop!r} maxstep={step!r} icmode="uic"'), tmp_path
    )
    t = np.asarray(plot["time"])
    x = np.asarray(plot["x1:xs_x"]) * coord(gyro, "x").scale
    y = np.asarray(plot["x1:xs_y"]) * coord(gyro, "y").scale
    check_sense_ratio(gyro, t, x, y, w)


@pytest.fixture(scope="module")
def proof_mass_xyz() -> MacroModel:
    return build_model(parse_structure(PROOF_MASS, "pm.toml"))


@pytest.mark.parametrize("drive, rate", [("x", "w_y"), ("y", "w_x")])
def test_out_of_plane_coriolis_in_ngspice(proof_mass_xyz, ngspice_version, tmp_path, drive, rate):
    """The 200 um mass of tests/mechanics/test_frame_inputs.py (x, y, z; Q = 5) driven along x
    under Omega_y, or along y under Omega_x: z feels -2 m (Omega x q')_z, +2 m Omega_y x' or
    -2 m Omega_x y', and the centrifugal -m Omega^2 on z, so |Z| = 2 m Omega w |D| / |k_z - m Omega^2 -
    m w^2 + i w b_z| with D the simulated drive amplitude. Tolerance as in the module docstring."""
    model, omega = proof_mass_xyz, 2000.0
    cd, cz = coord(model, drive), coord(model, "z")
    w = math.sqrt(cd.stiffness / cd.mass)
    period = 2 * math.pi / w
    stop = 30 * 2 * 5 / min(w, math.sqrt(cz.stiffness / cz.mass)) + PERIODS * period
    lib = tmp_path / "pm.lib"
    lib.write_text(subcircuit(model))
    sources = {"plate": "0", rate: repr(omega), f"f_{drive}": f"SIN(0 {FORCE} {w / (2 * math.pi)!r})"}
    plot = run_ngspice(
        Bench(model, lib, sources=sources).netlist(f".tran {period / 200!r} {stop!r} 0 {period / 200!r} uic"), tmp_path
    )[0]
    t = np.asarray(plot["time"])
    last = t > stop - PERIODS * period
    amp_d = sine_amplitude(t[last], np.asarray(plot[f"v(x1.xs_{drive})"])[last] * cd.scale, w)
    amp_z = sine_amplitude(t[last], np.asarray(plot["v(x1.xs_z)"])[last] * cz.scale, w)
    mass = MASS
    want = 2 * mass * omega * w * amp_d / abs(cz.stiffness - mass * omega**2 - mass * w**2 + 1j * w * cz.damping)
    assert amp_z == pytest.approx(want, rel=0.01, abs=0)


@pytest.mark.parametrize(
    "old, new, message",
    [
        ('rigid = ["x", "y"]', 'rigid = ["x"]', "k_xy couples x and y"),
        ('k_xy = "0.005 N/m"', 'k_xy = "40 N/m"', "not below sqrt"),
        ('k_xy = "0.005 N/m"', 'k_xy = "0.005 V"', "unit"),
        ('k_xy = "0.005 N/m"', "k_xy = true", "k_xy"),
    ],
)
def test_bad_k_xy_names_the_key_and_the_fix(old, new, message):
    """A coupling without both coordinates, one that makes the springs indefinite, or a non-stiffness:
    a StructureError (exit 2) naming conductor.flexure.k_xy and a fix."""
    text = example_text()
    assert old in text
    text = text.replace(old, new)
    if old.startswith("rigid"):
        text = text.replace('inertial = ["a_x", "a_y", "w_z"]', 'inertial = ["a_x"]')
    with pytest.raises(StructureError, match=message) as err:
        build_model(parse_structure(text, str(EXAMPLE)))
    assert "conductor.flexure.k_xy" in str(err.value) and "fix:" in str(err.value)
