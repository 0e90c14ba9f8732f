"""What a rounding-level change of the samples does to each example's fitted FUNCTION, against
what it does to the coefficients: the build's plate fits redone from samples perturbed by
1e-15 relative (another BLAS or CPU), then, per electrode, the relative change of the
coefficient vector, the max relative change of C and of its gradient (scaled coordinates,
relative to the largest gradient component) over the held-out points, and those changes as
fractions of the fit's own held-out max and rms relative errors.

    .venv/bin/python bench/fit_function_change.py cantilever cantilever_fb cc_beam calibrated_disk
    .venv/bin/python bench/fit_function_change.py --noise 1e-9 --seeds 5 cantilever cantilever_fb cc_beam
"""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

import numpy as np

from netgen.build import build
from netgen.fit import capacitance as cap
from netgen.structure import load_structure

ROOT = Path(__file__).resolve().parents[1]


def refit(b, i: int, k: int, noise: float, seed: int) -> cap.CapacitanceFit:
    """Electrode i's plate fit at patch grid k from its samples perturbed by `noise` relative."""
    s, x, e = b.structure, b.grid.x, b.electrodes[i]
    c = b.grid.c[:, i] * (1 + noise * np.random.default_rng(seed).standard_normal(len(x)))
    init = cap.patch_guess(s, e, b.mechanics.basis, b.scales, cap.PATCH_GRIDS[k], cap.reference(x, c))
    return cap.fit_plates(
        e.name, cap.FitData(x, c, b.holdout.x, b.holdout.c[:, i], cap.rest_of(b.grid, i)), init, s.fit.degree
    )


def grid_of(fit: cap.CapacitanceFit) -> int:
    """The PATCH_GRIDS index with the fit's term count."""
    return next(k for k, g in enumerate(cap.PATCH_GRIDS) if g[0] * g[1] == len(fit.polys))


def change(name: str, noise: float, seeds: int) -> None:
    """One line per (electrode, seed)."""
    with contextlib.chdir(ROOT):
        b = build(load_structure(f"examples/{name}.toml"))
    x = b.holdout.x
    for i, f in enumerate(b.fits):
        if f.target != "plates":
            continue
        for seed in range(seeds):
            g = refit(b, i, grid_of(f), noise, seed)
            a, a2 = (np.concatenate([p.coeffs for p in h.polys]) for h in (f, g))
            dc = float(np.max(np.abs(g.value(x) / f.value(x) - 1)))
            grad = f.gradient(x)
            dg = float(np.max(np.abs(g.gradient(x) - grad)) / np.max(np.abs(grad)))
            print(
                f"{name:16s} {f.electrode:10s} K={len(f.polys):2d} seed {seed}  coeffs {np.linalg.norm(a2 - a) / np.linalg.norm(a):.1e}"
                f"  C {dc:.1e}  grad {dg:.1e}  C/max_err {dc / max(f.max_rel_error, 1e-300):.1e}"
                f"  C/rms_err {dc / max(f.rms_rel_error, 1e-300):.1e}  grad/rms_err {dg / max(f.rms_rel_error, 1e-300):.1e}",
                flush=True,
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("examples", nargs="+")
    p.add_argument("--noise", type=float, default=1e-15)
    p.add_argument("--seeds", type=int, default=3)
    a = p.parse_args()
    for name in a.examples:
        change(name, a.noise, a.seeds)


if __name__ == "__main__":
    main()
