"""Time each pipeline stage of the reference example build, in one process.

    .venv/bin/python bench/build.py [--repeat N] [STRUCTURE.toml]

Runs the same stage functions as `netgen build` (netgen.build.build calls them in this
order) N times (default 3) and prints the median and spread of each stage, the total, and its
ratio to the budgets: 60 s for the whole build (the original acceptance target) and 20 s (the later
performance goal). Stage 1 includes the FEM eigenmodes; nothing is cached between repeats
except Python imports (the first repeat may include one-time library warm-up).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from support import ROOT

from netgen.build import Sampled, assemble
from netgen.electrostatics import extractor
from netgen.electrostatics.sampling import coordinate_scales, sample_corners, sample_grid, sample_holdout
from netgen.emit.ngspice import subcircuit
from netgen.fit.capacitance import at_corners, fit_all
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure import load_structure

BUDGET_S = 60.0  # the original target: a reference build within a minute
GOAL_S = 20.0  # the later performance target


def run_once(path: Path) -> dict[str, float]:
    """One build, stage by stage (same calls as netgen.build.build); seconds per stage."""
    times: dict[str, float] = {}
    clock = time.perf_counter

    def timed(label, fn, *args):
        t = clock()
        out = fn(*args)
        times[label] = clock() - t
        return out

    s = timed("read structure", load_structure, path)
    m = timed("mechanics (rigid body + FEM eigenmodes)", mechanics, s)

    def prepare():
        plate, shapes = plate_outline(s), electrodes(s)
        ext = extractor(s, plate)
        return plate, shapes, ext, ext.prepare(shapes, plate, m.basis)

    plate, shapes, ext, prepared = timed("electrodes + extractor quadrature", prepare)
    scales = timed("touching amplitudes", coordinate_scales, prepared, m.names, [e.gap for e in shapes])
    grid = timed(f"grid samples ({s.sampling.levels}^{len(scales)})", sample_grid, s, prepared, scales)
    held = timed(f"held-out samples ({s.fit.holdout})", sample_holdout, s, prepared, scales)
    corners = timed(f"corner checks (2^{len(scales)}, up to 2^6)", sample_corners, s, prepared, scales)
    fits = timed(f"fits ({len(shapes)} electrodes, {s.fit.target})", fit_all, s, shapes, m.basis, scales, grid, held)
    fits = timed("fit errors at the corners", at_corners, fits, corners)
    model = timed(
        "assemble MacroModel",
        assemble,
        s,
        m,
        plate,
        shapes,
        ext,
        prepared,
        scales,
        Sampled(grid, held, fits, None, corners),
    )
    timed("emit ngspice .lib", subcircuit, model)
    timed("JSON text", model.json_text)
    return times


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("structure", nargs="?", default=str(ROOT / "examples" / "levitated_disk.toml"))
    p.add_argument("--repeat", type=int, default=3, help="number of builds (default 3)")
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error("--repeat must be at least 1")

    runs = []
    for k in range(args.repeat):
        t = time.perf_counter()
        runs.append(run_once(Path(args.structure)))
        print(f"run {k + 1}/{args.repeat}: {time.perf_counter() - t:.2f} s", file=sys.stderr)

    totals = [sum(r.values()) for r in runs]
    width = max(len(k) for k in runs[0])
    print(f"{Path(args.structure).name}: median of {args.repeat} build(s), one process")
    print(f"{'stage':<{width}}  {'median s':>9}  {'min s':>8}  {'max s':>8}  {'share':>6}")
    total_median = statistics.median(totals)
    for stage in runs[0]:
        v = [r[stage] for r in runs]
        med = statistics.median(v)
        print(f"{stage:<{width}}  {med:9.3f}  {min(v):8.3f}  {max(v):8.3f}  {med / total_median:6.1%}")
    print(f"{'total':<{width}}  {total_median:9.3f}  {min(totals):8.3f}  {max(totals):8.3f}")
    print(
        f"budget {BUDGET_S:.0f} s: {total_median / BUDGET_S:.2f} of it;  "
        f"goal {GOAL_S:.0f} s: {total_median / GOAL_S:.2f} of it"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
