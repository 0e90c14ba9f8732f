"""The emitted Verilog-A module, checked by real compilers and a second simulator.

- compiles with openvaf-r (warnings denied) and with openvaf-py's compile_va, no warnings;
- openvaf-py evaluation: electrode charges and generalized forces equal the Python
  MacroModel's at 200 random states and voltages (forces read in force-port units, i.e.
  relative to the response to 1 V on f_<q>, so no emitter scaling enters the check);
- VACASK transient with the compiled module against ngspice with the .lib, same drive;
- the committed netlists/levitated_disk.va is what the emitter makes of the committed JSON.
"""

from __future__ import annotations

import time

import numpy as np
import openvaf_py
import pytest

from netgen.core.errors import ModelError
from netgen.emit import write_outputs
from netgen.emit.veriloga import module
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from tests.fixtures import ROOT, Bench, states, transient_drive, va_residuals, va_volts

JSON = ROOT / "netlists" / "levitated_disk.json"
LIB = ROOT / "netlists" / "levitated_disk.lib"
VA = ROOT / "netlists" / "levitated_disk.va"


@pytest.fixture(scope="module")
def model() -> MacroModel:
    return MacroModel.load_json(JSON)


@pytest.fixture(scope="module")
def compiled():
    """The committed module compiled by openvaf-py (one module in the file)."""
    modules = openvaf_py.compile_va(str(VA))
    assert [m.name for m in modules] == ["levitated_disk"]
    return modules[0]


def test_committed_module_is_current(model):
    """Re-rendering the committed JSON gives the committed .va exactly (regenerate with
    `netgen build examples/levitated_disk.toml -o netlists --format all`)."""
    assert module(model) == VA.read_text(encoding="utf-8"), "netlists/levitated_disk.va is stale"


def test_openvaf_r_compiles_without_warnings(tmp_path):
    """openvaf-r with every warning turned into an error, and nothing in its log that warns."""
    start = time.perf_counter()
    osdi, log = compile_va(VA, tmp_path / "levitated_disk.osdi", deny_warnings=True)
    print(f"openvaf-r: {time.perf_counter() - start:.2f} s")
    assert osdi.stat().st_size > 0
    assert "warning" not in log.lower() and "error" not in log.lower(), log


def test_openvaf_py_compiles_without_warnings(capfd):
    """compile_va prints OpenVAF's diagnostics on stderr: there must be none."""
    capfd.readouterr()
    modules = openvaf_py.compile_va(str(VA))
    out, err = capfd.readouterr()
    assert len(modules) == 1
    assert "warning" not in (out + err).lower(), out + err
    ports = [p["name"] for p in MacroModel.load_json(JSON).ports()]
    assert modules[0].get_dae_system()["terminals"] == ports  # same ports, same order as the .lib


def _random_points(model: MacroModel, n: int = 200):
    """States inside the sampled box, electrode voltages +-25 V, plate +-5 V."""
    rng = np.random.default_rng(2024)
    r = model.sampling["range"]
    x = rng.uniform(-r, r, (n, model.ncoords))
    v_el = rng.uniform(-25.0, 25.0, (n, len(model.electrodes)))
    v_plate = rng.uniform(-5.0, 5.0, n)
    return x, v_el, v_plate


def test_charges_and_forces_match_the_python_model(model, compiled):
    """200 random points: electrode charges (reactive residuals) and generalized forces within
    1e-9 relative of MacroModel.electrode_charges / electrostatic_force. The force is the residual
    of the force node fn_<q> (V(fn) - F/unit, read at V(fn) = 0), and 1 V on fn_<q> moves the
    velocity equation exactly as 1 V on the port f_<q> does."""
    params = {f"d_{c.name}": c.damping for c in model.coordinates} | {"fel_scale": 1.0, "mfactor": 1.0}
    unit = np.array([c.port_units[3] for c in model.coordinates])  # SI force per volt on f_<q>
    x, v_el, v_plate = _random_points(model)
    q_va, f_va = np.zeros_like(v_el), np.zeros_like(x)
    for p in range(len(x)):
        full = va_residuals(compiled, va_volts(model, x[p], v_el[p], v_plate[p]), params)
        still = np.full(len(model.electrodes), v_plate[p])  # no field: F_el = 0
        base = va_residuals(compiled, va_volts(model, x[p], still, v_plate[p]), params)
        pushed = va_residuals(compiled, va_volts(model, x[p], still, v_plate[p], force=1.0), params)
        nodes = va_volts(model, x[p], still, v_plate[p]) | {f"fn_{c.name}": 1.0 for c in model.coordinates}
        by_node = va_residuals(compiled, nodes, params)
        q_va[p] = [full[e.name][1] for e in model.electrodes]
        for v, c in enumerate(model.coordinates):
            u, fn = f"u_{c.name}", f"fn_{c.name}"
            f_va[p, v] = -unit[v] * (full[fn][0] - base[fn][0])
            assert by_node[u][0] - base[u][0] == pytest.approx(pushed[u][0] - base[u][0], rel=1e-12, abs=0), c.name
    q_py = model.electrode_charges(x, v_el, v_plate)
    f_py = model.electrostatic_force(x, v_el, v_plate)
    q_err = np.abs(q_va - q_py) / np.abs(q_py)
    f_err = np.abs(f_va - f_py) / np.abs(f_py)
    print(f"max relative difference: charges {q_err.max():.2e}, forces {f_err.max():.2e}")
    assert np.all(np.abs(q_py) > 0) and np.all(np.abs(f_py) > 0)
    assert q_err.max() < 1e-9
    assert f_err.max() < 1e-9


def test_vacask_transient_matches_ngspice(model, tmp_path):
    """The drive of test_ngspice's transient (pulses, a step, gravity on z), 105 us with a 10 ns
    maximum step in both simulators: every coordinate within 1 % of its peak."""
    drive, stop = transient_drive(), 105e-6
    gravity_port = -model.coordinates[0].mass * 9.81 / model.coordinates[0].port_units[3]  # V on f_z
    osdi, _ = compile_va(VA, tmp_path / "levitated_disk.osdi")
    bench = VacaskBench(
        model,
        osdi,
        sources={k: p.vacask() for k, p in drive.items()} | {"plate": "dc=0", "f_z": f"dc={gravity_port!r}"},
        options="reltol=1e-5 chgtol=1e-18",
    )
    start = time.perf_counter()
    vac = run_vacask(
        bench.netlist(f'analysis tran1 tran step=10n stop={stop!r} maxstep=10n icmode="uic"'), tmp_path / "vacask"
    )
    t_vacask = time.perf_counter() - start
    spice = Bench(
        model,
        LIB,
        sources={k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity_port)},
        options="reltol=1e-5 chgtol=1e-18",
    )
    start = time.perf_counter()
    plot = run_ngspice(spice.netlist(f".tran 10n {stop!r} 0 10n uic"), tmp_path / "ngspice")[0]
    t_ngspice = time.perf_counter() - start
    x_ng, _ = states(plot, model)
    t = plot["time"]
    assert abs(vac["time"][-1] - stop) < 1e-12 and abs(t[-1] - stop) < 1e-12
    print(f"VACASK {t_vacask:.1f} s ({len(vac['time'])} points), ngspice {t_ngspice:.1f} s ({len(t)} points)")
    for v, c in enumerate(model.coordinates):
        x_vac = np.interp(t, vac["time"], vac[f"x1:xs_{c.name}"])
        peak = np.abs(x_ng[:, v]).max()
        err = np.abs(x_vac - x_ng[:, v]).max() / peak
        print(f"{c.name}: peak {peak:.3e} (units of L), max difference {err:.2e} of peak")
        assert peak > 0 and err < 0.01, c.name
        out = np.interp(t, vac["time"], vac[f"x_{c.name}"])  # the buffered port, in its unit
        assert np.allclose(out, x_vac * c.scale / c.port_units[1], rtol=1e-9, atol=1e-12 * peak)


def test_bad_names_are_refused_clearly(model):
    """An electrode named like a Verilog-A keyword never reaches the emitter: the model's name
    policy (netgen.core.names, checked when a model is read) refuses it with the key and the fix."""
    d = model.to_dict()
    d["electrodes"][0]["name"] = d["capacitances"][0]["electrode"] = "module"
    with pytest.raises(ModelError, match=r"electrodes\[0\]\.name: electrode name 'module' is a Verilog-A keyword"):
        module(MacroModel.from_dict(d))


def test_unknown_format_is_refused(model, tmp_path):
    """write_outputs names the known dialects and writes nothing."""
    with pytest.raises(ValueError, match="ngspice, veriloga, xspice, osdi, xschem, kicad, fmu, all"):
        write_outputs(model, tmp_path / "out", "spectre")
    assert not (tmp_path / "out").exists()
