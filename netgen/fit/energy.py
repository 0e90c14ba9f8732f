"""The nonlinear strain energy U(q) of a conductor (netgen.mechanics.base.StrainEnergy) as a
polynomial of the scaled coordinates, and its MacroModel entry (the emitters' restoring force
-dU/dq)."""

from __future__ import annotations

import numpy as np

from ..electrostatics.sampling import sampling_grid
from .polynomial import Polynomial, monomial_exponents, monomials


def fit_energy(
    energy, scales: np.ndarray, levels: int = 5, half_range: float = 1.0, degrees: tuple[int, ...] = (4,)
) -> tuple[Polynomial, dict]:
    """Least-squares polynomial U(xs) (J) of the scaled coordinates xs = q / scale, with monomials
    of the given total degrees only, on a levels^n grid over +-half_range (and a check at random
    points). Returns the polynomial and its fit report."""
    n = len(scales)
    exps = monomial_exponents(n, max(degrees))
    exps = exps[np.isin(exps.sum(axis=1), degrees)]
    x = sampling_grid(n, levels, half_range)
    u = energy(x * scales)
    coef, *_ = np.linalg.lstsq(monomials(x, exps), u, rcond=None)
    keep = np.abs(coef) > 1e-9 * np.max(np.abs(coef)) if np.any(coef) else np.zeros(len(coef), bool)
    poly = Polynomial(exps[keep], coef[keep])  # drop terms at rounding level (symmetry zeros)
    check = np.random.default_rng(7).uniform(-half_range, half_range, (200, n))
    ref = energy(check * scales)
    top = float(np.max(np.abs(u)))
    err = float(np.max(np.abs(poly(check) - ref))) / top if top > 0 else 0.0
    return poly, {
        "levels": levels,
        "range": half_range,
        "samples": int(len(x)),
        "degrees": list(degrees),
        "max_error_rel_to_peak": err,
    }


def energy_entry(poly: Polynomial, description: str, report: dict) -> dict:
    """The JSON-ready nonlinear stiffness entry: U(xs) in J as a polynomial of the scaled states."""
    return {
        "energy_J": {"exponents": poly.exponents.tolist(), "coeffs": [float(v) for v in poly.coeffs]},
        "variables": "xs (scaled coordinates q / scale)",
        "force": "F_v = -(1/scale_v) dU/dxs_v (N), added to -K q",
        "description": description,
        "fit": report,
    }
