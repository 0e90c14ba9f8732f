"""The comb finger's 2-D side capacitance against the textbook parallel plate: the ratio of the
converged periodic-cell solve (netgen.electrostatics.comb_section, per side at the nominal gap, no
offset) to eps t / g (the textbook comb 2 n eps t L / g per side), for t/g = 1, 2, 5, 20, with and
without a grounded substrate under the fingers; and the side instability of a comb whose moving
finger sits between two fixed fingers of one electrode: the pull-in voltage with the 2-D
section's curvature d^2 C'/dx^2 (two direct solves, x = +-0.1 g: one cell gives both faces) over
the closed form V = sqrt(k g^3 / (2 eps n t L)) (textbook curvature 4 eps t / g^3 per finger):
V_2D / V_closed = sqrt(4 eps t / g^3 / C''_2D), independent of k, n and L.

    .venv/bin/python bench/comb_textbook.py [--gap 2e-6] [--width 2e-6] [--substrate-gap 2e-6] [--ratios 1,2,5,20]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

from netgen.core.constants import EPS0
from netgen.electrostatics import comb_section


def main() -> None:
    """Print one line per t/g: the 2-D/textbook ratio over a substrate and in free space."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gap", type=float, default=2e-6)
    ap.add_argument("--width", type=float, default=2e-6)
    ap.add_argument("--substrate-gap", type=float, default=2e-6)
    ap.add_argument("--ratios", default="1,2,5,20")
    a = ap.parse_args()
    print(
        f"finger width {a.width:.3g} m, gap {a.gap:.3g} m, pitch {a.width + a.gap:.3g} m, "
        f"substrate gap {a.substrate_gap:.3g} m; tol {comb_section.SETTINGS['tol']}"
    )
    print(f"{'t/g':>6} {'C2D/textbook sub':>17} {'free':>8} {'V_pull 2D/closed sub':>21} {'free':>8} {'s':>6}")
    for r in (float(x) for x in a.ratios.split(",")):
        t0 = time.time()
        cells = [
            SimpleNamespace(width=a.width, thickness=r * a.gap, pitch=a.width + a.gap, substrate_gap=sg, eps=EPS0)
            for sg in (a.substrate_gap, None)
        ]
        ratios = [comb_section.textbook_ratio(c) for c in cells]
        shifts = [pull_in_ratio(c, 0.1 * a.gap) for c in cells]
        print(f"{r:6g} {ratios[0]:17.4f} {ratios[1]:8.4f} {shifts[0]:21.4f} {shifts[1]:8.4f} {time.time() - t0:6.1f}")


def pull_in_ratio(cell, h: float) -> float:
    """V_pull(2-D) / V_pull(closed form) of a finger between two fixed fingers at the nominal gap."""
    g = comb_section.Geometry.of(cell)
    mid = sum(comb_section.solve_cell(g, g.gap, 0.0)[:2])
    shifted = sum(comb_section.solve_cell(g, g.gap - h, 0.0)[:2])  # the cell at x = h: both faces
    curvature = 2.0 * (shifted - mid) / h**2  # C_cell(x) is even in x
    return (4.0 * g.eps * g.thickness / g.gap**3 / curvature) ** 0.5


if __name__ == "__main__":
    main()
