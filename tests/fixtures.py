"""Shared fixtures and helpers of the test suite: the reference example (built once per session
and xdist worker), the repository paths, and the testbench helpers for simulator runs of an
emitted macromodel (PULSE sources evaluable in Python, a bench around one instance, states:
tests/oracles/testbench.py, shared with the bench scripts, re-exported here). Test modules import
the helpers from here; conftest.py registers the fixtures."""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import time
from pathlib import Path

import pytest

from netgen.emit import xspice
from netgen.model import MacroModel
from netgen.sim import codemodel, ngspice
from tests.oracles.small_disk import SMALL_BEM_DISK  # noqa: F401  (re-exported for the test modules)
from tests.oracles.testbench import (  # noqa: F401  (re-exported for the test modules)
    NGSPICE,
    Bench,
    Pulse,
    reference_transient,
    states,
    transient_drive,
    using_ngspice,
)

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "examples/levitated_disk.toml"  # relative to ROOT: the path the netlist header names
NETLISTS = ROOT / "netlists"
# the ngspice emissions the physics tests run, per release: the B-source .lib on both, the xspice
# .lib (the netgen_es code model) on 39 only, where its source is reachable; on 46 the code model
# is refused with exit 3 (tests/sim/test_codemodel.py, tests/testbench/test_sigma_delta.py)
EMISSIONS = [("39", "fast"), ("39", "xspice"), ("46", "fast")]


# the folder shared by the session's processes (xdist workers) where shared_model keeps built models
# (set by conftest.pytest_configure; unset, shared_model builds every time)
MODEL_CACHE_ENV = "NETGEN_TEST_MODEL_CACHE"
MODEL_WAIT_S = 900.0  # how long a worker waits for another's build of the same structure


def shared_model(structure) -> MacroModel:
    """build_model(structure), built once per test session across modules and xdist workers: several
    modules build the same structure (the etch forms and laws tests each the process accelerometer,
    about 15 s each), and a model is a deterministic function of its structure (tests/pipeline/
    test_outputs.py holds builds in separate processes byte-identical), so each module gets an
    unpickled copy of one build."""
    from netgen.build import build_model

    return shared("model", structure, build_model)


def shared(kind: str, structure, make):
    """make(structure), once per session (shared_model): the first process to ask builds and pickles
    it into MODEL_CACHE_ENV's folder, the others wait for the file. The key is a hash of the pickled
    structure (every field, its source path too; a set pickled in another order costs a second build,
    never a wrong result)."""
    folder = os.environ.get(MODEL_CACHE_ENV)
    if not folder:
        return make(structure)
    key = kind + "-" + hashlib.sha256(pickle.dumps(structure)).hexdigest()[:32]
    done, lock = Path(folder) / f"{key}.pkl", Path(folder) / f"{key}.lock"
    try:
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL))
    except FileExistsError:
        return waited(done, lock, structure, make)
    try:
        result = make(structure)
        part = done.with_suffix(f".{os.getpid()}.part")
        part.write_bytes(pickle.dumps(result))
        os.replace(part, done)
        return result
    finally:
        if not done.exists():
            lock.unlink(missing_ok=True)  # a failed build: a waiter builds (and fails) itself


def waited(done: Path, lock: Path, structure, make):
    """What another process is building (shared), once it is written; made here if that build failed
    or takes longer than MODEL_WAIT_S."""
    deadline = time.monotonic() + MODEL_WAIT_S
    while time.monotonic() < deadline:
        if done.exists():
            return pickle.loads(done.read_bytes())
        if not lock.exists():
            break
        time.sleep(0.2)
    return make(structure)


def emission_id(param: tuple[str, str]) -> str:
    """Test ids such as 39-fast, 46-fast."""
    return "-".join(param)


@pytest.fixture(params=sorted(NGSPICE))
def ngspice_version(request, monkeypatch) -> ngspice.Version:
    """A test that takes it runs once per ngspice release of NGSPICE (NETGEN_NGSPICE set for it)."""
    monkeypatch.setenv(ngspice.ENV, NGSPICE[request.param])
    return ngspice.version()


@pytest.fixture(scope="session")
def reference_build():
    """Every stage output of the reference example (netgen.build.build; its .model is what
    build_model returns). Loaded from ROOT with the relative path, as the committed netlists
    were, so the model's `source` matches theirs. About 10-14 s; once per worker (its mechanics
    stage holds a closure, so it does not pickle for shared)."""
    from netgen.build import build
    from netgen.structure import load_structure

    with contextlib.chdir(ROOT):
        return build(load_structure(REFERENCE))


@pytest.fixture(scope="session")
def reference_model(reference_build):
    """The reference MacroModel (treat as read-only: it is shared by the session)."""
    return reference_build.model


def emitted_library(model: MacroModel, style: str, folder: Path, committed: Path) -> tuple[Path, list[str]]:
    """The model's .lib in one ngspice form and the .control lines it needs: "fast" is the
    committed B-source netlist, "xspice" the plate terms in the compiled netgen_es code model
    (built once)."""
    if style == "fast":
        return committed, []
    lib = Path(folder) / f"{model.name}_{style}.lib"
    lib.write_text(xspice.subcircuit(model))
    return lib, codemodel.control_lines(codemodel.build(progress=lambda m: None))


# ----------------------------------------------------------------------------- Verilog-A evaluation (openvaf-py)


def va_residuals(va_module, volts: dict[str, float], params: dict[str, float]) -> dict[str, tuple[float, float]]:
    """(resistive, reactive) residual per node name of an openvaf-py compiled module for the given
    node voltages and parameters."""
    inputs = {}
    for name, kind in zip(va_module.param_names, va_module.param_kinds):
        if kind == "voltage":  # V(a) or V(a,b)
            hi, _, lo = name[2:-1].partition(",")
            inputs[name] = volts.get(hi.strip(), 0.0) - volts.get(lo.strip(), 0.0)
        elif kind == "param":
            inputs[name] = params[name]
        elif kind == "current":
            inputs[name] = 0.0
    for name in va_module.init_param_names:
        inputs.setdefault(name, params.get(name, 1.0))  # mfactor = 1
    residuals, _ = va_module.run_init_eval(inputs)
    rows = va_module.get_dae_system()["residuals"]
    return {row["node_name"]: residuals[row["equation_idx"]] for row in rows}


def va_volts(model: MacroModel, x, v_el, v_plate, force: float = 0.0) -> dict[str, float]:
    """Node voltages of one Verilog-A evaluation: states xs_<q>, electrodes, plate, force ports; u = 0."""
    volts = {e.name: float(v) for e, v in zip(model.electrodes, v_el)} | {model.plate: float(v_plate)}
    for c, xv in zip(model.coordinates, x):
        volts |= {f"xs_{c.name}": float(xv), f"f_{c.name}": force}
    return volts
