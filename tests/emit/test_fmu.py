"""The FMU of --format fmu (netgen.emit.fmu): fmpy's validator passes for every committed example
model; its charges are the MacroModel's Q(q, V); its co-simulation matches ngspice's transient of
the same model's .lib; a request it cannot serve exits 2 and writes nothing."""

from __future__ import annotations

import contextlib
import math
import zipfile

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.emit import write_outputs
from netgen.model import MacroModel
from netgen.sim import fmu
from netgen.sim.ngspice import run_ngspice
from tests.fixtures import NETLISTS, ROOT, Bench, states, using_ngspice
from tests.oracles.fmu_process import phase_bound

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

# the committed model JSONs: a model is <name>.json beside its <name>.lib (a build's manifest and
# calibration JSONs are not models)
MODELS = sorted(p for p in NETLISTS.rglob("*.json") if p.with_suffix(".lib").exists())
G = 9.81


@pytest.mark.parametrize("json_path", MODELS, ids=lambda p: p.stem)
def test_validator_passes(json_path, tmp_path):
    """fmpy.validation.validate_fmu (modelDescription schema, names, ModelStructure, start values,
    causality/variability, units) finds no problem in the FMU of each committed example model, and
    the archive holds the library for this platform and the source it lists."""
    model = MacroModel.load_json(json_path)
    write_outputs(model, tmp_path, "fmu")
    path = tmp_path / f"{model.name}.fmu"
    assert validate_fmu(str(path)) == []
    names = zipfile.ZipFile(path).namelist()
    assert f"sources/{model.name}.c" in names
    assert any(n.startswith("binaries/linux64/") and n.endswith(".so") for n in names)


CHARGE_MODELS = [
    "levitated_disk.json",
    "accelerometer_xyz/accelerometer_xyz.json",
    "calibrated_disk/calibrated_disk.json",
]


@pytest.mark.parametrize("rel", CHARGE_MODELS)
def test_charges_are_the_macromodels(rel):
    """At 100 random states (|xs| within the sampled range) and voltages (+-10 V electrodes, +-1 V
    plate) the FMU's Q_<e> equal MacroModel.electrode_charges and Q_plate its plate_charge within
    1e-12 of the sum of the absolute contributions (|C_e dV_e| + sum_j |C_ej (V_e - V_j)|): both
    sum the same <= 100 monomial terms per electrode in another order, n eps = 1e-14 each, and the
    C runtime's clamp and gradient are the MacroModel's formulas; the accelerations q'' likewise
    against MacroModel.accelerations (relative to their largest)."""
    model = MacroModel.load_json(NETLISTS / rel)
    inst = fmu.Instance(fmu.built(model), cosim=False)
    inst.start()
    rng = np.random.default_rng(7)
    n, names = model.ncoords, [e.name for e in model.electrodes]
    for _ in range(100):
        xs = rng.uniform(-1, 1, n) * model.sampling["range"]
        v, vp = rng.uniform(-10, 10, len(names)), rng.uniform(-1, 1)
        inst.set_states(np.concatenate([xs * model.scales, np.zeros(n)]))
        inst.set({f"V_{e}": x for e, x in zip(names, v)} | {f"V_{model.plate}": vp})
        q = inst.get([f"Q_{e}" for e in names])
        ref = model.electrode_charges(xs, v, vp)[0]
        scale = (
            np.abs(model.capacitance(xs)[0] * (v - vp))
            + np.abs(model.coupling) @ np.abs(v)
            + np.abs(model.coupling * v[:, None]).sum(axis=1)
        )
        assert np.all(np.abs(q - ref) <= 1e-12 * scale)
        qp = inst.get([f"Q_{model.plate}"])[0]
        assert abs(qp - model.plate_charge(xs, v, vp)[0]) <= 1e-12 * np.sum(np.abs(model.capacitance(xs)[0] * (v - vp)))
        acc = inst.get([f"qdd_{c.name}" for c in model.coordinates])
        ref_acc = model.accelerations(xs, np.zeros(n), v, vp) * model.scales
        assert np.max(np.abs(acc - ref_acc)) <= 1e-12 * np.max(np.abs(ref_acc))
    inst.close()


# ----------------------------------------------------------------------------- against ngspice


CASES = {
    # name: (model JSON, ngspice sources, FMU inputs (SI), stop time, ngspice step cap, ngspice reltol)
    "piston-free-fall": ("piston/piston.json", {"f_z": -1.8639999999999997e-10 * G / 1e-6}, 300e-6, 2e-9, 1e-9),
    "piston-step": ("piston/piston.json", {"drive": 5.0}, 300e-6, 2e-9, 1e-9),
    "disk-free-fall": ("levitated_disk.json", {"f_z": -1.6376763419123287e-08 * G / 1e-6}, 400e-6, 20e-9, 1e-8),
    "disk-step": ("levitated_disk.json", {"top_r2s1": 10.0, "top_r1s2": 5.0}, 20e-6, 0.5e-9, 1e-8),
}


def fmu_inputs(model: MacroModel, ports: dict[str, float]) -> dict[str, float]:
    """The FMU inputs (SI) of the .lib's port values (V, and force ports in their display units)."""
    out = {}
    for name, value in ports.items():
        coord = next((c for c in model.coordinates if f"f_{c.name}" == name), None)
        out[name if coord else f"V_{name}"] = value * coord.port_units[3] if coord else value
    return out


@pytest.mark.parametrize("case", sorted(CASES))
def test_transient_matches_ngspice(case, tmp_path):
    """The FMU's co-simulation (DP45 at tolerance 1e-10, communication grid of 200 points) against
    ngspice 39's transient of the committed .lib from the same rest state, with the inputs applied
    at t = 0 (uic): every coordinate within 1e-5 of its peak |q|. The error budget, asserted below
    to stay under 1e-5: ngspice's trapezoidal phase error (w h)^2 w T / 12 at its step cap h
    (phase_bound; the rigid free fall is integrated exactly); its Newton convergence test, which
    leaves each step's solution within reltol of the O(1) scaled states, a random-signed error that
    accumulates as reltol sqrt(N) over the N = T / h steps (measured on the piston step: 4.5e-6 of
    the peak at reltol 1e-7, 3.3e-7 at 1e-9, where reltol sqrt(N) is 3.9e-5 and 3.9e-7); the
    linear interpolation of its output onto the FMU's grid ((w h)^2/8 <= 1e-7); and the FMU's own
    global error (1.3e-9 of the peak against itself at tolerance 1e-13: counted as 1e-7)."""
    rel, ports, stop, cap, reltol = CASES[case]
    model = MacroModel.load_json(NETLISTS / rel)
    lib = NETLISTS / rel.replace(".json", ".lib")
    sources = {k: f"DC {v!r}" for k, v in ports.items()} | {model.plate: "DC 0"}  # the FMU's V_plate
    ics = " ".join(f"v(x1.xs_{c.name})=0 v(x1.u_{c.name})=0" for c in model.coordinates)
    bench = Bench(
        model, lib, sources=sources, extra=[f".ic {ics}"], options=f"reltol={reltol!r} vntol=1e-14 abstol=1e-17"
    )
    with using_ngspice("39"):
        plot = run_ngspice(bench.netlist(f".tran {cap!r} {stop!r} 0 {cap!r} uic"), tmp_path / "ng")[0]
    t_ng = np.asarray(plot["time"])
    x_ng = states(plot, model)[0] * model.scales
    budget = phase_bound(model, cap, stop, list(np.any(x_ng != 0.0, axis=0))) + reltol * math.sqrt(stop / cap) + 2e-7
    assert budget < 1e-5

    inst = fmu.Instance(fmu.built(model), tolerance=1e-10)
    inst.set(fmu_inputs(model, ports))
    inst.start()
    grid = np.linspace(0.0, stop, 201)
    names = [f"x_{c.name}" for c in model.coordinates]
    got = [inst.get(names)]
    for a, b in zip(grid[:-1], grid[1:]):
        inst.step(b - a)
        got.append(inst.get(names))
    inst.close()
    x_fmu = np.array(got)
    for v, c in enumerate(model.coordinates):
        ref = np.interp(grid, t_ng, x_ng[:, v])
        peak = np.max(np.abs(ref))
        if peak == 0.0:
            assert np.max(np.abs(x_fmu[:, v])) == 0.0
            continue
        assert np.max(np.abs(x_fmu[:, v] - ref)) <= 1e-5 * peak, c.name


# ----------------------------------------------------------------------------- refusals


def test_no_compiler_exits_2_and_writes_nothing(tmp_path, monkeypatch, capsys):
    """A CC that is not an executable: exit 2 naming it and the fix, no output folder."""
    monkeypatch.setenv("CC", "/nonexistent/cc")
    out = tmp_path / "out"
    with contextlib.chdir(ROOT):
        code = cli.main(["build", "examples/piston.toml", "-o", str(out), "-q", "--no-plots", "--format", "fmu"])
    err = capsys.readouterr().err
    assert code == 2
    assert "no C compiler found" in err and "/nonexistent/cc" in err and "fix:" in err
    assert not out.exists()


def test_not_in_all():
    """--format all leaves the FMU out (it needs a C compiler; netgen.emit.EMITTERS says why)."""
    from netgen.emit import chosen

    assert "fmu" not in chosen(MacroModel.load_json(NETLISTS / "piston/piston.json"), "all")


def test_text_from_input_files_only_escaped(tmp_path):
    """A description with XML and C comment breakers reaches the modelDescription only escaped and
    the C only inside comments (the FMU still validates and compiles)."""
    model = MacroModel.load_json(NETLISTS / "piston/piston.json")
    model.description = 'a <b> & "c" */ int x; /* \\'
    write_outputs(model, tmp_path, "fmu")
    assert validate_fmu(str(tmp_path / "piston.fmu")) == []
    text = (tmp_path / "piston_fmu.c").read_text()
    assert "*/ int x;" not in text


def test_saved_state_continues_bit_for_bit():
    """fmi2GetFMUstate / fmi2SetFMUstate through fmpy: the accelerometer's co-simulation driven by a
    ramp sequence on its top electrode, saved after 40 steps, continued 60 steps, restored and
    continued again with the same drives, gives the same outputs to the last bit (a state is the
    instance's data, the adaptive step's warm start included, so the restored instance makes the
    same floating-point operations); so does a second instance that deserializes the serialized
    state (fmi2SerializeFMUstate). The continuation from a fresh instance instead differs: the
    comparison can fail."""
    model = MacroModel.load_json(NETLISTS / "accelerometer_z" / "accelerometer_z.json")
    path = fmu.built(model)
    outputs = ["Q_top", "Q_bottom", "x_z"]
    drives = [(2.0 * math.sin(0.3 * k), 1e6 * math.cos(0.7 * k)) for k in range(100)]

    def start() -> fmu.Instance:
        inst = fmu.Instance(path, tolerance=1e-9)
        inst.set({"a_in": G})
        inst.start()
        return inst

    def run(inst: fmu.Instance, steps) -> np.ndarray:
        step = inst.stepper(["V_top"], outputs)
        return np.array([step([v], [dv], 1e-7).copy() for v, dv in steps])

    inst = start()
    run(inst, drives[:40])
    saved, t_saved = inst.fmu.getFMUstate(), inst.time
    first = run(inst, drives[40:])
    blob = inst.fmu.serializeFMUstate(saved)
    inst.fmu.setFMUstate(saved)
    inst.time = t_saved
    again = run(inst, drives[40:])
    inst.fmu.freeFMUstate(saved)
    inst.close()
    other = start()
    state = other.fmu.deSerializeFMUstate(blob)
    other.fmu.setFMUstate(state)
    other.time = t_saved
    elsewhere = run(other, drives[40:])
    other.fmu.freeFMUstate(state)
    other.close()
    fresh = start()
    fresh.time = 0.0
    unrelated = run(fresh, drives[40:])
    fresh.close()
    assert np.array_equal(first, again) and np.array_equal(first, elsewhere)
    assert not np.array_equal(first, unrelated)
