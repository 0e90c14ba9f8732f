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
    a = force_gain(c, ws)
    parts, linear = [f"{gain}*v({n})" for n, gain in _linear_force_terms(model, v, ws)], []
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


def force_gain(c, ws: float) -> float:
    """Scaled velocity rate per newton (or N*m) of generalized force on coordinate c:
    d u / d tau = F / (m L w_s^2), the factor every force term of its velocity integrator carries."""
    return 1.0 / (c.mass * c.scale * ws * ws)


def _linear_force_terms(model: MacroModel, v: int, ws: float) -> list[tuple[str, str]]:
    """(node, gain) of the linear right-hand side of coordinate v's velocity integrator (the
    external force port, spring, damper), i.e. `_force_terms` without the electrostatics, as VCCS."""
    c = model.coordinates[v]
    a = force_gain(c, ws)
    terms = [(f"f_{c.name}", num(a * c.port_units[3]))]
    if c.stiffness:
        terms.append((f"xs_{c.name}", num(-c.stiffness / (c.mass * ws * ws))))
    if c.damping:
        terms.append((f"u_{c.name}", num(-c.damping / (c.mass * ws))))
    return terms


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


def charge_node(electrode: str, factor: str, plate: str, c_ref: float) -> dict:
    """The behavioural part of an electrode's charge, c_ref c_i (V_e - V_plate) with c_i the
    expression `factor` (e.g. v(c_e)), as the node qn_e = c_i (V_e - V_plate) on a linear
    capacitor c_ref, whose current the electrode draws through a CCCS. Why not `C ... Q=`:
    ngspice expands that into 3 equations
    per electrode (G, L, B) whose coupling filled the sparse LU 2.4x more (723 against 297 fill-ins
    in the sigma-delta bench, 15 % of its instructions per Newton iteration; README "Performance");
    this form adds 2 and integrates the same charge with the same rule."""
    return {"b": f"Bqn_{electrode} qs_{electrode} 0 V={factor}*v({electrode},{plate})",
            "v": f"Vqm_{electrode} qs_{electrode} qn_{electrode} 0",
            "c": f"Cqn_{electrode} qn_{electrode} 0 {num(c_ref)}",
            "f": f"Fq_{electrode} {electrode} {plate} Vqm_{electrode} 1"}


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
    f_max = max([c.frequency_hz for c in model.coordinates] + [ws / (2 * math.pi)]
                + [w / (2 * math.pi) for c in model.coordinates for _, w in c.film])   # film branch corners
    dt = float(f"{1.0 / (50.0 * f_max):.3g}")
    sources = [{"name": c.name, "rms": num(math.sqrt(2.0 * K_B * temp * c.damping) / c.port_units[3]),
                "gain": num(c.port_units[3] / (c.mass * c.scale * ws * ws))}
               for c in model.coordinates if c.damping > 0]
    return {"noise_sources": sources, "noise_temperature": f"{temp:g}", "noise_dt": f"{dt:g}",
            "subckt_params": f"\n+ params: noise=1 noise_dt={dt:g}" if sources else ""}


STYLES = ("fast", "nodes", "naive", "xspice")


def subcircuit(model: MacroModel, noise: bool | None = None, style: str = "fast") -> str:
    """The complete .lib text of the model's subcircuit (thermal force noise per `noise_enabled`).

    style "fast" (default): the form ngspice evaluates cheapest (measured, see README
    "Performance"): affine P_k as linear VCCS networks, one clamped 1/P_k node per plate term,
    force nodes y = dv2 g^2 slope, charges linear in the g nodes, stop forces gated by a ternary.
    "nodes": the previous shared-node form (P_k, clamped P_k and y = dv2 slope / P^2 as B-sources).
    "naive": the benchmark baseline, every charge and force written out inline (no shared nodes,
    no contact model): see `naive_subcircuit`.
    "xspice": the plate terms, forces and stops in the compiled XSPICE code model netgen_es
    (netgen.codemodel; the netlist must load it): see `xspice_context`."""
    if style not in STYLES:
        raise ValueError(f"unknown ngspice emission style {style!r}; choose one of {STYLES}")
    if style == "naive":
        return naive_subcircuit(model)
    if style == "xspice" and xspice_refusal(model):
        raise ValueError(f"{xspice_refusal(model)}; fix: emit with style 'fast'")
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    ctx = header_context(model)
    if noise_enabled(model, noise):
        ctx.update(noise_context(model, ws))
    for v, (row, c) in enumerate(zip(ctx["coords"], model.coordinates)):
        if style == "xspice":                   # every mechanical term is linear here: VCCS, no parse trees
            row["force_g"] = _linear_force_terms(model, v, ws)
        terms = ("", []) if style == "xspice" else _force_terms(model, v, ws, state)
        row.update({"cint": num(1.0 / ws), **dict(zip(("force_expr", "linear"), terms)),
                    "out_gain": num(c.scale / c.port_units[1])})
    clamps = model.term_clamps()
    ctx["style"] = style
    for i, (row, f) in enumerate(zip(ctx["fits"], model.capacitances)):
        cl = clamps[i] if clamps else [None] * len(f.polys)
        if style == "fast":
            row.update(_fast_fit(model, f, cl, state))
            continue
        if style == "xspice":
            row.update(_xspice_fit(model, f))
            continue
        row.update({
            "nodes": [n for k, p in enumerate(f.polys) for n in _term_nodes(f.electrode, k, poly_expr(p, state), cl[k])],
            "dv2": {"name": dv2_node(f.electrode), "expr": f"v({f.electrode},{model.plate})*v({f.electrode},{model.plate})"},
            "ys": [] if f.target == "direct" else
                  [{"name": y_node(f.electrode, k), "expr": f"v({dv2_node(f.electrode)})"
                    + (f"*{slope_expr(f'v({node(f.electrode, k)})', *cl[k])}" if cl[k] else "")
                    + f"/(v({node(f.electrode, k)})*v({node(f.electrode, k)}))"}
                   for k in range(len(f.polys))],
            "charge_expr": charge_expr(f, model.plate)})
    if style == "xspice":                       # the stops are evaluated inside the code model
        ctx["xspice"] = xspice_context(model, ws)
        stops, per_coord = [], [[] for _ in model.coordinates]
    else:
        stops, per_coord = contact_terms(model)
    for row, c, terms in zip(ctx["coords"], model.coordinates, per_coord):
        a = force_gain(c, ws)
        row["stops"] = [(name, num(a * gain)) for name, gain in terms]
    if style == "fast":                 # no penetration, no force: the ternary skips the penalty's derivative trees
        for pt in stops:
            pt["f_expr"] = f"v({pt['g']}) > 0 ? {pt['f_expr']} : 0"
    ctx["stops"] = stops
    ctx["nonlinear"] = nonlinear_sources(model, ws, state)
    ctx["film"] = film_branches(model, ws, noise_enabled(model, noise))
    ctx["inertial"] = inertial_loads(model, ws)
    if any("rms" in b for b in ctx["film"]) and not ctx.get("subckt_params"):
        dt = noise_context(model, ws)["noise_dt"]            # the branches' noise needs the instance params
        ctx.update({"noise_dt": dt, "subckt_params": f"\n+ params: noise=1 noise_dt={dt}"})
    return render("ngspice_subckt.lib.j2", **ctx)


# ------------------------------------------------------------------ the "fast" form (what ngspice evaluates cheapest)
#
# ngspice evaluates a B-source by walking its parse tree and one symbolic derivative tree per
# variable, about 100 instructions per tree node, with no sharing between the trees. Measured
# per evaluation (callgrind, ngspice 39.3): B-source with an affine expression in 7 nodes 3.9k
# instructions, the same as 7 VCCS + R 1.4k; clamp of P as max(...exp(min(...))) 3.6k; y =
# dv2 slope(P) / P^2 6.6k; 1/P with the clamp as a ternary 2.8k; y = dv2 g min(g, (1 - f g)/s) 5.0k,
# the same as a ternary on g 3.4k; a Q= capacitor with 9 x 1/v(p) terms 15.5k, with 9 v(g) terms
# 10.9k, with one v(c) node 3.5k (+ the linear network summing the g nodes into c, ~1.5k).

def g_node(electrode: str, k: int) -> str:
    """Node carrying 1/P_eff of plate term k (the term's capacitance over c_ref)."""
    return f"g_{electrode}_{k + 1}"


def c_node(electrode: str) -> str:
    """Node carrying (C_i(q) - C_i(0)) / c_ref = sum_k g_k - sum_k 1/P_k(0)."""
    return f"c_{electrode}"


def _rest_capacitance(f, ncoords: int) -> float:
    """C_i(0) / c_ref = sum_k 1/P_k(0) of a plate fit (at rest no term is clamped)."""
    zero = np.zeros((1, ncoords))
    return float(sum(1.0 / poly(zero)[0] for poly in f.polys))


def _affine(poly: Polynomial) -> bool:
    return bool(np.all(poly.exponents.sum(axis=1) <= 1))


def _linear_network(name: str, poly: Polynomial, state: list[str]) -> list[str]:
    """Node `name` = affine P(xs) from linear elements: 1 ohm to ground fed by a constant current and
    one VCCS per coordinate (no parse trees to evaluate)."""
    lines = [f"R{name} {name} 0 1"]
    for e, c in zip(poly.exponents, poly.coeffs):
        if c == 0.0:
            continue
        if e.sum() == 0:
            lines.append(f"I{name} 0 {name} {num(c)}")
        else:
            lines.append(f"G{name}_{int(np.argmax(e)) + 1} 0 {name} {state[int(np.argmax(e))]} 0 {num(c)}")
    return lines


def _fast_fit(model: MacroModel, f, clamp: list, state: list[str]) -> dict:
    """Template rows of one electrode in the fast form (see the section comment above)."""
    e, plate = f.electrode, model.plate
    dv2 = {"name": dv2_node(e), "expr": f"v({e},{plate})*v({e},{plate})"}
    if f.target == "direct":
        return {"nodes": [{"name": node(e, 0), "expr": poly_expr(f.polys[0], state)}], "dv2": dv2, "ys": [],
                "gs": [], "charge_expr": charge_expr(f, plate)}
    nodes, gs, ys = [], [], []
    for k, poly in enumerate(f.polys):
        p, g = f"v({node(e, k)})", f"v({g_node(e, k)})"
        if _affine(poly):
            nodes.append({"name": node(e, k), "lines": _linear_network(node(e, k), poly, state)})
        else:
            nodes.append({"name": node(e, k), "expr": poly_expr(poly, state)})
        if clamp[k]:
            knee, floor = clamp[k]
            span = knee - floor
            gs.append({"name": g_node(e, k), "expr": f"{p} > {num(knee)} ? 1/{p} : "
                       f"1/({num(floor)} + {num(span)}*exp(({p} - {num(knee)})/{num(span)}))"})
            # slope / P_eff^2 = g min(g, (1 - floor g) / span): g^2 above the knee (g < 1/knee), E g^2 below
            ys.append({"name": y_node(e, k), "expr": f"{g} < {num(1 / knee)} ? v({dv2['name']})*{g}*{g} : "
                       f"v({dv2['name']})*{g}*({num(1 / span)} - {num(floor / span)}*{g})"})
        else:
            gs.append({"name": g_node(e, k), "expr": f"1/{p}"})
            ys.append({"name": y_node(e, k), "expr": f"v({dv2['name']})*{g}*{g}"})
    # C(0) as a linear capacitor and only the rest behavioural: the same charge, but the plate row of
    # the matrix is never empty (with uic every g node starts at 0: a floating plate was singular)
    # node c_i = sum_k g_k - C_i(0)/c_ref as a linear network, so the charge expression has 3 variables
    c0 = _rest_capacitance(f, len(state))
    cs = c_node(e)
    sums = [f"R{cs} {cs} 0 1", f"I{cs} {cs} 0 {num(c0)}"] + \
        [f"G{cs}_{k + 1} 0 {cs} {g_node(e, k)} 0 1" for k in range(len(f.polys))]
    return {"nodes": nodes, "gs": gs, "ys": ys, "dv2": dv2, "sums": sums, "c0": num(f.c_ref * c0),
            "charge": charge_node(e, f"v({cs})", plate, f.c_ref)}


# ------------------------------------------------------------------ the XSPICE code model form
#
# One compiled netgen_es instance (netgen/xspice/netgen_es/cfunc.mod) evaluates every plate term
# g_k = 1/P_eff,k, the generalized forces and the contact stops, with analytic partials; a second
# instance of the same model drives the capacitance nodes c_i only (an XSPICE instance stamps every
# output x input pair of its ports, so the charges' instance takes the coordinates alone). The
# charges stay ngspice capacitors, so the electrode currents are ngspice's own dQ/dt.

def _vector(values) -> str:
    return "[" + " ".join(str(int(v)) if isinstance(v, (int, np.integer)) else num(float(v)) for v in values) + "]"


def xspice_refusal(model: MacroModel) -> str | None:
    """Why the model has no xspice form, or None: the code model takes 1/P plate fits only."""
    direct = [f.electrode for f in model.capacitances if f.target == "direct"]
    return (f"electrode {direct[0]} has a 'direct' capacitance fit and the xspice emission needs 1/P fits "
            "(fit target 'plates')") if direct else None


def _xspice_fit(model: MacroModel, f) -> dict:
    """Template rows of one electrode in the xspice form: node c_i (driven by the code model into
    1 ohm), C_i(0) as a linear capacitor, the rest of the charge on the node qn_i (charge_node)."""
    c0 = _rest_capacitance(f, model.ncoords)
    cs = c_node(f.electrode)
    return {"sums": [f"R{cs} {cs} 0 1"], "c0": num(f.c_ref * c0),
            "charge": charge_node(f.electrode, f"v({cs})", model.plate, f.c_ref)}


def xspice_context(model: MacroModel, ws: float) -> dict:
    """The netgen_es instances and their .model card: every plate term as monomials of its
    polynomial, its clamp, and the per-coordinate force gains (the same scalings as the B form)."""
    n = model.ncoords
    clamps = model.term_clamps()
    p = {k: [] for k in ("term_elec", "mono_term", "mono_coef", "mono_exp", "knee", "floor", "cref", "c0")}
    for i, f in enumerate(model.capacitances):
        p["cref"].append(f.c_ref)
        p["c0"].append(_rest_capacitance(f, n))
        for k, poly in enumerate(f.polys):
            term = len(p["term_elec"])
            p["term_elec"].append(i)
            knee, floor = clamps[i][k] if clamps and clamps[i][k] else (0.0, 0.0)
            p["knee"].append(knee)
            p["floor"].append(floor)
            for e, c in zip(poly.exponents, poly.coeffs):
                if c != 0.0:
                    p["mono_term"].append(term)
                    p["mono_coef"].append(float(c))
                    p["mono_exp"].extend(int(x) for x in e)
    gains = [force_gain(c, ws) for c in model.coordinates]
    p["fgain"] = [a / (2.0 * c.scale) for a, c in zip(gains, model.coordinates)]
    stops = stop_constants(model)
    nstop = len(stops["a"]) if stops else 1             # the model card needs the vectors even without stops
    sa, sg = np.zeros((nstop, n)), np.zeros((nstop, n))
    delta, damp = (stops["delta"], stops["damp"]) if stops else (1e-3, 0.0)
    if stops:
        sa[:] = stops["a"]
        sg[:] = np.asarray(stops["gain"]) * np.asarray(gains)[None, :]
    sr = sa * ws
    p.update({"stop_a": sa.ravel(), "stop_rate": sr.ravel(), "stop_gain": sg.ravel()})
    xs = " ".join(f"xs_{c.name}" for c in model.coordinates)
    us = " ".join(f"u_{c.name}" for c in model.coordinates)
    ve = " ".join(f"%vd({f.electrode} {model.plate})" for f in model.capacitances)
    cs = " ".join(c_node(f.electrode) for f in model.capacitances)
    return {"name": f"{model.name}_es", "c_instance": f"[{xs}] NULL NULL NULL [{cs}]",
            "f_instance": f"[{xs}] [{ve}] [{us}] [{us}] NULL",
            "params": [(k, _vector(v)) for k, v in p.items()] + [("stop_delta", num(delta)), ("stop_damp", num(damp))],
            "terms": len(p["knee"]), "stops": len(stops["a"]) if stops else 0}


# ------------------------------------------------------------------ the naive baseline (benchmarks only)

def naive_subcircuit(model: MacroModel) -> str:
    """The benchmark baseline (README "Performance", design.md "cost of naive emission"): the same
    ports and states, but every charge written out as c_ref * sum_k 1/P_k(xs) with the polynomials
    inline and every generalized force as one B-source holding the derivative polynomials of all
    terms, -c_ref/(2 L) sum_i dv_i^2 sum_k dP_k/dxs / P_k^2: no shared nodes, no contact model,
    no thermal noise. Not for use: it is what the fast form is measured against."""
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    plate = model.plate
    lines = [f"* {model.name}: NAIVE benchmark baseline emission (netgen.emit_ngspice.naive_subcircuit)",
             f".subckt {model.name} " + " ".join(p["name"] for p in model.ports())]
    dv = {f.electrode: f"v({f.electrode},{plate})" for f in model.capacitances}
    for v, c in enumerate(model.coordinates):
        a = force_gain(c, ws)
        parts = [f"{num(a * c.port_units[3])}*v(f_{c.name})"]
        if c.stiffness:
            parts.append(f"{num(-c.stiffness / (c.mass * ws * ws))}*v({state[v]})")
        if c.damping:
            parts.append(f"{num(-c.damping / (c.mass * ws))}*v(u_{c.name})")
        for f in model.capacitances:
            g = a * f.c_ref / (2.0 * c.scale)
            for poly in f.polys:
                d = poly.derivative(v)
                if not np.any(d.coeffs):
                    continue
                if f.target == "direct":
                    parts.append(f"{num(g)}*({poly_expr(d, state)})*{dv[f.electrode]}*{dv[f.electrode]}")
                else:
                    pe = poly_expr(poly, state)
                    parts.append(f"{num(-g)}*({poly_expr(d, state)})*{dv[f.electrode]}*{dv[f.electrode]}"
                                 f"/(({pe})*({pe}))")
        lines += [f"Cx_{c.name} xs_{c.name} 0 {num(1.0 / ws)}", f"Bx_{c.name} 0 xs_{c.name} I=v(u_{c.name})",
                  f"Cu_{c.name} u_{c.name} 0 {num(1.0 / ws)}",
                  f"Bu_{c.name} 0 u_{c.name} I=" + " + ".join(parts).replace("+ -", "- "),
                  f"Ex_{c.name} x_{c.name} 0 xs_{c.name} 0 {num(c.scale / c.port_units[1])}"]
    for f in model.capacitances:
        if f.target == "direct":
            cap = f"{num(f.c_ref)}*({poly_expr(f.polys[0], state)})"
        else:
            cap = f"{num(f.c_ref)}*(" + " + ".join(f"1/({poly_expr(p, state)})" for p in f.polys) + ")"
        lines.append(f"Cq_{f.electrode} {f.electrode} {plate} Q='{cap}*{dv[f.electrode]}'")
    lines += [f"Cc_{names[0]}_{names[1]} {names[0]} {names[1]} {num(model.coupling[i, j])}"
              for i, j, names in ((i, j, (model.electrodes[i].name, model.electrodes[j].name))
                                  for i in range(len(model.electrodes)) for j in range(i + 1, len(model.electrodes)))
              if model.coupling[i, j]]
    lines.append(f".ends {model.name}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ nonlinear stiffness (netgen.suspended)

def nonlinear_forces(model: MacroModel, state: list[str], access: str = "v({})",
                     gain: list[float] | None = None) -> list[str]:
    """Per coordinate v, the restoring force -(1/L_v) dU/dxs_v of the model's fitted strain energy
    U(xs) (J) as an explicit polynomial of the states, times gain[v] (default 1: SI force)."""
    poly = model.nonlinear_energy_polynomial()
    if poly is None:
        return []
    out = []
    for v, c in enumerate(model.coordinates):
        d = poly.derivative(v)
        factor = -(1.0 if gain is None else gain[v]) / c.scale
        out.append(poly_expr(Polynomial(d.exponents, d.coeffs * factor), state, access=access))
    return out


def nonlinear_sources(model: MacroModel, ws: float, state: list[str]) -> list[dict]:
    """B current sources into the velocity nodes: the nonlinear restoring forces, scaled like
    every other force of that node (1 / (M L w_s^2))."""
    gains = [force_gain(c, ws) for c in model.coordinates]
    return [{"name": c.name, "expr": e} for c, e in zip(model.coordinates, nonlinear_forces(model, state, gain=gains))
            if e != "0"]


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


def stop_constants(model: MacroModel) -> dict | None:
    """The contact stops' numbers (netgen.contact): smoothing delta, damping factor (c/k)/delta^2,
    and per stop point its direction a_j (in xs) and the SI force per unit penalty on each
    coordinate, gain_jv = -k gap^2 delta a_jv / L_v; None without stop points."""
    c = model.contact
    if not c.get("points"):
        return None
    delta = c["smoothing"]
    gains = [[-c["stiffness"] * pt["gap"] ** 2 * delta * a / model.coordinates[v].scale if a != 0.0 else 0.0
              for v, a in enumerate(pt["a"])] for pt in c["points"]]
    return {"delta": delta, "damp": c["damping"] / c["stiffness"] / delta ** 2,
            "a": [list(pt["a"]) for pt in c["points"]], "gain": gains}


def contact_terms(model: MacroModel, access: str = "v({})",
                  var: str = "v({})") -> tuple[list[dict], list[list[tuple[str, float]]]]:
    """Stop points as (penetration, penalty) expressions, and per coordinate the (variable, SI force
    per unit) pairs: F_v = sum_j gain_jv * sf_j, sf_j = (pen + (c/k) w dp/dt) / delta."""
    points, per_coord = [], [[] for _ in model.coordinates]
    k = stop_constants(model)
    if k is None:
        return points, per_coord
    ws, delta = time_scale(model), k["delta"]
    xs = [access.format(f"xs_{c.name}") for c in model.coordinates]
    us = [access.format(f"u_{c.name}") for c in model.coordinates]
    for j, (pt, a_j, gain_j) in enumerate(zip(model.contact["points"], k["a"], k["gain"])):
        g, f = stop_name(j)
        used = [(v, a) for v, a in enumerate(a_j) if a != 0.0]
        gap_expr = " + ".join(f"{num(a)}*{xs[v]}" for v, a in used).replace("+ -", "- ") + " - 1"
        r = f"min(max({var.format(g)}, 0), {num(delta)})"
        rate = " + ".join(f"{num(a * ws)}*{us[v]}" for v, a in used).replace("+ -", "- ")
        pen = (f"({r}*{r}*{num(0.5 / delta)} + max({var.format(g)} - {num(delta)}, 0))*{num(1 / delta)}"
               f" + {num(k['damp'])}*{r}*({rate})")
        points.append({"g": g, "g_expr": gap_expr, "f": f, "f_expr": pen, "electrode": pt["electrode"]})
        for v, _ in used:
            per_coord[v].append((f, gain_j[v]))
    return points, per_coord


# ------------------------------------------------------------------ compressible squeeze film (Maxwell branches)

def film_branches(model: MacroModel, ws: float, noise: bool) -> list[dict]:
    """Template rows of the compressible-film branches (Coordinate.film): per branch j of q a state
    w = F_j / (r_j L w_s) in the units of u obeying (1/w_s) w' = (corner/w_s)(u - w [+ noise]),
    and the force -r_j L w_s w on q. With noise each branch's damper carries its own thermal force
    S_F = 4 k_B T r_j (fluctuation-dissipation per branch: the sum has S_F = 4 k_B T Re B(omega))."""
    temp = float(model.report.get("damping", {}).get("temperature_K", 300.0))
    rows = []
    for c in model.coordinates:
        for j, (r, corner) in enumerate(c.film):
            row = {"coord": c.name, "node": f"w_{c.name}_{j + 1}", "corner_hz": f"{corner / (2 * math.pi):.6g}",
                   "damping": f"{r:.6g}", "g_in": num(corner / ws), "r_out": num(ws / corner),
                   "g_force": num(r / (c.mass * ws))}
            if noise:
                row.update({"rms": num(math.sqrt(2.0 * K_B * temp * r) / c.port_units[3]),
                            "gain": num(corner * c.port_units[3] / (ws * r * c.scale * ws))})
            rows.append(row)
    return rows


def inertial_loads(model: MacroModel, ws: float) -> list[dict]:
    """Per coordinate with a non-zero participation G_v: the gain from the a_in port (m/s^2) into
    its velocity node, G_v / (M L w_s^2) (the inertial force -G_v a_in, like F_ext)."""
    return [{"coord": c.name, "gain": num(g / (c.mass * c.scale * ws * ws)), "participation": f"{g:.6g}"}
            for c, g in zip(model.coordinates, model.acceleration) if g != 0.0]
