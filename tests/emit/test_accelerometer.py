"""The three-axis accelerometer example (examples/accelerometer_xyz.toml: six rigid-body
coordinates, comb and plate electrodes) through every emitter: its Verilog-A compiles without
warnings and matches the Python MacroModel at 200 random points (openvaf-py), VACASK's transient
matches ngspice's within 1 %, and a z acceleration leaves x and y (symmetry) below 1e-3 of their
own sensitivity in ngspice."""

from __future__ import annotations

import numpy as np
import openvaf_py
import pytest

from netgen.build import build
from netgen.emit import write_outputs
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from netgen.structure import load_structure
from tests.fixtures import ROOT, Bench, Pulse, states, va_residuals, va_volts


@pytest.fixture(scope="module")
def emitted(tmp_path_factory):
    """The example built once and written in every format: (model, folder)."""
    folder = tmp_path_factory.mktemp("acc")
    model = build(load_structure(ROOT / "examples" / "accelerometer_xyz.toml")).model
    write_outputs(model, folder, "all")
    return model, folder


def test_every_format_is_written(emitted):
    model, folder = emitted
    for suffix in (".lib", "_xspice.lib", ".va", ".json"):
        assert (folder / f"accelerometer_xyz{suffix}").stat().st_size > 0
    assert [c.name for c in model.coordinates] == ["x", "y", "rot_z", "z", "tilt_x", "tilt_y"]


def test_veriloga_matches_the_python_model_at_200_points(emitted, tmp_path):
    """openvaf-r compiles with warnings denied; openvaf-py's charges and forces within 1e-9 relative
    of MacroModel.electrode_charges / electrostatic_force at 200 random states and voltages."""
    model, folder = emitted
    va = folder / "accelerometer_xyz.va"
    osdi, log = compile_va(va, tmp_path / "acc.osdi", deny_warnings=True)
    assert osdi.stat().st_size > 0 and "warning" not in log.lower()
    compiled = openvaf_py.compile_va(str(va))[0]
    params = {f"d_{c.name}": c.damping for c in model.coordinates} | {"fel_scale": 1.0, "mfactor": 1.0}
    unit = np.array([c.port_units[3] for c in model.coordinates])
    rng = np.random.default_rng(2024)
    r = model.sampling["range"]
    x = rng.uniform(-r, r, (200, model.ncoords))
    v_el = rng.uniform(-10.0, 10.0, (200, len(model.electrodes)))
    v_plate = rng.uniform(-2.0, 2.0, 200)
    q_va, f_va = np.zeros_like(v_el), np.zeros_like(x)
    for p in range(len(x)):
        full = va_residuals(compiled, va_volts(model, x[p], v_el[p], v_plate[p]), params)
        base = va_residuals(
            compiled, va_volts(model, x[p], np.full(len(model.electrodes), v_plate[p]), v_plate[p]), params
        )
        q_va[p] = [full[e.name][1] for e in model.electrodes]
        f_va[p] = [
            -unit[v] * (full[f"fn_{c.name}"][0] - base[f"fn_{c.name}"][0]) for v, c in enumerate(model.coordinates)
        ]
    q_py = model.electrode_charges(x, v_el, v_plate)
    f_py = model.electrostatic_force(x, v_el, v_plate)
    q_err = np.abs(q_va - q_py).max() / np.abs(q_py).max()
    f_err = np.abs(f_va - f_py) / np.abs(f_py).max(axis=0)
    print(f"max relative difference: charges {q_err:.2e}, forces {f_err.max():.2e}")
    assert q_err < 1e-9 and f_err.max() < 1e-9


DRIVE = {
    "xp_t": Pulse(0, 6, 10e-6, 1e-7, 1e-7, 1.0, 2.0),
    "yn_l": Pulse(0, 6, 30e-6, 1e-7, 1e-7, 1.0, 2.0),
    "zs": Pulse(0, 3, 50e-6, 1e-7, 1e-7, 1.0, 2.0),
}


def test_vacask_transient_matches_ngspice(emitted, tmp_path):
    """Steps on an x comb, a y comb and the z plate, 150 us with a 50 ns maximum step in both
    simulators: every coordinate within 1 % of its peak."""
    model, folder = emitted
    stop = 150e-6
    osdi, _ = compile_va(folder / "accelerometer_xyz.va", tmp_path / "acc.osdi")
    vac = run_vacask(
        VacaskBench(
            model,
            osdi,
            sources={k: p.vacask() for k, p in DRIVE.items()} | {"plate": "dc=0"},
            options="reltol=1e-5 chgtol=1e-18",
        ).netlist(f'analysis tran1 tran step=50n stop={stop!r} maxstep=50n icmode="uic"'),
        tmp_path / "vacask",
    )
    spice = Bench(
        model,
        folder / "accelerometer_xyz.lib",
        sources={k: p.spice() for k, p in DRIVE.items()} | {"plate": "0"},
        options="reltol=1e-5 chgtol=1e-18",
    )
    plot = run_ngspice(spice.netlist(f".tran 50n {stop!r} 0 50n uic"), tmp_path / "ngspice")[0]
    x_ng, _ = states(plot, model)
    t = plot["time"]
    for v, c in enumerate(model.coordinates):
        x_vac = np.interp(t, vac["time"], vac[f"x1:xs_{c.name}"])
        peak = np.abs(x_ng[:, v]).max()
        err = np.abs(x_vac - x_ng[:, v]).max() / peak
        print(f"{c.name}: peak {peak:.3e} (units of L), max difference {err:.2e} of peak")
        if c.name in ("x", "y", "z"):
            assert peak > 1e-3, c.name
        assert err < 0.01, c.name


def test_z_acceleration_leaves_x_and_y_alone(emitted):
    """With every comb at 3 V and the plate at 2 V, a z acceleration of 1000 m/s^2 (port a_in) moves
    x and y by less than 1e-3 of what the same acceleration does along x or y (m a / k), in an
    ngspice operating point."""
    model, folder = emitted
    lib = folder / "accelerometer_xyz.lib"
    volts = {e.name: "DC 3" for e in model.electrodes} | {"zs": "DC 2", "plate": "0"}
    base = run_ngspice(Bench(model, lib, sources=volts).netlist(".op"), folder / "op0")[0]
    push = run_ngspice(Bench(model, lib, sources=volts | {"a_in": "DC 1000"}).netlist(".op"), folder / "op1")[0]
    for name in ("x", "y"):
        c = next(c for c in model.coordinates if c.name == name)
        own = c.mass * 1000 / c.stiffness  # m: the in-plane sensitivity
        moved = abs(float(push[f"x1.xs_{name}"][0]) - float(base[f"x1.xs_{name}"][0])) * c.scale
        assert moved < 1e-3 * own, name
    z = next(c for c in model.coordinates if c.name == "z")
    dz = (float(push["x1.xs_z"][0]) - float(base["x1.xs_z"][0])) * z.scale
    assert dz < -z.mass * 1000 / z.stiffness  # z itself moves, further than m a / k (the bias softens it)
