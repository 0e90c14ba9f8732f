"""The state-dependent part of a comb's capacitance ratio under a process parameter (an Axis: etch,
netgen.model.process.capacitance_laws, or tscale, thickness_capacitance): C(q; etch) = pc(etch)
(1 + u P1(xs) + u^2 P2(xs)) C(q + shift etch; 0), u = etch / 1 um (tscale: C(q; t) = pc(t) (1 + u P1
+ u^2 P2) C(q; 1), u = t - 1), xs = q / L the model's scaled state (unshifted: every form has it), P1
and P2 polynomials of total degree DEGREE without a constant term (the ratio pc is fitted at rest).

What it carries: after the shifts (the geometric one and netgen.model.etch_combs' effective part
across the fingers) a field2d comb's ratio C(q; etch) / (pc C(q + shift etch; 0)) still depends on
the state, even in the fingers' out-of-plane offset (z and the tilts: the narrower finger's fringe)
and more where that meets a closed gap (accelerometer_xyz: 3.1e-3 over the fit box at -+0.1 um). A
ratio in etch alone cannot carry it; a polynomial in the state can, and its derivative enters the
forces by the product rule, which the emitters render. Why u and u^2: the residual is not linear in
etch (the best shift at each etch apart runs from 0.135 to 0.24 per m of etch across the range), and
a term linear in u alone left 2.0e-3 on accelerometer_xyz where the two leave 8e-4 (degree 2).
Under tscale the fringe above and below the fingers does not grow with t while the faces do, so
the ratio falls with the gap and the out-of-plane offset (accelerometer_xyz: 9.4e-3 at 0.9 / 1.1).

P1, P2 are one least-squares fit over the parameter's points other than the nominal of the mechanics' re-runs and
FIT_POINTS points of the fit box other than the points the law's stated error is checked at (held
out); points where a gap closes (nan) are left out. Electrodes whose residual stays below FLOOR get
none (the textbook combs: 9.3e-5, their law is a shift to that).

Why degree 3 (83 monomials, 166 coefficients a factor, against 27 and 54 at degree 2): on
accelerometer_xyz at 400 fresh points of the fit box (bench/process_cross.py) the tscale law is 2.5e-3
off at degree 2, 7.8e-4 at 3 (its stated figure, with the box's corners, 3.3e-3 -> 1.4e-3), the etch
law 9.8e-4 -> 3.2e-4, and with both parameters the product's cross factor (cross_laws, below) leaves
3.9e-3 at degree 2, 1.1e-3 at 3.

With tscale and etch both declared the product of the two laws, each fitted with the other parameter
nominal, misses what moves with both (the finger's fringe share depends on its width and thickness
together; the plain product is 3.5e-3 off at the (tscale, etch) box's corners at degree 3, 4.6e-3 at
2, mostly odd in tscale - 1: at degree 2 the residuals at 0.9 and 1.1 correlate at -0.85). cross_laws fits the factor 1 +
(tscale - 1) (u Q1(xs) + u^2 Q2(xs)) to it at the corners (netgen.model.etch_cross.cross_capacitance).

A cantilever's tip overhanging its electrode (netgen.model.etch_knots.tip_knots) gets the same factor
in v = (k - u)+ instead of u (the law marked "below": k), so that it is 1 where the beam ends inside
the electrode and the law is exact there (netgen.model.process.capacitance_laws, TIP_DEGREE).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..electrostatics.sampling import check_points
from ..fit.polynomial import Polynomial, monomial_exponents, monomials
from .etch_knots import ETCH_UNIT, knot_value

DEGREE = 3  # total degree of P1, P2 in the scaled state (why 3: the module docstring)
FIT_POINTS = 256  # fit-box points P is fitted at, drawn after the points the law is checked at
FLOOR = 2e-4  # largest |residual| of an electrode's shift-and-ratio law below which it gets no P


@dataclass(frozen=True)
class Axis:
    """The process parameter a state factor is fitted over: u = (value - nominal) / unit, and its
    ratio cubic's variable value / unit (etch: etch / 1 um, nominal 0; tscale: tscale, nominal 1)."""

    name: str
    nominal: float
    unit: float

    def u(self, value: float) -> float:
        """The factor's u at the parameter's value."""
        return (value - self.nominal) / self.unit


ETCH = Axis("etch", 0.0, ETCH_UNIT)
TSCALE = Axis("tscale", 1.0, 1.0)


def state_laws(
    s: Any,
    extract: Callable,
    etched: Callable,
    laws: dict[int, tuple[np.ndarray, list[float]]],
    etches: tuple[float, ...],
    skip: int,
    degree: int = DEGREE,
    powers: int = 2,
    axis: Axis = ETCH,
    knots: tuple[float, ...] = (),
    below: dict[int, float] | None = None,
) -> dict[int, dict]:
    """electrode index -> {"exponents", "coeffs": [P1's, P2's]} for the electrodes of `laws` (index ->
    (shift per unit of the parameter in SI per coordinate, ratio cubic)) of `s`, from
    `extract(structure, n, offset)` (netgen.build.capacitance_sampler) at `etched(s, value)` for the
    `etches` (the `axis` parameter's values) other than the nominal, on the rows after `skip` + 1 (and
    rest); `degree` and `powers` (1: u P1 alone, P2 = 0) for bench/etch_state.py's comparison; `knots`
    the ratios' (netgen.model.etch_knots); `below` (index -> knot k, etch / 1 um): that electrode's
    factor is in (k - u)+ instead of u (a cantilever's tip overhanging the electrode: the state
    dependence exists on that side of k only), marked "below" in its law."""
    if not laws:
        return {}
    n = skip + FIT_POINTS
    rows = np.r_[0, np.arange(skip + 1, n + 1)]
    xs = check_points(s.sampling, n, len(next(iter(laws.values()))[0]))[rows]
    exps = monomial_exponents(xs.shape[1], degree)
    exps = exps[exps.sum(axis=1) > 0]
    basis = monomials(xs, exps)
    points = [e for e in etches if e != axis.nominal]
    moved = {e: extract(etched(s, e), n)[rows] for e in points}
    memo: dict[tuple, np.ndarray] = {}

    def drawn(offset: np.ndarray) -> np.ndarray:
        """The drawn structure's capacitances moved by `offset` (one extraction per distinct offset)."""
        key = tuple(offset.tolist())
        if key not in memo:
            memo[key] = extract(s, n, offset)[rows]
        return memo[key]

    out: dict[int, dict] = {}
    for k, (v, ratio) in laws.items():
        with np.errstate(divide="ignore", invalid="ignore"):  # touching points: nan, left out
            r = np.array(
                [
                    moved[e][:, k] / (ratio_at(ratio, e, axis, knots) * drawn(v * (e - axis.nominal))[:, k]) - 1.0
                    for e in points
                ]
            )
        ok = np.all(np.isfinite(r), axis=0)
        if np.max(np.abs(r[:, ok])) < FLOOR:
            continue
        k_below = (below or {}).get(k)
        u = np.array([axis.u(e) if k_below is None else max(k_below - axis.u(e), 0.0) for e in points])
        design = np.concatenate([np.hstack([ui**j * basis[ok] for j in range(1, powers + 1)]) for ui in u])
        coef, *_ = np.linalg.lstsq(design, r[:, ok].ravel(), rcond=None)
        m = len(exps)
        second = coef[m:] if powers == 2 else np.zeros(m)
        out[k] = {"exponents": exps.tolist(), "coeffs": [coef[:m].tolist(), second.tolist()]}
        out[k] |= {"below": k_below} if k_below is not None else {}
    return out


def ratio_at(ratio: list[float], etch: float, axis: Axis = ETCH, knots: tuple[float, ...] = ()) -> float:
    """A ratio cubic in the value / unit (with the truncated powers of `knots` where it has them,
    netgen.model.etch_knots) at the `axis` parameter's value `etch` (etch: m)."""
    u = etch / axis.unit
    if len(ratio) > 4:
        return knot_value(ratio, u, knots)
    return float(np.dot(ratio[:4], [1.0, u, u * u, u**3]))


def state_factor(law: dict, xs: np.ndarray, etch: float, axis: Axis = ETCH) -> np.ndarray:
    """1 + u P1(xs) + u^2 P2(xs) at scaled states xs (npoints, ncoords) and the `axis` parameter's value:
    the factor the emitters render; a law marked "below" k is in (k - u)+ (state_laws)."""
    return state_polynomial(law, etch, axis)(np.atleast_2d(xs))


def state_polynomial(law: dict, value: float, axis: Axis = ETCH) -> Polynomial:
    """The factor state_factor evaluates, 1 + u P1(xs) + u^2 P2(xs) at the `axis` parameter's value, as
    one polynomial in xs (netgen.sweep.point puts it on a process point's capacitance fit)."""
    u = law_u(law, value, axis)
    return weighted_polynomial(law, u, u * u)


def weighted_polynomial(law: dict, w1: float, w2: float) -> Polynomial:
    """1 + w1 P1(xs) + w2 P2(xs) as one polynomial in xs (a cross law's constant row folded into the 1)."""
    exps = np.array(law["exponents"], dtype=int)
    coeffs = w1 * np.array(law["coeffs"][0]) + w2 * np.array(law["coeffs"][1])
    constant = exps.sum(axis=1) == 0
    return Polynomial(
        np.vstack([np.zeros((1, exps.shape[1]), dtype=int), exps[~constant]]),
        np.r_[1.0 + float(np.sum(coeffs[constant])), coeffs[~constant]],
    )


def cross_weights(tscale: float, etch: float) -> tuple[float, float]:
    """The cross factor's weights (tscale - 1) u and (tscale - 1) u^2, u = etch / 1 um (cross_laws)."""
    u = ETCH.u(etch)
    return (tscale - 1.0) * u, (tscale - 1.0) * u * u


def cross_factor(law: dict, xs: np.ndarray, tscale: float, etch: float) -> np.ndarray:
    """1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs)) at scaled states xs (npoints, ncoords) (cross_laws)."""
    return weighted_polynomial(law, *cross_weights(tscale, etch))(np.atleast_2d(xs))


def cross_laws(
    xs: np.ndarray, residuals: dict[tuple[float, float], np.ndarray], degree: int = DEGREE
) -> dict[int, dict]:
    """electrode index -> {"exponents", "coeffs": [Q1, Q2]} of the cross factor 1 + (tscale - 1) (u
    Q1(xs) + u^2 Q2(xs)) from the product laws' residuals C / (pc_t S_t pc_e S_e C0(xe)) - 1 at the
    (tscale, etch) points (npoints, nelectrodes each) over the scaled states xs: least squares, touching
    points (nan) left out; electrodes whose residual stays below FLOOR get none. Q1, Q2 keep their
    constant (the two ratios pc are fitted apart at rest, so their product is not exact there)."""
    exps = monomial_exponents(xs.shape[1], degree)
    basis = monomials(xs, exps)
    points = list(residuals)
    r = np.array([residuals[p] for p in points])  # (points, npoints, nelectrodes)
    out: dict[int, dict] = {}
    for k in range(r.shape[2]):
        rk = r[:, :, k]
        ok = np.all(np.isfinite(rk), axis=0)
        if np.max(np.abs(rk[:, ok]), initial=0.0) < FLOOR:
            continue
        design = np.concatenate([np.hstack([w * basis[ok] for w in cross_weights(*p)]) for p in points])
        coef, *_ = np.linalg.lstsq(design, rk[:, ok].ravel(), rcond=None)
        m = len(exps)
        out[k] = {"exponents": exps.tolist(), "coeffs": [coef[:m].tolist(), coef[m:].tolist()]}
    return out


def law_u(law: dict, value: float, axis: Axis = ETCH) -> float:
    """The variable a state law is in at the `axis` parameter's value: u, or (k - u)+ for a law marked
    "below" k (an overhanging tip's, state_laws)."""
    return axis.u(value) if "below" not in law else max(law["below"] - axis.u(value), 0.0)
