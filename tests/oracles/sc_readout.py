"""The transistor-level switched-capacitor readout (examples/sc_readout.inc) around the committed z
accelerometer or two fixed capacitors: netlist text, one batch run with its cost, the bits per
period, and the force balance the bitstream must meet, computed from the MacroModel JSON (not
from the netlist). Shared by tests/testbench/test_sc_readout.py and bench/sc_readout.py."""

from __future__ import annotations

import resource
import time
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
# ngspice built with OpenMP (Debian's 39, the 46 of .ci/setup) loads BSIM4 in a parallel loop with
# `num_threads` threads: 2 by default in 39 (cktsetup.c; omp_set_num_threads overrides
# OMP_NUM_THREADS), 8 from 46's spinit. On a shared 2-core machine the threads spin at every
# load's barrier: ngspice 39 spent 40x the CPU of one thread on the same time points and Newton
# iterations (bench/sc_readout.py --only threads). A `set` in .control overrides both (`.options
# num_threads=1` reaches 39 only: 46's spinit value wins over it).
ONE_THREAD = [".control", "set num_threads=1", "run", ".endc"]


@dataclass
class Run:
    """One simulated run: bits per period (1 = push up), x_z in um, time points, CPU and wall seconds."""

    bits: np.ndarray
    time: np.ndarray
    x_um: np.ndarray
    points: int
    cpu: float
    wall: float = 0.0


def steps(values: list[float], each: int) -> str:
    """A PWL source value holding each acceleration for `each` periods (3 ns ramps at the boundaries)."""
    pts = [f"0 {values[0]!r}"]
    for i, (a, b) in enumerate(zip(values, values[1:]), start=1):
        t = i * each * TS
        pts += [f"{t!r} {a!r}", f"{t + 3e-9!r} {b!r}"]
    return f"PWL({' '.join(pts)})"


def netlist(
    accel: float | str,
    periods: int,
    model: bool = True,
    options: str = RELTOL,
    step: float = 20e-9,
    threads: int = 1,
    start: str = "uic",
    tmax: float | None = None,
) -> str:
    """The testbench of examples/accelerometer_z_sc.cir (model) or _fixed.cir, with absolute
    includes; accel in m/s^2 or a source value such as steps() gives; threads=1 sets one OpenMP
    thread (ONE_THREAD), anything else leaves the simulator's default; start "uic" or "" (the
    transient from the operating point); tmax the maximum step (None: ngspice's, the step)."""
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
    lines += [
        ".save v(qb) v(x_z)",
        " ".join(
            [".tran", repr(step), repr(periods * TS), "0", *([] if tmax is None else [repr(tmax)]), start]
        ).rstrip(),
    ]
    return "\n".join([*lines, *(ONE_THREAD if threads == 1 else []), ".end", ""])


def children_cpu() -> float:
    """CPU seconds of this process's finished children (the simulator runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(
    workdir: Path,
    accel: float | str,
    periods: int,
    model: bool = True,
    options: str = RELTOL,
    name: str = "sc",
    timeout: float = 3600.0,
    **settings,
) -> Run:
    """Simulate (at the readout's reltol unless `options` says otherwise; `settings`: netlist()'s
    step, threads, start), return the bits decided in each period and the trace of x_z, with the
    ngspice process's CPU and wall seconds."""
    before, began = children_cpu(), time.monotonic()
    plot = ngspice.run_ngspice(netlist(accel, periods, model, options, **settings), workdir, name, timeout)[0]
    cpu, wall = children_cpu() - before, time.monotonic() - began
    t = np.real(plot["time"])
    qb, x = np.real(plot["v(qb)"]), np.real(plot["v(x_z)"])
    bits = np.interp(np.arange(periods) * TS + T_BIT, t, qb) > 0.9
    return Run(bits.astype(float), t, x, len(t), cpu, wall)


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


def momentum_mean(model: MacroModel, r: Run, first: int) -> float:
    """The bit mean from `first` on, net of the momentum the mass gained meanwhile: over N periods
    sum(impulses) = m (v_end - v_start) + N T_s (G a + k z) exactly, so subtracting
    m (v_end - v_start) / (N d T_s (F_top - F_bottom)) leaves the force balance's mean up to the
    per-bit impulses' error and two bits over N: the period-mean velocities (period_velocity) stand
    in for the instantaneous ones at the ends (one bit's impulse), and the last bit is decided
    but not yet applied within the run (one bit)."""
    v = period_velocity(r, first)
    n = len(r.bits) - first
    return float(r.bits[first:].mean() - (v[-1] - v[0]) / (n * bit_impulse(model)))


def full_scale(model: MacroModel) -> float:
    """The acceleration (m/s^2) the loop balances with every bit pushing up: d F_top / G at rest."""
    return float(sc_force(model)[0] * (WINDOW / TS) / model.acceleration[0])


def sc_force(model: MacroModel) -> np.ndarray:
    """F_top, F_bottom (N) of the feedback level at rest: 1/2 dC_i/dz V_fb^2."""
    return 0.5 * model.capacitance_gradient(np.zeros((1, 1)))[0, :, 0] * V_FB**2


CF = 1e-12  # the never-reset charge amplifier's feedback capacitor (charge_netlist)
ABSTOL, VNTOL = 1e-12, 1e-6  # ngspice's defaults, which charge_netlist leaves alone


def drift_bound(periods: int) -> float:
    """Allowed difference (V) of the clamped model's and the fixed capacitors' output drifts over
    `periods`: each accepted time point leaves the summing node's current balanced to within
    abstol (the residual of Newton's converged iterate), a charge abstol h per step, so abstol T
    per run accumulates in each of the two runs; the model's charges are node voltages on linear
    capacitors (their trapezoidal currents telescope: no accumulated error, whatever chgtol, which
    sets only the step size through the truncation-error estimate), adding c_ref vntol at any
    instant, twice (both ends). As a voltage on Cf."""
    return (2 * ABSTOL * periods * TS + 2 * C_REST * VNTOL) / CF


def charge_netlist(sensor: str, periods: int, options: str = "") -> str:
    """A never-reset charge amplifier (the OTA of examples/sc_readout.inc, Cf, one reset at
    1 us) around `sensor`: "clamped" (the model with its mass held by a stiff critically damped
    spring on f_z), "free" (the model driven through a_in at -3000 m/s^2: up to the stop after
    ~30 us), "moving" (the model on a 1 N/m critically damped spring, a_in a +-50 m/s^2 square
    wave: z swings +-0.6 um, a third of the gap, for any run length) or "fixed" (two C(0) capacitors);
    the electrodes switch every 1 us between VCM +- 0.5 V, top and bottom opposite.
    The reset switch's body is at VCM, as a designer isolates the p-well of a switch on a
    never-reset integrating node: with the body at 0 its junction on the summing node sits at
    -0.9 V, and ngspice's gmin (1e-12 S, which BSIM4 puts across each junction) leaked 0.9 pA out
    of the node, 0.9 fC per ms (all of the fixed capacitors' drift; it scaled with gmin); at VCM it
    leaks only gmin times the OTA's offset (~1.4 mV: 1.4e-15 A).
    Shared by tests/testbench/test_sc_charge.py (short) and bench/sc_readout.py (4096 periods)."""
    lines = [
        "* never-reset charge amplifier",
        *(f'.include "{p}"' for p in (EXAMPLES / "generic_018.lib", EXAMPLES / "sc_readout.inc")),
        "Vdd vdd 0 1.8",
        "Vcm vcm 0 0.9",
        "Xota sum vcm out vdd sc_ota",
        f"Cf sum out {CF!r}",
        "Vphr phr 0 PWL(0 1.8 1u 1.8 1.003u 0)",
        "Mrst sum phr out vcm nch w=4u l=0.18u",  # body at VCM: no bias on the summing node's junction
        "Vtop top 0 PULSE(1.4 0.4 2u 3n 3n 997n 2u)",
        "Vbot bottom 0 PULSE(0.4 1.4 2u 3n 3n 997n 2u)",
    ]
    if sensor == "fixed":
        lines += [f"Ctop top sum {C_REST!r}", f"Cbot bottom sum {C_REST!r}", "Vxz x_z 0 0"]
    else:
        lines += [f'.include "{MODEL_LIB}"', "X1 top bottom sum f_z x_z a_in accelerometer_z"]
    if sensor == "clamped":  # f_z in uN, x_z in um: -K x - c v with K = 1e6 N/m, c = 2 sqrt(K m)
        lines += ["Cv x_z xv 1", "Vv xv 0 0", "Bclamp f_z 0 V=-1e6*v(x_z) - 0.2159*i(Vv)", "Vacc a_in 0 0"]
    elif sensor == "free":
        lines += ["Vacc a_in 0 -3000"]
    elif sensor == "moving":  # K = 1 N/m, c = 2 sqrt(K m); +-50 m/s^2 every 200 us: z ~ +-m a / K ~ +-0.6 um
        lines += [
            "Cv x_z xv 1",
            "Vv xv 0 0",
            "Bspring f_z 0 V=-1.0*v(x_z) - 2.16e-4*i(Vv)",
            "Vacc a_in 0 PULSE(-50 50 10u 3u 3u 197u 400u)",
        ]
    if options:
        lines.append(f".options {options}")
    lines += [".save v(out) v(sum) v(x_z) v(top) v(bottom)", f".tran 20n {periods * TS!r} 0 uic", *ONE_THREAD]
    return "\n".join([*lines, ".end", ""])


def quiet(plot, periods: int) -> dict[str, np.ndarray]:
    """Node voltages of a charge_netlist run 0.8 us after each electrode edge, from the third period on."""
    t = np.real(plot["time"])
    at = np.array([k * 1e-6 + 0.8e-6 for k in range(4, 2 * periods)])
    return {n: np.interp(at, t, np.real(plot[f"v({n})"])) for n in ("out", "sum", "x_z", "top", "bottom")}


def charge_error(
    model: MacroModel, v: dict[str, np.ndarray], fixed: dict[str, np.ndarray] | None = None
) -> tuple[float, float]:
    """Largest |Cf (V_out - V_sum) - Q_plate| change along a moving run (MacroModel.plate_charge at
    the simulated z), and the plate charge's swing, both in C. With `fixed` (the quiet samples of
    the fixed-capacitor run of the same length) its own Cf (V_out - V_sum) - Q_plate change, the
    circuit's leakage into the never-reset summing node, is subtracted first: what is left is the
    model's."""
    xs = (v["x_z"] * 1e-6 / model.coordinates[0].scale)[:, None]
    q_model = model.plate_charge(xs, np.stack([v["top"], v["bottom"]], axis=1), v["sum"])
    err = residual(CF * (v["out"] - v["sum"]), q_model)
    if fixed is not None:
        c = np.full((1, 2), C_REST)
        q_fixed = -np.sum(c * (np.stack([fixed["top"], fixed["bottom"]], axis=1) - fixed["sum"][:, None]), axis=1)
        err = err - residual(CF * (fixed["out"] - fixed["sum"]), q_fixed)
    return float(np.abs(err).max()), float(np.ptp(q_model))


def residual(q_cf: np.ndarray, q_plate: np.ndarray) -> np.ndarray:
    """The collected charge's change minus the plate charge's, from the first sample on."""
    return (q_cf - q_cf[0]) - (q_plate - q_plate[0])
