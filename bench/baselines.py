"""Benchmark baselines of the ngspice emission, for what the product emitter
(netgen.emit.ngspice) is measured against in bench/sigma_delta.py and bench/callgrind.py:

  naive   every charge and force written out inline (no shared nodes, no contact model, no
          noise): docs/performance.md, 'Where it started: the cost of naive emission';
  nodes   the previous shared-node emission: each P_k (and its contact clamp) and each force
          node y = dv2 slope / P^2 as a B-source, the charges as `C ... Q=` capacitors; the rest
          (mechanics, stops, film, inertial loads) as in the product .lib.
"""

from __future__ import annotations

import numpy as np

from netgen.core.templating import render
from netgen.emit import ngspice
from netgen.emit.common import (
    clamp_expr,
    contact_terms,
    dv2_node,
    force_gain,
    node,
    num,
    poly_expr,
    slope_expr,
    time_scale,
    y_node,
)
from netgen.model import MacroModel


def nodes_subcircuit(model: MacroModel, noise: bool | None = False) -> str:
    """The shared-node baseline (module docstring), rendered with the product template."""
    ctx = ngspice.mechanics_context(model, noise)
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    for v, row in enumerate(ctx["coords"]):
        row["force_expr"], row["linear"] = ngspice.force_terms(model, v, ws, state)
    clamps = model.term_clamps()
    for i, (row, f) in enumerate(zip(ctx["fits"], model.capacitances)):
        cl = clamps[i] if clamps else [None] * len(f.polys)
        row.update(
            {
                "nodes": [
                    n for k, p in enumerate(f.polys) for n in term_nodes(f.electrode, k, poly_expr(p, state), cl[k])
                ],
                "dv2": {
                    "name": dv2_node(f.electrode),
                    "expr": f"v({f.electrode},{model.plate})*v({f.electrode},{model.plate})",
                },
                "gs": [],
                "ys": []
                if f.target == "direct"
                else [
                    {
                        "name": y_node(f.electrode, k),
                        "expr": f"v({dv2_node(f.electrode)})"
                        + (f"*{slope_expr(f'v({node(f.electrode, k)})', *cl[k])}" if cl[k] else "")
                        + f"/(v({node(f.electrode, k)})*v({node(f.electrode, k)}))",
                    }
                    for k in range(len(f.polys))
                ],
                "charge_expr": ngspice.charge_expr(f, model.plate),
            }
        )
    stops, per_coord = contact_terms(model)
    ngspice.add_stops(ctx, model, stops, per_coord)
    return (
        f"* {model.name}: NODES benchmark baseline emission (bench/baselines.py nodes_subcircuit); the section\n"
        "* comments below are the product template's (netgen.emit.ngspice), the B-sources are the baseline's\n"
        + render(ngspice.TEMPLATE, **ctx)
    )


BASELINES = {"naive": lambda model, noise=False: naive_subcircuit(model), "nodes": nodes_subcircuit}


def naive_subcircuit(model: MacroModel) -> str:
    """The benchmark baseline (docs/performance.md, 'the cost of naive emission'): the same
    ports and states, but every charge written out as c_ref * sum_k 1/P_k(xs) with the polynomials
    inline and every generalized force as one B-source holding the derivative polynomials of all
    terms, -c_ref/(2 L) sum_i dv_i^2 sum_k dP_k/dxs / P_k^2: no shared nodes, no contact model,
    no thermal noise. Not for use: it is what the fast form is measured against."""
    ws = time_scale(model)
    state = [f"xs_{c.name}" for c in model.coordinates]
    plate = model.plate
    lines = [
        f"* {model.name}: NAIVE benchmark baseline emission (bench/baselines.py naive_subcircuit)",
        f".subckt {model.name} " + " ".join(p["name"] for p in model.ports()),
    ]
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
                    parts.append(
                        f"{num(-g)}*({poly_expr(d, state)})*{dv[f.electrode]}*{dv[f.electrode]}/(({pe})*({pe}))"
                    )
        lines += [
            f"Cx_{c.name} xs_{c.name} 0 {num(1.0 / ws)}",
            f"Bx_{c.name} 0 xs_{c.name} I=v(u_{c.name})",
            f"Cu_{c.name} u_{c.name} 0 {num(1.0 / ws)}",
            f"Bu_{c.name} 0 u_{c.name} I=" + " + ".join(parts).replace("+ -", "- "),
            f"Ex_{c.name} x_{c.name} 0 xs_{c.name} 0 {num(c.scale / c.port_units[1])}",
        ]
    for f in model.capacitances:
        if f.target == "direct":
            cap = f"{num(f.c_ref)}*({poly_expr(f.polys[0], state)})"
        else:
            cap = f"{num(f.c_ref)}*(" + " + ".join(f"1/({poly_expr(p, state)})" for p in f.polys) + ")"
        lines.append(f"Cq_{f.electrode} {f.electrode} {plate} Q='{cap}*{dv[f.electrode]}'")
    lines += [
        f"Cc_{names[0]}_{names[1]} {names[0]} {names[1]} {num(model.coupling[i, j])}"
        for i, j, names in (
            (i, j, (model.electrodes[i].name, model.electrodes[j].name))
            for i in range(len(model.electrodes))
            for j in range(i + 1, len(model.electrodes))
        )
        if model.coupling[i, j]
    ]
    lines.append(f".ends {model.name}")
    return "\n".join(lines) + "\n"


def term_nodes(electrode: str, k: int, expr: str, clamp: tuple[float, float] | None) -> list[dict]:
    """B-source nodes of one plate term: P itself, or the raw P and its clamp (a one-variable
    expression: ngspice differentiates it far faster than the clamp of the full polynomial)."""
    name = node(electrode, k)
    if clamp is None:
        return [{"name": name, "expr": expr}]
    raw = "r" + name
    return [{"name": raw, "expr": expr}, {"name": name, "expr": clamp_expr(f"v({raw})", *clamp)}]
