"""Two coaxial unit disks against Love's integral equation (closed_forms.love_disks) at d/a = 0.01,
0.02 and 0.05: the multipole extractor's C00 - C01 (the charge at +-1 V), its deviation from Love's
value and its own error bar, at the extractor's default settings (two levels, order 2 assumed).

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/fastcap_love.py

d/a = 0.05 and 0.02 are also tests/electrostatics/test_fastcap.py::test_coaxial_disks_against_love;
d/a = 0.01 (35.6k panels on the fine level) is too slow for the suite and is run here.
"""

from __future__ import annotations

import argparse
import math
import time

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
    a = ap.parse_args()
    st = fastcap.FastcapSettings()
    print(
        f"{'d/a':>6} {'Love':>10} {'FastCap':>10} {'deviation':>10} {'error bar':>10} {'within 2 e':>11} {'panels':>14} {'s':>6}"
    )
    for kappa in a.kappa:
        t0 = time.perf_counter()
        m = two_disks(kappa, st)
        seconds = time.perf_counter() - t0
        ref = closed_forms.love_disks(kappa)
        c = (m.matrix[0, 0] - m.matrix[0, 1]) / EPS0
        dev = c / ref - 1.0
        panels = "/".join(str(r["panels"]) for r in m.settings["solves"][:-1])
        inside = "inside" if abs(dev) <= 2.0 * m.error else "OUTSIDE"
        print(
            f"{kappa:6.3f} {ref:10.5f} {c:10.5f} {100 * dev:+9.3f}% {100 * m.error:9.3f}% {inside:>11} {panels:>14} {seconds:6.1f}"
        )


if __name__ == "__main__":
    main()
