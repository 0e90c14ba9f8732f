"""The comb finger's 2-D side capacitance against the textbook parallel plate: the ratio of the
converged periodic-cell solve (netgen.electrostatics.comb_section, per side at the nominal gap, no
offset) to eps t / g (the textbook comb 2 n eps t L / g per side), for t/g = 1, 2, 5, 20, with and
without a grounded substrate under the fingers.

    .venv/bin/python bench/comb_textbook.py [--gap 2e-6] [--width 2e-6] [--substrate-gap 2e-6] [--ratios 1,2,5,20]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

from netgen.constants import EPS0
from netgen.electrostatics import comb_section


def main() -> None:
    """Print one line per t/g: the 2-D/textbook ratio over a substrate and in free space."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gap", type=float, default=2e-6)
    ap.add_argument("--width", type=float, default=2e-6)
    ap.add_argument("--substrate-gap", type=float, default=2e-6)
    ap.add_argument("--ratios", default="1,2,5,20")
    a = ap.parse_args()
    print(f"finger width {a.width:.3g} m, gap {a.gap:.3g} m, pitch {a.width + a.gap:.3g} m, "
          f"substrate gap {a.substrate_gap:.3g} m; tol {comb_section.SETTINGS['tol']}")
    print(f"{'t/g':>6} {'2-D/textbook (substrate)':>26} {'2-D/textbook (free)':>20} {'s':>6}")
    for r in (float(x) for x in a.ratios.split(",")):
        t0 = time.time()
        cells = [SimpleNamespace(width=a.width, thickness=r * a.gap, pitch=a.width + a.gap, substrate_gap=sg, eps=EPS0)
                 for sg in (a.substrate_gap, None)]
        on, free = (comb_section.textbook_ratio(c) for c in cells)
        print(f"{r:6g} {on:26.4f} {free:20.4f} {time.time() - t0:6.1f}")


if __name__ == "__main__":
    main()
