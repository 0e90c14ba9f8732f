"""ngspice emitter: renders a MacroModel into a .subckt with Jinja2 (no physics here)."""

from __future__ import annotations

import math

import numpy as np

from .fit import Polynomial
from .model import MacroModel
from .templating import render


def num(value: float) -> str:
    """Deterministic, round-trip-safe number text for netlists."""
    if not math.isfinite(value):
        raise ValueError(f"non-finite value {value} cannot be emitted")
    return repr(float(value))


def poly_expr(poly: Polynomial, names: list[str], drop: float = 0.0, access: str = "v({})") -> str:
    """Polynomial as explicit products of node voltages, `access` formatting each (ngspice's ^ is |x|^y)."""
    terms = []
    for e, c in zip(poly.exponents, poly.coeffs):
        if c == 0.0 or abs(c) < drop:
            continue
        factors = [access.format(names[v]) for v in range(len(names)) for _ in range(int(e[v]))]
        terms.append("*".join([num(c)] + factors))
    if not terms:
        return "0"
    return " + ".join(terms).replace("+ -", "- ")


def time_scale(model: MacroModel) -> float:
    """Model time scale w_s (rad/s): the geometric mean of the modal frequencies, else 1e6."""
    freqs = [c.frequency_hz for c in model.coordinates if c.frequency_hz > 0]
    f = math.exp(float(np.mean(np.log(freqs)))) if freqs else 1e6 / (2 * math.pi)
    return 2 * math.pi * f


def _force_terms(model: MacroModel, v: int, ws: float, state: list[str]) -> tuple[str, list[tuple[str, str]]]:
    """Right-hand side current of the velocity integrator of coordinate v: a behavioural
    expression, and (node, gain) pairs of forces linear in a y node (emitted as cheap VCCS)."""
    c = model.coordinates[v]
    a = 1.0 / (c.mass * c.scale * ws * ws)
    parts, linear = [f"{num(a * c.port_units[3])}*v(f_{c.name})"], []
    if c.stiffness:
        parts.append(f"{num(-c.stiffness / (c.mass * ws * ws))}*v({state[v]})")
    if c.damping:
        parts.append(f"{num(-c.damping / (c.mass * ws))}*v(u_{c.name})")
    for f in model.capacitances:
        for k, poly in enumerate(f.polys):
            dpoly = poly.derivative(v)
            if not np.any(dpoly.coeffs):
                continue
            g = a * f.c_ref / (2.0 * c.scale)
            if f.target == "direct":                            # F = g dP/dx dV^2
                parts.append(f"{num(g)}*({poly_expr(dpoly, state)})*v({dv2_node(f.electrode)})")
            elif dpoly.exponents.sum() == 0:                     # affine P_k: F linear in y_k
                linear.append((y_node(f.electrode, k), num(-g * float(dpoly.coeffs.sum()))))
            else:
                parts.append(f"{num(-g)}*({poly_expr(dpoly, state)})*v({y_node(f.electrode, k)})")
    return " + ".join(parts).replace("+ -", "- "), linear


def node(electrode: str, k: int) -> str:
    """Name of the node carrying term k of an electrode's capacitance polynomial(s)."""
    return f"p_{electrode}_{k + 1}"


def dv2_node(electrode: str) -> str:
    """Node carrying (V_electrode - V_plate)^2, shared by the force terms of one electrode."""
    return f"dv2_{electrode}"


def y_node(electrode: str, k: int) -> str:
    """Node carrying (V_e - V_plate)^2 / P_k^2: the force terms are linear in it."""
    return f"y_{electrode}_{k + 1}"


def charge_expr(f, plate: str) -> str:
    """Charge of one plate-electrode capacitor, Q = C(q) * (V_e - V_plate)."""
    if f.target == "direct":
        cap = f"{num(f.c_ref)}*v({node(f.electrode, 0)})"
    else:
        cap = f"{num(f.c_ref)}*(" + " + ".join(f"1/v({node(f.electrode, k)})" for k in range(len(f.polys))) + ")"
    return f"{cap}*v({f.electrode},{plate})"


def _si(value: float, unit: str) -> str:
    return f"{value:.6g} {unit}".strip()


def header_context(model: MacroModel) -> dict:
    """Template context shared by the dialects: header tables, time scale, fit form, ports, couplings."""
    coords = []
    for c in model.coordinates:
        xu, _, fu, _ = c.port_units
        mass_unit = "kg" if c.unit == "m" else "kg*m^2"
        stiff_unit = "N/m" if c.unit == "m" else "N*m/rad"
        coords.append({
            "name": c.name, "kind": c.kind + (f" {c.label}" if c.label else ""), "xunit": xu, "funit": fu,
            "scale_text": _si(c.scale, c.unit), "mass_text": _si(c.mass, mass_unit),
            "stiff_text": _si(c.stiffness, stiff_unit),
            "freq_text": f"{c.frequency_hz:.6g}" if c.frequency_hz else "-"})
    fits = [{"electrode": f.electrode, "c_ref_text": f"{f.c_ref:.6e}", "max_text": f"{f.max_rel_error:.3e}",
             "rms_text": f"{f.rms_rel_error:.3e}", "terms": len(f.polys)} for f in model.capacitances]
    fit_form = {"plates": "C = c_ref * sum_k 1/P_k(xs): K effective parallel plates",
                "inverse": "C = c_ref / P(xs): fit of 1/C", "direct": "C = c_ref * P(xs)"}[model.capacitances[0].target]
    degree = max(f.degree for f in model.capacitances)
    names = [e.name for e in model.electrodes]
    couplings = [{"a": names[i], "b": names[j], "value": num(model.coupling[i, j])}
                 for i in range(len(names)) for j in range(i + 1, len(names)) if model.coupling[i, j]]
    c = model.contact
    contact_text = "" if not c else (
        f"Contact: below {c['knee']:g} of its value at xs = 0 each P_k is clamped smoothly (never under "
        f"{c['floor']:g}), and {len(c.get('points', []))} stop points carry a penalty spring "
        f"{c['stiffness']:.4g} N/m with damping {c['damping']:.4g} N*s/m, engaged over {c['smoothing']:g} of the gap"
        " (lone coordinates stop at xs = +-1; see netgen/contact.py for the model and its limits).")
    return {"m": model, "ports": model.ports(), "coords": coords, "fits": fits, "couplings": couplings,
            "ws_text": f"{time_scale(model):.6g}", "fit_form": fit_form, "degree": degree,
            "contact_text": contact_text}


K_B = 1.380649e-23      # J/K


def noise_enabled(model: MacroModel, noise: bool | None) -> bool:
    """Emit thermal noise sources: the explicit option, else the structure's [damping] noise."""
    return model.report.get("damping", {}).get("noise", False) if noise is None else noise


def noise_context(model: MacroModel, ws: float) -> dict:
    """Template fields of the thermal force noise sources (damped coordinates only)."""
    temp = float(model.report.get("damping", {}).get("temperature_K", 300.0))
    f_max = max([c.frequency_hz for c in model.coordinates] + [ws / (2 * math.pi)])
    dt = float(f"{1.0 / (50.0 * f_max):.3g}")
    sources = [{"name": c.name, "rms": num(math.sqrt(2.0 * K_B * temp * c.damping) / c.port_units[3]),
                "gain": num(c.port_units[3] / (c.mass * c.scale * ws * ws))}
               for c in model.coordinates if c.damping > 0]
    return {"noise_sources": sources, "noise_temperature": f"{temp:g}", "noise_dt": f"{dt:g}",
            "subckt_params": f"\n+ params: noise=1 noise_dt={dt:g}" if sources else ""}


def subcircuit(model: MacroModel, noise: bool | None = None) -> str:
    """The complete .lib text of the model's subcircuit (thermal force noise per `noise_enabled`)."""
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    ctx = header_context(model)
    if noise_enabled(model, noise):
        ctx.update(noise_context(model, ws))
    for v, (row, c) in enumerate(zip(ctx["coords"], model.coordinates)):
        row.update({"cint": num(1.0 / ws), **dict(zip(("force_expr", "linear"), _force_terms(model, v, ws, state))),
                    "out_gain": num(c.scale / c.port_units[1])})
    clamps = model.term_clamps()
    for i, (row, f) in enumerate(zip(ctx["fits"], model.capacitances)):
        cl = clamps[i] if clamps else [None] * len(f.polys)
        row.update({
            "nodes": [n for k, p in enumerate(f.polys) for n in _term_nodes(f.electrode, k, poly_expr(p, state), cl[k])],
            "dv2": {"name": dv2_node(f.electrode), "expr": f"v({f.electrode},{model.plate})*v({f.electrode},{model.plate})"},
            "ys": [] if f.target == "direct" else
                  [{"name": y_node(f.electrode, k), "expr": f"v({dv2_node(f.electrode)})"
                    + (f"*{slope_expr(f'v({node(f.electrode, k)})', *cl[k])}" if cl[k] else "")
                    + f"/(v({node(f.electrode, k)})*v({node(f.electrode, k)}))"}
                   for k in range(len(f.polys))],
            "charge_expr": charge_expr(f, model.plate)})
    stops, per_coord = contact_terms(model)
    for row, c, terms in zip(ctx["coords"], model.coordinates, per_coord):
        a = 1.0 / (c.mass * c.scale * ws * ws)
        row["stops"] = [(name, num(a * gain)) for name, gain in terms]
    ctx["stops"] = stops
    return render("ngspice_subckt.lib.j2", **ctx)


# ------------------------------------------------------------------ pull-in and contact (netgen.contact)

def clamp_expr(expr: str, knee: float, floor: float) -> str:
    """P clamped from below (C1 at the knee, never under the floor); the text is valid ngspice and Verilog-A."""
    span = knee - floor
    return f"max({expr}, {num(floor)} + {num(span)}*exp(min({expr} - {num(knee)}, 0)/{num(span)}))"


def slope_expr(p: str, knee: float, floor: float) -> str:
    """dP_eff/dP of the clamp, from the clamped value p."""
    return f"min(1, ({p} - {num(floor)})/{num(knee - floor)})"


def _term_nodes(electrode: str, k: int, expr: str, clamp: tuple[float, float] | None) -> list[dict]:
    """B-source nodes of one plate term: P itself, or the raw P and its clamp (a one-variable
    expression: ngspice differentiates it far faster than the clamp of the full polynomial)."""
    name = node(electrode, k)
    if clamp is None:
        return [{"name": name, "expr": expr}]
    raw = "r" + name
    return [{"name": raw, "expr": expr}, {"name": name, "expr": clamp_expr(f"v({raw})", *clamp)}]


def stop_name(j: int) -> tuple[str, str]:
    """Nodes/variables of stop point j: penetration fraction and scaled penalty force."""
    return f"sg_{j + 1}", f"sf_{j + 1}"


def contact_terms(model: MacroModel, access: str = "v({})",
                  var: str = "v({})") -> tuple[list[dict], list[list[tuple[str, float]]]]:
    """Stop points as (penetration, penalty) expressions, and per coordinate the (variable, SI force
    per unit) pairs: F_v = sum_j gain_jv * sf_j, sf_j = (pen + (c/k) w dp/dt) / delta."""
    c = model.contact
    points, per_coord = [], [[] for _ in model.coordinates]
    if not c.get("points"):
        return points, per_coord
    ws, delta = time_scale(model), c["smoothing"]
    xs = [access.format(f"xs_{k.name}") for k in model.coordinates]
    us = [access.format(f"u_{k.name}") for k in model.coordinates]
    for j, pt in enumerate(c["points"]):
        g, f = stop_name(j)
        used = [(v, a) for v, a in enumerate(pt["a"]) if a != 0.0]
        gap_expr = " + ".join(f"{num(a)}*{xs[v]}" for v, a in used).replace("+ -", "- ") + " - 1"
        r = f"min(max({var.format(g)}, 0), {num(delta)})"
        rate = " + ".join(f"{num(a * ws)}*{us[v]}" for v, a in used).replace("+ -", "- ")
        pen = (f"({r}*{r}*{num(0.5 / delta)} + max({var.format(g)} - {num(delta)}, 0))*{num(1 / delta)}"
               f" + {num(c['damping'] / c['stiffness'] / delta ** 2)}*{r}*({rate})")
        points.append({"g": g, "g_expr": gap_expr, "f": f, "f_expr": pen, "electrode": pt["electrode"]})
        for v, a in used:
            per_coord[v].append((f, -c["stiffness"] * pt["gap"] ** 2 * delta * a / model.coordinates[v].scale))
    return points, per_coord
