"""Do two models of one structure (e.g. the grid design's and an adaptive or sparse design's) give
the same sigma-delta in-band floors? The disk's default loop sits at a mean z bit of 0.5 (gravity
at density 0.5), where the floor moves by several dB for a change of the DC input far below the
fit tolerance. So each model runs at the DC input scaled by (1 + eps) for each eps of --eps (the
feedback voltage held at the first model's), and the floors are compared as a mean and spread
over those inputs, not from one run each:

    .venv/bin/python bench/sigma_delta_designs.py examples/levitated_disk.toml \\
        netlists/levitated_disk.json out/adaptive/levitated_disk.json -o out/sd_designs \\
        [--eps=-1e-3,0,1e-3] [--cycles 8192] [--simulator ngspice-xspice]

Prints per model and channel the floor at each eps, their mean, median and range, and the
difference of each model's mean and median from the first model's (the median is robust to the
one input at which a loop locks to the mean bit 1/2 and its z floor drops 5-10 dB); writes
sigma_delta_designs.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.model import MacroModel
from netgen.testbench.sigma_delta.loop import design

CHANNELS = ("z", "tilt_x", "tilt_y")


def loop_file(folder: Path, force_uN: float, vfb: float) -> Path:
    """A [loop] description with the feedback voltage fixed and a DC force on z (uN)."""
    p = folder / f"loop_{force_uN:.9f}.toml"
    p.write_text(
        f'[loop]\nfeedback_voltage = "{vfb} V"\n[loop.input]\nforce = {{ coordinate = "z", dc = {force_uN:.9f} }}\n'
    )
    return p


def run(structure: Path, model: Path, loop: Path, out: Path, args) -> dict:
    """One `netgen sigma-delta` run; its summary's floor and bit mean per channel."""
    cmd = [
        str(ROOT / ".venv/bin/netgen"),
        "sigma-delta",
        str(structure),
        "--model",
        str(model),
        "--loop",
        str(loop),
        "--simulator",
        args.simulator,
        "--cycles",
        str(args.cycles),
        "--no-plots",
        "-q",
        "-o",
        str(out),
    ]
    subprocess.run(cmd, check=True)
    s = json.loads((out / "summary.json").read_text())
    floor = {ch: s["channels"][ch]["noise_floor_db_per_hz"] for ch in CHANNELS}  # None: run too short
    return {
        ch: {"floor_db": float("nan") if floor[ch] is None else floor[ch], "bit_mean": s["channels"][ch]["bit_mean"]}
        for ch in CHANNELS
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("structure", type=Path)
    p.add_argument("models", type=Path, nargs="+", help="model .json files; the first is the reference")
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--eps", default="-1e-3,0,1e-3", help="relative changes of the DC input")
    p.add_argument("--cycles", type=int, default=8192)
    p.add_argument("--simulator", default="ngspice-xspice")
    args = p.parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    eps = [float(e) for e in args.eps.split(",")]
    first = MacroModel.load_json(args.models[0])
    d = design(first, 1e-6)
    weight_uN = d.inputs["f_z"]  # -m g in uN (the default input)
    rows = {}
    for k, model in enumerate(args.models):
        name = f"{k}_{model.parent.name}"
        rows[name] = {}
        for e in eps:
            loop = loop_file(args.output, weight_uN * (1 + e), d.vfb)
            rows[name][e] = run(args.structure, model, loop, args.output / f"{name}_eps{e:+.0e}", args)
            print(name, e, {ch: round(v["floor_db"], 2) for ch, v in rows[name][e].items()}, flush=True)
    ref = next(iter(rows))
    print(
        f"\n{'model':24} {'channel':7} "
        + " ".join(f"{e:+9.0e}" for e in eps)
        + "      mean median  range  mean, median diff vs first"
    )
    summary = {}
    for name, by_eps in rows.items():
        for ch in CHANNELS:
            f = np.array([by_eps[e][ch]["floor_db"] for e in eps])
            r = np.array([rows[ref][e][ch]["floor_db"] for e in eps])
            summary[f"{name}/{ch}"] = {
                "floors": f.tolist(),
                "mean": float(f.mean()),
                "median": float(np.median(f)),
                "range": float(np.ptp(f)),
                "diff_of_means": float(f.mean() - r.mean()),
                "diff_of_medians": float(np.median(f) - np.median(r)),
            }
            print(
                f"{name:24} {ch:7} "
                + " ".join(f"{v:9.2f}" for v in f)
                + f"  {f.mean():8.2f} {np.median(f):6.2f} {np.ptp(f):6.2f} {f.mean() - r.mean():+6.2f} "
                f"{np.median(f) - np.median(r):+6.2f}"
            )
    (args.output / "sigma_delta_designs.json").write_text(
        json.dumps(
            {"eps": eps, "rows": {n: {str(e): v for e, v in r.items()} for n, r in rows.items()}, "summary": summary},
            indent=1,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
