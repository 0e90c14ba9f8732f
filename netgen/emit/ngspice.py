"""The ngspice emitter: a MacroModel as a .subckt of behavioural (B) sources and linear
elements (templates/ngspice/subckt.lib.j2). The electrode currents are ngspice's own dQ/dt of
charge-conserving charges; no physics here, everything is read from the MacroModel."""

from __future__ import annotations

import math

import numpy as np

from ..core.constants import K_B
from ..core.templating import render
from ..fit.polynomial import Polynomial
from ..model import MacroModel
from . import etch_state, inertial, process
from .common import (
    c_node,
    contact_terms,
    dv2_node,
    force_gain,
    g_node,
    header_context,
    node,
    noise_enabled,
    noise_kelvin,
    nonlinear_forces,
    num,
    poly_expr,
    rest_capacitance,
    time_scale,
    unit_load,
    y_node,
)


def force_terms(model: MacroModel, v: int, ws: float, state: list[str]) -> tuple[str, list[tuple[str, str]]]:
    """Right-hand side current of the velocity integrator of coordinate v: a behavioural
    expression, and (node, gain) pairs of forces linear in a y node (emitted as cheap VCCS)."""
    c = model.coordinates[v]
    a = force_gain(c, ws)
    parts, linear = [f"{gain}*v({n})" for n, gain in linear_force_terms(model, v, ws)], []
    for f in model.capacitances:
        fstate = process.electrode_state(model, f.electrode, state)
        for k, poly in enumerate(f.polys):
            dpoly = poly.derivative(v)
            if not np.any(dpoly.coeffs):
                continue
            g = a * f.c_ref / (2.0 * c.scale)
            if f.target == "direct":  # F = g dP/dx dV^2
                parts.append(f"{num(g)}*({poly_expr(dpoly, fstate)})*v({dv2_node(f.electrode)})")
            elif dpoly.exponents.sum() == 0:  # affine P_k: F linear in y_k
                linear.append((y_node(f.electrode, k), num(-g * float(dpoly.coeffs.sum()))))
            else:
                parts.append(f"{num(-g)}*({poly_expr(dpoly, fstate)})*v({y_node(f.electrode, k)})")
    return " + ".join(parts).replace("+ -", "- "), linear


def linear_force_terms(model: MacroModel, v: int, ws: float) -> list[tuple[str, str]]:
    """(node, gain) of the linear right-hand side of coordinate v's velocity integrator (the
    external force port, spring, damper), i.e. `force_terms` without the electrostatics, as VCCS."""
    c = model.coordinates[v]
    a = force_gain(c, ws)
    terms = [(f"f_{c.name}", num(a * c.port_units[3]))]
    if c.stiffness:
        terms.append((f"xs_{c.name}", process.factor(model, "pk", c.name, num(-c.stiffness / (c.mass * ws * ws)))))
    if c.damping:
        terms.append((f"u_{c.name}", process.factor(model, "pd", c.name, num(-c.damping / (c.mass * ws)))))
    return terms


def charge_expr(f, plate: str, ratio: str = "") -> str:
    """Charge of one plate-electrode capacitor, Q = C(q) * (V_e - V_plate) (times `ratio`, an etch
    ratio's parameter, where given)."""
    c_ref = f"{{{ratio}*{num(f.c_ref)}}}" if ratio else num(f.c_ref)
    if f.target == "direct":
        cap = f"{c_ref}*v({node(f.electrode, 0)})"
    else:
        cap = f"{c_ref}*(" + " + ".join(f"1/v({node(f.electrode, k)})" for k in range(len(f.polys))) + ")"
    return f"{cap}*v({f.electrode},{plate})"


def charge_node(electrode: str, factor: str, plate: str, c_ref: float | str) -> dict:
    """The behavioural part of an electrode's charge, c_ref c_i (V_e - V_plate) with c_i the
    expression `factor` (e.g. v(c_e)), as the node qn_e = c_i (V_e - V_plate) on a linear
    capacitor c_ref, whose current the electrode draws through a CCCS. Why not `C ... Q=`:
    ngspice expands that into 3 equations
    per electrode (G, L, B) whose coupling filled the sparse LU 2.4x more (723 against 297 fill-ins
    in the sigma-delta bench, 15 % of its instructions per Newton iteration; bench/callgrind.py);
    this form adds 2 and integrates the same charge with the same rule."""
    return {
        "b": f"Bqn_{electrode} qs_{electrode} 0 V={factor}*v({electrode},{plate})",
        "v": f"Vqm_{electrode} qs_{electrode} qn_{electrode} 0",
        "c": f"Cqn_{electrode} qn_{electrode} 0 {c_ref if isinstance(c_ref, str) else num(c_ref)}",
        "f": f"Fq_{electrode} {electrode} {plate} Vqm_{electrode} 1",
    }


def noise_context(model: MacroModel, ws: float) -> dict:
    """Template fields of the thermal force noise sources (damped coordinates only): a TRNOISE source
    for .tran and, in series, the CCVS Hn_<q> reading the resistor Rn_<q> whose thermal noise .noise sees
    (noise_resistance, noise_resistor)."""
    temp = noise_kelvin(model)
    f_max = max(
        [c.frequency_hz for c in model.coordinates]
        + [ws / (2 * math.pi)]
        + [w / (2 * math.pi) for c in model.coordinates for _, w in c.film]
    )  # film branch corners
    dt = float(f"{1.0 / (50.0 * f_max):.3g}")
    sources = [
        {
            "name": c.name,
            "rms": num(math.sqrt(2.0 * K_B * temp * c.damping) / c.port_units[3])
            + (f"*sqrt(pt_{c.name})" if process.active(model, "pt") else ""),
            "gain": num(c.port_units[3] / (c.mass * c.scale * ws * ws)),
            **noise_resistor(
                model, process.factor(model, "pd", c.name, num(noise_resistance(c.damping, c.port_units[3])))
            ),
        }
        for c in model.coordinates
        if c.damping > 0
    ]
    return {
        "noise_sources": sources,
        "noise_temperature": "the instance's temp + 273.15" if process.declared(model, "temp") else f"{temp:g}",
        "noise_dt": f"{dt:g}",
        "subckt_params": f"\n+ params: noise=1 noise_dt={dt:g}" if sources else "",
    }


# ngspice's default nominal temperature TNOM (27 degC, in K): a resistor's value is R (1 + tc1 (T - TNOM))
# at the circuit temperature T, so tc1 = 1 / TNOM makes it R T / TNOM (noise_resistor)
NGSPICE_TNOM_K = 300.15
# ngspice's Boltzmann constant (CONSTboltz in its const.h: CODATA 2014, 1.38064852e-23 J/K, in 39 and
# 46 alike): a resistor's noise PSD is 4 CONSTboltz T R, 3.5e-7 below 4 K_B T R with the exact SI K_B
K_B_NGSPICE = 1.38064852e-23


def noise_resistance(damping: float, force_unit: float) -> float:
    """The .noise resistor whose ngspice noise PSD 4 CONSTboltz T R is 4 K_B T D in force-port units
    (D / unit^2 scaled by K_B / K_B_NGSPICE); it carries no current, so only its noise sees R."""
    return damping / force_unit**2 * (K_B / K_B_NGSPICE)


def noise_resistor(model: MacroModel, rn: str) -> dict[str, str]:
    """The .noise source of a resistance rn (ngspice text) at the model's noise temperature T_d under any
    .temp: the resistor Rn = rn TNOM / T_d with tc1 = 1 / TNOM is rn T / T_d at the circuit temperature T,
    so its short-circuit noise current 4 k T / (rn T / T_d) = 4 k T_d / rn does not depend on T; a CCVS of
    gain rn reads it as the voltage noise 4 k T_d rn. (ngspice's resistor temp= and dtemp cannot do it:
    39 ignores temp=, 46 adds TNOM to it, and numparam cannot read the circuit temperature.)"""
    inner = rn[1:-1] if rn.startswith("{") else rn
    t_d = process.noise_temperature(model)
    if inner == rn and not process.declared(model, "temp"):
        ohms = num(float(rn) * NGSPICE_TNOM_K / float(t_d))
    else:
        ohms = f"{{{inner}*{num(NGSPICE_TNOM_K)}/{t_d}}}"
    return {"rn": rn, "rn_ohms": ohms, "tc1": num(1.0 / NGSPICE_TNOM_K)}


TEMPLATE = "ngspice/subckt.lib.j2"


def mechanics_context(model: MacroModel, noise: bool | None, gaps: bool = True) -> dict:
    """Template context of every part of the .lib but the electrostatics: the header tables, the
    integrators of each coordinate, thermal noise, strain-energy forces, film branches and inertial
    loads (shared with netgen.emit.xspice)."""
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    ctx = header_context(model)
    if noise_enabled(model, noise):
        ctx.update(noise_context(model, ws))
    for row, c in zip(ctx["coords"], model.coordinates):
        row.update({"cint": num(1.0 / ws), "out_gain": num(c.scale / c.port_units[1])})
        row["cu"] = process.factor(model, "pm", c.name, num(1.0 / ws))
    ctx["nonlinear"] = nonlinear_sources(model, ws, state)
    ctx["film"] = film_branches(model, ws, noise_enabled(model, noise))
    ctx["inertial"] = inertial_loads(model, ws)
    ctx["inertial_xy"] = inertial.acceleration_gains(model, ws)
    ctx["rates"] = inertial.rate_expressions(model, ws)
    ctx["inertial_text"] = inertial.header_lines(model)
    if any("rms" in b for b in ctx["film"]) and not ctx.get("subckt_params"):
        dt = noise_context(model, ws)["noise_dt"]  # the branches' noise needs the instance params
        ctx.update({"noise_dt": dt, "subckt_params": f"\n+ params: noise=1 noise_dt={dt}"})
    add_process(ctx, model, gaps)
    return ctx


def add_process(ctx: dict, model: MacroModel, gaps: bool = True) -> None:
    """The process instance parameters (netgen.emit.process): defaults on the .subckt line, the derived
    .param lines, the shifted gap states (`gaps`: the form reads them) and the header's statement."""
    if not process.enabled(model):
        return
    extra = " ".join(f"{n}={v}" for n, v in process.params(model, gaps))
    old = ctx.get("subckt_params", "")
    if extra:
        ctx["subckt_params"] = f"{old} {extra}" if old else f"\n+ params: {extra}"
    ctx["process_params"] = [f".param {n} = {{{e}}}" for n, e in process.factors(model)]
    ctx["gap_shift"] = process.gap_networks(model) if gaps else []
    ctx["etch_shift"] = process.etch_networks(model)
    ctx["etch_state"] = etch_state.factor_lines(model)
    ctx["state_forces"] = etch_state.force_rows(model, time_scale(model))
    ctx["process_text"] = process.header_text(model, gaps)


def add_stops(ctx: dict, model: MacroModel, stops: list[dict], per_coord: list[list[tuple[str, float]]]) -> None:
    """The contact stops' rows (netgen.emit.common.contact_terms) and their force gains per coordinate."""
    ws = time_scale(model)
    for row, c, terms in zip(ctx["coords"], model.coordinates, per_coord):
        a = force_gain(c, ws)
        row["stops"] = [(name, num(a * gain)) for name, gain in terms]
        row["stop_damping"] = ""  # the B form's dampers: context (stop_damping)
    ctx["stops"] = stops


def context(model: MacroModel, noise: bool | None = None) -> dict:
    """Template context of the B-source .lib: the form ngspice evaluates cheapest (measured,
    bench/callgrind.py): affine P_k as linear VCCS networks, one clamped 1/P_k node per plate
    term, force nodes y = dv2 g^2 slope, charges linear in the g nodes, stop forces gated by a ternary."""
    ctx = mechanics_context(model, noise)
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    for v, row in enumerate(ctx["coords"]):
        row["force_expr"], row["linear"] = force_terms(model, v, ws, state)
    clamps = model.term_clamps()
    for i, (row, f) in enumerate(zip(ctx["fits"], model.capacitances)):
        fstate = process.electrode_state(model, f.electrode, state)
        row.update(fast_fit(model, f, clamps[i] if clamps else [None] * len(f.polys), fstate))
    stops, per_coord = contact_terms(model, offsets=process.stop_offsets(model, braces=True))
    for pt in stops:  # no penetration, no force: the ternary skips the penalty's derivative trees
        pt["f_expr"] = f"v({pt['g']}) > 0 ? {pt['spring']} : 0"
    add_stops(ctx, model, stops, per_coord)
    damping = stop_damping(model, stops, per_coord)
    for row, c in zip(ctx["coords"], model.coordinates):
        row["stop_damping"] = damping.get(c.name, "")
    return ctx


def stop_damping(model: MacroModel, stops: list[dict], per_coord: list[list[tuple[str, float]]]) -> dict[str, str]:
    """coordinate -> the current its stops' dampers feed into u_<coordinate>: sum_j gain_j (v(sg_j) > 0 ?
    (c/k) w dp_j/dt / delta : 0). A current, not a term of the node sf_j, for a tight .op: with the damper
    in sf_j, accelerometer_xyz pushed onto a finger stop at etch 0.1 um (reltol 1e-12, vntol 1e-15) failed
    Newton, gmin and source stepping, and ngspice's transient op left the mass moving (1.5e-6 off the rest);
    10 of 17 round-off-level variants of that deck failed so, 1 of 17 in this form (CHANGELOG). That vntol
    lies under the velocity nodes' rounding floor, where convergence is luck (docs/contact.md, Newton at
    a stop): at vntol 1e-12 V this form converges in 5-6 iterations on every variant."""
    ws = time_scale(model)
    parts = {pt["f"]: (pt["g"], pt["damping"]) for pt in stops}
    out = {}
    for c, terms in zip(model.coordinates, per_coord):
        a = force_gain(c, ws)
        items = [f"(v({parts[f][0]}) > 0 ? {num(a * gain)}*{parts[f][1]} : 0)" for f, gain in terms]
        if items:
            out[c.name] = " + ".join(items)
    return out


def subcircuit(model: MacroModel, noise: bool | None = None) -> str:
    """The complete .lib text of the model's subcircuit (thermal force noise per `noise_enabled`)."""
    return render(TEMPLATE, **context(model, noise))


# ------------------------------------------------------------------ the fast form (what ngspice evaluates cheapest)
#
# ngspice evaluates a B-source by walking its parse tree and one symbolic derivative tree per
# variable, about 100 instructions per tree node, with no sharing between the trees. Measured
# per evaluation (callgrind, ngspice 39.3): B-source with an affine expression in 7 nodes 3.9k
# instructions, the same as 7 VCCS + R 1.4k; clamp of P as max(...exp(min(...))) 3.6k; y =
# dv2 slope(P) / P^2 6.6k; 1/P with the clamp as a ternary 2.8k; y = dv2 g min(g, (1 - f g)/s) 5.0k,
# the same as a ternary on g 3.4k; a Q= capacitor with 9 x 1/v(p) terms 15.5k, with 9 v(g) terms
# 10.9k, with one v(c) node 3.5k (+ the linear network summing the g nodes into c, ~1.5k).


def affine(poly: Polynomial) -> bool:
    """Every term of degree <= 1."""
    return bool(np.all(poly.exponents.sum(axis=1) <= 1))


def linear_network(name: str, poly: Polynomial, state: list[str]) -> list[str]:
    """Node `name` = affine P(xs) from linear elements: 1 ohm to ground fed by a constant current and
    one VCCS per coordinate (no parse trees to evaluate)."""
    lines = [unit_load(name)]
    for e, c in zip(poly.exponents, poly.coeffs):
        if c == 0.0:
            continue
        if e.sum() == 0:
            lines.append(f"I{name} 0 {name} {num(c)}")
        else:
            lines.append(f"G{name}_{int(np.argmax(e)) + 1} 0 {name} {state[int(np.argmax(e))]} 0 {num(c)}")
    return lines


def deviation(poly: Polynomial) -> Polynomial:
    """P(xs) - P(0): the polynomial without its constant term, 0 at rest."""
    return Polynomial(poly.exponents, np.where(poly.exponents.sum(axis=1) == 0, 0.0, poly.coeffs))


def plate_term(e: str, k: int, p0: float, clamp: tuple[float, float] | None, dv2: str) -> tuple[dict, dict]:
    """The g and y rows of plate term k of electrode e, g = 1/P_eff, from the node p = P - P(0):
    ngspice's operating-point Newton iteration starts from all nodes at 0, and p = 0 is the rest
    state, where an absolute P = 0 read as the clamped contact force and led it to the pulled-in root."""
    p, g = f"v({node(e, k)})", f"v({g_node(e, k)})"
    if not clamp:
        return {"name": g_node(e, k), "expr": f"1/({p} + {num(p0)})"}, {
            "name": y_node(e, k),
            "expr": f"v({dv2})*{g}*{g}",
        }
    knee, floor = clamp
    span = knee - floor
    below = f"({p} - {num(knee - p0)})".replace("- -", "+ ")  # P - knee
    gs = {
        "name": g_node(e, k),
        "expr": f"{p} > {num(knee - p0)} ? 1/({p} + {num(p0)}) : "
        f"1/({num(floor)} + {num(span)}*exp({below}/{num(span)}))",
    }
    # slope / P_eff^2 = g min(g, (1 - floor g) / span): g^2 above the knee (g < 1/knee), E g^2 below
    ys = {
        "name": y_node(e, k),
        "expr": f"{g} < {num(1 / knee)} ? v({dv2})*{g}*{g} : v({dv2})*{g}*({num(1 / span)} - {num(floor / span)}*{g})",
    }
    return gs, ys


def fast_fit(model: MacroModel, f, clamp: list, state: list[str]) -> dict:
    """Template rows of one electrode in the fast form (see the section comment above)."""
    e, plate = f.electrode, model.plate
    # the etch's capacitance ratio (netgen.emit.process.capacitance_ratios) scales C, so the charge and,
    # through dv2 (every force of the electrode is linear in it), the forces
    ratio = f"pc_{e}" if e in process.capacitance_ratios(model) else ""
    # a comb's state factor (netgen.emit.etch_state) scales C too: pr_<e> on dv2 and the charge
    pr = f"v(pr_{e})*" if e in etch_state.state_laws(model) else ""
    dv2 = {"name": dv2_node(e), "expr": (f"{{{ratio}}}*" if ratio else "") + f"{pr}v({e},{plate})*v({e},{plate})"}
    if f.target == "direct":
        return {
            "nodes": [{"name": node(e, 0), "expr": poly_expr(f.polys[0], state)}],
            "dv2": dv2,
            "ys": [],
            "gs": [],
            "charge_expr": pr + charge_expr(f, plate, ratio),
        }
    nodes, gs, ys = [], [], []
    zero = np.zeros((1, len(state)))
    for k, poly in enumerate(f.polys):
        shifted = deviation(poly)
        if affine(poly):
            lines = linear_network(node(e, k), shifted, state) + process.offset_lines(
                model, e, node(e, k), shifted, state
            )
            nodes.append({"name": node(e, k), "lines": lines})
        else:
            nodes.append({"name": node(e, k), "expr": poly_expr(shifted, state)})
        g_row, y_row = plate_term(e, k, float(poly(zero)[0]), clamp[k], dv2["name"])
        gs.append(g_row)
        ys.append(y_row)
    # C(0) as a linear capacitor and only the rest behavioural: the same charge, but the plate row of
    # the matrix is never empty (with uic every g node starts at 0: a floating plate was singular)
    # node c_i = sum_k g_k - C_i(0)/c_ref as a linear network, so the charge expression has 3 variables
    c0 = rest_capacitance(f, len(state))
    cs = c_node(e)
    sums = [unit_load(cs), f"I{cs} {cs} 0 {num(c0)}"] + [
        f"G{cs}_{k + 1} 0 {cs} {g_node(e, k)} 0 1" for k in range(len(f.polys))
    ]
    return {
        "nodes": nodes,
        "gs": gs,
        "ys": ys,
        "dv2": dv2,
        "sums": sums,
        "c0": process.charge_scale(model, e, num(f.c_ref * c0)),
        "charge": charge_node(
            e, etch_state.charge_factor(model, f, f"v({cs})"), plate, process.charge_scale(model, e, num(f.c_ref))
        ),
    }


def nonlinear_sources(model: MacroModel, ws: float, state: list[str]) -> list[dict]:
    """B current sources into the velocity nodes: the nonlinear restoring forces, scaled like
    every other force of that node (1 / (M L w_s^2))."""
    gains = [force_gain(c, ws) for c in model.coordinates]
    scale = "{pu}*" if process.energy_moved(model) else ""  # the strain energy's process law
    return [
        {"name": c.name, "expr": f"{scale}({e})" if scale else e}
        for c, e in zip(model.coordinates, nonlinear_forces(model, state, gain=gains))
        if e != "0"
    ]


# ------------------------------------------------------------------ compressible squeeze film (Maxwell branches)


def film_branches(model: MacroModel, ws: float, noise: bool) -> list[dict]:
    """Template rows of the compressible-film branches (Coordinate.film): per branch j of q a state
    w = F_j / (r_j L w_s) in the units of u obeying (1/w_s) w' = (corner/w_s)(u - w [+ noise]),
    and the force -r_j L w_s w on q. With noise each branch's damper carries its own thermal force
    S_F = 4 k_B T r_j (fluctuation-dissipation per branch: the sum has S_F = 4 k_B T Re B(omega))."""
    temp = noise_kelvin(model)
    # each branch's damper r_j times its factor d (netgen.emit.process_film.branch_law: pv under temp, pg_<set>
    # at a moved gap) and its corner times rg_<set> / d; the noise force sqrt(2 k_B T r) at the instance's
    # temp, its gain into w ~ corner / r
    rows = []
    for v, c in enumerate(model.coordinates):
        for j, (r, corner) in enumerate(c.film):
            law = process.branch_law(model, v, j)
            f = branch_texts(law)
            row = {
                "coord": c.name,
                "node": f"w_{c.name}_{j + 1}",
                "corner_hz": f"{corner / (2 * math.pi):.6g}",
                "damping": f"{r:.6g}",
                "g_in": f(num(corner / ws), "corner"),
                "r_out": f(num(ws / corner), "inverse"),
                "g_force": f(num(r / (c.mass * ws)), "damper"),
            }
            if noise:
                rms = num(math.sqrt(2.0 * K_B * temp * r) / c.port_units[3])
                t_ratio = f"*(temp + {num(process.KELVIN)})/{num(temp)}" if process.film_scaled(model) else ""
                row.update(
                    {
                        "rms": f"{rms}*sqrt({law[0]}{t_ratio})" if law else rms,
                        "gain": f(num(corner * c.port_units[3] / (ws * r * c.scale * ws)), "gain"),
                        **noise_resistor(model, f(num(noise_resistance(r, c.port_units[3])), "damper")),
                    }
                )
            rows.append(row)
    return rows


def branch_texts(law: tuple[str, str] | None):
    """(value, kind) -> ngspice text of a film branch's value times its process factor (netgen.emit.
    process.branch_law): kind damper (d), corner (rg / d), inverse (d / rg) or gain (rg / d^2)."""
    if law is None:
        return lambda x, kind: x
    d, gset = law
    dd = f"({d})" if "*" in d else d
    rg = f"rg_{gset}" if gset else ""
    texts = {
        "damper": f"*{dd}",
        "corner": f"*{rg}/{dd}" if rg else f"/{dd}",
        "inverse": f"*{dd}/{rg}" if rg else f"*{dd}",
        "gain": f"*{rg}/({dd}*{dd})" if rg else f"/({dd}*{dd})",
    }
    return lambda x, kind: f"{{{x}{texts[kind]}}}"


def inertial_loads(model: MacroModel, ws: float) -> list[dict]:
    """Per coordinate with a non-zero participation G_v: the gain from the a_in port (m/s^2) into
    its velocity node, G_v / (M L w_s^2) (the inertial force -G_v a_in, like F_ext), times its process
    law (netgen.emit.process.load_factor)."""
    return [
        {
            "coord": c.name,
            "gain": process.load_factor(model, v, num(g / (c.mass * c.scale * ws * ws))),
            "participation": f"{g:.6g}",
        }
        for v, (c, g) in enumerate(zip(model.coordinates, model.acceleration))
        if g != 0.0
    ]
