"""Where VACASK's gyroscope drive loses amplitude: the model (netlists/gyroscope_z/gyroscope_z.va)
and the drive block (netgen/testbench/gyro/drive.va) alone in VACASK, the block at G = 1e-9 (pure
velocity feedback, which cancels b_x: the amplitude then decays at Delta b_x / (2 m), Delta the
simulator's own loss), electrodes and inputs at 0 V, 2 ms. Once without other sources, once with
the sigma-delta bench's two electrode-phase pulse sources on nodes nothing else touches (their
corners become breakpoints, where VACASK restarts its integration; nothing else changes), and once
more with those at tran_fbr 0.05. Delta from a line through the amplitudes of eight windowed
sinusoid fits (docs/gyroscope.md, "Why the open-loop drive ended 0.43 % under X_d").

    .venv/bin/python bench/gyroscope_vacask_loss.py     (about 1 min)
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.model import MacroModel
from netgen.sim.vacask import run_vacask
from netgen.testbench.gyro import analysis
from netgen.testbench.gyro.run import GyroRequest, drive_osdi, drive_parameters
from netgen.testbench.sigma_delta.vacask import OPTIONS, compile_model, merge_options

FOLDER = ROOT / "netlists" / "gyroscope_z"
PULSES = """vphs (phs 0) vsource type="pulse" val0=0 val1=1 delay=0.0 rise=2e-08 fall=2e-08 width=4.3e-07 period=1e-06
vphf (phf 0) vsource type="pulse" val0=0 val1=1 delay=4.9e-07 rise=2e-08 fall=2e-08 width=4.2e-07 period=1e-06
"""
STOP, SKIP = 2e-3, 2.5e-4  # s: the run, and its start left out (the start-up pulse)


def netlist(model: MacroModel, cache: Path, pulses: bool, extra: str) -> str:
    """The model, its electrodes and inputs on 0 V sources, the drive block on f_x at G = 1e-9."""
    mems, block = compile_model(model, cache, FOLDER / "gyroscope_z.va"), drive_osdi(cache)
    params = drive_parameters(model, GyroRequest().drive_amplitude, 1e-9)
    held = [e.name for e in model.electrodes] + ["f_y", "a_x", "a_y", "w_z"]
    sources = "\n".join(f"v{n} ({n} 0) vsource dc=0" for n in held)
    ports = " ".join(p["name"] if p["name"] != model.plate else "0" for p in model.ports())
    return f"""gyroscope drive block alone
load "{mems}"
load "{block}"
model mems {model.name}
model vsource vsource
model gdrive gyro_drive
x1 ({ports}) mems
{sources}
xdrive (f_x 0 x_x) gdrive {params}
{PULSES if pulses else ""}
control
  options {merge_options(OPTIONS.format(reltol=1e-3), extra)}
  save v(x_x)
  analysis tran1 tran step=2e-08 stop={STOP} maxstep=5e-08 icmode="uic"
endc
"""


def loss(t: np.ndarray, x: np.ndarray, gamma: float) -> tuple[float, float]:
    """Delta and the mean amplitude over X_d - 1, from eight windows after SKIP."""
    tt = np.linspace(SKIP, STOP, 8000)
    xx = np.interp(tt, t, x)
    edges = np.linspace(0, len(tt), 9).astype(int)
    mid = [float(tt[a:b].mean()) for a, b in zip(edges[:-1], edges[1:])]
    amp = [analysis.sinusoid(tt[a:b], xx[a:b])["amplitude"] for a, b in zip(edges[:-1], edges[1:])]
    return -np.polyfit(mid, amp, 1)[0] / float(np.mean(amp)) / gamma, float(np.mean(amp))


def main() -> None:
    model = MacroModel.load_json(FOLDER / "gyroscope_z.json")
    cx = next(c for c in model.coordinates if c.name == "x")
    gamma = cx.damping / (2 * cx.mass)
    x_d = GyroRequest().drive_amplitude
    with tempfile.TemporaryDirectory(prefix="gyro-loss-") as tmp:
        for pulses, extra in [(False, ""), (True, ""), (True, "tran_fbr=0.05")]:
            run = Path(tmp) / f"run{int(pulses)}{len(extra)}"
            text = netlist(model, Path(tmp) / "osdi", pulses, extra)
            plot = run_vacask(text, run, "tran1", "loss", 1200)
            t, x = np.asarray(plot["time"]), np.asarray(plot["v(x_x)"]) * cx.port_units[1]
            delta, amp = loss(t, x, gamma)
            label = ("with the bench's pulse corners" if pulses else "no pulse sources") + (
                f", {extra}" if extra else ""
            )
            print(
                f"{label:45s} points {len(t):7d}  Delta {delta * 100:.3f} % of b_x  "
                f"mean amplitude / X_d - 1 {amp / x_d - 1:+.2e}  (w_x {math.sqrt(cx.stiffness / cx.mass):.6g} rad/s)"
            )


if __name__ == "__main__":
    main()
