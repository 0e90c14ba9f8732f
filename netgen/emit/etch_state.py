"""The combs' state factor under etch or tscale (netgen.model.etch_state: C = pc (1 + u P1(xs) + u^2
P2(xs)) C0(xe), u = etch / 1 um, or u = tscale - 1 from the tscale record; one parameter a model:
tscale with etch on field2d combs is refused) in the ngspice forms (.lib and _xspice.lib): a node pr_<e> holding the factor,
the charge and dv2 times it, and the product rule's second force term pc dV^2/2 C0 dpr/dq into the
velocity nodes; the texts of the factor and its gradient for the .va (netgen.emit.va_terms: VA_U,
live states whose derivatives the compiler takes). No physics here: the polynomials are the model's."""

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
RECORDS = {"etch": "capacitance", "tscale": "capacitance_laws"}  # where each parameter's laws are


def state_laws(model: MacroModel) -> dict[str, dict]:
    """electrode -> its state factor's law where its parameter is declared and the comb has one, else {}."""
    return {
        r["electrode"]: r["state"]
        for name, key in RECORDS.items()
        if declared(model, name)
        for r in model.process[name].get(key, [])
        if "state" in r
    }


def parameter(model: MacroModel) -> str:
    """The parameter the model's state factors are in: tscale where its record has them, else etch."""
    laws = model.process.get("tscale", {}).get("capacitance_laws", []) if declared(model, "tscale") else []
    return "tscale" if any("state" in r for r in laws) else "etch"


def u_texts(model: MacroModel, va: bool = False, law: dict | None = None) -> tuple[str, str]:
    """u and u^2 of the model's state factors as ngspice (or, `va`, Verilog-A) text; a `law` marked
    "below" k (a cantilever's overhanging tip, netgen.model.etch_state) in (k - u)+, written branch-free
    as (x + abs(x)) / 2 like the knots' ek_<j> (netgen.emit.process_etch.knot_params)."""
    if parameter(model) == "tscale":
        return T_VA_U if va else T_U
    if law is not None and "below" in law:
        x = f"({num(law['below'])} - 1e6*etch)"
        p = f"0.5*({x} + abs({x}))"
        return (f"({p})", f"(({p})*({p}))") if va else (f"{{{p}}}", f"{{({p})*({p})}}")
    return VA_U if va else (U1, U2)


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
    """ngspice lines of the nodes pr_<e> = the electrode's state factor (a B voltage source)."""
    state = [f"xs_{c.name}" for c in model.coordinates]
    laws = state_laws(model)
    return [f"Bpr_{e} pr_{e} 0 V={factor_text(law, state, u=u_texts(model, law=law))}" for e, law in laws.items()]


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
            law = laws.get(f.electrode)
            grad = gradient_text(law, v, state, u=u_texts(model, law=law)) if law else None
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
