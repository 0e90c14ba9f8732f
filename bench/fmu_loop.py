"""The z accelerometer's sigma-delta loop with the mechanics in the FMU against the same loop in
ngspice-xspice (the compiled netgen_sdloop and netgen_es), same model and Design:

    .venv/bin/python bench/fmu_loop.py [--cycles 65536] [--reference DIR] [--loop LOOP.toml]
        [-o out/fmu_loop]

Runs `netgen sigma-delta examples/accelerometer_z.toml --model <committed JSON> --simulator
ngspice-xspice` into OUT/ngspice-xspice (or takes --reference DIR, such a run's folder), then the
FMU loop (examples/fmu_sigma_delta.py), and prints both walls, bit means, in-band floors (OSR 64,
first eighth skipped) and the first period whose bit differs; writes OUT/fmu_loop.json.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import time
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.cli import commands as cli


def example():
    """examples/fmu_sigma_delta.py as a module (the loop and its analysis)."""
    spec = importlib.util.spec_from_file_location("fmu_sigma_delta", ROOT / "examples" / "fmu_sigma_delta.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def reference(out: Path, cycles: int, loop: str | None) -> tuple[Path, float]:
    """The ngspice-xspice run's folder and its wall time."""
    folder = out / "ngspice-xspice"
    ex = example()
    args = ["sigma-delta", str(ex.STRUCTURE), "--model", str(ex.MODEL), "-o", str(folder), "--cycles", str(cycles)]
    args += ["--simulator", "ngspice-xspice", "--no-plots", "-q", *(["--loop", loop] if loop else [])]
    start = time.perf_counter()
    code = cli.main(args)
    if code:
        raise SystemExit(f"netgen sigma-delta exited {code}")
    return folder, time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=65536)
    p.add_argument("--reference", help="an existing ngspice-xspice run folder of the same cycles")
    p.add_argument("--loop", help="loop description (default: the structure's [loop])")
    p.add_argument("-o", "--output", default="out/fmu_loop")
    args = p.parse_args()
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    ref_wall = None
    if args.reference:
        folder = Path(args.reference)
    else:
        folder, ref_wall = reference(out, args.cycles, args.loop)
    ex = example()
    clock, summary, wall = ex.simulate(args.cycles, args.loop)
    ref = np.load(folder / "bitstreams.npz")
    ref_z = json.loads((folder / "summary.json").read_text())["channels"]["z"]
    z = summary["channels"]["z"]
    result = {
        "cycles": args.cycles,
        "fmu_wall_s": wall,
        "ngspice_xspice_wall_s": ref_wall,
        "first_differing_bit": ex.first_difference(clock["bits_z"], ref["bits_z"]),
        "fmu_floor_db_per_hz": z["noise_floor_db_per_hz"],
        "ngspice_xspice_floor_db_per_hz": ref_z["noise_floor_db_per_hz"],
        "floor_difference_db": z["noise_floor_db_per_hz"] - ref_z["noise_floor_db_per_hz"],
        "fmu_bit_mean": z["bit_mean"],
        "ngspice_xspice_bit_mean": ref_z["bit_mean"],
        "reference": str(folder),
    }
    (out / "fmu_loop.json").write_text(json.dumps(result, indent=1) + "\n")
    for k, v in result.items():
        print(f"{k:32s} {v}")


if __name__ == "__main__":
    main()
