"""The combs' state factors under etch and tscale (netgen.model.etch_state: C = pc (1 + u P1(xs) + u^2
P2(xs)) C0(xe), u = etch / 1 um from the etch record, or u = tscale - 1 from the tscale record; with both
declared, a comb carries both factors and the cross factor of its etch law, 1 + (tscale - 1) (u Q1(xs)
+ u^2 Q2(xs)) (netgen.model.etch_state.cross_laws), and C is times their product) in the ngspice forms
(.lib and _xspice.lib): a node pr_<e> holding the factor (the product of nodes pr_<e>_<kind>, one a
factor, where there are several), the charge and dv2 times it, and the product rule's second force
term pc dV^2/2 C0 dpr/dq into the velocity nodes; the texts of the factor and its gradient for the .va
(netgen.emit.va_terms: VA_U, live states whose derivatives the compiler takes). No physics here: the
polynomials are the model's."""

from __future__ import annotations

import numpy as np

from ..fit.polynomial import Polynomial
from ..model import MacroModel
from .common import c_node, force_gain, node, num, poly_expr, rest_capacitance
from .process_base import declared

U1, U2 = "{1e6*etch}", "{1e12*etch*etch}"  # u and u^2 as ngspice parameter expressions
VA_U = ("(1e6 * etch)", "(1e12 * etch * etch)")  # the same in Verilog-A
# under tscale: u = tscale - 1, parenthesized inside the braces (ngspice 39 and 46 read a B source's
# V=1 + {tscale-1}*(2) at tscale 0.9 as -0.1, with {(tscale-1)} as 0.8)
T_U = ("{(tscale-1)}", "{(tscale-1)*(tscale-1)}")
T_VA_U = ("(tscale - 1)", "((tscale - 1) * (tscale - 1))")
# under both: the cross factor's weights (tscale - 1) u and (tscale - 1) u^2
X_U = ("{(tscale-1)*1e6*etch}", "{(tscale-1)*1e12*etch*etch}")
X_VA_U = ("((tscale - 1) * 1e6 * etch)", "((tscale - 1) * 1e12 * etch * etch)")
RECORDS = {"etch": "capacitance", "tscale": "capacitance_laws"}  # where each parameter's laws are
KINDS = ("etch", "tscale", "cross")  # a comb's factors in the order they multiply (FMU: STATE_KIND)


def state_laws(model: MacroModel) -> dict[str, list[tuple[str, dict]]]:
    """electrode -> its state factors [(kind, law)] in KINDS order, where their parameters are declared
    and the comb has them (the cross factor needs both); electrodes without any are left out."""
    out: dict[str, list[tuple[str, dict]]] = {}
    for name, key in RECORDS.items():
        if not declared(model, name):
            continue
        for r in model.process[name].get(key, []):
            if "state" in r:
                out.setdefault(r["electrode"], []).append((name, r["state"]))
    if declared(model, "tscale") and declared(model, "etch"):
        for r in model.process["etch"].get("capacitance", []):
            if "cross" in r:
                out.setdefault(r["electrode"], []).append(("cross", r["cross"]))
    return {e: sorted(fs, key=lambda f: KINDS.index(f[0])) for e, fs in out.items()}


def u_texts(kind: str, va: bool = False, law: dict | None = None) -> tuple[str, str]:
    """The two weights of a factor of `kind` (u and u^2; the cross factor's (tscale - 1) u and
    (tscale - 1) u^2) as ngspice (or, `va`, Verilog-A) text; an etch `law` marked "below" k (a
    cantilever's overhanging tip, netgen.model.etch_state) in (k - u)+, written branch-free as
    (x + abs(x)) / 2 like the knots' ek_<j> (netgen.emit.process_etch.knot_params)."""
    if kind == "tscale":
        return T_VA_U if va else T_U
    if kind == "cross":
        return X_VA_U if va else X_U
    if law is not None and "below" in law:
        x = f"({num(law['below'])} - 1e6*etch)"
        p = f"0.5*({x} + abs({x}))"
        return (f"({p})", f"(({p})*({p}))") if va else (f"{{{p}}}", f"{{({p})*({p})}}")
    return VA_U if va else (U1, U2)


def factor_names(model: MacroModel, electrode: str) -> list[str]:
    """The names of the electrode's factor nodes (.lib) or variables (.va): pr_<e> alone with one
    factor, else pr_<e>_<kind> per factor (pr_<e> is then their product)."""
    fs = state_laws(model).get(electrode, [])
    return [f"pr_{electrode}"] if len(fs) == 1 else [f"pr_{electrode}_{k}" for k, _ in fs]


def factor_defs(model: MacroModel, state: list[str], access: str, ref: str, va: bool = False) -> list[tuple[str, str]]:
    """(name, expression) of each comb's factor nodes or variables over the states `state` (`access`
    formats each), then pr_<e> as their product where there are several (`ref` formats a name)."""
    out = []
    for e, fs in state_laws(model).items():
        names = factor_names(model, e)
        out += [(n, factor_text(law, state, access, u_texts(k, va, law))) for n, (k, law) in zip(names, fs)]
        if len(fs) > 1:
            out.append((f"pr_{e}", "*".join(ref.format(n) for n in names)))
    return out


def gradient(model: MacroModel, electrode: str, v: int, state: list[str], access: str, ref: str, va: bool = False):
    """d pr_<e>/dxs_v over `state`: one factor's gradient_text, or the product rule over the factors
    (each one's gradient times the others' nodes or variables, `ref`); None where identically 0."""
    fs, names = state_laws(model)[electrode], factor_names(model, electrode)
    terms = []
    for i, (k, law) in enumerate(fs):
        g = gradient_text(law, v, state, access, u_texts(k, va, law))
        if g is not None:
            others = "".join(f"*{ref.format(n)}" for j, n in enumerate(names) if j != i)
            terms.append(g if len(fs) == 1 else f"({g}){others}")
    return " + ".join(terms) if terms else None


def polys(law: dict) -> tuple[Polynomial, Polynomial]:
    """P1 and P2 of a state law as polynomials in the scaled state."""
    exps = np.array(law["exponents"], dtype=int)
    return Polynomial(exps, np.array(law["coeffs"][0])), Polynomial(exps, np.array(law["coeffs"][1]))


def factor_text(law: dict, state: list[str], access: str = "v({})", u: tuple[str, str] = (U1, U2)) -> str:
    """1 + u P1 + u^2 P2 over the states `state` (`access` formats each; `u`: u and u^2's texts)."""
    p1, p2 = polys(law)
    return f"1 + {u[0]}*({poly_expr(p1, state, access=access)}) + {u[1]}*({poly_expr(p2, state, access=access)})"


def gradient_text(
    law: dict, v: int, state: list[str], access: str = "v({})", u: tuple[str, str] = (U1, U2)
) -> str | None:
    """d(1 + u P1 + u^2 P2)/dxs_v over `state` (as factor_text), None where identically 0."""
    d1, d2 = (p.derivative(v) for p in polys(law))
    if not (np.any(d1.coeffs) or np.any(d2.coeffs)):
        return None
    return f"{u[0]}*({poly_expr(d1, state, access=access)}) + {u[1]}*({poly_expr(d2, state, access=access)})"


def factor_lines(model: MacroModel) -> list[str]:
    """ngspice lines of the nodes pr_<e> = the electrode's state factor (a B voltage source; with several
    factors one a factor, pr_<e> their product)."""
    state = [f"xs_{c.name}" for c in model.coordinates]
    return [f"B{n} {n} 0 V={x}" for n, x in factor_defs(model, state, "v({})", "v({})")]


def charge_factor(model: MacroModel, f, c_text: str) -> str:
    """The charge node's factor of a plate electrode with C/c_ref = c0 + c_text (the linear c0
    capacitor stays): pr (c0 + c) - c0 = c pr + c0 (pr - 1); `c_text` unchanged without a state law."""
    if f.electrode not in state_laws(model):
        return c_text
    c0, pr = num(rest_capacitance(f, model.ncoords)), f"v(pr_{f.electrode})"
    return f"({c_text}*{pr} + {c0}*({pr} - 1))"


def force_rows(model: MacroModel, ws: float) -> list[dict]:
    """Per coordinate the product rule's second term into its velocity node: sum over the electrodes
    with a state law of gain c_ref/(2 L) pc dV^2 (C0/c_ref) dpr/dxs (the first term, pr dC0/dq, is the
    forms' own force with dv2 times pr)."""
    laws, state = state_laws(model), [f"xs_{c.name}" for c in model.coordinates]
    out = []
    for v, c in enumerate(model.coordinates):
        parts = []
        for f in model.capacitances:
            grad = gradient(model, f.electrode, v, state, "v({})", "v({})") if f.electrode in laws else None
            if grad is None:
                continue
            e, plate = f.electrode, model.plate
            c0 = (
                f"v({node(e, 0)})"
                if f.target == "direct"
                else f"({num(rest_capacitance(f, model.ncoords))} + v({c_node(e)}))"
            )
            gain = num(force_gain(c, ws) * f.c_ref / (2.0 * c.scale))
            parts.append(f"{gain}*{{pc_{e}}}*v({e},{plate})*v({e},{plate})*{c0}*({grad})")
        if parts:
            out.append({"name": c.name, "expr": " + ".join(parts)})
    return out
