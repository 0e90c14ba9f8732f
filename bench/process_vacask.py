"""Process corners and a Monte Carlo in VACASK's own netlist (docs/process.md): the accelerometer
with [process] dg and tscale built once and compiled to OSDI, one VACASK run sweeping tscale and
dg_bottom over their ranges' ends and over RUNS points drawn here (numpy, --seed; VACASK has no
random functions), against the closed form (the deck and its reference: tests/oracles/process_vacask.py,
tests/oracles/process_mc.py). With -o the netlist, the .osdi and the raw files stay in that folder
(rerun there with `vacask process_sweep.sim`).

    .venv/bin/python bench/process_vacask.py [--runs 200] [--seed 7] [-o FOLDER]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from support import process_mc, process_vacask

from netgen import emit


def report(rows: dict, runs: int, seed: int) -> None:
    """Print the corners, the worst point against the closed form, the slopes and the spread."""
    bias = process_vacask.BIAS
    print(f"corners at {bias} V (tscale, dg_bottom: x_z um, f0 Hz; closed form):")
    for t, d, p in rows["corner"]:
        r = process_mc.closed_form(t, d, bias)
        print(f"  {t:g}, {d * 1e9:+.0f} nm: {p.z * 1e6:.6f} um, {p.f0:.3f} Hz ({r.z * 1e6:.6f} um, {r.f0:.3f} Hz)")
    every = rows["corner"] + rows["mc"]
    refs = [process_mc.closed_form(t, d, bias) for t, d, _ in every]
    worst_z = max(abs(p.z / r.z - 1) for (_, _, p), r in zip(every, refs))
    worst_f = max(abs(p.f0 / r.f0 - 1) for (_, _, p), r in zip(every, refs))
    print(f"{runs} runs (seed {seed}) and 4 corners: |z/z_ref - 1| <= {worst_z:.1e}, |f0/f0_ref - 1| <= {worst_f:.1e}")
    mc = rows["mc"]
    got, analytic = process_mc.regression(mc), process_mc.sensitivities(bias)
    for key, want in analytic.items():
        print(f"  d ln {key[0]} / d {key[2]}: MC {got[key]:.6g}  closed form {want:.6g}  ({got[key] / want - 1:+.2%})")
    z = np.array([p.z for _, _, p in mc])
    f = np.array([p.f0 for _, _, p in mc])
    first = {
        q: math.hypot(analytic[f"{q}_t"] * process_mc.SIGMA_T, analytic[f"{q}_g"] * process_mc.SIGMA_G) for q in "zf"
    }
    dt, dg = np.array([t - 1 for t, _, _ in mc]), np.array([d for _, d, _ in mc])
    drawn = {q: np.std(analytic[f"{q}_t"] * dt + analytic[f"{q}_g"] * dg, ddof=1) for q in "zf"}
    for q, values in (("ln|z|", np.log(-z)), ("ln f", np.log(f))):
        k = q[3]
        print(
            f"  std {q} {np.std(values, ddof=1):.4g}: first order {first[k]:.4g} over the distribution, "
            f"{drawn[k]:.4g} over the draws"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("-o", "--output", type=Path, help="keep the netlist, .osdi and raw files here")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = (a.output or Path(tmp)).resolve()
        folder.mkdir(parents=True, exist_ok=True)
        start = time.perf_counter()
        model = process_mc.model()
        emit.write_outputs(model, folder, "osdi")
        t_build = time.perf_counter() - start
        start = time.perf_counter()
        rows = process_vacask.run(folder / "accelerometer_z.osdi", folder, a.runs, a.seed)
        t_run = time.perf_counter() - start
    report(rows, a.runs, a.seed)
    print(f"wall time: one [process] build and compile {t_build:.2f} s, one VACASK run {t_run:.2f} s")


if __name__ == "__main__":
    main()
