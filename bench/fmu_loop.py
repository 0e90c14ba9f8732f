"""The z accelerometer's sigma-delta loop with the mechanics in the FMU against the same loop in
ngspice-xspice (the compiled netgen_sdloop and netgen_es), same model and Design:

    .venv/bin/python bench/fmu_loop.py [--cycles 65536] [--reference DIR] [--converged DIR]
        [--loop LOOP.toml] [-o out/fmu_loop]

Runs `netgen sigma-delta examples/accelerometer_z.toml --model <committed JSON> --simulator
ngspice-xspice` into OUT/ngspice-xspice (or takes --reference DIR, such a run's folder) and the same
Design at the settings where ngspice's bits stop moving (CONVERGED: reltol 1e-6, abstol 1e-20 A,
vntol 1e-14 V, 20 equal steps per drive edge; docs/fmu.md) into OUT/ngspice-xspice-converged (or
--converged DIR), then the FMU loop
(examples/fmu_sigma_delta.py), and prints the walls, bit means, in-band floors (OSR 64, first
eighth skipped) and the first period whose bit differs against each; writes OUT/fmu_loop.json.
--realizations K also runs the FMU loop K times with a_in scaled by 1 + k 1e-7 (realizations)
and gives the floors' mean and spread, and each ngspice floor's distance from that mean.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.cli import commands as cli
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import fmu
from netgen.testbench.sigma_delta.analysis import analyse
from netgen.testbench.sigma_delta.runner import RunRequest

# ngspice where its bits stop moving with its settings (docs/fmu.md): at its default absolute
# tolerances they part after 26-60 periods whatever reltol or the maximum step, and inside the
# feedback edges its own steps miss the V^2 impulse by up to 2e-3 (Design.ramp_steps: 20 equal steps
# per edge; 192 bits as the FMU loop's at these settings, 456-512 at reltol 1e-7 with 40-80 steps)
CONVERGED = {"reltol": 1e-6, "abstol": 1e-20, "vntol": 1e-14, "ramp_steps": 20}


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


def xspice_run(folder: Path, cycles: int, loop: str | None = None, **settings) -> dict:
    """The ngspice-xspice run of the example's Design (the structure's [loop], or the file `loop`)
    with `settings` replacing its fields (reltol, abstol, vntol, tmax, ramp_steps) into `folder`:
    sd.run's result. The request both benches compare the FMU loop with."""
    ex = example()
    model, d = ex.design(loop)
    request = RunRequest(
        ex.TS,
        cycles,
        None,
        progress=False,
        plots=False,
        simulator="ngspice-xspice",
        loop=sd.read_loop_file(loop) if loop else sd.read_structure_loop(ex.STRUCTURE),
        designed=replace(d, **settings),
    )
    return sd.run(model, ex.MODEL.with_suffix(".lib"), folder, request)


def converged(out: Path, cycles: int, loop: str | None) -> tuple[Path, float]:
    """The ngspice-xspice run of the same Design at the CONVERGED settings: folder, wall time."""
    folder = out / "ngspice-xspice-converged"
    start = time.perf_counter()
    xspice_run(folder, cycles, loop, **CONVERGED)
    return folder, time.perf_counter() - start


def against(ex, clock: dict, z: dict, folder: Path, wall: float | None, tag: str) -> dict:
    """The comparison with one ngspice-xspice run folder, keys prefixed by `tag`."""
    ref = np.load(folder / "bitstreams.npz")
    ref_z = json.loads((folder / "summary.json").read_text())["channels"]["z"]
    return {
        f"{tag}_wall_s": wall,
        f"{tag}_first_differing_bit": ex.first_difference(clock["bits_z"], ref["bits_z"]),
        f"{tag}_floor_db_per_hz": ref_z["noise_floor_db_per_hz"],
        f"{tag}_floor_difference_db": z["noise_floor_db_per_hz"] - ref_z["noise_floor_db_per_hz"],
        f"{tag}_bit_mean": ref_z["bit_mean"],
        f"{tag}_folder": str(folder),
    }


def realizations(cycles: int, count: int, loop: str | None) -> list[float]:
    """The FMU loop's in-band floor over `count` realizations of the same loop: the DC input a_in
    scaled by 1 + k 1e-7 (k = 0: the design's), a change far below what 2^16 bits resolve (1.5e-5)
    that still flips a decision somewhere and so gives another bit sequence, as another machine's
    round-off or another simulator's would: the spread of the floor estimate itself."""
    ex = example()
    model, d = ex.design(loop)
    floors = []
    for k in range(count):
        dk = replace(d, inputs={**d.inputs, "a_in": d.inputs["a_in"] * (1 + k * 1e-7)})
        clock = fmu.run(model, dk, cycles)
        floors.append(analyse(clock, dk, skip=cycles // 8)["channels"]["z"]["noise_floor_db_per_hz"])
    return floors


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=65536)
    p.add_argument("--reference", help="an existing ngspice-xspice run folder of the same cycles")
    p.add_argument("--converged", help="an existing run folder of the same cycles at the CONVERGED tolerances")
    p.add_argument("--loop", help="loop description (default: the structure's [loop])")
    p.add_argument("--realizations", type=int, default=0, help="FMU loop floors over this many realizations")
    p.add_argument("-o", "--output", default="out/fmu_loop")
    args = p.parse_args()
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    folder, ref_wall = (Path(args.reference), None) if args.reference else reference(out, args.cycles, args.loop)
    tight, tight_wall = (Path(args.converged), None) if args.converged else converged(out, args.cycles, args.loop)
    ex = example()
    clock, summary, wall = ex.simulate(args.cycles, args.loop)
    z = summary["channels"]["z"]
    result = {
        "cycles": args.cycles,
        "fmu_wall_s": wall,
        "fmu_floor_db_per_hz": z["noise_floor_db_per_hz"],
        "fmu_bit_mean": z["bit_mean"],
        **against(ex, clock, z, folder, ref_wall, "ngspice_xspice"),
        **against(ex, clock, z, tight, tight_wall, "ngspice_xspice_converged"),
    }
    if args.realizations > 1:
        floors = np.array(realizations(args.cycles, args.realizations, args.loop))
        mean, std = float(floors.mean()), float(floors.std(ddof=1))
        result |= {"fmu_floor_realizations_db_per_hz": floors.tolist(), "fmu_floor_mean": mean, "fmu_floor_std": std}
        for tag in ("ngspice_xspice", "ngspice_xspice_converged"):
            result[f"{tag}_floor_minus_fmu_mean_db"] = result[f"{tag}_floor_db_per_hz"] - mean
    (out / "fmu_loop.json").write_text(json.dumps(result, indent=1) + "\n")
    for k, v in result.items():
        print(f"{k:44s} {v}")


if __name__ == "__main__":
    main()
