"""`netgen sweep` over a process parameter both ways: one [process] build with each run's point as
instance parameters ([sweep] process = "parameters") against a rebuild per run (process =
"rebuild", the reference), both in this process (--scheduler serial, so that the CPU time of this
process and its reaped children counts every build and simulator run); the wall and CPU time of
each sweep, and the largest difference of the runs' results between the two.

    OMP_NUM_THREADS=1 .venv/bin/python bench/process_sweep.py [--parameter tscale] [--values 0.9,0.95,1.05,1.1]
        [--structure examples/levitated_disk.toml | --crab-legs] [--simulator ngspice] [--cycles 128]
        [--reltol 1e-3] [--full]

--parameter: tscale, escale, temp (degC), etch (m) or dg_<set> (m); [process] parameters = [it] (dg
for dg_<set>) is appended to the structure. Default structure: the levitated disk's rigid-body
model (rigid_only, as examples/sweep_ts.toml sweeps it); --full keeps its four plate modes.
--crab-legs: examples/accelerometer_z.toml on crab legs (the structure of
tests/sweep/test_sweep_process.py; etch needs flexure beams).
"""

from __future__ import annotations

import argparse
import csv
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import support

from netgen.cli import commands as cli

SWEEP = """
[sweep]
figure = "gravity_balance.ratio"
x = "process.{name}"
process = "{path}"
[fixed]
cycles = {cycles}
skip = 0
reltol = {reltol}
simulator = "{simulator}"
{rigid}
[[parameters]]
name = "process.{name}"
values = [{values}]
"""
# the crab legs of tests/sweep/test_sweep_process.py
CRAB_LEGS = support.crab_legs.crab_legs(500.0, 20.0, 800.0)


def cpu_s() -> float:
    """User + system CPU seconds of this process and its reaped children."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def run(structure: Path, tmp: Path, path: str, args) -> tuple[float, float, list[dict]]:
    """One sweep (a fresh output folder): its wall and CPU time and results.csv rows."""
    sweep = tmp / f"{path}.toml"
    rigid = "rigid_only = true" if args.rigid else ""
    text = SWEEP.format(
        name=args.parameter,
        path=path,
        cycles=args.cycles,
        values=args.values,
        reltol=args.reltol,
        simulator=args.simulator,
        rigid=rigid,
    )
    sweep.write_text(text)
    out = tmp / path
    start, cpu = time.perf_counter(), cpu_s()
    rc = cli.main(["sweep", str(structure), str(sweep), "-o", str(out), "--scheduler", "serial", "-q"])
    wall, cpu = time.perf_counter() - start, cpu_s() - cpu
    if rc != 0:
        raise SystemExit(f"sweep {path} exited {rc}")
    with open(out / "results.csv", newline="") as fh:
        return wall, cpu, list(csv.DictReader(fh))


def first_flip(run_p: str, run_r: str) -> str:
    """Where the two runs' bitstreams first differ (or that they do not), per channel, and the largest
    displacement difference before it."""
    a, b = np.load(Path(run_p) / "bitstreams.npz"), np.load(Path(run_r) / "bitstreams.npz")
    out = []
    for k in sorted(k for k in a.files if k.startswith("bits_")):
        d = np.nonzero(a[k] != b[k])[0]
        n = int(d[0]) + 1 if d.size else len(a[k])
        x = f"x_{k[5:]}"
        dx = float(np.max(np.abs(a[x][:n] - b[x][:n]))) if x in a.files else float("nan")
        out.append(
            f"{k[5:]} " + ("same bits" if d.size == 0 else f"first differs at period {d[0]}") + f", x {dx:.1e} V"
        )
    return ", ".join(out)


def structure_text(args) -> str:
    """The structure with [process] declaring the parameter (dg for dg_<set>)."""
    text = Path(args.structure).read_text()
    if args.crab_legs:
        a, b = text.index("[conductor]"), text.index("[[electrodes]]")
        text = text[:a] + CRAB_LEGS + text[b:]
    declared = "dg" if args.parameter.startswith("dg_") else args.parameter
    return text + f'\n[process]\nparameters = ["{declared}"]\n'


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--structure", default=None, help="default: the levitated disk (--crab-legs: the accelerometer)")
    ap.add_argument("--crab-legs", action="store_true", help="examples/accelerometer_z.toml on crab legs")
    ap.add_argument("--parameter", default="tscale", help="tscale, escale, temp, etch or dg_<set>")
    ap.add_argument("--values", default="0.9,0.95,1.05,1.1", help="the parameter's values")
    ap.add_argument("--simulator", default="ngspice", help="the sweep's back end (ngspice, ngspice-xspice, ...)")
    ap.add_argument("--cycles", type=int, default=128)
    ap.add_argument("--reltol", type=float, default=1e-3, help="the simulator's reltol in both sweeps")
    ap.add_argument("--full", action="store_true", help="keep the disk's modes (default: rigid_only)")
    args = ap.parse_args()
    default = "examples/accelerometer_z.toml" if args.crab_legs else "examples/levitated_disk.toml"
    args.structure = args.structure or str(support.ROOT / default)
    args.rigid = not args.full and not args.crab_legs
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        structure = tmp / "structure.toml"
        structure.write_text(structure_text(args))
        (wall_p, cpu_p, rows_p), (wall_r, cpu_r, rows_r) = (
            run(structure, tmp, p, args) for p in ("parameters", "rebuild")
        )
        print(
            f"{args.parameter} on {Path(args.structure).name}{' (crab legs)' if args.crab_legs else ''}, "
            f"{args.simulator}: {len(rows_p)} runs of {args.cycles} periods at reltol {args.reltol:g}: "
            f"parameters {wall_p:.1f} s wall / {cpu_p:.1f} s CPU, rebuild {wall_r:.1f} s / {cpu_r:.1f} s "
            f"({wall_r / wall_p:.2f}x wall, {cpu_r / cpu_p:.2f}x CPU)"
        )
        for p, r in zip(rows_p, rows_r):
            cols = [k for k in p if k.endswith(("bit_mean", "gravity_balance.ratio")) and p[k] and r[k]]
            diffs = ", ".join(f"{k} {float(p[k]) - float(r[k]):+.1e}" for k in cols)
            flips = first_flip(p["dir"], r["dir"])
            print(f"  {args.parameter}={p[f'process.{args.parameter}']}: {p['status']}/{r['status']}: {diffs}; {flips}")


if __name__ == "__main__":
    main()
