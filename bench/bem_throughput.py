"""BEM solves per hour on 1 and 2 workers (netgen.electrostatics.bem_sampling through
netgen.runtime.executor), and the projection for the paper's 2187 points (3^7 grid).

    .venv/bin/python bench/bem_throughput.py                       # the suite's reduced problem, 24 points
    .venv/bin/python bench/bem_throughput.py --problem disk --gap 0.05 --points 4
    .venv/bin/python bench/bem_throughput.py --scheduler local      # Dask LocalCluster instead of processes

Workers are warmed first (one solve each, paying bempp's numba JIT once per process), so the
rate is the steady state; the JIT time is printed separately. Each point is one converged solve
(two mesh levels). `--problem disk` is the reference disk (examples/levitated_disk.toml) with
its gaps set to g/R = --gap.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from netgen.electrostatics import bem
from netgen.electrostatics.bem_sampling import sample_maxwell
from netgen.electrostatics.sampling import sampling_grid
from netgen.runtime.executor import executor

PAPER_POINTS = 2187


def problem(name: str, gap: float) -> tuple[bem.PreparedBem, np.ndarray]:
    """The prepared extractor and the coordinate scale of each sampled coordinate."""
    if name == "reduced":
        from support import bem_reduced

        return bem_reduced.reduced(), np.array([bem_reduced.GAP, bem_reduced.GAP / bem_reduced.R])
    from bem_reference_disk import structure

    from netgen.geometry.layout import electrodes, plate_outline
    from netgen.mechanics import mechanics

    s = structure(gap)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    p = bem.from_structure(s, plate).prepare(shapes, plate, m.basis)
    amp = np.abs(p.geometry.probe.phi).max(axis=0)
    return p, p.gap / amp


def rate(p: bem.PreparedBem, q: np.ndarray, spec: str) -> tuple[float, float]:
    """(solves per hour after warm-up, warm-up seconds) on the executor `spec`."""
    with executor(spec) as ex:
        t0 = time.perf_counter()
        sample_maxwell(p, q[: ex.workers], executor=ex)  # one point per worker: the JIT
        warm = time.perf_counter() - t0
        t0 = time.perf_counter()
        sample_maxwell(p, q, executor=ex)
        wall = time.perf_counter() - t0
    return 3600.0 * len(q) / wall, warm


def main() -> None:
    """Measure on 1 and 2 workers, print the rates and the projection."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--problem", choices=["reduced", "disk"], default="reduced")
    ap.add_argument("--gap", type=float, default=0.05, help="g/R of --problem disk")
    ap.add_argument("--points", type=int, default=24)
    ap.add_argument("--scheduler", choices=["processes", "local"], default="processes")
    a = ap.parse_args()
    p, scale = problem(a.problem, a.gap)
    rng = np.random.default_rng(1)
    x = np.zeros((a.points, p.ncoords))
    k = min(len(scale), 3)
    x[:, :k] = sampling_grid(k, 3, 0.2)[rng.permutation(3**k)[: a.points] % 3**k]
    q = x * scale
    elements = [len(lv.plate.triangles) + sum(len(e.triangles) for e in lv.electrodes) for lv in p.levels[:2]]
    print(f"problem {a.problem}: {len(p.names)} conductors, {elements} elements per level, {a.points} points")
    for workers in (1, 2):
        r, warm = rate(p, q, f"{a.scheduler}:{workers}")
        print(
            f"{workers} worker(s): {r:8.1f} solves/h (warm-up incl. JIT {warm:.0f} s); "
            f"{PAPER_POINTS} points: {PAPER_POINTS / r:.2f} h"
        )


if __name__ == "__main__":
    main()
