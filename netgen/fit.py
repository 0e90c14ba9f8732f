"""Analytic capacitance functions C(x) fitted to sampled capacitances.

Variables are the scaled coordinates x_v = q_v / L_v (L_v: touching amplitude), the same
numbers the emitted netlist carries as node voltages. A fit is a polynomial P of total
degree d in x; the capacitance is C = c_ref / P(x) ("inverse": 1/C is nearly affine in
the coordinates of a gap electrode) or C = c_ref * P(x) ("direct"). Derivatives are analytic.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np
from scipy.optimize import least_squares


def monomial_exponents(ncoords: int, degree: int) -> np.ndarray:
    """All exponent vectors of total degree <= `degree`, in a fixed (graded) order."""
    rows = [np.zeros(ncoords, dtype=int)]
    for d in range(1, degree + 1):
        for combo in combinations_with_replacement(range(ncoords), d):
            e = np.zeros(ncoords, dtype=int)
            for v in combo:
                e[v] += 1
            rows.append(e)
    return np.array(rows, dtype=int).reshape(-1, ncoords)


def monomials(x: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """Matrix of monomial values, shape (npoints, nterms), for points x of shape (npoints, ncoords)."""
    x = np.atleast_2d(x)
    out = np.ones((x.shape[0], exponents.shape[0]))
    for v in range(exponents.shape[1]):
        for p in range(1, int(exponents[:, v].max(initial=0)) + 1):
            out[:, exponents[:, v] == p] *= x[:, [v]] ** p
    return out


@dataclass(frozen=True)
class Polynomial:
    """Sparse multivariate polynomial sum_k coeffs[k] * prod_v x_v**exponents[k, v]."""
    exponents: np.ndarray
    coeffs: np.ndarray

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return monomials(x, self.exponents) @ self.coeffs

    def derivative(self, v: int) -> "Polynomial":
        """Analytic partial derivative with respect to x_v."""
        keep = self.exponents[:, v] > 0
        exps = self.exponents[keep].copy()
        coeffs = self.coeffs[keep] * exps[:, v]
        exps[:, v] -= 1
        return Polynomial(exps, coeffs)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dP/dx at points x, shape (npoints, ncoords)."""
        return np.stack([self.derivative(v)(x) for v in range(self.exponents.shape[1])], axis=-1)


@dataclass(frozen=True)
class CapacitanceFit:
    """One fitted capacitance between the moving conductor and an electrode.

    target "plates": C = c_ref * sum_k 1 / P_k(x) (K effective parallel plates; K = 1 is the
    plain fit of 1/C); "inverse": the same with K = 1; "direct": C = c_ref * P_0(x).
    """
    electrode: str
    c_ref: float                        # F, capacitance at x = 0 (sampled)
    target: str
    polys: tuple[Polynomial, ...]
    max_rel_error: float                # on held-out random points inside the sampled box
    rms_rel_error: float
    grid_max_rel_error: float           # on the sampling grid itself

    def value(self, x: np.ndarray) -> np.ndarray:
        """C(x) in farad."""
        if self.target == "direct":
            return self.c_ref * self.polys[0](x)
        return self.c_ref * sum(1.0 / p(x) for p in self.polys)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dC/dx in farad per unit of scaled coordinate, shape (npoints, ncoords)."""
        if self.target == "direct":
            return self.c_ref * self.polys[0].gradient(x)
        out = 0.0
        for p in self.polys:
            v = p(x)
            out = out - p.gradient(x) / (v * v)[:, None]
        return self.c_ref * out

    @property
    def degree(self) -> int:
        return int(max(p.exponents.sum(axis=1).max() for p in self.polys))


def fit_polynomial(x: np.ndarray, y: np.ndarray, degree: int) -> Polynomial:
    """Least-squares polynomial of total degree `degree`, solved in well-scaled variables."""
    exps = monomial_exponents(x.shape[1], degree)
    span = _span(x)
    coeffs, *_ = np.linalg.lstsq(monomials(x / span, exps), y, rcond=None)
    return Polynomial(exps, coeffs / np.prod(span[None, :] ** exps, axis=1))


def _span(x: np.ndarray) -> np.ndarray:
    return np.maximum(np.max(np.abs(x), axis=0), 1e-300)


def _reference(x: np.ndarray, c: np.ndarray) -> float:
    """Sampled capacitance nearest the origin: the fit's natural unit."""
    return float(c[np.argmin(np.sum(x * x, axis=1))])


def _errors(fit: CapacitanceFit, x: np.ndarray, c: np.ndarray, x_check: np.ndarray,
            c_check: np.ndarray) -> CapacitanceFit:
    """The same fit with its held-out and grid errors filled in."""
    held = np.abs(fit.value(x_check) / c_check - 1.0)
    grid = np.abs(fit.value(x) / c - 1.0)
    return CapacitanceFit(fit.electrode, fit.c_ref, fit.target, fit.polys, float(held.max()),
                          float(np.sqrt(np.mean(held**2))), float(grid.max()))


def fit_capacitance(name: str, x: np.ndarray, c: np.ndarray, degree: int, target: str,
                    x_check: np.ndarray, c_check: np.ndarray) -> CapacitanceFit:
    """Fit one capacitance as a single polynomial of C or of 1/C; report held-out errors."""
    c_ref = _reference(x, c)
    if target == "direct":
        poly = fit_polynomial(x, c / c_ref, degree)
    else:
        poly = fit_polynomial(x, c_ref / c, degree)
    draft = CapacitanceFit(name, c_ref, "direct" if target == "direct" else "inverse", (poly,), 0.0, 0.0, 0.0)
    return _errors(draft, x, c, x_check, c_check)


def fit_plates(name: str, x: np.ndarray, c: np.ndarray, initial: np.ndarray, degree: int,
               x_check: np.ndarray, c_check: np.ndarray, max_nfev: int = 60) -> CapacitanceFit:
    """Fit C = c_ref sum_k 1/P_k(x) by least squares on the relative error.

    `initial` (K, 1 + ncoords) holds affine first guesses of the P_k (from physical patches
    of the electrode); higher-degree coefficients start at zero. The Jacobian is analytic.
    """
    c_ref = _reference(x, c)
    exps = monomial_exponents(x.shape[1], degree)
    span = _span(x)
    basis = monomials(x / span, exps)                       # well-scaled design matrix
    k_terms, nterm = initial.shape[0], exps.shape[0]
    start = np.zeros((k_terms, nterm))
    start[:, : 1 + x.shape[1]] = initial * np.concatenate([[1.0], span])[None, :]

    def residual(a: np.ndarray) -> np.ndarray:
        return c_ref * np.sum(1.0 / (basis @ a.reshape(k_terms, nterm).T), axis=1) / c - 1.0

    def jacobian(a: np.ndarray) -> np.ndarray:
        p = basis @ a.reshape(k_terms, nterm).T                # (npts, K)
        w = -c_ref / (p * p) / c[:, None]                      # d residual / d P_k
        return (w[:, :, None] * basis[:, None, :]).reshape(len(c), k_terms * nterm)

    # a capped Levenberg-Marquardt run: the error budget is met long before full convergence
    sol = least_squares(residual, start.ravel(), jac=jacobian, method="lm", max_nfev=max_nfev)
    scale = np.prod(span[None, :] ** exps, axis=1)
    polys = tuple(Polynomial(exps, row / scale) for row in sol.x.reshape(k_terms, nterm))
    return _errors(CapacitanceFit(name, c_ref, "plates", polys, 0.0, 0.0, 0.0), x, c, x_check, c_check)


def sampling_grid(ncoords: int, levels: int, half_range: float) -> np.ndarray:
    """Full tensor grid of `levels` values in [-half_range, half_range] per coordinate."""
    axis = np.linspace(-half_range, half_range, levels)
    mesh = np.meshgrid(*([axis] * ncoords), indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=-1)


def holdout_points(ncoords: int, count: int, half_range: float, seed: int) -> np.ndarray:
    """Uniform random points inside the sampled box (held out from the fit)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-half_range, half_range, size=(count, ncoords))
