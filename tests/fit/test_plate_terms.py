"""A plate-sum fit is physical only if every term 1/P_k is a positive capacitance wherever the
fit was sampled or checked (netgen.fit.capacitance.physical): a term that turns negative puts a
pole P_k = 0 between the samples. Hand-made polynomials: 1 - x/2 vanishes at x = 2."""

from __future__ import annotations

import numpy as np

from netgen.core.errors import StructureError
from netgen.fit.capacitance import CapacitanceFit, physical, refuse_unphysical
from netgen.fit.polynomial import Polynomial
from netgen.structure import parse_structure
from tests.fit.test_adaptive import PISTON

EXPS = np.array([[0], [1]])


def fit_of(*coeffs) -> CapacitanceFit:
    """C = sum_k 1 / (a_k + b_k x) in units of c_ref = 1 F."""
    return CapacitanceFit("e", 1.0, "plates", tuple(Polynomial(EXPS, np.array(c, float)) for c in coeffs), 0, 0, 0)


def test_a_sum_of_positive_plates_is_physical():
    x = np.linspace(-1, 1, 11)[:, None]
    assert physical(fit_of([1.0, -0.5], [2.0, 0.3]), x, x)


def test_a_term_crossing_zero_inside_the_points_is_not():
    """1 - x/2 is negative at x = 3: the term's pole at x = 2 lies among the points."""
    x = np.linspace(0, 3, 7)[:, None]
    f = fit_of([1.0, -0.5], [2.0, 0.3])
    assert not physical(f, x[:4], x[4:])  # the check points alone reveal it
    assert physical(f, x[:4], x[:4])


def test_a_model_with_such_a_term_is_refused_naming_the_electrode_and_the_fix():
    s = parse_structure(PISTON.format(sampling="levels = 3"), "piston3.toml")
    x = np.linspace(0, 3, 7)[:, None]
    refuse_unphysical(s, [fit_of([2.0, 0.3])], x, x)  # physical: nothing said
    try:
        refuse_unphysical(s, [fit_of([1.0, -0.5])], x[:4], x[4:])
    except StructureError as exc:
        text = str(exc)
    else:
        raise AssertionError("not refused")
    assert "piston3.toml" in text and "electrode e" in text and "sampling.range" in text and "narrow" in text
