"""netgen sweep's model at a process point (netgen.sweep.point.at_point) against the law the netlists
render (netgen.model.process.capacitance_at), with the field2d combs' state factor on its fits and
without it (as it was): the figures quoted in docs/process.md and CHANGELOG.md. accelerometer_xyz with
its field2d combs (process_cases.xyz_text under etch, xyz_thick under tscale), 100 points of the box
(+-0.15): the largest |C / C_law - 1| and, per electrode, the largest |dC/dq - its law| over the
largest |dC/dq| of the law (the law's slopes from a central difference of capacitance_at, step 1e-5).
Run from the repository root:
    .venv/bin/python bench/sweep_state_factor.py
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from support import process_cases

from netgen.build import build_model
from netgen.model.process import capacitance_at
from netgen.structure import parse_structure
from netgen.sweep.point import at_point

H = 1e-5


def field2d(text: str) -> str:
    return text.replace('comb_model = "textbook"', 'comb_model = "field2d"')


def law_slopes(model, x: np.ndarray, param: str, value: float) -> np.ndarray:
    """dC/dxs of the law by a central difference (npoints, nelectrodes, ncoords)."""
    out = []
    for v in range(model.ncoords):
        e = H * np.eye(model.ncoords)[v]
        up, down = capacitance_at(model, x + e, **{param: value}), capacitance_at(model, x - e, **{param: value})
        out.append((up - down) / (2 * H))
    return np.stack(out, axis=-1)


def figures(model, param: str, value: float) -> None:
    x = np.random.default_rng(1).uniform(-0.15, 0.15, (100, model.ncoords))
    law, slopes = capacitance_at(model, x, **{param: value}), law_slopes(model, x, param, value)
    point = at_point(model, {param: value})
    bare = dataclasses.replace(point, capacitances=[dataclasses.replace(f, factor=None) for f in point.capacitances])
    for name, m in (("with the factor", point), ("without (before)", bare)):
        c, g = m.capacitance(x), m.capacitance_gradient(x) * m.scales
        dc = float(np.max(np.abs(c / law - 1)))
        dg = float(np.max(np.max(np.abs(g - slopes), axis=(0, 2)) / np.max(np.abs(slopes), axis=(0, 2))))
        print(f"{param} {value:g}  {name:17s}  C {dc:.2g}  dC/dq {dg:.2g}")


def main() -> None:
    t = time.perf_counter()
    etch = build_model(
        parse_structure(field2d(process_cases.xyz_text(process='[process]\nparameters = ["etch"]\n')), "xyz.toml")
    )
    thick = build_model(
        parse_structure(field2d(process_cases.xyz_thick(process='\n[process]\nparameters = ["tscale"]\n')), "xyz.toml")
    )
    print(f"builds {time.perf_counter() - t:.0f} s (dC/dq: the law's by difference, truncation and rounding ~1e-9)")
    for value in (-1e-7, 1e-7):
        figures(etch, "etch", value)
    for value in (0.9, 1.1):
        figures(thick, "tscale", value)


if __name__ == "__main__":
    main()
