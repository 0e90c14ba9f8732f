"""The emitted subcircuit in the real ngspice, against independent references.

- motional current: I = V dC/dt, with dC/dt from the Python model's gradient and ngspice's
  own velocity states (the chain rule, not ngspice's charge differentiation);
- transient: every coordinate against scipy's solve_ivp of the same equations;
- DC operating point: against scipy's fsolve of the static equilibrium;
- floating plate: total plate charge conserved over 10^4 switching events.

Each runs on both ngspice emissions: the B-source .lib (netlists/) and the xspice .lib whose plate
terms, forces and stops are the compiled netgen_es code model (netgen.sim.codemodel); the .lib in
ngspice 39 and 46, the xspice .lib in 39 (fixtures.EMISSIONS).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import fsolve

from netgen.model import MacroModel
from netgen.sim.ngspice import ENV, run_ngspice
from tests.fixtures import (
    EMISSIONS,
    NGSPICE,
    ROOT,
    Bench,
    Pulse,
    emission_id,
    emitted_library,
    reference_transient,
    states,
    transient_drive,
)

LIB = ROOT / "netlists" / "levitated_disk.lib"


@pytest.fixture(scope="module")
def model() -> MacroModel:
    return MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")


@pytest.fixture(params=EMISSIONS, ids=emission_id)
def lib(request, model, tmp_path, monkeypatch) -> tuple[Path, list[str]]:
    """Both ngspice emissions: B-sources (the committed .lib) and the compiled XSPICE code model,
    each in the ngspice releases it runs in (NETGEN_NGSPICE set for the test)."""
    release, style = request.param
    monkeypatch.setenv(ENV, NGSPICE[release])
    folder = tmp_path / "lib"
    folder.mkdir()
    return emitted_library(model, style, folder, LIB)


def _names(model: MacroModel) -> list[str]:
    return [e.name for e in model.electrodes]


def test_motional_current_is_v_dc_dt(model, lib, tmp_path):
    """Electrode at constant 2 V, tilt driven by a 50 kHz torque: I = V sum_v dC/dq_v dq_v/dt."""
    electrode, volts = "top_r2s1", 2.0
    bench = Bench(
        model,
        lib[0],
        control=lib[1],
        sources={electrode: f"DC {volts}", "plate": "0", "f_tilt_y": "SIN(0 28.5 50k 0 0 90)"},  # nN*m
        options="reltol=1e-5 chgtol=1e-18",
    )
    plot = run_ngspice(bench.netlist(".tran 10n 60u 0 10n uic"), tmp_path)[0]
    x, xdot = states(plot, model)
    grad = model.capacitance_gradient(x)[:, _names(model).index(electrode), :]
    expected = volts * np.einsum("pv,pv->p", grad, xdot * model.scales)
    current = -plot[f"i(v{electrode})"]  # into the electrode terminal
    settled = plot["time"] > 20e-6  # past the first period of the drive
    peak = np.abs(expected[settled]).max()
    assert np.abs(x[:, 2]).max() > 0.05  # the tilt really moved (5 % of touch)
    assert np.abs(current - expected)[settled].max() < 5e-3 * peak


def test_transient_matches_scipy_integration(model, lib, tmp_path):
    """Steps and 1 MHz pulses on four electrodes plus gravity, 105 us (> 10 periods of the
    97.6 kHz mode): every coordinate within 1 % of its peak of the scipy solution."""
    drive = transient_drive()
    gravity = -model.coordinates[0].mass * 9.81  # N on z
    stop = 105e-6
    sources = {k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)}
    bench = Bench(model, lib[0], control=lib[1], sources=sources, options="reltol=1e-5 chgtol=1e-18")
    plot = run_ngspice(bench.netlist(f".tran 10n {stop} 0 10n uic"), tmp_path)[0]
    x, _ = states(plot, model)
    f_ext = np.zeros(model.ncoords)
    f_ext[0] = gravity
    ref = reference_transient(model, drive, f_ext, plot["time"], stop)
    for v, c in enumerate(model.coordinates):
        peak = np.abs(ref[:, v]).max()
        assert peak > 0, c.name
        assert np.abs(x[:, v] - ref[:, v]).max() < 0.01 * peak, c.name
    assert np.abs(ref).max() < model.sampling["range"]  # stayed in the fitted box


def test_dc_operating_point_is_the_static_equilibrium(model, lib, tmp_path):
    """Bias 15..25 V on all electrodes and small external loads: ngspice .op equals scipy's
    root of F_el(q) + F_ext - K q = 0 (electrostatic spring softening included)."""
    names = _names(model)
    volts = np.round(np.random.default_rng(3).uniform(15, 25, len(names)), 2)
    loads = {"f_z": 0.5, "f_tilt_x": -0.3, "f_tilt_y": 0.2}  # uN, nN*m, nN*m
    f_ext = np.zeros(model.ncoords)
    for v, c in enumerate(model.coordinates):
        f_ext[v] = loads.get(f"f_{c.name}", 0.0) * c.port_units[3]
    sources = (
        {n: repr(float(v)) for n, v in zip(names, volts)} | {"plate": "0"} | {k: repr(v) for k, v in loads.items()}
    )
    # the in-range equilibrium of the free plate is unstable (no spring on z) and the contact model
    # adds the stable pulled-in state at the stop; a plain .op (no .nodeset) starts at the
    # undeflected plate (every internal node is 0 at rest) and finds the in-range root
    bench = Bench(model, lib[0], control=lib[1], sources=sources, options="reltol=1e-9 vntol=1e-12 abstol=1e-18")
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    x_spice = np.array([plot[f"v(x1.xs_{c.name})"][0] for c in model.coordinates])

    mass = np.array([c.mass for c in model.coordinates])
    stiffness = np.array([c.stiffness for c in model.coordinates])

    def residual(x):
        return model.accelerations(x, np.zeros_like(x), volts, 0.0, f_ext) * mass * model.scales

    x_ref = fsolve(residual, np.zeros(model.ncoords), xtol=1e-13)
    assert np.abs(residual(x_ref)).max() < 1e-12 * np.abs(f_ext).max() + 1e-18
    assert np.abs(x_spice - x_ref).max() < 1e-6  # scaled units (1 = contact)
    assert 0.01 < np.abs(x_ref[:3]).max() < model.sampling["range"]  # a real, in-range deflection
    # softening matters: the stiffness-only estimate of the driven modes is off by > 5 %
    modes = stiffness > 0
    force0 = model.electrostatic_force(np.zeros(model.ncoords), volts, 0.0)[0] + f_ext
    linear = force0[modes] / stiffness[modes] / model.scales[modes]
    driven = np.abs(linear) > 1e-4
    assert np.any(np.abs(x_ref[modes][driven] / linear[driven] - 1) > 0.05)


def test_floating_plate_conserves_charge(model, lib, tmp_path):
    """All 16 electrodes switch 0/5 V at 5 MHz in two phase groups (10^4 switching events);
    the plate floats, its rigid motion held by testbench springs on the force ports. The plate
    potential equals the charge-conservation value sum C_i V_i / sum C_i (zero total charge)."""
    names, amp, period = _names(model), 5.0, 200e-9
    events, per_period = 10_000, 2 * len(names)
    stop = events / per_period * period
    drive = {
        n: Pulse(0, amp, (i % 2) * period / 4, 5e-9, 5e-9, period / 2 - 5e-9 - (i % 3 == 0) * 20e-9, period)
        for i, n in enumerate(names)
    }
    springs = [f"Bspring_{c.name} f_{c.name} 0 V=-100*v(x_{c.name})" for c in model.coordinates[:3]]
    bench = Bench(
        model,
        lib[0],
        control=lib[1],
        sources={k: p.spice() for k, p in drive.items()},
        extra=springs,
        options="reltol=1e-4 chgtol=1e-20",
        driven_elsewhere={f"f_{c.name}" for c in model.coordinates[:3]},
    )
    plot = run_ngspice(bench.netlist(f".tran 20n {stop} 0 20n uic"), tmp_path)[0]
    x, _ = states(plot, model)
    v_el = np.stack([plot[f"v({n})"] for n in names], axis=-1)
    caps = model.capacitance(x)
    expected = np.sum(caps * v_el, axis=1) / np.sum(caps, axis=1)
    assert np.abs(x).max() > 1e-4  # the plate moved
    assert abs(plot["v(plate)"][-1] - expected[-1]) < 1e-4 * amp
    assert np.abs(plot["v(plate)"] - expected).max() < 1e-4 * amp


def test_ac_compliance_includes_the_electrostatic_spring(model, lib, tmp_path):
    """Small-signal analysis linearises the model at its operating point (the code model's AC gains
    are its Newton partials): 15 V on every electrode, the rigid coordinates held by 20 kHz
    external springs through the force ports, an AC force on z. The compliances x_v / F_z equal
    (K - dF_el/dq - M w^2)^-1 of the Python model, with dF_el/dq by central differences at the
    ngspice operating point, within 0.5 % from 2 kHz to 500 kHz (5 points per decade, across the
    resonances); the electrostatic spring changes the z compliance at 2 kHz by more than 10 %."""
    volts = np.full(len(model.electrodes), 15.0)
    n = model.ncoords
    k_ext = np.zeros(n)
    springs, held = [], set()
    for v, c in enumerate(model.coordinates[:3]):
        k_ext[v] = c.mass * (2 * np.pi * 20e3) ** 2
        xu, xf, fu, ff = c.port_units
        port = "fsp" if v == 0 else f"f_{c.name}"
        springs.append(f"Bsp_{c.name} {port} 0 V={float(-k_ext[v] * xf / ff)!r}*v(x_{c.name})")
        held.add(f"f_{c.name}")
    springs.append("Vac f_z fsp DC 0 AC 1")
    sources = {e.name: "15" for e in model.electrodes} | {"plate": "0"}
    bench = Bench(
        model,
        lib[0],
        control=lib[1],
        sources=sources,
        extra=springs,
        driven_elsewhere=held,
        options="reltol=1e-9 vntol=1e-12 abstol=1e-18",
    )
    plot = run_ngspice(bench.netlist(".ac dec 5 2k 500k"), tmp_path)[0]
    freqs = np.real(plot["frequency"])
    op = run_ngspice(bench.netlist(".op"), tmp_path, name="op")[0]
    x0 = np.array([op[f"v(x1.xs_{c.name})"][0] for c in model.coordinates])
    mass = np.array([c.mass for c in model.coordinates])
    stiff = np.array([c.stiffness for c in model.coordinates]) + k_ext
    jac = np.zeros((n, n))  # dF_el/dq, SI
    for v in range(n):
        h = np.zeros(n)
        h[v] = 1e-4
        diff = model.electrostatic_force(x0 + h, volts)[0] - model.electrostatic_force(x0 - h, volts)[0]
        jac[:, v] = diff / (2e-4 * model.scales[v])
    z = model.coordinates[0]
    f_unit = z.port_units[3]
    for i, freq in enumerate(freqs):
        w = 2 * np.pi * freq
        ref = np.linalg.solve(np.diag(stiff - mass * w**2) - jac, np.eye(n)[0])  # q per N of F_z
        for v, c in enumerate(model.coordinates):
            got = plot[f"v(x_{c.name})"][i] * c.port_units[1] / f_unit
            assert abs(got - ref[v]) < 5e-3 * np.abs(ref).max(), (freq, c.name)
    free = 1 / (stiff[0] - mass[0] * (2 * np.pi * freqs[0]) ** 2)
    assert abs(plot["v(x_z)"][0].real * z.port_units[1] / f_unit / free - 1) > 0.1


def test_code_model_takes_non_affine_plate_terms(model, tmp_path):
    """The code model's curvature path (plate terms of degree 2: values, gradients and the
    Hessian in the force Jacobian): the reference model with quadratic terms added to every
    P_k, emitted in the xspice form, follows scipy's integration of the same modified model
    within 0.2 % of each coordinate's peak, while the curvature moves the rigid coordinates by
    more than 2 % (the affine path is the test above)."""
    import dataclasses

    from netgen.fit import Polynomial

    extra = np.zeros((3, model.ncoords), dtype=int)
    extra[0, 0] = 2  # x_z^2
    extra[1, 0] = extra[1, 1] = 1  # x_z x_tilt_x
    extra[2, 2] = 2  # x_tilt_y^2
    fits = []
    for f in model.capacitances:
        polys = [
            Polynomial(np.vstack([p.exponents, extra]), np.concatenate([p.coeffs, [8.0, 6.0, -4.0]])) for p in f.polys
        ]
        fits.append(dataclasses.replace(f, polys=polys))
    curved = dataclasses.replace(model, capacitances=fits)
    folder = tmp_path / "lib"
    folder.mkdir()
    lib, control = emitted_library(curved, "xspice", folder, LIB)
    drive = transient_drive()
    gravity = -curved.coordinates[0].mass * 9.81
    stop = 60e-6
    sources = {k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)}
    bench = Bench(curved, lib, control=control, sources=sources, options="reltol=1e-5 chgtol=1e-18")
    plot = run_ngspice(bench.netlist(f".tran 10n {stop} 0 10n uic"), tmp_path)[0]
    x, _ = states(plot, curved)
    f_ext = np.zeros(curved.ncoords)
    f_ext[0] = gravity
    ref = reference_transient(curved, drive, f_ext, plot["time"], stop)
    plain = reference_transient(model, drive, f_ext, plot["time"], stop)
    for v, c in enumerate(curved.coordinates):
        peak = np.abs(ref[:, v]).max()
        print(
            f"{c.name}: |ngspice - scipy| {np.abs(x[:, v] - ref[:, v]).max() / peak:.1e}, "
            f"|unmodified - modified| {np.abs(plain[:, v] - ref[:, v]).max() / peak:.1e} of the peak"
        )
        assert np.abs(x[:, v] - ref[:, v]).max() < 2e-3 * peak, c.name
    # the added curvature matters: the unmodified model's motion differs by 10x the tolerance
    assert max(np.abs(plain[:, v] - ref[:, v]).max() / np.abs(ref[:, v]).max() for v in range(3)) > 0.02
