"""The inertial inputs of [coordinates] inertial (netgen.mechanics.inertial, netgen.model.inertial):
frame acceleration a_x, a_y, a_z (a_z = the port a_in) and rotation rate w_x, w_y, w_z, against
independent references:
- static: a proof mass deflects -m a / k along each axis (m = rho t L W of the structure plus its comb fingers, k the
  coordinate's spring) in ngspice 39 and 46 (.op of a linear circuit: exact up to the solver's
  LU round-off, so 1e-6) and in VACASK (a settled transient: 1e-3, see its docstring);
- Coriolis: driven along x at its resonance under a constant Omega_z, the y amplitude equals
  2 m Omega X w / |k_y - m Omega^2 - m w^2 + i w b_y| (steady state of m y'' + b y' + k y = -2 m Omega x')
  within 1 % in an ngspice transient;
- conservation: with constant Omega and no damping the Jacobi integral T2 - T0 + V (T0 from the
  closed form 1/2 m |Omega x (d + r_c)|^2 of a translating body, not from the model's matrices) of the
  MacroModel's own equations stays within 1e-6 of its start over 10^4 periods;
- rigid rotation: the tilts of a thick free disk in a frame spinning about z follow a free rigid
  body's Euler equations (integrated in the inertial frame) within 1 %.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import linalg
from scipy.integrate import solve_ivp

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.emit.veriloga import module
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import StructureError, parse_structure
from tests.fixtures import ROOT, Bench
from tests.oracles.crab_legs import crab_legs, plate

RHO, T, SIDE = 2330.0, 2e-6, 200e-6  # the proof mass below: density, thickness, side
# its rigid mass by hand: the plate and the 20 moving fingers of its two combs (2 x 40 um each, from
# the edge at 100 um to the tip at centre 125 + overlap 30 / 2 = 140 um)
MASS = RHO * T * (SIDE * SIDE + 20 * 2e-6 * 40e-6)
# and its centre of mass: comb xp's 10 fingers centred at y = 120 um, yp's at x = 120 um
CENTRE = np.array([1.0, 1.0, 0.0]) * 10 * RHO * T * 2e-6 * 40e-6 * 120e-6 / MASS
COMB = """
[[electrodes]]
name = "{name}"
kind = "transverse_comb"
orientation = "{orientation}"
fingers = 10
width = "2 um"
gap = "1.5 um"
length = "40 um"
overlap = "30 um"
side = "+"
root = "+"
center = {center}
"""
PROOF_MASS = (
    'name = "pm"\n'
    'description = "A 200 um square proof mass on crab legs with one comb per in-plane axis and a plate below"\n'
    + crab_legs(200.0, 2.0, 100.0)
    + plate("zs", "below")
    + COMB.format(name="xp", orientation="y", center='["0 um", "125 um"]')
    + COMB.format(name="yp", orientation="x", center='["125 um", "0 um"]')
    + """
[coordinates]
rigid = ["x", "y", "z"]
inertial = ["a_x", "a_y", "a_z", "w_x", "w_y", "w_z"]

[sampling]
levels = 3
range = 0.2

[fit]
degree = 2

[damping]
q_factor = { x = 5, y = 5, z = 5 }
"""
)


@pytest.fixture(scope="module")
def proof_mass() -> MacroModel:
    return build_model(parse_structure(PROOF_MASS, "pm.toml"))


ACCEL = {"a_x": 100.0, "a_y": -60.0, "a_in": 30.0}  # m/s^2
AXIS = {"a_x": "x", "a_y": "y", "a_in": "z"}


def expected_static(model: MacroModel) -> dict[str, float]:
    """-m a / k per axis, m from the structure's dimensions (no holes)."""
    mass = MASS
    k = {c.name: c.stiffness for c in model.coordinates}
    return {AXIS[p]: -mass * a / k[AXIS[p]] for p, a in ACCEL.items()}


def test_proof_mass_deflects_m_a_over_k_per_axis_in_ngspice(proof_mass, ngspice_version, tmp_path):
    """.op with a_x, a_y, a_in applied at once (electrodes and plate grounded, rates 0)."""
    lib = tmp_path / "pm.lib"
    lib.write_text(subcircuit(proof_mass))
    bench = Bench(proof_mass, lib, sources={"plate": "0"} | {p: repr(a) for p, a in ACCEL.items()})
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    got = {c.name: float(np.ravel(plot[f"v(x1.xs_{c.name})"])[0]) * c.scale for c in proof_mass.coordinates}
    for name, want in expected_static(proof_mass).items():
        assert got[name] == pytest.approx(want, rel=1e-6, abs=0), name


def test_proof_mass_deflects_m_a_over_k_per_axis_in_vacask(proof_mass, tmp_path):
    """The Verilog-A module in a VACASK transient from rest, Q = 5: after 40 time constants 2Q/w0
    the transient is below e^-40 and the trapezoidal rule's steady state is exact, so 1e-3 only
    covers VACASK's default tolerances (reltol 1e-3 on the states)."""
    va = tmp_path / "pm.va"
    va.write_text(module(proof_mass))
    osdi, _ = compile_va(va)
    sources = {"plate": "dc=0"} | {p: f"dc={a!r}" for p, a in ACCEL.items()}
    w0 = min(math.sqrt(c.stiffness / c.mass) for c in proof_mass.coordinates)
    stop = 40 * 2 * 5 / w0
    bench = VacaskBench(proof_mass, osdi, sources=sources)
    plot = run_vacask(bench.netlist(f'analysis tran1 tran step={stop / 4000!r} stop={stop!r} icmode="uic"'), tmp_path)
    for name, want in expected_static(proof_mass).items():
        c = next(c for c in proof_mass.coordinates if c.name == name)
        assert plot[f"x1:xs_{name}"][-1] * c.scale == pytest.approx(want, rel=1e-3, abs=0), name


def sine_amplitude(t: np.ndarray, y: np.ndarray, w: float) -> float:
    """Amplitude of the component at w (least squares on sin, cos and a constant)."""
    a = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (s, c, _), *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(math.hypot(s, c))


def test_coriolis_amplitude_in_ngspice(proof_mass, ngspice_version, tmp_path):
    """A sine force on f_x at the x resonance, Omega_z = 2000 rad/s constant: the y amplitude is
    2 m Omega X w / |k_y - m Omega^2 - m w^2 + i w b_y| with X the simulated x amplitude. Settled
    after 30 time constants 2Q/w (e^-30); with maxstep = period/200 the trapezoidal rule's amplitude
    and phase errors are (w h)^2/12 = 8e-5, and the fit over the last 10 periods is exact for a
    sinusoid, so 1 % leaves margin for ngspice's step control."""
    cx = next(c for c in proof_mass.coordinates if c.name == "x")
    cy = next(c for c in proof_mass.coordinates if c.name == "y")
    omega, mass = 2000.0, MASS
    w = math.sqrt(cx.stiffness / cx.mass)
    period = 2 * math.pi / w
    stop = 30 * 2 * 5 / w + 10 * period
    lib = tmp_path / "pm.lib"
    lib.write_text(subcircuit(proof_mass))
    force = 0.01  # uN
    bench = Bench(
        proof_mass, lib, sources={"plate": "0", "w_z": repr(omega), "f_x": f"SIN(0 {force} {w / (2 * math.pi)!r})"}
    )
    plot = run_ngspice(bench.netlist(f".tran {period / 200!r} {stop!r} 0 {period / 200!r} uic"), tmp_path)[0]
    t = np.asarray(plot["time"])
    last = t > stop - 10 * period
    amp_x = sine_amplitude(t[last], np.asarray(plot["v(x1.xs_x)"])[last] * cx.scale, w)
    amp_y = sine_amplitude(t[last], np.asarray(plot["v(x1.xs_y)"])[last] * cy.scale, w)
    want = 2 * mass * omega * amp_x * w / abs(cy.stiffness - mass * omega**2 - mass * w**2 + 1j * w * cy.damping)
    assert amp_y == pytest.approx(want, rel=0.01, abs=0)


def undamped(model: MacroModel) -> MacroModel:
    """A copy without damping (the conservation law needs none)."""
    return dataclasses.replace(model, coordinates=[dataclasses.replace(c, damping=0.0) for c in model.coordinates])


def test_jacobi_integral_is_conserved(proof_mass):
    """MacroModel.accelerations with Omega = (3, -2, 5) krad/s, no damping, electrodes at 0 V: the
    model is affine in (x, x') there, so its matrix is read from accelerations() (and checked at
    random points to 1e-12), and its exact flow over 10^4 periods of x (0.54 * 10^4 of z) is the
    matrix exponential of the augmented system (state, 1) over an eighth of the fastest period,
    applied 8 * 10^4 times. h = 1/2 q'^T M q' + 1/2 q^T K q - 1/2 m |Omega x (q + r_c)|^2 for the
    translations q (r_c: the centre of mass by hand, off the origin by the combs' fingers, CENTRE).
    The exact flow keeps h; each step's rounding (expm's and the product's, a few eps in the
    eigenbasis) is amplified by the condition number kappa of the eigenvector matrix (of the balanced
    system: positions and velocities on comparable scales) and adds up over the N steps, and h is quadratic in the state: |dh| / h <= 2 * N * 16 eps * kappa (about 1e-9 here).
    A model that broke the law (a symmetric G, an asymmetric S) would show at O(1)."""
    model = undamped(proof_mass)
    n, s = model.ncoords, model.scales
    rates = {"w_x": 3e3, "w_y": -2e3, "w_z": 5e3}
    volts = np.zeros(len(model.electrodes))

    def acc(x, v):
        return model.accelerations(x, v, volts, 0.0, inertial=rates)

    b = acc(np.zeros(n), np.zeros(n))
    cols = [acc(e, np.zeros(n)) - b for e in np.eye(n)] + [acc(np.zeros(n), e) - b for e in np.eye(n)]
    a = np.column_stack(cols)
    rng = np.random.default_rng(7)
    for _ in range(4):
        x, v = rng.normal(size=n) * 0.05, rng.normal(size=n) * 1e4
        assert np.max(np.abs(acc(x, v) - a @ np.r_[x, v] - b)) <= 1e-12 * np.max(np.abs(acc(x, v)))
    aug = np.zeros((2 * n + 1, 2 * n + 1))  # (x, x', 1): the constant column carries b
    aug[:n, n : 2 * n] = np.eye(n)
    aug[n : 2 * n, : 2 * n] = a
    aug[n : 2 * n, -1] = b
    w = max(math.sqrt(k.stiffness / k.mass) for k in model.coordinates)
    steps, dt = 8 * 10**4, 2 * math.pi / w / 8
    step = linalg.expm(aug * dt)
    y = np.empty((steps + 1, 2 * n + 1))
    y[0] = [0.01, 0.02, -0.01, 0, 0, 0, 1.0]
    for i in range(steps):
        y[i + 1] = step @ y[i]
    kappa = np.linalg.cond(np.linalg.eig(linalg.matrix_balance(aug, permute=False)[0])[1])
    mass = np.array([k.mass for k in model.coordinates])
    k = np.array([k.stiffness for k in model.coordinates])
    omega = np.array([rates["w_x"], rates["w_y"], rates["w_z"]])
    q, qd = y[:, :n] * s, y[:, n : 2 * n] * s
    h = 0.5 * np.sum(mass * qd * qd, axis=1) + 0.5 * np.sum(k * q * q, axis=1)
    h -= 0.5 * MASS * np.sum(np.cross(omega, q + CENTRE) ** 2, axis=1)
    bound = 2 * steps * 16 * np.finfo(float).eps * kappa
    print(
        f"Jacobi integral: drift {np.max(np.abs(h - h[0])) / abs(h[0]):.2e} of h over {steps} steps, bound {bound:.2e}"
    )
    assert np.max(np.abs(h - h[0])) <= bound * abs(h[0])


DISK_R, DISK_H, DISK_RHO = 473e-6, 473e-6, 2330.0  # the example's radius, as thick: J_zz = m h^2/12 is 1/3 of J_xx


def thick_disk() -> MacroModel:
    """The levitated disk's structure made as thick as its radius, rigid coordinates and the rates."""
    text = (ROOT / "examples" / "levitated_disk.toml").read_text()
    text = text.replace('modes = ["2,0c", "2,0s", "3,0c", "3,0s"]', 'modes = 0\ninertial = ["w_x", "w_y", "w_z"]')
    assert 'radius = "473 um"' in text and 'thickness = "10 um"' in text
    text = text.replace('thickness = "10 um"', f'thickness = "{DISK_H * 1e6:g} um"')
    return undamped(build_model(parse_structure(text, "levitated_disk.toml")))


def euler_tilts(omega: float, theta0: np.ndarray, rate0: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Tilts (rotation vector x, y of the body relative to the frame) of a free rigid disk (inertia
    m (R^2/4 + h^2/12), m R^2/2) from Euler's equations I w' = -w x I w and R' = R [w]x in the
    inertial frame; the frame turns at omega about z."""
    m = DISK_RHO * math.pi * DISK_R**2 * DISK_H
    inertia = np.array([m * (DISK_R**2 / 4 + DISK_H**2 / 12)] * 2 + [m * DISK_R**2 / 2])

    def cross(v):
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    def rhs(t, y):
        r, w = y[:9].reshape(3, 3), y[9:]
        return np.r_[(r @ cross(w)).ravel(), -np.cross(w, inertia * w) / inertia]

    th = np.r_[theta0, 0.0]
    ang = np.linalg.norm(th)
    k = cross(th / ang)
    r0 = np.eye(3) + math.sin(ang) * k + (1 - math.cos(ang)) * k @ k
    w0 = r0.T @ (np.array([0.0, 0.0, omega]) + np.r_[rate0, 0.0])
    sol = solve_ivp(rhs, (0, times[-1]), np.r_[r0.ravel(), w0], "DOP853", t_eval=times, rtol=1e-11, atol=1e-14)
    out = []
    for t, y in zip(sol.t, sol.y.T):
        c, s = math.cos(omega * t), math.sin(omega * t)
        rel = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) @ y[:9].reshape(3, 3)
        out.append([0.5 * (rel[2, 1] - rel[1, 2]), 0.5 * (rel[0, 2] - rel[2, 0])])
    return np.array(out)


def test_spinning_disk_tilts_follow_eulers_equations():
    """Omega_z = 1e4 rad/s, an initial tilt 1e-4 rad and tilt rate 0.5 Omega * 1e-4: the model's
    tilts (MacroModel.accelerations: Coriolis -2 J_zz Omega, centrifugal (J_yy - J_zz) Omega^2) against
    the free body over 5 turns. The linearisation's error is of the order of the tilt (1e-4 relative),
    both integrations are at rtol 1e-10 or tighter, so 1 % of the tilt amplitude is a loose bound."""
    model = thick_disk()
    names = [c.name for c in model.coordinates]
    ix, iy = names.index("tilt_x"), names.index("tilt_y")
    omega = 1e4
    theta0, rate0 = np.array([1e-4, 0.0]), np.array([0.0, 0.5 * omega * 1e-4])
    times = np.linspace(0, 5 * 2 * math.pi / omega, 400)
    s = model.scales
    volts = np.zeros(len(model.electrodes))
    x0, v0 = np.zeros(model.ncoords), np.zeros(model.ncoords)
    x0[[ix, iy]], v0[[ix, iy]] = theta0 / s[[ix, iy]], rate0 / s[[ix, iy]]

    def rhs(t, y):
        n = model.ncoords
        return np.r_[y[n:], model.accelerations(y[:n], y[n:], volts, 0.0, inertial={"w_z": omega})]

    sol = solve_ivp(rhs, (0, times[-1]), np.r_[x0, v0], "DOP853", t_eval=times, rtol=1e-10, atol=1e-16)
    got = sol.y[[ix, iy]].T * s[[ix, iy]]
    want = euler_tilts(omega, theta0, rate0, times)
    assert np.max(np.abs(got - want)) <= 0.01 * np.max(np.abs(want))


@pytest.mark.parametrize(
    "line, message",
    [
        ('inertial = "a_x"', "inertial must be a list"),
        ('inertial = ["a_q"]', "unknown inertial input 'a_q'"),
        ('inertial = ["w_z", "w_z"]', "listed twice"),
        ("inertial = [1]", "inertial must be a list"),
    ],
)
def test_bad_inertial_descriptions_name_the_key_and_the_fix(line, message):
    text = PROOF_MASS.replace('inertial = ["a_x", "a_y", "a_z", "w_x", "w_y", "w_z"]', line)
    with pytest.raises(StructureError, match=message) as err:
        parse_structure(text, "pm.toml")
    assert "coordinates.inertial" in str(err.value) and ("inertial = [" in str(err.value) or "once" in str(err.value))


def test_model_json_round_trip_and_old_json(proof_mass, tmp_path):
    """The inertial data survive save/load; a JSON without them loads as a model without the ports."""
    path = tmp_path / "pm.json"
    proof_mass.save_json(path)
    again = MacroModel.load_json(path)
    assert again.json_text() == proof_mass.json_text()
    old = proof_mass.to_dict()
    old.pop("inertial_inputs")
    bare = MacroModel.from_dict(old)
    assert [p["name"] for p in bare.ports() if p["kind"] in ("acceleration_in", "rate_in")] == ["a_in"]


def test_gyroscopic_matrices_are_antisymmetric_and_proof_mass_values(proof_mass):
    """G_z[x][y] = -2 m (Coriolis force +2 m Omega_z y' on x), antisymmetric; P along x = m."""
    mass = MASS
    names = [c.name for c in proof_mass.coordinates]
    g = np.array(proof_mass.inertial.gyroscopic["z"])
    assert g[names.index("x"), names.index("y")] == pytest.approx(-2 * mass, rel=1e-12, abs=0)
    for gk in proof_mass.inertial.gyroscopic.values():
        assert np.array_equal(np.array(gk), -np.array(gk).T)
    assert proof_mass.inertial.participation["a_x"][names.index("x")] == pytest.approx(mass, rel=1e-12, abs=0)
