"""netgen sweep's model at a process point (netgen.sweep.point.at_point) carries the field2d combs'
state factor 1 + u P1(xs) + u^2 P2(xs) (netgen.model.etch_state) as each comb fit's factor
(CapacitanceFit.factor), on accelerometer_xyz with its field2d combs under etch (-0.1 / 0.1 um) and
tscale (0.9 / 1.1) (the models of tests/emit/test_process_etch_field2d_forms.py and
tests/model/test_process_tscale_combs.py, built once per module).

Tolerances:
- C and dC/dq at 100 points of the box (+-0.15) against the law as netgen.model.process.capacitance_at
  evaluates it (C) and as the emitters render it, r (F dC0(x + d) + C0(x + d) dF) composed here from the
  nominal fits and the law's P1, P2 (dC/dq): the same real function by two routes, each within the
  running-error bound (Higham, Accuracy and Stability of Numerical Algorithms, sec. 3.1) of `rounding`:
  a polynomial's value within gamma_n times its absolute-coefficient polynomial at |x| + |d| (d the
  shift), n = M + 7 deg + 7 (M monomials summed; deg multiplications a monomial and deg the rounded
  x + d, one the coefficient; the re-expanded coefficients of point.shift, up to deg + 1 products of
  deg + 2 roundings, for each of the two shifted coordinates), carried through 1/P, the factor and the
  product rule to first order, so the two routes agree within twice that bound (no clamp is active at
  the points: asserted).
- dC/dq against a central difference of the point model's own C, step h = 1e-5 in xs: truncation h^2/6
  max |C'''| over +-h, bounded from the point fit's own polynomials (a term 1/P with P quadratic
  along x_v: |(1/P)'''| <= 6 |P'| |P''| / P^3 + 6 |P'|^3 / P^4, with P's least value and |P'|'s
  largest over the step; the factor F a polynomial: C''' = r c (F f''' + 3 F' f'' + 3 F'' f' + F''' f),
  each derivative of F bounded over the step by its Taylor series, exact to F's degree), rounding
  the two C's bound over 2h, the step's own rounding u (|x| + h) / h times |dC/dx|, and the point
  model's gradient's bound.
- end to end: the .lib (ngspice 39 and 46) at etch -0.1 um, z and the tilts held by force inputs,
  5 V on xp_t: its C from .ac without bias against the point model's C at the .op's state (1e-9, the
  .ac's round-off, tests/emit/test_process_etch_field2d_forms.check_rest) and its forces on x, y,
  rot_z (K(etch) L^2 xs at the .op) against 1/2 V^2 dC/dxs of the point model (F2D_TOL, derived there
  for the law's five-point difference against the same forms: the point model is the law to the
  round-off above, and its analytic gradient has no truncation); the point model without the factor
  is seen (more than 1e3 F2D_TOL off).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from netgen import emit
from netgen.emit import ngspice as emit_ngspice
from netgen.fit.polynomial import Polynomial, monomial_exponents
from netgen.model.etch_state import DEGREE, ETCH, TSCALE
from netgen.model.process import capacitance_at
from netgen.model.process_values import ratio_value
from netgen.sim.ngspice import run_ngspice
from netgen.sweep.point import at_point
from tests.emit.test_process_etch_field2d_forms import (  # noqa: F401  (xyz registers the fixture)
    F2D_TOL,
    OUT_OF_PLANE,
    STATE_ETCH,
    VOLTS,
    form_slopes,
    plot_of,
    state_deck,
    state_of,
    xyz,
)
from tests.model.test_process_tscale_combs import nominal2d  # noqa: F401  (registers the fixture)

U = 2.0**-53  # unit round-off
POINTS = [("etch", -1e-7), ("etch", 1e-7), ("tscale", 0.9), ("tscale", 1.1)]
H = 1e-5  # central difference step in xs


def gamma(n: int) -> float:
    """Higham's gamma_n = n u / (1 - n u)."""
    return n * U / (1 - n * U)


@pytest.fixture
def case(request, param_value):
    """(nominal model, parameter, value): the etch model for etch, the tscale one for tscale."""
    param, value = param_value
    return request.getfixturevalue("xyz" if param == "etch" else "nominal2d"), param, value


@pytest.fixture(params=POINTS, ids=[f"{p}={v:g}" for p, v in POINTS])
def param_value(request):
    return request.param


def law_of(model, param: str, electrode: str) -> dict:
    """The electrode's capacitance law under `param` ({} without one)."""
    rows = (model.process.get(param) or {}).get("capacitance" if param == "etch" else "capacitance_laws", [])
    return next((r for r in rows if r["electrode"] == electrode), {})


def absolute(p: Polynomial) -> Polynomial:
    return Polynomial(p.exponents, np.abs(p.coeffs))


def law_parts(model, param: str, value: float, k: int, x: np.ndarray) -> dict:
    """Electrode k's law at scaled x, composed from the nominal fit and the law (the emitters'
    arithmetic: C = r F(x) C0(x + d)), with each part's running-error bound (module doc)."""
    f, law = model.capacitances[k], law_of(model, param, model.capacitances[k].electrode)
    names = [c.name for c in model.coordinates]
    d = np.zeros(model.ncoords)
    for q, s in law.get("shift", {}).items() if param == "etch" else ():
        d[names.index(q)] = s * value / model.coordinates[names.index(q)].scale
    r = ratio_value(law["ratio"], value) if param == "etch" and law else 1.0
    if param == "tscale" and law:
        r = float(np.dot(law["ratio"], [1.0, value, value**2, value**3]))
    deg = max(f.degree, DEGREE)  # the fit's and the factor's
    g = gamma(len(monomial_exponents(model.ncoords, deg)) + 7 * deg + 7)
    xd, w = x + d, np.abs(x) + np.abs(d)
    nv = model.ncoords
    c0, g0, e_c0, e_g0 = np.zeros(len(x)), np.zeros((len(x), nv)), np.zeros(len(x)), np.zeros((len(x), nv))
    for p in f.polys:
        pv, ph = p(xd), absolute(p)(w)
        dp = p.gradient(xd)
        dh = np.stack([absolute(p.derivative(v))(w) for v in range(nv)], axis=-1)
        c0 += f.c_ref / pv
        g0 -= f.c_ref * dp / (pv * pv)[:, None]
        e_c0 += f.c_ref * g * ph / pv**2
        e_g0 += f.c_ref * (g * dh / (pv * pv)[:, None] + 2 * np.abs(dp) * (g * ph / pv**3)[:, None])
    e_c0 += gamma(len(f.polys) + 1) * c0
    e_g0 += gamma(len(f.polys) + 2) * np.abs(g0)
    fv, fg, e_f, e_fg = np.ones(len(x)), np.zeros((len(x), nv)), np.zeros(len(x)), np.zeros((len(x), nv))
    if "state" in law:
        u = (ETCH if param == "etch" else TSCALE).u(value)
        exps = np.array(law["state"]["exponents"], dtype=int)
        coeffs = u * np.array(law["state"]["coeffs"][0]) + u * u * np.array(law["state"]["coeffs"][1])
        p1 = Polynomial(exps, coeffs)
        fv = 1.0 + p1(x)
        fg = p1.gradient(x)
        e_f = g * (1.0 + absolute(p1)(np.abs(x)))
        e_fg = g * np.stack([absolute(p1.derivative(v))(np.abs(x)) for v in range(nv)], axis=-1)
    c = r * fv * c0
    grad = r * (fv[:, None] * g0 + c0[:, None] * fg)
    e_c = abs(r) * (e_f * c0 + np.abs(fv) * e_c0) + 3 * U * np.abs(c)
    e_g = abs(r) * (e_f[:, None] * np.abs(g0) + np.abs(fv)[:, None] * e_g0 + e_c0[:, None] * np.abs(fg))
    e_g += abs(r) * c0[:, None] * e_fg + 4 * U * np.abs(grad)
    return {"c": c, "grad": grad, "e_c": e_c, "e_g": e_g, "shift": d}


def unclamped(model, point, param: str, value: float, x: np.ndarray) -> None:
    """No plate term is clamped at x, in the nominal model read at x + d nor in the point model (the
    routes compare one function, not two clamps): each P above the knee of its own rest value."""
    knee, zero = model.contact.get("knee", 0.0), np.zeros((1, model.ncoords))
    for k, (f, g) in enumerate(zip(model.capacitances, point.capacitances)):
        d = law_parts(model, param, value, k, x[:1])["shift"]
        for p, q in zip(f.polys, g.polys):
            assert np.min(p(x + d)) > knee * float(p(zero)[0]) and np.min(q(x)) > knee * float(q(zero)[0])


def without_factors(point):
    """The point model as it was before its fits carried the combs' state factors."""
    return dataclasses.replace(point, capacitances=[dataclasses.replace(f, factor=None) for f in point.capacitances])


def test_point_model_is_the_law(case):
    """C and dC/dq of the point model against the law at 100 points, within twice the rounding bound."""
    model, param, value = case
    point = at_point(model, {param: value})
    assert any(f.factor is not None for f in point.capacitances)  # the case has state factors
    x = np.random.default_rng(11).uniform(-0.15, 0.15, (100, model.ncoords))
    unclamped(model, point, param, value, x)
    got_c, got_g = point.capacitance(x), point.capacitance_gradient(x) * point.scales[None, None, :]
    law_c = capacitance_at(model, x, **{param: value})
    for k in range(len(model.capacitances)):
        ref = law_parts(model, param, value, k, x)
        assert np.all(np.abs(got_c[:, k] - law_c[:, k]) <= 2 * ref["e_c"]), model.capacitances[k].electrode
        assert np.all(np.abs(got_c[:, k] - ref["c"]) <= 2 * ref["e_c"]), model.capacitances[k].electrode
        assert np.all(np.abs(got_g[:, k] - ref["grad"]) <= 2 * ref["e_g"]), model.capacitances[k].electrode
    seen = np.abs(without_factors(point).capacitance(x) - law_c) > 2 * np.stack(
        [law_parts(model, param, value, k, x)["e_c"] for k in range(len(model.capacitances))], axis=-1
    )
    assert np.any(seen)  # the check sees the factor


def third_derivative(f, x: np.ndarray, v: int, h: float) -> np.ndarray:
    """A bound on |d^3 C / dx_v^3| over x +- h e_v for the point fit f (C = F c_ref sum 1/P, P quadratic
    and F a polynomial along x_v: module doc; the ratio r is in its c_ref)."""
    assert f.degree <= 2
    out = np.zeros(len(x))
    fb = factor_bounds(f.factor, x, v, h) if f.factor is not None else [np.ones(len(x))] + [np.zeros(len(x))] * 3
    for p in f.polys:
        p1, p2 = p.derivative(v), p.derivative(v).derivative(v)
        b2 = np.abs(p2(x))
        lo = p(x) - np.abs(p1(x)) * h - b2 * h * h / 2
        d1 = np.abs(p1(x)) + b2 * h
        assert np.all(lo > 0)
        t3 = 6 * d1 * b2 / lo**3 + 6 * d1**3 / lo**4
        t2 = b2 / lo**2 + 2 * d1**2 / lo**3
        t1 = d1 / lo**2
        out += abs(f.c_ref) * (fb[0] * t3 + 3 * fb[1] * t2 + 3 * fb[2] * t1 + fb[3] / lo)
    return out


def factor_bounds(factor, x: np.ndarray, v: int, h: float) -> list[np.ndarray]:
    """Bounds on the factor F's |F|, |F'|, |F''|, |F'''| along x_v over x +- h e_v: each derivative's
    Taylor series about x, exact to F's degree along x_v (sum_j |F^(m+j)(x)| h^j / j!)."""
    derivs = [factor]
    for _ in range(max(int(factor.exponents[:, v].max()), 3)):
        derivs.append(derivs[-1].derivative(v))
    at = [np.abs(d(x)) for d in derivs]
    return [sum(at[m + j] * h**j / math.factorial(j) for j in range(len(at) - m)) for m in range(4)]


def test_gradient_is_the_slope_of_c(case):
    """dC/dxs of the point model against a central difference of its own C (module doc's bound)."""
    model, param, value = case
    point = at_point(model, {param: value})
    x = np.random.default_rng(12).uniform(-0.15, 0.15, (100, model.ncoords))
    grad = point.capacitance_gradient(x) * point.scales[None, None, :]
    for k, f in enumerate(point.capacitances):
        e_g = law_parts(model, param, value, k, x)["e_g"]
        for v in range(model.ncoords):
            step = H * np.eye(model.ncoords)[v]
            up, down = law_parts(model, param, value, k, x + step), law_parts(model, param, value, k, x - step)
            fd = (point.capacitance(x + step)[:, k] - point.capacitance(x - step)[:, k]) / (2 * H)
            bound = H * H / 6 * third_derivative(f, x, v, H) + (up["e_c"] + down["e_c"]) / (2 * H)
            bound += np.abs(grad[:, k, v]) * U * (np.abs(x[:, v]) + H) / H + e_g[:, v]
            assert np.all(np.abs(fd - grad[:, k, v]) <= bound), (f.electrode, model.coordinates[v].name)


def test_the_lib_runs_the_point_model(xyz, tmp_path, ngspice_version):  # noqa: F811
    """The emitted .lib at etch -0.1 um (its instance parameter) against the sweep's point model: C at a
    displaced state and the forces there under VOLTS on xp_t (module doc)."""
    point = at_point(xyz, {"etch": STATE_ETCH})
    (tmp_path / "xyz.lib").write_text(emit_ngspice.subcircuit(xyz))
    lib, k = str(tmp_path / "xyz.lib"), [f.electrode for f in xyz.capacitances].index("xp_t")

    def run(bias: float):
        return run_ngspice(state_deck(lib, xyz, STATE_ETCH, OUT_OF_PLANE, bias), tmp_path / f"r{bias}")

    plots = run(0.0)
    xs = state_of(xyz, plot_of(plots, "Operating"))
    cap = abs(float(np.imag(plot_of(plots, "AC")["i(vp)"])[0])) / (2 * math.pi * 1e3)
    assert cap == pytest.approx(point.capacitance(xs[None])[0, k], rel=1e-9, abs=0)
    xs = state_of(xyz, plot_of(run(VOLTS), "Operating"))
    got = form_slopes(xyz, xs, STATE_ETCH)

    def slopes(m) -> np.ndarray:
        return 0.5 * VOLTS**2 * (m.capacitance_gradient(xs[None])[0, k] * m.scales)[:3]

    ref = slopes(point)
    assert np.max(np.abs(got - ref)) <= F2D_TOL * np.max(np.abs(ref)), (got, ref)
    assert np.max(np.abs(slopes(without_factors(point)) - ref)) > 1e3 * F2D_TOL * np.max(np.abs(ref))


def test_factor_through_the_json(xyz):  # noqa: F811
    """A point model's factors survive its JSON (MacroModel.to_dict / from_dict: the same polynomial,
    its coefficients written in full, so C to the last bit), and the nominal JSON has none."""
    point = at_point(xyz, {"etch": STATE_ETCH})
    x = np.random.default_rng(13).uniform(-0.15, 0.15, (20, xyz.ncoords))
    back = type(point).from_dict(json.loads(point.json_text()))
    np.testing.assert_array_equal(back.capacitance(x), point.capacitance(x))
    np.testing.assert_array_equal(back.capacitance_gradient(x), point.capacitance_gradient(x))
    assert all("factor" not in f for f in json.loads(xyz.json_text())["capacitances"])


def test_emitters_refuse_a_point_model(xyz, tmp_path):  # noqa: F811
    """The forms render c_ref and the polynomials and take the point as instance parameters: a point
    model's fits (with factors) are refused, not emitted with the factor dropped."""
    point = at_point(xyz, {"etch": STATE_ETCH})
    for fmt in ("ngspice", "osdi", "fmu"):
        with pytest.raises(ValueError, match="process point's factor"):
            emit.write_outputs(point, tmp_path, fmt)
