"""The levitated disk's committed macromodel (netlists/levitated_disk.lib) in a PySpice Circuit, run
through ngspice's shared library in this process; results as numpy arrays in metres, radians,
amperes (docs/pyspice.md).

    .venv/bin/python examples/pyspice_transient.py [--save run.npz]

The ngspice is the one netgen selects (NETGEN_NGSPICE, default the one on PATH): its libngspice
is found beside it, or named by NETGEN_LIBNGSPICE. PySpice loads one libngspice per process.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from netgen.sim.pyspice import ModelCircuit, load_model

LIB = Path(__file__).resolve().parents[1] / "netlists" / "levitated_disk.lib"
STOP, STEP = 20e-6, 10e-9


def drive(mass: float) -> dict[str, float | str]:
    """1 MHz pulses on two electrodes, a step at 5 us on a third, gravity on z (SI numbers, or
    source specifications in port volts)."""
    return {
        "top_r2s1": "PULSE(0 3 0 10n 10n 0.49u 1u)",
        "top_r1s2": "PULSE(0 2 0.25u 10n 10n 0.3u 1u)",
        "bot_r1s3": "PULSE(0 2 5u 10n 10n 1 2)",
        "f_z": -mass * 9.81,
    }  # N


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--save", metavar="NPZ", help="write time, coordinates (m, rad) and currents (A) to NPZ")
    args = ap.parse_args()

    model = load_model(LIB)
    bench = ModelCircuit.build(
        model,
        LIB,
        drive=drive(model.coordinates[0].mass),
        nodes={"x_z": "z_out", "x_tilt_x": "tilt_x_out", "top_r2s1": "drive_a"},
    )
    run = bench.transient(STEP, STOP, max_step=STEP, options={"reltol": 1e-5})
    print(f"{run.release} through PySpice: transient to {run.axis[-1] * 1e6:.0f} us")
    for c in model.coordinates[:3]:
        q = run.q[c.name]
        scale = 1e9 if c.unit == "m" else 1e6
        unit = "nm" if c.unit == "m" else "urad"
        print(
            f"{c.name:7s} peak |q| {np.abs(q).max() * scale:9.3f} {unit}   at {STOP * 1e6:.0f} us "
            f"{q[-1] * scale:9.3f} {unit}"
        )
    print(f"top_r2s1 peak current {np.abs(run.current['top_r2s1']).max() * 1e6:.3f} uA")
    if args.save:
        np.savez(
            args.save,
            time=run.axis,
            **{f"q_{k}": v for k, v in run.q.items()},
            **{f"v_{k}": v for k, v in run.velocity.items()},
            **{f"i_{k}": v for k, v in run.current.items()},
        )


if __name__ == "__main__":
    main()
