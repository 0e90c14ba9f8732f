"""The combs' etch state factor's form (netgen.model.etch_state) against its alternatives on
accelerometer_xyz's field2d combs: the law's largest error against the etched extractor at points
of the fit box held out of the fit (the 32 the stated error is checked at and 200 drawn after the
fit's), at the four nonzero etch points, without a factor, with u P1 alone and with u P1 + u^2 P2, of
degree 2 (kept) and 3. The figures docs/process.md and CHANGELOG.md quote. Run from the repository root:
    .venv/bin/python bench/etch_state.py
"""

from __future__ import annotations

import time

import numpy as np
from support import process_cases

from netgen.build import build_model, capacitance_sampler
from netgen.electrostatics.sampling import check_points
from netgen.mechanics import mechanics
from netgen.model.etch_state import FIT_POINTS, ratio_at, state_factor, state_laws
from netgen.model.process import CAPACITANCE_POINTS, etch_points, etched
from netgen.structure import parse_structure

HELD = 200  # held-out points drawn after the fit's


def main() -> None:
    """Print the held-out errors of each variant (largest over the combs and etch points)."""
    t0 = time.process_time()
    text = process_cases.xyz_text(process='[process]\nparameters = ["etch"]\n')
    s = parse_structure(text.replace('comb_model = "textbook"', 'comb_model = "field2d"'), "xyz.toml")
    model = build_model(s)
    extract = capacitance_sampler(s, mechanics(s), model.scales)
    names = [f.electrode for f in model.capacitances]
    coords = [c.name for c in model.coordinates]
    laws = {
        names.index(r["electrode"]): (np.array([r["shift"].get(q, 0.0) for q in coords]), r["ratio"])
        for r in model.process["etch"]["capacitance"]
        if "state" in r
    }
    points = [e for e in etch_points(s.process) if e != 0.0]
    n = CAPACITANCE_POINTS + FIT_POINTS + HELD
    held = np.r_[np.arange(1, CAPACITANCE_POINTS + 1), np.arange(CAPACITANCE_POINTS + FIT_POINTS + 1, n + 1)]
    xs = check_points(s.sampling, n, len(coords))[held]
    moved = {e: extract(etched(s, e), n)[held] for e in points}
    residual = {
        (k, e): moved[e][:, k] / (ratio_at(r, e) * extract(s, n, v * e)[held, k])
        for k, (v, r) in laws.items()
        for e in points
    }
    print(f"accelerometer_xyz field2d: {len(laws)} combs, build and extraction {time.process_time() - t0:.1f} s CPU")
    none = max(float(np.nanmax(np.abs(x - 1.0))) for x in residual.values())
    print(f"  held-out law error without a state factor: {none:.2e}")
    for degree in (2, 3):
        for powers in (1, 2):
            fits = state_laws(s, extract, etched, laws, tuple(points), CAPACITANCE_POINTS, degree, powers)
            worst = max(
                float(np.nanmax(np.abs(state_factor(fits[k], xs, e) / residual[k, e] - 1.0))) for k, e in residual
            )
            terms = len(fits[next(iter(fits))]["exponents"]) * powers
            label = "u P1" if powers == 1 else "u P1 + u^2 P2"
            print(f"  degree {degree}, {label:14s} ({terms:3d} coefficients a comb): held-out error {worst:.2e}")


if __name__ == "__main__":
    main()
