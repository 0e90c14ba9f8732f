"""The dense BEM (netgen.electrostatics.bem, bempp-cl) on two coaxial unit disks against Love's
integral equation (closed_forms.love_disks): C11 - C12 (disks at +1/-1) and C11 + C12 (both at +1)
at the suite's coarse settings (two levels + Richardson, elements up to 4 gaps), their deviations
and the time per kappa = d/a.

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python bench/bem_love.py [--kappa 0.05 0.1 0.2]

d/a = 0.1 and 0.2 are also tests/electrostatics/test_bem.py::test_two_disks_against_love (bound 0.5 %);
d/a = 0.05 (about a minute of CPU) is run here: the dense solver's cost grows as the gap closes,
and the multipole extractor carries the suite's narrow-gap checks (bench/fastcap_love.py).
"""

from __future__ import annotations

import argparse
import time

from support import closed_forms

from netgen.electrostatics import bem
from netgen.electrostatics.bem_mesh import disk_sheet

# the suite's coarse settings (tests/electrostatics/test_bem.py COARSE)
COARSE = bem.BemSettings(
    element_to_gap=4.0, edge_to_gap=0.25, element_to_size=0.125, levels=2, max_levels=2, tolerance=1.0
)
BOUND = 5e-3  # the suite's bound on both combinations


def two_disks(kappa: float) -> bem.MaxwellMatrix:
    """Two coaxial unit disks at distance kappa (eps = 1), the suite's meshes."""

    def meshes(k):
        s = COARSE.sizes(kappa, k, 1.0)
        return [disk_sheet(1.0, s), disk_sheet(1.0, s, kappa)]

    return bem.converged(meshes, ["a", "b"], 1.0, kappa, COARSE, h_max=COARSE.sizes(kappa, 0, 1.0).h_max)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kappa", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    args = ap.parse_args()
    print(
        f"{'d/a':>6} {'C11-C12':>10} {'Love':>10} {'dev':>8} {'C11+C12':>10} {'Love':>10} {'dev':>8} {'order':>5} {'s':>6}"
    )
    for kappa in args.kappa:
        t0 = time.perf_counter()
        m = two_disks(kappa)
        c = m.matrix
        diff, same = c[0, 0] - c[0, 1], c[0, 0] + c[0, 1]
        ld, ls = closed_forms.love_disks(kappa), closed_forms.love_disks(kappa, same_potential=True)
        dd, ds = diff / ld - 1, same / ls - 1
        verdict = "inside" if max(abs(dd), abs(ds)) <= BOUND else "OUTSIDE"
        print(
            f"{kappa:6.3f} {diff:10.5f} {ld:10.5f} {dd:+8.2%} {same:10.5f} {ls:10.5f} {ds:+8.2%} "
            f"{m.settings['solves'][0]['order']:5d} {time.perf_counter() - t0:6.1f}  {verdict} {BOUND:.1%}"
        )


if __name__ == "__main__":
    main()
