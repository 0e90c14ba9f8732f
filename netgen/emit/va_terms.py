"""The plate terms, charges and electrostatic forces of the Verilog-A module with their Jacobian
written out from shared factors (netgen.emit.veriloga renders them; no physics here).

Automatic differentiation (openvaf-r) of F_v = sum_t g_tv dP_t/dxs_v y_t forms every
dF_v/dxs_w as its own sum over the plate terms t, each product re-derived per pair: for the
reference disk (94 terms, 7 coordinates) most of the model's evaluation. Here the plate terms
are evaluated once, as values, on derivative-free copies of the states and electrode voltages
(`frozen`: rounded to 2^-40, and floor() has no derivative), and the derivatives the simulator
needs are added as explicit terms that vanish in value:

    F_v = F_v(xf, V) - 1/(2 L_v) sum_w S_vw (V(xs_w) - xf_w),
    S_vw = sum_t c_t dv2f_t [grad_tv grad_tw dw_t/dP + hess_tvw w_t]   (symmetric: 28 of 49 sums)

with r = 1/P (the one division per plate term), w = slope r^2 (slope of the contact clamp) and the
capacitance slopes m_iw = dC_i/dxs_w = -c_i sum_k grad_kw w_k, shared by the charge and the force:
Q_i = c_i (sum_k r_k) dV_i + dVf_i sum_w m_iw (V(xs_w) - xf_w),   F_v = 1/(2 L_v) sum_i dv2_i m_iv + ...
(one sum per electrode and coordinate instead of one for the charge and one for the force; a slope
that is identically zero is left out, so it is no entry of the stamp pattern).
The derivatives with respect to the electrode voltages come from dv2 = dV^2 and dV as before.
The Jacobian is the exact one (to the 2^-40 rounding of the copies), so AC, noise and Newton
see the same matrix; the values differ from the direct form by below 1e-12 relative.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..fit.capacitance import CapacitanceFit
from ..fit.polynomial import Polynomial
from ..model import MacroModel
from . import etch_state, process
from .common import clamp_expr, dv2_node, node, num, poly_expr

ROUND = num(2.0**40)  # the copies' grid: 2^-40 ~ 9e-13 of a state (O(1)) or a volt


def frozen(expr: str) -> str:
    """`expr` rounded to 2^-40: a value without derivative (floor() has none in Verilog-A compilers)."""
    return f"floor({expr} * {ROUND} + 0.5) / {ROUND}"


def xf(name: str) -> str:
    """The derivative-free copy of state xs_<q>."""
    return f"xf_{name}"


def dx(name: str) -> str:
    """V(xs_<q>) - xf_<q>: zero in value, derivative 1 with respect to xs_<q>."""
    return f"dx_{name}"


def vf(electrode: str) -> str:
    """The derivative-free copy of V(electrode, plate)."""
    return f"vf_{electrode}"


def w_var(electrode: str, k: int) -> str:
    """slope/P^2 of a 1/P plate term (the force and motional-charge factor)."""
    return f"w_{electrode}_{k + 1}"


def r_var(electrode: str, k: int) -> str:
    """1/P of a plate term (its capacitance over c_ref, shared by the charge, w and b)."""
    return f"r_{electrode}_{k + 1}"


def m_var(electrode: str, coordinate: str) -> str:
    """dC/dxs of one electrode's capacitance at the copies (shared by its charge and the force)."""
    return f"m_{electrode}_{coordinate}"


def b_var(electrode: str, k: int) -> str:
    """dv2f * d(slope/P^2)/dP of a 1/P plate term (its factor in the force Jacobian)."""
    return f"b_{electrode}_{k + 1}"


def s_var(model: MacroModel, v: int, w: int) -> str:
    """Entry (v, w) of the symmetric force Jacobian sum S (stored once, v <= w)."""
    a, b = sorted((v, w))
    return f"s_{model.coordinates[a].name}_{model.coordinates[b].name}"


def _poly(poly: Polynomial, names: list[str]) -> str:
    """A polynomial of the derivative-free copies, or its constant."""
    return poly_expr(poly, names, access="{}")


def _constant(poly: Polynomial) -> float | None:
    """The value of a constant polynomial, None if it depends on the states."""
    live = poly.coeffs != 0.0
    if np.any(poly.exponents[live].sum(axis=1) > 0):
        return None
    return float(poly.coeffs[live].sum())


Fold = Callable[[float, Polynomial], bool]


def _times(c: float, poly: Polynomial, names: list[str], factor: str, fold: Fold | None = None) -> str | None:
    """c * poly * factor as text (None when zero): a constant poly folded into c, and c into the
    poly's sum unless `fold` says openvaf-r compiles the product right (netgen.emit.veriloga.misfolds)."""
    k = _constant(poly)
    if k is not None:
        return None if c * k == 0.0 else f"{num(c * k)} * {factor}"
    if fold is not None and not fold(c, poly):
        return f"{num(c)} * ({_poly(poly, names)}) * {factor}"
    terms = [(e, float(a) * c) for e, a in zip(poly.exponents, poly.coeffs) if a != 0.0]
    return f"({_poly(Polynomial(np.array([e for e, _ in terms]), np.array([a for _, a in terms])), names)}) * {factor}"


def _sum(terms: Sequence[str | None], sep: str = "\n            + ", per_line: int = 1) -> str:
    """Non-empty terms joined (`per_line` to a line when sep breaks lines), '+ -' folded; '0.0' if none."""
    live = [t for t in terms if t]
    if per_line > 1:
        live = [" + ".join(live[i : i + per_line]) for i in range(0, len(live), per_line)]
    return sep.join(live).replace("+ -", "- ") if live else "0.0"


def ratio(model: MacroModel, electrode: str) -> str:
    """ "pc_<electrode> * " where the electrode's capacitance has an etch ratio (netgen.emit.process.
    capacitance_ratios: it scales C, so the charge, the forces and their Jacobian), else ""; times
    "pr_<electrode> * ", a comb's state factor (netgen.emit.etch_state), a variable of the live states:
    the compiler's derivatives of it complete the Jacobian (pr' C0 and pr' dC0/dq)."""
    pc = f"pc_{electrode} * " if electrode in process.capacitance_ratios(model) else ""
    return pc + (f"pr_{electrode} * " if electrode in etch_state.state_laws(model) else "")


def live_capacitance(f: CapacitanceFit, model: MacroModel, m_rows: list[dict], fold: Fold) -> str:
    """C0 of one fit with its xs-derivative written out, c_ref sum_k r_k + sum_w m_w dx_w (as the
    charge): the factor of the product rule's second force term (state_force)."""
    e = f.electrode
    if f.target == "direct":
        value = node(e, 0) if fold(f.c_ref, f.polys[0]) else f"{num(f.c_ref)} * {node(e, 0)}"
    else:
        value = f"{num(f.c_ref)} * (" + " + ".join(r_var(e, k) for k in range(len(f.polys))) + ")"
    parts = [f"{dx(model.coordinates[m['coord']].name)} * {m['name']}" for m in m_rows]
    return f"({value}" + (f" + {_sum(parts, ' + ')})" if parts else ")")


def state_force(model: MacroModel, v: int, live: dict[str, str]) -> list[str]:
    """The product rule's second terms of F_v times 2 L_v: pc dV^2 C0 dpr/dxs_v per electrode with a
    state factor (netgen.emit.etch_state; `live`: electrode -> live_capacitance), on the live states."""
    out = []
    states = [f"xs_{c.name}" for c in model.coordinates]
    for e in etch_state.state_laws(model):
        grad = etch_state.gradient(model, e, v, states, "V({})", "{}", va=True)
        if grad is not None:
            pc = f"pc_{e} * " if e in process.capacitance_ratios(model) else ""
            out.append(f"{pc}V({e}, {model.plate}) * V({e}, {model.plate}) * {live[e]} * ({grad})")
    return out


def dv2_value(model: MacroModel, electrode: str) -> str:
    """The frozen dv2f of one electrode times its etch ratio (ratio)."""
    return f"{ratio(model, electrode)}{vf(electrode)} * {vf(electrode)}"


def _term_rows(
    f: CapacitanceFit, clamps: Sequence[tuple[float, float]] | None, names: list[str], fold: Fold, dv2f: str
) -> list[dict]:
    """P_k(xf) (clamped), w_k and b_k of one fit's terms (a direct fit's P holds c_ref where `fold`);
    dv2f: the electrode's frozen dv2 text (dv2_value)."""
    rows = []
    for k, poly in enumerate(f.polys):
        p, ck = node(f.electrode, k), clamps[k] if clamps else None
        folded = f.target == "direct" and fold(f.c_ref, poly)
        text = _poly(Polynomial(poly.exponents, poly.coeffs * f.c_ref) if folded else poly, names)
        row = {
            "w": "",
            "r": "",
            "b": "",
            "p": p,
            "p_expr": f"({text} >= {num(ck[0])} ? {text} : {clamp_expr(text, *ck)})" if ck else text,
        }
        if f.target != "direct":
            w, r = w_var(f.electrode, k), r_var(f.electrode, k)
            row["r_expr"] = f"1.0 / {p}"
            if ck:
                knee, floor = ck
                slope = f"min(1, ({p} - {num(floor)}) * {num(1.0 / (knee - floor))})"
                dslope = f"(({p} - {num(floor)}) < {num(knee - floor)} ? {num(1.0 / (knee - floor))} : 0.0)"
                row["w_expr"] = f"{slope} * {r} * {r}"
                row["b_expr"] = f"{dv2f} * {w} * ({dslope} - 2.0 * {slope} * {r})"
            else:
                row["w_expr"] = f"{r} * {r}"
                row["b_expr"] = f"-2.0 * {dv2f} * {w} * {r}"
            row.update(w=w, r=r, b=b_var(f.electrode, k))
        rows.append(row)
    return rows


def slopes(f: CapacitanceFit, model: MacroModel, names: list[str], fold: Fold) -> list[dict]:
    """The nonzero capacitance slopes m_iw = dC_i/dxs_w of one fit at the copies, as variable rows."""
    rows = []
    for w, c in enumerate(model.coordinates):
        if f.target == "direct":
            text = _sum([_times(f.c_ref, f.polys[0].derivative(w), names, "1.0", fold)])
            text = text.removesuffix(" * 1.0")
        else:
            parts = [
                _times(-f.c_ref, p.derivative(w), names, w_var(f.electrode, k), fold) for k, p in enumerate(f.polys)
            ]
            text = _sum(parts, " + ")
        if text != "0.0":
            rows.append({"name": m_var(f.electrode, c.name), "coord": w, "expr": text})
    return rows


def charge(f: CapacitanceFit, model: MacroModel, m_rows: list[dict], fold: Fold) -> str:
    """The ddt() argument of one plate-electrode capacitor: C(xf) dV plus its explicit xs-derivative
    dVf sum_w m_w dx_w (the slopes `m_rows` of `slopes`)."""
    e, coords = f.electrode, model.coordinates
    dv = f"V({e}, {model.plate})"
    if f.target == "direct":
        value = (node(e, 0) if fold(f.c_ref, f.polys[0]) else f"{num(f.c_ref)} * {node(e, 0)}") + f" * {dv}"
    else:
        value = f"{num(f.c_ref)} * (" + " + ".join(r_var(e, k) for k in range(len(f.polys))) + f") * {dv}"
    parts = [f"{dx(coords[m['coord']].name)} * {m['name']}" for m in m_rows]
    return value + (f" + {vf(e)} * ({_sum(parts)})" if parts else "")


def force(model: MacroModel, v: int, m_rows: dict[str, list[dict]], live: dict[str, str] | None = None) -> str:
    """F_v (SI): 1/(2 L_v) (sum_i dv2_i m_iv - sum_w S_vw dx_w): the plate terms' share at xf through
    the slopes m (`slopes`, per electrode), and the explicit xs-derivative through S; plus the combs'
    state factors' product-rule terms (state_force, `live`)."""
    terms = [f"{dv2_node(e)} * {m['name']}" for e, rows in m_rows.items() for m in rows if m["coord"] == v]
    terms += state_force(model, v, live or {})
    jac = [f"{s_var(model, v, w)} * {dx(c.name)}" for w, c in enumerate(model.coordinates)]
    value = _sum(terms) if terms else "0.0"
    return f"{num(0.5 / model.coordinates[v].scale)} * ({value}\n            - ({' + '.join(jac)}))"


def stiffness(model: MacroModel, names: list[str], shifted: dict | None = None) -> list[dict]:
    """The sums S_vw (v <= w) of the force Jacobian (module doc; `shifted` as in force)."""
    n, rows, all_names = model.ncoords, [], names
    for v in range(n):
        for w in range(v, n):
            terms: list[str | None] = []
            for f in model.capacitances:
                names = (shifted or {}).get(f.electrode, all_names)
                dv2f = dv2_value(model, f.electrode)
                for k, p in enumerate(f.polys):
                    hess = p.derivative(v).derivative(w)
                    if f.target == "direct":
                        terms.append(_times(-f.c_ref, hess, names, dv2f))
                        continue
                    gv, gw = p.derivative(v), p.derivative(w)
                    cv, cw = _constant(gv), _constant(gw)
                    if cv is not None and cw is not None:
                        terms.append(None if cv * cw == 0.0 else f"{num(f.c_ref * cv * cw)} * {b_var(f.electrode, k)}")
                    else:
                        cgv = Polynomial(gv.exponents, gv.coeffs * f.c_ref)  # c_ref folded in (misfolds)
                        terms.append(f"({_poly(cgv, names)}) * ({_poly(gw, names)}) * {b_var(f.electrode, k)}")
                    terms.append(_times(f.c_ref, hess, names, f"{dv2f} * {w_var(f.electrode, k)}"))
            rows.append({"name": s_var(model, v, w), "expr": _sum(terms, per_line=4)})
    return rows


def rows(model: MacroModel, fits: list[dict], fold: Fold, shifted: dict | None = None) -> dict:
    """Template fields: the copies, each fit's terms and charge, the Jacobian sums, the forces;
    fold(c, poly): write c * poly as one sum (netgen.emit.veriloga.misfolds); `shifted`: electrode ->
    the state names its plate terms read (the gap offsets of netgen.emit.process), else the copies."""
    names = [xf(c.name) for c in model.coordinates]
    clamps = model.term_clamps()
    m_rows, live = {}, {}
    for i, (row, f) in enumerate(zip(fits, model.capacitances)):
        own = (shifted or {}).get(f.electrode, names)
        row["plate_terms"] = _term_rows(f, clamps[i] if clamps else None, own, fold, dv2_value(model, f.electrode))
        row["slopes"] = m_rows[f.electrode] = slopes(f, model, own, fold)
        live[f.electrode] = live_capacitance(f, model, row["slopes"], fold)
        scale, value = ratio(model, f.electrode), charge(f, model, row["slopes"], fold)
        row["charge"] = f"{scale}({value})" if scale else value
        row["dv2_scale"] = scale
        row["vf"] = vf(f.electrode)
    return {
        "frozen": [
            {"xf": xf(c.name), "dx": dx(c.name), "xs": f"xs_{c.name}", "expr": frozen(f"V(xs_{c.name})")}
            for c in model.coordinates
        ],
        "vf_expr": {f.electrode: frozen(f"V({f.electrode}, {model.plate})") for f in model.capacitances},
        "stiffness": stiffness(model, names, shifted),
        "forces": [force(model, v, m_rows, live) for v in range(model.ncoords)],
    }
