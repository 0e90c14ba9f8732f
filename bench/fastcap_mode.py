"""The multipole extractor at a non-zero mode-shape amplitude: a free disk (100 um radius, 2 um
thick) under four quadrant electrodes (10 um gap), its (2,0)c mode deflecting the rim by
--fraction of the gap, against the dense BEM on the same basis and the analytic (parallel-plate)
extractor: each quadrant's C at rest and at the amplitude, the relative change, and the CPU time.

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_mode.py

tests/electrostatics/test_fastcap_modes.py asserts the FastCap-BEM agreement at the amplitude.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from support import small_disk

from netgen.core.constants import EPS0
from netgen.electrostatics import bem, fastcap
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics
from netgen.structure import parse_structure

GAP = small_disk.MODE_GAP
DISK = small_disk.MODE_DISK


def solve(prepared, q: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(plate-electrode C, error bar, CPU seconds) of one converged Maxwell matrix."""
    c0 = time.process_time()
    m = prepared.maxwell(q)
    return m.plate_electrode, m.error, time.process_time() - c0


def main() -> None:
    """Solve at rest and at the amplitude with FastCap and the dense BEM; print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fraction", type=float, default=0.3, help="rim deflection in gaps")
    a = ap.parse_args()
    s = parse_structure(DISK, "disk_mode.toml")
    m, plate, els = mechanics(s), plate_outline(s), electrodes(s)
    pf = fastcap.from_structure(s, plate).prepare(els, plate, m.basis)
    pb = bem.BemExtractor(eps=EPS0, settings=bem.BemSettings(tolerance=1.0, max_levels=2)).prepare(els, plate, m.basis)
    pp = ParallelPlateExtractor(eps=EPS0).prepare(els, plate, m.basis)
    k = m.names.index("m2_0c")
    q = np.zeros(len(m.names))
    q[k] = a.fraction * GAP / np.abs(pf.geometry.probe.phi[:, k]).max()
    pb.maxwell(np.zeros_like(q))  # bempp's JIT, not timed
    rows = {}
    for label, at in (("rest", np.zeros_like(q)), ("mode", q)):
        rows[label] = {"fastcap": solve(pf, at), "bem": solve(pb, at), "analytic": (pp.capacitance(at), 0.0, 0.0)}
    names = [e.name for e in els]
    print(f"(2,0)c at {a.fraction:g} gap at the rim; FastCap panels {pf.estimate()['panels']}; C in fF")
    for label, r in rows.items():
        (cf, ef, tf), (cb, eb, tb), (ca, _, _) = r["fastcap"], r["bem"], r["analytic"]
        print(f"{label}: FastCap (bar {100 * ef:.2f} %, {tf:.1f} s CPU), BEM (bar {100 * eb:.2f} %, {tb:.1f} s CPU)")
        for i, n in enumerate(names):
            print(
                f"  {n}: FastCap {1e15 * cf[i]:.4f}  BEM {1e15 * cb[i]:.4f}  analytic {1e15 * ca[i]:.4f}  "
                f"FastCap - BEM {100 * (cf[i] / cb[i] - 1):+.2f} % (bound 2 (e_f + e_b) {200 * (ef + eb):.2f} %)"
            )
    print("change of C from rest to the mode's amplitude:")
    for i, n in enumerate(names):
        ch = {w: 100 * (rows["mode"][w][0][i] / rows["rest"][w][0][i] - 1) for w in ("fastcap", "bem", "analytic")}
        print(f"  {n}: FastCap {ch['fastcap']:+.3f} %  BEM {ch['bem']:+.3f} %  analytic {ch['analytic']:+.3f} %")


if __name__ == "__main__":
    main()
