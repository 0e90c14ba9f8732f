"""Mesh convergence of the 2-D field solver (netgen.electrostatics.field2d) on its three exact
references: the levels of one solve each (elements, dofs, C', error vs the exact C'), and the
box check (relative change when the open box is doubled).

    .venv/bin/python bench/field2d_convergence.py [--levels 4] [--order 2]

Cases: two coplanar thin strips w = s = 1 (eps K(k')/K(k)); a round wire r = 1 with its centre at
h = 2 over ground (2 pi eps / acosh(h/r)); thin fingers t/g = 20 face to face (the exact two-strip
map, closed_forms.parallel_strips, = eps t/g + Maxwell's fringe to 0.12 %).
"""

from __future__ import annotations

import argparse
import time

from support import closed_forms

from netgen.core.constants import EPS0
from netgen.electrostatics.field2d import Conductor, Problem, open_box, solve
from netgen.electrostatics.mesh2d import Disk, Strip

OPEN = {"bottom": "open", "right": "open", "top": "open", "left": "open"}


def cases() -> dict:
    """name -> (problem, exact C', how to read C' from a matrix)."""
    a = Conductor("a", (Strip(-1.5, 0.0, -0.5, 0.0),))
    b = Conductor("b", (Strip(0.5, 0.0, 1.5, 0.0),))
    w = Conductor("wire", (Disk(0.0, 2.0, 1.0),))
    fa = Conductor("a", (Strip(-0.5, 0.0, -0.5, 20.0),))
    fb = Conductor("b", (Strip(0.5, 0.0, 0.5, 20.0),))
    return {
        "coplanar strips w=s": (
            Problem((a, b), open_box((a, b)), OPEN),
            closed_forms.coplanar_strips(EPS0, 1.0, 1.0),
            lambda C: -C[0, 1],
        ),
        "wire over ground h/r=2": (
            Problem((w,), open_box((w,), ground_bottom=0.0), {**OPEN, "bottom": "ground"}),
            closed_forms.wire_over_plane(EPS0, 1.0, 2.0),
            lambda C: C[0, 0],
        ),
        "finger pair t/g=20": (
            Problem((fa, fb), open_box((fa, fb)), OPEN),
            closed_forms.parallel_strips(EPS0, 20.0, 1.0),
            lambda C: -C[0, 1],
        ),
    }


def main() -> None:
    """Print each case's convergence table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--order", type=int, default=2, choices=(1, 2))
    a = ap.parse_args()
    for name, (problem, exact, read) in cases().items():
        t0 = time.time()
        sol = solve(problem, tol=0.0, order=a.order, max_levels=a.levels, check_box=True)
        print(
            f"\n{name}: exact C' = {exact:.6e} F/m (P{a.order}, box check {sol.box_change:.1e}, {time.time() - t0:.1f} s)"
        )
        print(f"{'level':>5} {'elements':>9} {'dofs':>8} {'C_prime F/m':>14} {'error':>10}")
        for k, lev in enumerate(sol.levels):
            c = read(lev.capacitance)
            print(f"{k:5d} {lev.elements:9d} {lev.dofs:8d} {c:14.6e} {c / exact - 1:+10.2e}")


if __name__ == "__main__":
    main()
