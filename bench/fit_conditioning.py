"""Conditioning of the plate fits of each example, per patch grid: the condition number of the
least-squares Jacobian at the fit (netgen.fit.capacitance.fit_plates, columns in the scaled
basis x / span), the held-out max relative error, and the relative change of the coefficient
vector when the samples are perturbed by 1e-15 relative (another BLAS or CPU), for a capped
Levenberg-Marquardt run (the build's MAX_NFEV) or a longer one (--max-nfev).

    .venv/bin/python bench/fit_conditioning.py cantilever cantilever_fb cc_beam calibrated_disk
    .venv/bin/python bench/fit_conditioning.py --max-nfev 3000 cantilever
"""

from __future__ import annotations

import argparse
import contextlib
import math
import time
from pathlib import Path

import numpy as np

from netgen.build import build
from netgen.fit import capacitance as cap
from netgen.fit.polynomial import monomials, span
from netgen.structure import load_structure

ROOT = Path(__file__).resolve().parents[1]


def jacobian_condition(fit: cap.CapacitanceFit, x: np.ndarray, c: np.ndarray) -> float:
    """cond of d(C_fit / C - 1) / d(coefficients in the basis x / span) at the fit's coefficients."""
    sp, exps = span(x), fit.polys[0].exponents
    basis, scale = monomials(x / sp, exps), np.prod(sp[None, :] ** exps, axis=1)
    cols = [-(fit.c_ref / (basis @ (p.coeffs * scale)) ** 2 / c)[:, None] * basis for p in fit.polys]
    return float(np.linalg.cond(np.concatenate(cols, axis=1)))


def grids(name: str, max_nfev: int, electrodes: int) -> None:
    """One line per (electrode, patch grid) the build may try."""
    with contextlib.chdir(ROOT):
        b = build(load_structure(f"examples/{name}.toml"))
    s, x = b.structure, b.grid.x
    rng = np.random.default_rng(0)
    for i, e in enumerate(b.electrodes[:electrodes]):
        c, rest = b.grid.c[:, i], cap.rest_of(b.grid, i)
        perturbed = c * (1 + 1e-15 * rng.standard_normal(c.shape))
        for grid in cap.PATCH_GRIDS:
            k = grid[0] * grid[1]
            if k > s.fit.max_terms or k * math.comb(x.shape[1] + s.fit.degree, s.fit.degree) > len(x):
                break
            init = cap.patch_guess(s, e, b.mechanics.basis, b.scales, grid, cap.reference(x, c))
            t0 = time.perf_counter()
            one = cap.fit_plates(
                e.name, cap.FitData(x, c, b.holdout.x, b.holdout.c[:, i], rest), init, s.fit.degree, max_nfev
            )
            dt = time.perf_counter() - t0
            two = cap.fit_plates(
                e.name, cap.FitData(x, perturbed, b.holdout.x, b.holdout.c[:, i], rest), init, s.fit.degree, max_nfev
            )
            a, a2 = (np.concatenate([p.coeffs for p in f.polys]) for f in (one, two))
            print(
                f"{name:16s} {e.name:10s} K={k:2d}  cond(J) {jacobian_condition(one, x, c):8.2g}  "
                f"held-out {one.max_rel_error:.3e}  change {np.linalg.norm(a2 - a) / np.linalg.norm(a):.1e}  "
                f"{dt:.2f} s",
                flush=True,
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("examples", nargs="+")
    p.add_argument("--max-nfev", type=int, default=cap.MAX_NFEV)
    p.add_argument("--electrodes", type=int, default=1, help="electrodes per example")
    a = p.parse_args()
    for name in a.examples:
        grids(name, a.max_nfev, a.electrodes)


if __name__ == "__main__":
    main()
