"""How big a sweep is before any list of runs is made: the run count from the spec alone (the
product of the list lengths, or their common length for zip, times `samples`), the expected
wall time, and the cap (`netgen sweep --max-runs`) that refuses a sweep nobody meant to start."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import SweepError
from .spec import Sweep

# rough ngspice cost of one sampling period of the sigma-delta loop (s, summary.json wall_s per
# period), per model kind, for the levitated disk on this 2-core machine under load
# (bench/sweep_processes.py --calibrate: rigid 0.020, full 0.071; idle about 25 % less)
SECONDS_PER_PERIOD = {"rigid": 0.02, "full": 0.07}
RUN_SECONDS = 5.0  # per run besides the periods: ngspice start, netlist, analysis, files
BUILD_SECONDS = 60.0  # a run with structure parameters builds its own model first


@dataclass
class Estimate:
    """The run count, the seconds of one run, the whole sweep's wall time and what it rests on."""

    runs: int
    per_run_s: float
    wall_s: float
    basis: str

    def text(self, workers: int) -> str:
        """One line for the user: '12 runs, about 3.1 min each, about 19 min on 2 workers (...)'."""
        return (
            f"{self.runs} run(s), about {duration(self.per_run_s)} each, about {duration(self.wall_s)} "
            f"on {workers} worker(s) ({self.basis})"
        )


def run_count(sweep: Sweep) -> int:
    """Number of runs of the sweep, computed from the list lengths (nothing is enumerated)."""
    lengths = [len(p.values) for p in sweep.parameters if p.values is not None]
    if sweep.mode == "zip":
        combos = min(lengths) if lengths else 0
    else:
        combos = math.prod(lengths)
    return combos * sweep.samples


def duration(seconds: float) -> str:
    """A wall time in the unit a person reads: s, min, h or days."""
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def _cycles(sweep: Sweep) -> float:
    """Mean periods per run (a swept `cycles` list counts with its mean)."""
    if "cycles" in sweep.fixed:
        return float(sweep.fixed["cycles"])
    lists = [p.values for p in sweep.parameters if p.name == "cycles"]
    return float(sum(lists[0]) / len(lists[0])) if lists else 4096.0


def calibration(out: Path) -> float | None:
    """Measured seconds per period from the runs that finished in `out` before (their
    summary.json wall time over their periods), or None if there are none."""
    per = []
    for summary in sorted((out / "runs").glob("*/summary.json"))[:50]:
        try:
            s = json.loads(summary.read_text())
            per.append(float(s["wall_s"]) / float(s["requested_cycles"]))
        except (OSError, ValueError, KeyError, TypeError, ZeroDivisionError):
            continue
    return sum(per) / len(per) if per else None


def estimate(sweep: Sweep, workers: int, out: Path | None = None) -> Estimate:
    """Run count and expected wall time, from the runs already measured in `out` when there are
    any, else from SECONDS_PER_PERIOD (a stated rough figure)."""
    runs = run_count(sweep)
    measured = calibration(out) if out is not None and out.is_dir() else None
    rigid = bool(sweep.fixed.get("rigid_only", False))
    if measured is not None:
        per_period, basis = measured, f"{measured:.3g} s per period measured on the runs in {out}"
    else:
        kind = "rigid" if rigid else "full"
        per_period = SECONDS_PER_PERIOD[kind]
        basis = f"rough figure: {per_period:g} s of ngspice per period for a {kind} model on one core"
    per_run = per_period * _cycles(sweep) + RUN_SECONDS
    if any(p.structure for p in sweep.parameters):
        per_run += BUILD_SECONDS
        basis += f", plus ~{BUILD_SECONDS:.0f} s to build each run's model"
    waves = math.ceil(runs / max(1, workers)) if runs else 0
    return Estimate(runs, per_run, per_run * waves, basis)


def check_size(sweep: Sweep, max_runs: int, workers: int) -> Estimate:
    """The estimate, or a SweepError when the run count exceeds `max_runs` (before any run is
    listed: a 1e9-point grid is refused in microseconds, not by a MemoryError)."""
    est = estimate(sweep, workers)
    if est.runs > max_runs:
        lists = ", ".join(f"{p.name}: {len(p.values)}" for p in sweep.parameters if p.values is not None)
        raise SweepError(
            sweep.path,
            "runs",
            f"the sweep has {est.runs} runs ({sweep.mode} of {lists or 'no lists'}"
            f"{f', x {sweep.samples} samples' if sweep.samples > 1 else ''}; {est.text(workers)}), "
            f"more than --max-runs {max_runs}",
            'use fewer values (num) or samples, mode = "zip" for paired lists, or raise --max-runs if you mean it',
        )
    return est
