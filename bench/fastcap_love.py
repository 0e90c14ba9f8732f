"""Two coaxial unit disks against Love's integral equation (closed_forms.love_disks) at d/a = 0.01,
0.02 and 0.05: the multipole extractor's C00 - C01 (the charge at +-1 V), its deviation from Love's
value and its own error bar, at the extractor's default settings (two levels, order 2 assumed).

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_love.py

d/a = 0.05 and 0.02 are also tests/electrostatics/test_fastcap.py::test_coaxial_disks_against_love;
d/a = 0.01 (35.6k panels on the fine level) is too slow for the suite and is run here.

--edge-to-gap 0.25 0.125 0.0625 repeats each d/a with finer rim panels (the rest as the defaults):
the fine level's own deviation ("fine") shows how the rim's resolution, which the two levels'
error bar does not see, sets the bias (docs/fastcap.md, 'Against independent solutions').

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_love.py --kappa 0.01 --edge-to-gap 0.25 0.125 0.0625

--expansion-order 6 (the check solve at 8) takes the multipole part of the bias away.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

from support import closed_forms

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.fastcap_mesh import polar_panels


def two_disks(kappa: float, st: fastcap.FastcapSettings):
    """Two coaxial unit disks at distance kappa (eps_r = 1): the converged Maxwell matrix."""
    levels = []
    for k in range(max(2, st.levels)):
        s = st.sizes(kappa, k, 1.0)
        levels.append([polar_panels(0.0, 1.0, 0.0, 2 * math.pi, 0.0, s, z) for z in (0.0, kappa)])
    return fastcap.converged(levels, 1.0, st, ("a", "b"))


def main() -> None:
    """Solve each d/a, print FastCap against Love with the error bar, panels and time."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kappa", type=float, nargs="*", default=[0.01, 0.02, 0.05], help="d/a values")
    ap.add_argument("--edge-to-gap", type=float, nargs="*", default=[0.25], help="rim panel sizes, in gaps")
    ap.add_argument("--expansion-order", type=int, default=4, help="multipole order (the check: 2 more)")
    a = ap.parse_args()
    print(
        f"{'d/a':>6} {'edge':>7} {'Love':>10} {'FastCap':>10} {'deviation':>10} {'fine':>9} {'error bar':>10}"
        f" {'within 2 e':>11} {'panels':>14} {'s':>6}"
    )
    for kappa in a.kappa:
        for edge in a.edge_to_gap:
            order = a.expansion_order
            st = replace(fastcap.FastcapSettings(), edge_to_gap=edge, expansion_order=order, check_order=order + 2)
            t0 = time.perf_counter()
            m = two_disks(kappa, st)
            seconds = time.perf_counter() - t0
            ref = closed_forms.love_disks(kappa)
            c = (m.matrix[0, 0] - m.matrix[0, 1]) / EPS0
            fine = (
                m.coarse[0, 0] - m.coarse[0, 1]
            ) / EPS0 / ref - 1.0  # the fine level (`coarse`: the level before the extrapolation)
            dev = c / ref - 1.0
            panels = "/".join(str(r["panels"]) for r in m.settings["solves"][:-1])
            inside = "inside" if abs(dev) <= 2.0 * m.error else "OUTSIDE"
            print(
                f"{kappa:6.3f} {edge:7.4f} {ref:10.5f} {c:10.5f} {100 * dev:+9.3f}% {100 * fine:+8.3f}%"
                f" {100 * m.error:9.3f}% {inside:>11} {panels:>14} {seconds:6.1f}"
            )


if __name__ == "__main__":
    main()
