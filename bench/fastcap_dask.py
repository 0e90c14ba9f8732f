"""Cost per point of the multipole extractor's sampling, serial against a Dask LocalCluster of 2
workers (netgen.electrostatics.bem_sampling.sample_maxwell through netgen.runtime.executor; one
point per task, the fastcap2 problems built and solved in the workers), and the ratio.

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_dask.py
    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_dask.py --edge-to-gap 0.125 --points 6

The problem is the small disk of the test suite (100 um radius, 20 um gaps above and below, rigid
z), points spread over +-30 % of the gap. The cluster is started and warmed first (the prepared
extractor scattered, one point per worker: FastCap has no JIT, so this is the start-up only) and
its time printed apart; the workers' CPU seconds per point (against the serial process's)
show the overhead of the path apart from the machine's load; the parallel samples are checked equal to the serial ones bit for bit.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np
from support import small_disk

from netgen.electrostatics import fastcap
from netgen.electrostatics.bem_sampling import sample_maxwell
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.runtime.executor import DaskExecutor
from netgen.structure import parse_structure

DISK = small_disk.SMALL_BEM_DISK.replace('name = "small_bem"', 'name = "small_fc"').format(
    extractor="fastcap", extra=""
)
GAP = 20e-6


def prepared(edge_to_gap: float, element_to_gap: float) -> fastcap.PreparedFastcap:
    """The small disk's prepared extractor at the given panel sizes."""
    s = parse_structure(DISK, "small_fc.toml")
    m, plate = mechanics(s), plate_outline(s)
    ext = fastcap.from_structure(s, plate)
    st = replace(ext.settings, edge_to_gap=edge_to_gap, element_to_gap=element_to_gap)
    return replace(ext, settings=st).prepare(electrodes(s), plate, m.basis)


def timed(p: fastcap.PreparedFastcap, q: np.ndarray, ex=None):
    """(samples, wall seconds, this process's CPU seconds) of one sampling run."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = sample_maxwell(p, q, executor=ex)
    return out, time.perf_counter() - w0, time.process_time() - c0


def main() -> None:
    """Sample serially and on 2 workers; print cost per point and the ratio."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=8)
    ap.add_argument("--edge-to-gap", type=float, default=0.25)
    ap.add_argument("--element-to-gap", type=float, default=2.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    p = prepared(a.edge_to_gap, a.element_to_gap)
    q = np.linspace(-0.3, 0.3, a.points)[:, None] * GAP
    print(f"small disk, {p.estimate()['panels']} panels per level, {a.points} points, load {os.getloadavg()[0]:.1f}")
    serial, wall_s, cpu_s = timed(p, q)
    print(f"serial: {wall_s / a.points:.2f} s per point (wall), {cpu_s / a.points:.2f} s CPU per point")
    w0 = time.perf_counter()
    ex = DaskExecutor(None, a.workers)
    try:
        sample_maxwell(p, q[: ex.workers], executor=ex)  # scatter and one point per worker
        start = time.perf_counter() - w0
        before = ex.client.run(time.process_time)
        par, wall_p, _ = timed(p, q, ex)
        after = ex.client.run(time.process_time)
        cpu_w = sum(after[k] - before[k] for k in after if k in before)
    finally:
        ex.close()
    same = np.array_equal(par.matrix, serial.matrix) and np.array_equal(par.coarse, serial.coarse)
    print(
        f"{ex.workers} Dask workers: {wall_p / a.points:.2f} s per point (wall), worker solve "
        f"{par.seconds.mean():.2f} s per point (serial {serial.seconds.mean():.2f}), workers' CPU {cpu_w / a.points:.2f} s "
        f"per point; start-up and warm-up {start:.1f} s"
    )
    print(
        f"ratio serial / Dask wall per point: {wall_s / wall_p:.2f}; equal bit for bit: {same}; "
        f"load {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
