"""The testbench oracles of the simulator runs: the ngspice releases, PULSE sources evaluable in
Python, the transient drive of the cross-checks, a bench around one instance of a model, its states
from an ngspice plot, and the solve_ivp reference of that transient. The tests import them through
tests.fixtures, the bench scripts through bench/support.py."""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from netgen.emit.common import time_scale
from netgen.model import MacroModel
from netgen.sim import ngspice

# the two ngspice releases the suite runs: Debian 12's (on PATH) and bookworm-backports' 46, which
# .ci/setup unpacks into a private prefix; netgen.sim.ngspice.ngspice_path() takes it from NETGEN_NGSPICE
# ngspice 46 where .ci/setup unpacks it: ${XDG_CACHE_HOME:-~/.cache}/netgen/ngspice-46
NGSPICE = {
    "39": "ngspice",
    "46": os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "netgen/ngspice-46/bin/ngspice"
    ),
}


@contextlib.contextmanager
def using_ngspice(release: str):
    """NETGEN_NGSPICE set to the NGSPICE release for the block: module-scoped fixtures that
    simulate set it only around their own run, so it never leaks into other tests."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(ngspice.ENV, NGSPICE[release])
        yield ngspice.version()


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


def reference_transient(model, drive, f_ext, times, stop):
    """solve_ivp of M q'' + K q = F_el(q, V(t)) + F_ext, segment by segment between the
    corners of the piecewise-linear voltages (tight tolerances), sampled at `times`."""
    idx = [[e.name for e in model.electrodes].index(k) for k in drive]

    def rhs(t, y):
        v = np.zeros(len(model.electrodes))
        for k, i in zip(drive, idx):
            v[i] = drive[k](t)
        n = model.ncoords
        return np.concatenate([y[n:], model.accelerations(y[:n], y[n:], v, 0.0, f_ext)])

    corners = sorted({0.0, stop, *[t for d in drive.values() for t in d.breakpoints(stop)]})
    y, out = np.zeros(2 * model.ncoords), np.zeros((len(times), model.ncoords))
    for a, b in zip(corners[:-1], corners[1:]):
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-10, atol=1e-13, dense_output=True)
        y = sol.y[:, -1]
        sel = (times >= a) & (times < b)
        if sel.any():
            out[sel] = sol.sol(times[sel]).T[:, : model.ncoords]
    return out
