"""`netgen sweep` over a process parameter both ways: one [process] build with each run's point as
instance parameters ([sweep] process = "parameters") against a rebuild per run (process =
"rebuild", the reference), on one local worker; the wall time of each sweep, and the largest
difference of the runs' results between the two.

    OMP_NUM_THREADS=1 .venv/bin/python bench/process_sweep.py [--structure examples/levitated_disk.toml]
        [--values 0.9,0.95,1.05,1.1] [--cycles 128] [--reltol 1e-3] [--full]

Default: the levitated disk's rigid-body model (rigid_only, as examples/sweep_ts.toml sweeps it) with
[process] parameters = ["tscale"] appended; --full keeps its four plate modes.
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path

import numpy as np
import support

from netgen.cli import commands as cli

SWEEP = """
[sweep]
figure = "gravity_balance.ratio"
x = "process.tscale"
process = "{path}"
[fixed]
cycles = {cycles}
skip = 0
reltol = {reltol}
{rigid}
[[parameters]]
name = "process.tscale"
values = [{values}]
"""


def run(structure: Path, tmp: Path, path: str, args) -> tuple[float, list[dict]]:
    """One sweep (a fresh output folder): its wall time and results.csv rows."""
    sweep = tmp / f"{path}.toml"
    rigid = "" if args.full else "rigid_only = true"
    sweep.write_text(SWEEP.format(path=path, cycles=args.cycles, values=args.values, reltol=args.reltol, rigid=rigid))
    out = tmp / path
    start = time.perf_counter()
    rc = cli.main(["sweep", str(structure), str(sweep), "-o", str(out), "--scheduler", "local:1", "-q"])
    wall = time.perf_counter() - start
    if rc != 0:
        raise SystemExit(f"sweep {path} exited {rc}")
    with open(out / "results.csv", newline="") as fh:
        return wall, list(csv.DictReader(fh))


def first_flip(run_p: str, run_r: str) -> str:
    """Where the two runs' bitstreams first differ (or that they do not), per channel."""
    a, b = np.load(Path(run_p) / "bitstreams.npz"), np.load(Path(run_r) / "bitstreams.npz")
    out = []
    for k in sorted(k for k in a.files if k.startswith("bits_")):
        d = np.nonzero(a[k] != b[k])[0]
        out.append(f"{k[5:]} " + ("same bits" if d.size == 0 else f"first differs at period {d[0]}"))
    return ", ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--structure", default=str(support.ROOT / "examples/levitated_disk.toml"))
    ap.add_argument("--values", default="0.9,0.95,1.05,1.1", help="process.tscale values")
    ap.add_argument("--cycles", type=int, default=128)
    ap.add_argument("--reltol", type=float, default=1e-3, help="ngspice's reltol in both sweeps")
    ap.add_argument("--full", action="store_true", help="keep the modes (default: rigid_only)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        structure = tmp / "structure.toml"
        structure.write_text(Path(args.structure).read_text() + '\n[process]\nparameters = ["tscale"]\n')
        (wall_p, rows_p), (wall_r, rows_r) = (run(structure, tmp, p, args) for p in ("parameters", "rebuild"))
        print(
            f"{len(rows_p)} runs of {args.cycles} periods at reltol {args.reltol:g}: parameters {wall_p:.1f} s, "
            f"rebuild {wall_r:.1f} s ({wall_r / wall_p:.2f}x)"
        )
        for p, r in zip(rows_p, rows_r):
            cols = [k for k in p if k.endswith(("bit_mean", "gravity_balance.ratio")) and p[k] and r[k]]
            diffs = ", ".join(f"{k} {float(p[k]) - float(r[k]):+.1e}" for k in cols)
            flips = first_flip(p["dir"], r["dir"])
            print(f"  tscale={p['process.tscale']}: {p['status']}/{r['status']}: {diffs}; {flips}")


if __name__ == "__main__":
    main()
