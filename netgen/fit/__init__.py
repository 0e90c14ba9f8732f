"""The fit stage: analytic capacitance functions C(x) (netgen.fit.capacitance) and strain
energies U(x) (netgen.fit.energy) as polynomials of the scaled coordinates (netgen.fit.polynomial)."""

from .capacitance import CapacitanceFit, fit_all, fit_capacitance, fit_plates
from .polynomial import Polynomial, monomial_exponents, monomials

__all__ = [
    "CapacitanceFit",
    "Polynomial",
    "fit_all",
    "fit_capacitance",
    "fit_plates",
    "monomial_exponents",
    "monomials",
]
