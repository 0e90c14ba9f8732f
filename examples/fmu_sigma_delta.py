"""The z accelerometer's second-order sigma-delta loop with the proof mass in the model's FMU:

    .venv/bin/python examples/fmu_sigma_delta.py [--cycles 65536] [--loop LOOP.toml]
        [--compare DIR] [-o OUT.npz]

The loop's design is `netgen sigma-delta`'s (examples/accelerometer_z.toml's [loop], or --loop),
for the committed model netlists/accelerometer_z/accelerometer_z.json; the discrete-time part
(charge amplifier sample, lead filter, dithered 1-bit quantizer, feedback selection) runs in numpy
and the mechanics in the FMU's co-simulation between the clock edges
(netgen.testbench.sigma_delta.fmu). It prints the bit mean, the in-band floor (OSR 64, the first
eighth of the periods left out, as `netgen sigma-delta` does) and the wall time. --compare DIR
reads a `netgen sigma-delta ... --simulator ngspice-xspice` run's bitstreams.npz and summary.json
and prints the first period whose bit differs and the two floors. Needs fmpy and a C compiler.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import fmu, runner
from netgen.testbench.sigma_delta.analysis import analyse
from netgen.testbench.sigma_delta.loop import Choices

ROOT = Path(__file__).resolve().parents[1]
STRUCTURE = ROOT / "examples" / "accelerometer_z.toml"
MODEL = ROOT / "netlists" / "accelerometer_z" / "accelerometer_z.json"
TS = 1e-6  # netgen sigma-delta's default T_s


def design(loop_file: str | None = None):
    """The model and the design `netgen sigma-delta --simulator ngspice-xspice` makes of it."""
    model = MacroModel.load_json(MODEL)
    loop = sd.read_loop_file(loop_file) if loop_file else sd.read_structure_loop(STRUCTURE)
    return model, runner.backend_design(model, TS, loop, None, "ngspice-xspice", Choices())


def simulate(cycles: int, loop_file: str | None = None) -> tuple[dict, dict, float]:
    """The FMU loop's per-period arrays, its analysis and the wall time of the loop."""
    model, d = design(loop_file)
    start = time.perf_counter()
    clock = fmu.run(model, d, cycles)
    wall = time.perf_counter() - start
    return clock, analyse(clock, d, skip=cycles // 8), wall


def first_difference(a: np.ndarray, b: np.ndarray) -> int:
    """The first period whose bits differ (the common length if none)."""
    n = min(len(a), len(b))
    diff = np.nonzero(a[:n] != b[:n])[0]
    return int(diff[0]) if len(diff) else n


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=65536)
    p.add_argument("--loop", help="loop description (default: the structure's [loop])")
    p.add_argument("--compare", help="a `netgen sigma-delta` output folder to compare with")
    p.add_argument("-o", "--output", help="write the per-period arrays here (.npz)")
    args = p.parse_args(argv)
    clock, summary, wall = simulate(args.cycles, args.loop)
    z = summary["channels"]["z"]
    print(
        f"FMU loop: {args.cycles} periods in {wall:.1f} s, bit mean {z['bit_mean']:+.5f}, "
        f"in-band floor {z['noise_floor_db_per_hz']:.2f} dB/Hz"
    )
    if args.output:
        np.savez_compressed(args.output, **clock)
    if args.compare:
        ref = np.load(Path(args.compare) / "bitstreams.npz")
        ref_z = json.loads((Path(args.compare) / "summary.json").read_text())["channels"]["z"]
        n = first_difference(clock["bits_z"], ref["bits_z"])
        print(
            f"reference {args.compare}: first differing bit at period {n}, bit mean {ref_z['bit_mean']:+.5f}, "
            f"in-band floor {ref_z['noise_floor_db_per_hz']:.2f} dB/Hz "
            f"(difference {z['noise_floor_db_per_hz'] - ref_z['noise_floor_db_per_hz']:+.2f} dB)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
