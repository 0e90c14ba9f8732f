"""Shared fixtures and helpers of the test suite: the reference example (built once per session
and xdist worker), the repository paths, and the testbench helpers for simulator runs of an
emitted macromodel (PULSE sources evaluable in Python, a bench around one instance, states).
Test modules import the helpers from here; conftest.py registers the fixtures."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from netgen.emit import xspice
from netgen.emit.common import time_scale
from netgen.model import MacroModel
from netgen.sim import codemodel, ngspice

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "examples/levitated_disk.toml"  # relative to ROOT: the path the netlist header names
NETLISTS = ROOT / "netlists"
# the two ngspice releases the suite runs: Debian 12's (on PATH) and bookworm-backports' 46, which
# .ci/setup unpacks into a private prefix; netgen.sim.ngspice.ngspice_path() takes it from NETGEN_NGSPICE
NGSPICE = {"39": "ngspice", "46": str(Path.home() / ".cache/netgen/ngspice-46/bin/ngspice")}
# the ngspice emissions the physics tests run, per release: the B-source .lib on both, the xspice
# .lib (the netgen_es code model) on 39 only, where its source is reachable; on 46 the code model
# is refused with exit 3 (tests/sim/test_codemodel.py, tests/testbench/test_sigma_delta.py)
EMISSIONS = [("39", "fast"), ("39", "xspice"), ("46", "fast")]


def emission_id(param: tuple[str, str]) -> str:
    """Test ids such as 39-fast, 46-fast."""
    return "-".join(param)


@contextlib.contextmanager
def using_ngspice(release: str):
    """NETGEN_NGSPICE set to the NGSPICE release for the block: module-scoped fixtures that
    simulate set it only around their own run, so it never leaks into other tests."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(ngspice.ENV, NGSPICE[release])
        yield ngspice.version()


@pytest.fixture(params=sorted(NGSPICE))
def ngspice_version(request, monkeypatch) -> ngspice.Version:
    """A test that takes it runs once per ngspice release of NGSPICE (NETGEN_NGSPICE set for it)."""
    monkeypatch.setenv(ngspice.ENV, NGSPICE[request.param])
    return ngspice.version()


@pytest.fixture(scope="session")
def reference_build():
    """Every stage output of the reference example (netgen.build.build; its .model is what
    build_model returns). Loaded from ROOT with the relative path, as the committed netlists
    were, so the model's `source` matches theirs. About 10-14 s; once per worker."""
    from netgen.build import build
    from netgen.structure import load_structure

    with contextlib.chdir(ROOT):
        return build(load_structure(REFERENCE))


@pytest.fixture(scope="session")
def reference_model(reference_build):
    """The reference MacroModel (treat as read-only: it is shared by the session)."""
    return reference_build.model


@dataclass
class Pulse:
    """ngspice PULSE(v1 v2 td tr tf pw per), also evaluable in Python for reference solvers."""

    v1: float
    v2: float
    td: float
    tr: float
    tf: float
    pw: float
    per: float

    def spice(self) -> str:
        return f"PULSE({self.v1!r} {self.v2!r} {self.td!r} {self.tr!r} {self.tf!r} {self.pw!r} {self.per!r})"

    def vacask(self) -> str:
        """The same waveform as VACASK vsource parameters."""
        return (
            f'type="pulse" val0={self.v1!r} val1={self.v2!r} delay={self.td!r} rise={self.tr!r} '
            f"fall={self.tf!r} width={self.pw!r} period={self.per!r}"
        )

    def __call__(self, t: float) -> float:
        if t <= self.td:
            return self.v1
        tau = (t - self.td) % self.per
        if tau < self.tr:
            return self.v1 + (self.v2 - self.v1) * tau / self.tr
        if tau < self.tr + self.pw:
            return self.v2
        if tau < self.tr + self.pw + self.tf:
            return self.v2 + (self.v1 - self.v2) * (tau - self.tr - self.pw) / self.tf
        return self.v1

    def breakpoints(self, stop: float) -> list[float]:
        out, start = [self.td], self.td
        while start < stop:
            out += [start + self.tr, start + self.tr + self.pw, start + self.tr + self.pw + self.tf, start + self.per]
            start += self.per
        return [t for t in out if 0 < t < stop]


def transient_drive() -> dict[str, Pulse]:
    """The transient cross-checks' drive: 1 MHz pulses on three electrodes, a step at 20 us on a fourth."""
    return {
        "top_r2s1": Pulse(0, 3, 0, 10e-9, 10e-9, 0.49e-6, 1e-6),
        "top_r1s2": Pulse(0, 2, 0.25e-6, 10e-9, 10e-9, 0.3e-6, 1e-6),
        "bot_r2s2": Pulse(0, 3, 0, 10e-9, 10e-9, 0.99e-6, 2e-6),
        "bot_r1s3": Pulse(0, 2, 20e-6, 10e-9, 10e-9, 1.0, 2.0),
    }  # a step at 20 us


@dataclass
class Bench:
    """A testbench around one instance X1 of the model: sources per port, analyses, options."""

    model: MacroModel
    lib: Path
    sources: dict[str, str] = field(default_factory=dict)  # port -> source text (DC value or PULSE/SIN)
    extra: list[str] = field(default_factory=list)
    options: str = ""
    driven_elsewhere: set[str] = field(default_factory=set)  # ports the `extra` lines drive
    control: list[str] = field(default_factory=list)  # .control lines (the code model of an xspice .lib)

    def netlist(self, analysis: str) -> str:
        ports = [p["name"] for p in self.model.ports()]
        lines = [
            f"* netgen test bench for {self.model.name}",
            f".include {self.lib}",
            "X1 " + " ".join(ports) + f" {self.model.name}",
        ]
        for p in self.model.ports():
            name = p["name"]
            if name in self.sources:
                lines.append(f"V{name} {name} 0 {self.sources[name]}")
            elif (
                p["kind"] in ("force_in", "electrode", "acceleration_in", "rate_in")
                and name not in self.driven_elsewhere
            ):
                lines.append(f"V{name} {name} 0 0")  # grounded; the plate floats unless given
        lines += self.extra
        if self.options:
            lines.append(f".options {self.options}")
        if self.control:
            lines += [".control", *self.control, ".endc"]
        lines += [analysis, ".end", ""]
        return "\n".join(lines)


def states(plot, model: MacroModel, instance: str = "x1") -> tuple[np.ndarray, np.ndarray]:
    """Scaled coordinates x and their time derivatives (1/s) from an ngspice plot."""
    ws = time_scale(model)
    x = np.stack([plot[f"v({instance}.xs_{c.name})"] for c in model.coordinates], axis=-1)
    u = np.stack([plot[f"v({instance}.u_{c.name})"] for c in model.coordinates], axis=-1)
    return x, u * ws


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
