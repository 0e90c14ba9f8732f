"""Multivariate polynomials in the scaled coordinates x_v = q_v / L_v (L_v: touching amplitude,
the numbers the emitted netlist carries as node voltages): monomial bases, sparse polynomials
with analytic derivatives, and well-scaled least squares."""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np


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

    def derivative(self, v: int) -> Polynomial:
        """Analytic partial derivative with respect to x_v."""
        keep = self.exponents[:, v] > 0
        exps = self.exponents[keep].copy()
        coeffs = self.coeffs[keep] * exps[:, v]
        exps[:, v] -= 1
        return Polynomial(exps, coeffs)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dP/dx at points x, shape (npoints, ncoords)."""
        return np.stack([self.derivative(v)(x) for v in range(self.exponents.shape[1])], axis=-1)

    def times(self, other: Polynomial) -> Polynomial:
        """The product P Q as a polynomial (every pair of monomials; like powers summed)."""
        terms: dict[tuple[int, ...], float] = {}
        for ea, ca in zip(self.exponents, self.coeffs):
            for eb, cb in zip(other.exponents, other.coeffs):
                key = tuple(int(v) for v in ea + eb)
                terms[key] = terms.get(key, 0.0) + float(ca) * float(cb)
        keys = sorted(terms)
        return Polynomial(
            np.array(keys, dtype=int).reshape(-1, self.exponents.shape[1]), np.array([terms[k] for k in keys])
        )


def fit_polynomial(x: np.ndarray, y: np.ndarray, degree: int) -> Polynomial:
    """Least-squares polynomial of total degree `degree`, solved in well-scaled variables."""
    exps = monomial_exponents(x.shape[1], degree)
    sp = span(x)
    coeffs, *_ = np.linalg.lstsq(monomials(x / sp, exps), y, rcond=None)
    return Polynomial(exps, coeffs / np.prod(sp[None, :] ** exps, axis=1))


def span(x: np.ndarray) -> np.ndarray:
    """Largest |x| per coordinate (never 0): the scaling of a well-conditioned design matrix."""
    return np.maximum(np.max(np.abs(x), axis=0), 1e-300)
