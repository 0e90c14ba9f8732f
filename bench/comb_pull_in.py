"""Side instability of a lateral comb on converged 2-D field tables, read from an ngspice DC sweep:
tests/electrostatics/test_comb_pull_in.py's comb (30 fingers 2 um wide, 2 um gaps, 20 um overlap,
k = 5 N/m, substrate 2 um below, y only) at each t/g, built on the package's solver settings, and
per ngspice release the circuit's pull-in voltage against the Python MacroModel's (its fitted
curvature), the section table's (2 n L S''(g)), the direct solves' (bench/comb_textbook.py's
pull_in_ratio) and the closed form sqrt(k g^3 / (2 eps n t L)). The tables go to a private cache
(--cache, default a temporary folder); y moves no finger out of plane, so the offset axis is cut
to its 4-point minimum (--offsets). Minutes of CPU per t/g: run under `nice -n 10`.

    nice -n 10 .venv/bin/python bench/comb_pull_in.py [--ratios 2,20] [--offsets 4] [--cache DIR]
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace


def main() -> None:
    """One line per t/g and ngspice release."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ratios", default="2,20")
    ap.add_argument("--offsets", type=int, default=4)
    ap.add_argument("--cache", default=None)
    a = ap.parse_args()
    os.environ["NETGEN_CACHE"] = a.cache or tempfile.mkdtemp(prefix="comb_pull_in-")
    from comb_textbook import pull_in_ratio
    from support import NGSPICE, lateral_comb

    from netgen.build import build
    from netgen.core.constants import EPS0
    from netgen.electrostatics import comb_section
    from netgen.structure import parse_structure

    L0, G, K, N = lateral_comb.L0, lateral_comb.G, lateral_comb.K, lateral_comb.N

    comb_section.GRID = dict(comb_section.GRID, offsets=a.offsets)
    print(f"settings {comb_section.SETTINGS}, grid {comb_section.GRID}, cache {os.environ['NETGEN_CACHE']}")
    for r in (float(x) for x in a.ratios.split(",")):
        t0 = time.process_time()
        b = build(parse_structure(lateral_comb.structure(r), f"comb_t{r:g}.toml"))
        closed = math.sqrt(K * G**3 / (2 * EPS0 * N * r * G * L0))
        python, tables = lateral_comb.model_pull_in(b.model), lateral_comb.table_pull_in(b)
        direct = pull_in_ratio(
            SimpleNamespace(width=2e-6, thickness=r * G, pitch=2e-6 + G, substrate_gap=2e-6, eps=EPS0), 0.1 * G
        )
        print(
            f"t/g = {r:g}: built in {time.process_time() - t0:.0f} s CPU; closed form {closed:.4f} V; "
            f"Python {python / closed:.4f}, tables {tables / closed:.4f}, direct solves {direct:.4f} of it"
        )
        for release in sorted(NGSPICE):
            with tempfile.TemporaryDirectory() as tmp:
                circuit = lateral_comb.circuit_pull_in(b.model, Path(tmp), release, 1.02 * closed)
            print(
                f"  ngspice {release}: circuit {circuit:.4f} V = {circuit / closed:.4f} of the closed form, "
                f"circuit / Python - 1 = {circuit / python - 1:+.2e}"
            )


if __name__ == "__main__":
    main()
