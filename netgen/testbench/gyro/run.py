"""A gyroscope run: the sense loop's design (the sigma-delta testbench's loop.design, on the
channel y of the loop description), the drive loop on the model's f_x port, the rate on w_z, the
sigma-delta testbench's bench around both: in ngspice (its run_segments) the drive loop is a
behavioural source (drive_expression); in VACASK and in ngspice through OSDI it is the Verilog-A
block drive.va beside this module (drive_device), with the same loop law, gain and set amplitude;
the demodulation (analysis.py), and a rate sweep's linearity; summary.json and PNGs in the folder."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...core.errors import LoopError
from ...core.paths import spice_command
from ...emit.common import time_scale
from ...emit.osdi import GENERIC, compiled
from ...model import MacroModel
from ..sigma_delta import ngspice, osdi, vacask
from ..sigma_delta.analysis import per_clock
from ..sigma_delta.loop import Choices, Design
from ..sigma_delta.loopfile import LoopSpec
from ..sigma_delta.runner import backend_design
from . import analysis, plots

DRIVE, SENSE, RATE_PORT = "x", "y", "w_z"
SKIP = 8  # the first 1/SKIP of the periods (the sense loop's start) is left out of the demodulation
# the Verilog-A drive loop (drive_device) and its start-up pulse's length, 1/KICK of a drive period
DRIVE_VA = Path(__file__).resolve().parent / "drive.va"
KICK = 20


@dataclass(frozen=True)
class GyroRequest:
    """One run's settings (netgen.testbench.gyro.options declares them)."""

    ts: float = 1e-6
    cycles: int = 4096
    rate_deg_s: float = 0.0
    rate_points: int = 0
    rate_span: float = 0.5
    drive_amplitude: float = 4e-6
    agc_gain: float = 100.0
    simulator: str = "ngspice-xspice"
    progress: bool = True
    plots: bool = True


def coordinate(model: MacroModel, name: str):
    return next(c for c in model.coordinates if c.name == name)


def check_model(model: MacroModel, spec: LoopSpec) -> None:
    """The gyroscope needs the coordinates x (drive) and y (sense) and the rate port w_z; the loop
    closes on y alone (LoopError, exit 2, naming the key and the fix)."""
    names = [c.name for c in model.coordinates]
    if DRIVE not in names or SENSE not in names:
        raise LoopError(
            spec.source,
            "coordinates.rigid",
            f"the gyroscope drives x and senses y; the model's coordinates are {names}",
            'list rigid = ["x", "y"] in the structure',
        )
    if RATE_PORT not in [p["name"] for p in model.ports()]:
        raise LoopError(
            spec.source,
            "coordinates.inertial",
            "the model has no rate port w_z",
            'add "w_z" to [coordinates] inertial in the structure',
        )
    if spec.channels is None or [c.name for c in spec.channels] != [SENSE]:
        raise LoopError(
            spec.source,
            "loop.channels",
            "the gyroscope closes the sense loop on y alone",
            "give one channel, [loop.channels.y], with the sense electrodes' sense and feedback weights",
        )


def sense_design(model: MacroModel, spec: LoopSpec, req: GyroRequest) -> Design:
    """The sigma-delta design of the sense loop (loop.design through the sigma-delta back end's checks)."""
    check_model(model, spec)
    d = backend_design(model, req.ts, spec, None, req.simulator, Choices())
    check_request(model, spec, req, d)
    return d


def check_request(model: MacroModel, spec: LoopSpec, req: GyroRequest, d: Design) -> None:
    """The drive amplitude inside the model's sampled travel of x (beyond it the fits extrapolate)
    and the rate inside the full scale F_fb / (2 m X_d w_d) (beyond it the bits saturate): else
    LoopError (exit 2) naming the option and the fix."""
    c = coordinate(model, DRIVE)
    travel = float(model.sampling.get("range", 1.0)) * c.scale
    if req.drive_amplitude > travel:
        raise LoopError(
            spec.source,
            "--drive-amplitude",
            f"the drive amplitude {req.drive_amplitude * 1e6:.4g} um is beyond the model's sampled travel of x, "
            f"+-{travel * 1e6:.4g} um ([sampling] range {model.sampling.get('range')} of {c.scale * 1e6:.4g} um): "
            "the fits would extrapolate",
            f"give --drive-amplitude at most {travel * 1e6:.4g} um, or widen [sampling] range in the structure",
        )
    full_scale = d.channels[0]["full_scale_force_si"] / (
        2 * c.mass * req.drive_amplitude * math.sqrt(c.stiffness / c.mass)
    )
    if not req.rate_points and abs(req.rate_deg_s * analysis.DEG) > full_scale:
        raise LoopError(
            spec.source,
            "--rate",
            f"the rate {req.rate_deg_s:.6g} deg/s is beyond the full scale {full_scale / analysis.DEG:.6g} deg/s "
            f"at the {req.drive_amplitude * 1e6:.4g} um drive: the sense bits would saturate",
            f"give |--rate| below {full_scale / analysis.DEG:.6g} deg/s, or a smaller --drive-amplitude",
        )


def drive_expression(model: MacroModel, amplitude: float, gain: float) -> str:
    """The drive loop as a B-source on f_x (port units): the velocity pick-off times the drive's own
    damping b_x (so the loop cancels it: self-oscillation at the resonance), scaled by the amplitude
    control 1 + G (1 - A / X_d), A = sqrt(x^2 + (x' / w_x)^2) (the amplitude of a sinusoid, ripple-free);
    the factor is at most 1 + G. Read from the model's nodes: x from the port x_x, x' from the
    velocity node u_x (x' = u ws scale)."""
    c = coordinate(model, DRIVE)
    w = math.sqrt(c.stiffness / c.mass)
    length = c.port_units[1]  # m per port volt of x_x
    force = c.port_units[3]  # N per port volt of f_x
    vel = f"(v(x1.u_{DRIVE})*{time_scale(model) * c.scale!r})"
    pos = f"(v(x_{DRIVE})*{length!r})"
    amp = f"sqrt({pos}*{pos}+{vel}*{vel}*{1 / w**2!r})"
    return f"{c.damping / force!r}*{vel}*(1+{gain!r}*(1-{amp}/{amplitude!r}))"


def start_state(model: MacroModel, amplitude: float) -> tuple[tuple[str, float], ...]:
    """x at the set amplitude, at rest: the drive starts at its turning point."""
    c = coordinate(model, DRIVE)
    return ((f"x1.xs_{DRIVE}", amplitude / c.scale), (f"x1.u_{DRIVE}", 0.0))


def drive_parameters(model: MacroModel, amplitude: float, gain: float) -> str:
    """drive.va's instance parameters: the loop law of drive_expression (the damping b_x, the
    resonance w_x, the set amplitude X_d and the gain G, in SI; lx, fu the x_x and f_x port units)
    and the start-up pulse: length tk = T / KICK of the drive period T, impulse p such that the
    undamped oscillator (the pulse's velocity pick-off cancels b_x) leaves it from rest at amplitude
    X_d: p |S| = m X_d w with S = int_0^tk (1 - cos(Omega t)) e^(-i w t) dt / tk, Omega = 2 pi / tk,
    |S| = (2 sin(w tk / 2) / (w tk)) Omega^2 / (Omega^2 - w^2) (1 - 1.6e-3 at KICK = 20)."""
    c = coordinate(model, DRIVE)
    w = math.sqrt(c.stiffness / c.mass)
    tk = 2 * math.pi / w / KICK
    big = 2 * math.pi / tk
    s = 2 * math.sin(w * tk / 2) / (w * tk) * big**2 / (big**2 - w**2)
    p = c.mass * amplitude * w / s
    return (
        f"lx={c.port_units[1]!r} fu={c.port_units[3]!r} b={c.damping!r} w={w!r} xd={amplitude!r} g={gain!r} "
        f"p={p!r} tk={tk!r}"
    )


def drive_osdi(cache: Path, cpu: str = GENERIC) -> Path:
    """drive.va compiled by openvaf-r (cached by text and target cpu)."""
    return compiled(DRIVE_VA.read_text(encoding="utf-8"), "gyro_drive", cache, cpu)


def drive_device(model: MacroModel, req: GyroRequest, cache: Path) -> vacask.Device:
    """The drive loop in VACASK: drive.va between f_x and ground, reading x_x (VACASK has no
    behavioural sources, and the OSDI model's velocity node is internal: the block takes x' as
    d/dt of x_x). Its states start at 0 (no .ic reaches them), hence the start-up pulse."""
    params = drive_parameters(model, req.drive_amplitude, req.agc_gain)
    return vacask.Device(
        drive_osdi(cache), "gdrive", "gyro_drive", "xdrive", f"(f_{DRIVE} 0 x_{DRIVE}) gdrive {params}", (f"f_{DRIVE}",)
    )


def run_vacask(model: MacroModel, lib: Path, out: Path, d: Design, req: GyroRequest) -> dict:
    """The sense loop in VACASK (the sigma-delta testbench's bench, one run) with the drive loop
    of drive.va on f_x: the per-period samples; the raw file is dropped after the sampling."""
    va = Path(lib).with_suffix(".va")
    how = vacask.BenchOptions(va=va if va.exists() else None, devices=(drive_device(model, req, out / "osdi"),))
    plot = vacask.run_bench(model, d, out, req.cycles, None, req.progress, how)
    clock = per_clock(plot, d, req.cycles, model)
    del plot
    (out / "tran1.raw").unlink(missing_ok=True)
    return clock


def run_osdi(model: MacroModel, lib: Path, out: Path, d: Design, req: GyroRequest) -> dict:
    """The sense loop in ngspice through OSDI (the sigma-delta testbench's osdi bench: the model's
    compiled module and blocks.va) with drive.va on f_x, as in VACASK; one ngspice run (.ic cannot
    reach the OSDI states, netgen.testbench.sigma_delta.osdi): the per-period samples."""
    state = osdi.prepare(model, lib, out, req.progress)
    block = drive_osdi(out / "osdi")
    params = drive_parameters(model, req.drive_amplitude, req.agc_gain)
    lines = f"Ndrive f_{DRIVE} 0 x_{DRIVE} gdrive {params}\n.model gdrive gyro_drive"
    settings = ngspice.Settings(
        "osdi",
        [f"pre_osdi {spice_command(block, out)}", *state["control"]],
        devices=((f"f_{DRIVE}", lines),),
        segment=0,
    )
    clock, _, _ = ngspice.run_segments(model, d, state["lib"], out, req.cycles, None, req.progress, settings)
    return clock


RUNS = {"vacask": run_vacask, "ngspice-osdi": run_osdi}


def run_rate(model: MacroModel, lib: Path, out: Path, d: Design, req: GyroRequest, rate: float) -> dict:
    """One rate (rad/s): the bench, its per-period samples, the demodulated figures."""
    d = replace(d, inputs=d.inputs | {RATE_PORT: float(rate)})
    clock = RUNS.get(req.simulator, run_ngspice)(model, lib, out, d, req)
    keep = slice(len(clock["time"]) // SKIP, None)
    cx = coordinate(model, DRIVE)
    fs = d.channels[0]["full_scale_force_si"]
    demod = analysis.demodulate(
        clock["time"][keep], clock[f"bits_{SENSE}"][keep], clock[f"x_{DRIVE}"][keep] * cx.port_units[1], cx.mass, fs
    )
    demod |= analysis.rate_noise(
        clock["time"][keep],
        clock[f"bits_{SENSE}"][keep],
        d.ts,
        2 * math.pi * demod["drive_hz"],
        demod["design_scale_factor_per_rad_s"],
    )
    return demod | {"rate_applied_rad_s": rate, "clock": clock}


def run_ngspice(model: MacroModel, lib: Path, out: Path, d: Design, req: GyroRequest) -> dict:
    """The sense loop in ngspice (the sigma-delta testbench's bench) with the behavioural drive loop
    on f_x, one run: the per-period samples."""
    control: list[str] = []
    loop = "analog"
    if req.simulator == "ngspice-xspice":
        lib, control = ngspice.xspice_library(model, out, ngspice.code_models(req.progress))
        loop = "xspice"
    settings = ngspice.Settings(
        loop,
        control,
        behavioural=(("f_x", drive_expression(model, req.drive_amplitude, req.agc_gain)),),
        start_state=start_state(model, req.drive_amplitude),
        segment=0,  # one ngspice run: run_segments stops after a segment whose coordinates leave the
        # levitation bound (analysis.levitation), which the drive's x amplitude does by design
    )
    clock, _, _ = ngspice.run_segments(model, d, lib, out, req.cycles, None, req.progress, settings)
    return clock


def run(model: MacroModel, lib: Path, out: Path, spec: LoopSpec, req: GyroRequest) -> dict:
    """The run (or the sweep) at the request's rates; summary.json and the PNGs in `out`."""
    d = sense_design(model, spec, req)
    out.mkdir(parents=True, exist_ok=True)
    cx = coordinate(model, DRIVE)
    per_rate = (
        2 * cx.mass * req.drive_amplitude * math.sqrt(cx.stiffness / cx.mass) / d.channels[0]["full_scale_force_si"]
    )
    full_scale = 1.0 / per_rate  # rad/s at which the Coriolis force alone needs every bit
    if req.rate_points:
        rates = [float(r) for r in np.linspace(-req.rate_span, req.rate_span, req.rate_points) * full_scale]
    else:
        rates = [req.rate_deg_s * analysis.DEG]
    runs = [run_rate(model, lib, out, d, req, r) for r in rates]
    first = runs[len(runs) // 2]
    summary: dict = {
        "model": model.name,
        "simulator": req.simulator,
        "ts": req.ts,
        "cycles": req.cycles,
        "full_scale_rate_deg_s": full_scale / analysis.DEG,
        "feedback_force_n": d.channels[0]["full_scale_force_si"],
        "feedback_voltage": d.vfb,
        "loop_filter": d.channels[0]["filter"],
        "drive_loop": {
            "amplitude_m": req.drive_amplitude,
            "agc_gain": req.agc_gain,
            "force": "b_x x' (1 + G (1 - A / X_d)), A = sqrt(x^2 + (x' / w_x)^2), on f_x",
            "block": "drive.va (from rest, a start-up pulse of momentum m X_d w_x)"
            if req.simulator in RUNS
            else "B-source (from x = X_d at rest)",
        },
        "design_scale_factor_per_rad_s": per_rate,
        "runs": [{k: v for k, v in r.items() if k != "clock"} for r in runs],
    }
    if len(runs) > 1:
        fit = analysis.sweep_fit(rates, [r["rate_rad_s"] for r in runs])
        summary["sweep"] = fit | {
            "scale_factor_over_design": fit["slope"],
            "rates_rad_s": rates,
        }
    np.savez_compressed(
        out / "bitstreams.npz", **{f"{k}_{i}": v for i, r in enumerate(runs) for k, v in r["clock"].items()}
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if req.plots:
        plots.spectrum(first["clock"][f"bits_{SENSE}"], req.ts, first["drive_hz"], out / "spectrum.png", model.name)
        if len(runs) > 1:
            plots.sweep(rates, [r["rate_rad_s"] for r in runs], out / "rate_sweep.png", model.name)
    return summary
