"""The transistor-level switched-capacitor readout (examples/sc_readout.inc) around the committed z
accelerometer or two fixed capacitors: netlist text, one batch run with its cost, the bits per
period, and the force balance the bitstream must meet, computed from the MacroModel JSON (not
from the netlist). Shared by tests/testbench/test_sc_readout.py and bench/sc_readout.py."""

from __future__ import annotations

import resource
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from netgen.model import MacroModel
from netgen.sim import ngspice

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
MODEL_LIB = ROOT / "netlists/accelerometer_z/accelerometer_z.lib"
MODEL_JSON = ROOT / "netlists/accelerometer_z/accelerometer_z.json"
TS = 2e-6  # the readout's period (examples/sc_readout.inc)
WINDOW = 0.70e-6  # its feedback window: phf on (0.02 us) to psr on (0.72 us)
V_FB = 1.8 - 0.9  # VDD - VCM on the pushing electrode, the plate at VCM
T_BIT = 1.95e-6  # phase at which the SR latch holds this period's decision (clk 1.75-1.86 us)
C_REST = 1.1067734766e-12  # the fixed-capacitor twin's value: C(0) of the model (its .lib header)
# the readout's comparator decides on mV at ~1 V nodes: at the default reltol 1e-3 ngspice 46 lets
# the decisions lose the position (the mass drifted 17 nm in 60 periods at 3 m/s^2), 1e-4 holds it
RELTOL = "reltol=1e-4"


@dataclass
class Run:
    """One simulated run: bits per period (1 = push up), x_z in um, time points, CPU seconds."""

    bits: np.ndarray
    time: np.ndarray
    x_um: np.ndarray
    points: int
    cpu: float


def steps(values: list[float], each: int) -> str:
    """A PWL source value holding each acceleration for `each` periods (3 ns ramps at the boundaries)."""
    pts = [f"0 {values[0]!r}"]
    for i, (a, b) in enumerate(zip(values, values[1:]), start=1):
        t = i * each * TS
        pts += [f"{t!r} {a!r}", f"{t + 3e-9!r} {b!r}"]
    return f"PWL({' '.join(pts)})"


def netlist(accel: float | str, periods: int, model: bool = True, options: str = RELTOL, step: float = 20e-9) -> str:
    """The testbench of examples/accelerometer_z_sc.cir (model) or _fixed.cir, with absolute
    includes; accel in m/s^2 or a source value such as steps() gives."""
    inc = [EXAMPLES / "generic_018.lib", EXAMPLES / "sc_readout.inc"] + ([MODEL_LIB] if model else [])
    lines = ["* sc readout run", *(f'.include "{p}"' for p in inc)]
    if model:
        lines += [
            "X1 top bottom plate f_z x_z a_in accelerometer_z",
            f"Vacc a_in 0 {accel if isinstance(accel, str) else repr(accel)}",
        ]
    else:
        lines += [f"Ctop top plate {C_REST!r}", f"Cbot bottom plate {C_REST!r}", "Vxz x_z 0 0"]
    lines += ["Xro top bottom plate q qb sc_readout"]
    if options:
        lines.append(f".options {options}")
    lines += [".save v(qb) v(x_z)", f".tran {step!r} {periods * TS!r} 0 uic", ".end", ""]
    return "\n".join(lines)


def children_cpu() -> float:
    """CPU seconds of this process's finished children (the simulator runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(
    workdir: Path, accel: float | str, periods: int, model: bool = True, options: str = "", name: str = "sc"
) -> Run:
    """Simulate, return the bits decided in each period and the trace of x_z."""
    before = children_cpu()
    plot = ngspice.run_ngspice(netlist(accel, periods, model, options), workdir, name)[0]
    cpu = children_cpu() - before
    t = np.real(plot["time"])
    qb, x = np.real(plot["v(qb)"]), np.real(plot["v(x_z)"])
    bits = np.interp(np.arange(periods) * TS + T_BIT, t, qb) > 0.9
    return Run(bits.astype(float), t, x, len(t), cpu)


def balance(model: MacroModel, accel: float, z_mean: float = 0.0) -> float:
    """mean(bit) of the force balance d (b F_top + (1 - b) F_bottom) = G a + k z: F_i =
    1/2 dC_i/dz V_fb^2 at the mean position (MacroModel.capacitance_gradient), G the participation
    (MacroModel.acceleration), k the stiffness; d = WINDOW / TS."""
    z = model.coordinates[0]
    grad = model.capacitance_gradient(np.array([[z_mean / z.scale]]))[0, :, 0]
    f_top, f_bot = 0.5 * grad * V_FB**2
    need = (model.acceleration[0] * accel + z.stiffness * z_mean) / (WINDOW / TS)
    return float((need - f_bot) / (f_top - f_bot))


def bit_impulse(model: MacroModel) -> float:
    """Velocity change (m/s) of one bit's difference: d T_s (F_top - F_bottom) / m, at rest."""
    z = model.coordinates[0]
    grad = model.capacitance_gradient(np.zeros((1, 1)))[0, :, 0]
    return float(WINDOW * 0.5 * V_FB**2 * (grad[0] - grad[1]) / z.mass)


def period_velocity(r: Run, first: int) -> np.ndarray:
    """Mean velocity (m/s) over each period from `first` on, from x_z one period apart."""
    k = np.arange(first, len(r.bits) + 1)
    x = np.interp(k * TS, r.time, r.x_um) * 1e-6
    return np.diff(x) / TS
