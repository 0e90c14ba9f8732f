"""The physical schema of a model JSON (after netgen.model.validate's names and text): one table of
fields with type, range and the fix per field, and the shape checks of the fitted polynomials
(exponent rows of the model's coordinate count, non-negative integers up to MAX_EXPONENT, one
coefficient per row) and of the stop points. Errors are ModelError (exit 2) naming the file, the
entry and the fix; a document that passes builds a MacroModel whose arithmetic cannot fail."""

from __future__ import annotations

import math
from typing import Any

from .validate import FIX, Checker, shown

MAX_EXPONENT = 24  # a fit's degree is at most 8 per coordinate ([fit] degree); 24 leaves room
MAX_TERMS = 100_000  # monomials in one polynomial
MAX_COEFF = 1e6  # |coefficient| of a fit in scaled coordinates; the examples reach 21
SIDES = ("above", "below", "in_plane")

# (list, field, low, low allowed, high, meaning and fix); list "" = the document itself
FIELDS: tuple[tuple[str, str, float, bool, float, str], ...] = (
    # 1e-12: a femtometre-scale stop; the forms divide by scale^2 and scale^3 (netgen.emit.common.force_gain)
    ("coordinates", "scale", 1e-12, True, 10.0, "the touching amplitude (m or rad), 1e-12 .. 10"),
    ("coordinates", "mass", 0.0, False, 1e6, "the (modal) mass in kg or kg*m^2, > 0"),
    ("coordinates", "stiffness", 0.0, True, 1e15, "the stiffness in N/m or N*m/rad, >= 0"),
    ("coordinates", "damping", 0.0, True, 1e9, "the damping in N*s/m or N*m*s/rad, >= 0"),
    ("coordinates", "frequency_hz", 0.0, True, 1e13, "the resonance in Hz, >= 0"),
    ("electrodes", "gap", 0.0, False, 10.0, "the gap in m, > 0"),
    ("electrodes", "area", 0.0, False, 1e2, "the area in m^2, > 0"),
    ("capacitances", "c_ref", 0.0, False, 1.0, "the reference capacitance in F, > 0"),
    ("capacitances", "max_rel_error", 0.0, True, 1e9, "the fit's error, >= 0"),
    ("capacitances", "rms_rel_error", 0.0, True, 1e9, "the fit's error, >= 0"),
    ("capacitances", "grid_max_rel_error", 0.0, True, 1e9, "the fit's error, >= 0"),
    ("contact", "stiffness", 0.0, True, 1e15, "the stop points' penalty stiffness, >= 0"),
    ("contact", "damping", 0.0, True, 1e9, "the stop points' damping, >= 0"),
    ("contact", "knee", 0.0, False, 1.0, "the clamp knee as a fraction of the rest term, in (0, 1]"),
    ("contact", "floor", 0.0, False, 1.0, "the clamp floor as a fraction of the rest term, in (0, 1]"),
    ("contact", "smoothing", 0.0, False, 1.0, "the penetration smoothing, in (0, 1]"),
)


# the document's entries that are objects where present (MacroModel.from_dict reads them with .get)
OBJECTS = (
    "sampling",
    "report",
    "contact",
    "nonlinear_stiffness",
    "acceleration_port",
    "calibration",
    "layout",
    "inertial_inputs",
    "process",
)


def check(c: Checker, d: dict) -> None:
    """Ranges (FIELDS), choices and shapes of a model document validate.check has passed."""
    for key in OBJECTS:
        if key in d and not isinstance(d[key], dict):
            c.fail(key, f"{shown(d[key])} is not an object", FIX)
    ncoords = len(d["coordinates"])
    sampling = d["sampling"]
    c.number("sampling.samples", sampling.get("samples"), integer=True)
    if not isinstance(sampling.get("design"), str):  # the headers print the design, else the grid's levels
        c.number("sampling.levels", sampling.get("levels"), integer=True)
    for key in ("excluded_touching", "holdout"):  # the headers print them
        c.number(f"sampling.{key}", sampling.get(key), integer=True)
    if "corner_checks" in sampling:
        c.number("sampling.corner_checks", sampling["corner_checks"], integer=True)
    ranged(c, "sampling.range", sampling.get("range"), 0.0, False, 10.0, "the sampled half-width in units of L, > 0")
    per = sampling.get("coordinate_range")
    if per is not None:
        if not isinstance(per, dict):
            c.fail("sampling.coordinate_range", f"{shown(per)} is not an object of coordinate half-widths", FIX)
        for name, value in per.items():
            ranged(c, f"sampling.coordinate_range.{name}", value, 0.0, False, 10.0, "a half-width in units of L, > 0")
    if "tolerance" in sampling:  # the fit tolerance the headers compare each fit's error with
        ranged(c, "sampling.tolerance", sampling["tolerance"], 0.0, False, 1e9, "the fit tolerance (relative), > 0")
    report = d.get("report", {})
    if not isinstance(report, dict):
        c.fail("report", "must be an object of per-stage objects", FIX)
    for key, value in report.items():  # the emitters read each stage's entries (netgen.emit.common)
        if not isinstance(value, dict):
            c.fail(f"report.{key}", f"{shown(value)} is not an object", FIX)
    if ncoords == 0:
        c.fail("coordinates", "no coordinates", FIX)
    for e, row in enumerate(d["electrodes"]):
        c.choice(f"electrodes[{e}].side", row.get("side"), SIDES)
    if not d["capacitances"] or len(d["capacitances"]) != len(d["electrodes"]):
        c.fail(
            "capacitances",
            f"{len(d['capacitances'])} capacitance fits for {len(d['electrodes'])} electrodes",
            "one fit per electrode, in the electrodes' order; " + FIX,
        )
    for e, fit in enumerate(d["capacitances"]):
        terms = fit.get("terms")
        if not isinstance(terms, list) or not terms:
            c.fail(f"capacitances[{e}].terms", "must be a non-empty list of polynomials", FIX)
        for t, term in enumerate(terms):
            polynomial(c, f"capacitances[{e}].terms[{t}]", term, ncoords)
            if fit.get("target") == "plates":
                plate_at_rest(c, f"capacitances[{e}].terms[{t}]", term)
        if "factor" in fit:  # a process point's state factor (netgen.sweep.point)
            polynomial(c, f"capacitances[{e}].factor", fit["factor"], ncoords)
    contact = d.get("contact") or {}
    if not isinstance(contact, dict):
        c.fail("contact", "must be an object (empty: no contact model)", FIX)
    for lst, key, low, closed, high, meaning in FIELDS:
        rows = ([contact] if contact else []) if lst == "contact" else d[lst]
        for i, row in enumerate(rows):
            where = f"{lst}.{key}" if lst == "contact" else f"{lst}[{i}].{key}"
            ranged(c, where, row.get(key), low, closed, high, meaning)
    points(c, contact, ncoords)
    nonlinear = d.get("nonlinear_stiffness")
    if nonlinear:
        if not isinstance(nonlinear, dict) or not isinstance(nonlinear.get("energy_J"), dict):
            c.fail("nonlinear_stiffness.energy_J", "must be an object with exponents and coeffs", FIX)
        polynomial(c, "nonlinear_stiffness.energy_J", nonlinear["energy_J"], ncoords)
    participation = (d.get("acceleration_port") or {}).get("participation", [])
    if not isinstance(participation, list) or len(participation) not in (0, ncoords):
        c.fail("acceleration_port.participation", f"must list one number per coordinate ({ncoords})", FIX)
    for i, g in enumerate(participation):
        c.number(f"acceleration_port.participation[{i}]", g)


def ranged(c: Checker, where: str, value: Any, low: float, closed: bool, high: float, meaning: str) -> None:
    """A finite number in (low, high] (or [low, high] when `closed`)."""
    c.number(where, value)
    if not ((value >= low) if closed else (value > low)) or value > high:
        lo = "[" if closed else "("
        c.fail(where, f"{value!r} lies outside {lo}{low:g}, {high:g}]", f"give {meaning}; " + FIX)


def polynomial(c: Checker, where: str, term: Any, ncoords: int) -> None:
    """{"exponents": rows of ncoords integers 0..MAX_EXPONENT, "coeffs": one finite number per row}."""
    if not isinstance(term, dict):
        c.fail(where, "must be an object with exponents and coeffs", FIX)
    exps, coeffs = term.get("exponents"), term.get("coeffs")
    if not isinstance(exps, list) or not exps or len(exps) > MAX_TERMS:
        c.fail(f"{where}.exponents", f"must be a list of 1 to {MAX_TERMS} exponent rows", FIX)
    for r, row in enumerate(exps):
        if not isinstance(row, list) or len(row) != ncoords:
            c.fail(
                f"{where}.exponents[{r}]",
                f"{row!r:.60} is not a row of {ncoords} exponents (one per coordinate)",
                FIX,
            )
        for k, x in enumerate(row):
            if isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= MAX_EXPONENT:
                c.fail(
                    f"{where}.exponents[{r}][{k}]",
                    f"{x!r:.40} is not an integer exponent in 0..{MAX_EXPONENT}",
                    "exponents are whole powers of the scaled coordinates; " + FIX,
                )
    if not isinstance(coeffs, list) or len(coeffs) != len(exps):
        n = len(coeffs) if isinstance(coeffs, list) else "no list of"
        c.fail(f"{where}.coeffs", f"{n} coefficients for {len(exps)} exponent rows", "one per row; " + FIX)
    for k, x in enumerate(coeffs):
        c.number(f"{where}.coeffs[{k}]", x)
        if abs(x) > MAX_COEFF:
            c.fail(
                f"{where}.coeffs[{k}]",
                f"{x:g} is beyond {MAX_COEFF:g}: a fit of scaled coordinates (|q| <= 1) has no such term",
                FIX,
            )


def plate_term_at_rest(term: dict) -> float:
    """P(0) of a plate term: the sum of its constant rows' coefficients."""
    return sum(x for row, x in zip(term["exponents"], term["coeffs"]) if not any(row))


def plate_at_rest(c: Checker, where: str, term: dict) -> None:
    """A plate term's gap polynomial P is positive at rest (1/P is its capacitance share)."""
    p0 = plate_term_at_rest(term)
    if not p0 > 0.0:
        c.fail(f"{where}.coeffs", f"the plate term's P at rest is {p0:g}, not > 0 (1/P would be infinite)", FIX)


def points(c: Checker, contact: dict, ncoords: int) -> None:
    """Each stop point: a gap > 0 and a direction of ncoords numbers (its electrode is a label,
    checked as text by netgen.model.validate)."""
    pts = contact.get("points", [])
    if not isinstance(pts, list) or not all(isinstance(p, dict) for p in pts):
        c.fail("contact.points", "must be a list of objects", FIX)
    for i, p in enumerate(pts):
        where = f"contact.points[{i}]"
        ranged(c, f"{where}.gap", p.get("gap"), 0.0, False, 10.0, "the stop's gap in m, > 0")
        a = p.get("a")
        if not isinstance(a, list) or len(a) != ncoords:
            c.fail(f"{where}.a", f"must list one number per coordinate ({ncoords})", FIX)
        for k, x in enumerate(a):
            c.number(f"{where}.a[{k}]", x)
        if not any(math.isfinite(x) and x != 0 for x in a):
            c.fail(f"{where}.a", "is all zeros: the stop point is reached by no motion", FIX)
        if not isinstance(p.get("electrode"), str):
            c.fail(f"{where}.electrode", "must name the electrode the stop faces (the netlists label it)", FIX)
