"""The process Monte Carlo of docs/process.md at full size: RUNS runs of ngspice's own `.control`
loop (agauss on tscale and dg_bottom of the accelerometer with [process]; the deck and its closed
form: tests/oracles/process_mc.py) against the closed-form sensitivities, and its wall time
against rebuilding the model at each draw (REBUILDS rebuilds timed, in-process build_model +
emit, extrapolated to RUNS when fewer).

    .venv/bin/python bench/process_mc.py [--runs 200] [--rebuilds 200] [--seed 7]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from support import ROOT, process_mc

from netgen.build import build_model
from netgen.emit import ngspice as emit_ngspice
from netgen.structure import parse_structure


def structure_text(t: float = 1.0, dg: float = 0.0, process: bool = False) -> str:
    """examples/accelerometer_z.toml at thickness t x 20 um and bottom gap 2 um + dg."""
    text = (ROOT / "examples/accelerometer_z.toml").read_text()
    text = text.replace('thickness = "20 um"', f'thickness = "{20.0 * t!r} um"')
    parts = text.split('name = "bottom"\nside = "below"\ngap = "2 um"')
    assert len(parts) == 2, "examples/accelerometer_z.toml changed: update bench/process_mc.py"
    text = parts[0] + f'name = "bottom"\nside = "below"\ngap = "{(2e-6 + dg) * 1e6!r} um"' + parts[1]
    return text + (process_mc.PROCESS if process else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--rebuilds", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        start = time.perf_counter()
        model = build_model(parse_structure(structure_text(process=True), "accelerometer_z.toml"))
        lib = folder / "accelerometer_z.lib"
        lib.write_text(emit_ngspice.subcircuit(model))
        t_build = time.perf_counter() - start
        start = time.perf_counter()
        rows = process_mc.run(lib, folder, a.runs, a.seed)
        t_mc = time.perf_counter() - start
        draws = [(t, d) for t, d, _ in rows[: a.rebuilds]]
        start = time.perf_counter()
        for t, d in draws:
            emit_ngspice.subcircuit(build_model(parse_structure(structure_text(t, d), "accelerometer_z.toml")))
        t_rebuild = (time.perf_counter() - start) / len(draws)
    refs = [process_mc.closed_form(t, d) for t, d, _ in rows]
    worst_z = max(abs(p.z / r.z - 1) for (_, _, p), r in zip(rows, refs))
    worst_f = max(abs(p.f0 / r.f0 - 1) for (_, _, p), r in zip(rows, refs))
    got, analytic = process_mc.regression(rows), process_mc.sensitivities()
    print(f"{a.runs} runs (seed {a.seed}): per run |z/z_ref - 1| <= {worst_z:.2e}, |f0/f0_ref - 1| <= {worst_f:.2e}")
    for key, want in analytic.items():
        print(f"  d ln {key[0]} / d {key[2]}: MC {got[key]:.6g}  closed form {want:.6g}  ({got[key] / want - 1:+.2%})")
    z = np.array([p.z for _, _, p in rows])
    f = np.array([p.f0 for _, _, p in rows])
    spread = {
        "z": math.hypot(analytic["z_t"] * process_mc.SIGMA_T, analytic["z_g"] * process_mc.SIGMA_G),
        "f": math.hypot(analytic["f_t"] * process_mc.SIGMA_T, analytic["f_g"] * process_mc.SIGMA_G),
    }
    print(
        f"  std ln|z| {np.std(np.log(-z), ddof=1):.4g} (first order {spread['z']:.4g}), "
        f"std ln f {np.std(np.log(f), ddof=1):.4g} (first order {spread['f']:.4g}); "
        f"sampling error of a std over {a.runs} runs ~ {1 / math.sqrt(2 * (a.runs - 1)):.1%}"
    )
    total = t_rebuild * a.runs
    print(
        f"wall time: one [process] build {t_build:.2f} s + {a.runs} ngspice runs {t_mc:.2f} s = {t_build + t_mc:.2f} s; "
        f"{a.runs} rebuilds {total:.1f} s ({t_rebuild:.2f} s each over {len(draws)} timed"
        f"{', extrapolated' if len(draws) < a.runs else ''}): {total / (t_build + t_mc):.0f}x"
    )


if __name__ == "__main__":
    main()
