"""The ngspice .lib with the electrostatics in the compiled XSPICE code model netgen_es
(netgen/sim/codemodel/netgen_es, built by netgen.sim.codemodel): the same ports, states,
scaling and header as the B-source .lib (netgen.emit.ngspice), whose template it shares."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.templating import render
from ..model import MacroModel
from . import etch_state, ngspice, process
from .common import c_node, force_gain, num, rest_capacitance, stop_constants, time_scale, unit_load

# ------------------------------------------------------------------ the XSPICE code model form
#
# One compiled netgen_es instance (netgen/sim/codemodel/netgen_es/cfunc.mod) evaluates every plate term
# g_k = 1/P_eff,k, the generalized forces and the contact stops, with analytic partials; a second
# instance of the same model drives the capacitance nodes c_i only (an XSPICE instance stamps every
# output x input pair of its ports, so the charges' instance takes the coordinates alone). The
# charges stay ngspice capacitors, so the electrode currents are ngspice's own dQ/dt.


def vector(values) -> str:
    return "[" + " ".join(str(int(v)) if isinstance(v, (int, np.integer)) else num(float(v)) for v in values) + "]"


def refusal(model: MacroModel) -> str | None:
    """Why the model has no xspice form, or None: the code model takes 1/P plate fits only."""
    direct = [f.electrode for f in model.capacitances if f.target == "direct"]
    return (
        (
            f"electrode {direct[0]} has a 'direct' capacitance fit and the xspice emission needs 1/P fits "
            "(fit target 'plates')"
        )
        if direct
        else None
    )


def fit_rows(model: MacroModel, f) -> dict:
    """Template rows of one electrode in the xspice form: node c_i (driven by the code model into
    1 ohm), C_i(0) as a linear capacitor, the rest of the charge on the node qn_i (charge_node)."""
    c0 = rest_capacitance(f, model.ncoords)
    cs, e = c_node(f.electrode), f.electrode
    return {
        "sums": [unit_load(cs)],
        "c0": process.charge_scale(model, e, num(f.c_ref * c0)),
        "charge": ngspice.charge_node(
            e, etch_state.charge_factor(model, f, f"v({cs})"), model.plate, process.charge_scale(model, e, num(f.c_ref))
        ),
    }


def etch_voltages(model: MacroModel) -> tuple[list[str], dict[str, str]]:
    """The code model's voltage inputs of the electrodes with an etch capacitance ratio pc_<e>
    (netgen.emit.process.capacitance_ratios): a VCVS node pv_<e> = sqrt(pc_<e>) (V_e - V_plate) (times
    sqrt(pr_<e>), a comb's state factor: netgen.emit.etch_state), so the compiled forces (quadratic in
    the voltage) carry pc_<e>; the charges scale on their capacitors
    (fit_rows). Lines and electrode -> its input."""
    lines, inputs, states = [], {}, etch_state.state_laws(model)
    for e in process.capacitance_ratios(model):
        if e in states:  # the comb's state factor pr_<e> too (netgen.emit.etch_state)
            lines.append(f"Bpv_{e} pv_{e} 0 V=sqrt({{pc_{e}}}*v(pr_{e}))*v({e},{model.plate})")
        else:
            lines.append(f"Epv_{e} pv_{e} 0 {e} {model.plate} {{sqrt(pc_{e})}}")
        inputs[e] = f"%vd(pv_{e} 0)"
    return lines, inputs


def gap_columns(model: MacroModel) -> tuple[list[str], dict[str, dict[int, int]], list[int]]:
    """The code model's extra state columns for the gap offsets and the combs' etch shifts
    (netgen.emit.process): one node xg_<set> = xs_z - sign dg_<set> / L_z per gap set and one node
    xe_<q>_<i> = xs_q + (shift / L_q) etch per etch shift; electrode -> {coordinate index: the column
    its terms read instead}; and per extra column its coordinate's index. A column's force output goes
    to that coordinate's u with its gain (dC/dxg = dC/dxs): the shifts exact, the compiled code model
    unchanged."""
    if not process.enabled(model):
        return [], {}, []
    n, sets = model.ncoords, [g["set"] for g in model.process["gaps"]]
    names = [c.name for c in model.coordinates]
    etch = process.etch_columns(model, stops=True)
    extra = [f"xg_{s}" for s in sets] + [c[0] for c in etch]
    coords = [names.index("z") for _ in sets] + [names.index(c[1]) for c in etch]
    column: dict[str, dict[int, int]] = {
        e: {names.index("z"): n + sets.index(g)} for e, (g, _) in process.gap_shifts(model).items()
    }
    for e, moves in process.etch_states(model).items():
        column.setdefault(e, {}).update({names.index(q): n + extra.index(node) for q, node in moves.items()})
    return extra, column, coords


def stop_columns(model: MacroModel, column: dict[str, dict[int, int]]) -> dict[str, dict[int, int]]:
    """electrode -> {coordinate index: the column its contact stops read}: the gap offset's column as
    the terms', and a comb's geometric etch shift (netgen.emit.process.etch_states with stops: not a
    plate's fill shift nor a comb's effective part, netgen.model.etch_combs)."""
    names = [c.name for c in model.coordinates]
    extra, _, _ = gap_columns(model)
    n, terms = model.ncoords, process.etch_states(model)
    out = {}
    for e, cols in column.items():  # the terms' etch columns dropped, the gap offset's kept
        moved = {names.index(q) for q in terms.get(e, {})}
        out[e] = {v: c for v, c in cols.items() if v not in moved}
    for e, moves in process.etch_states(model, stops=True).items():
        out.setdefault(e, {}).update({names.index(q): n + extra.index(node) for q, node in moves.items()})
    return out


def moved(row, moves: dict[int, int], width: int) -> list:
    """A row over the coordinates widened to `width` columns, each entry of `moves` (coordinate index ->
    column) moved to its column."""
    out = list(row) + [0] * (width - len(row))
    for v, col in moves.items():
        out[col], out[v] = out[v], 0
    return out


def code_model_context(model: MacroModel, ws: float) -> dict:
    """The netgen_es instances and their .model card: every plate term as monomials of its
    polynomial, its clamp, and the per-coordinate force gains (the same scalings as the B form);
    with gap offsets the extra columns of gap_columns."""
    extra, column, owner = gap_columns(model)
    n = model.ncoords + len(extra)
    clamps = model.term_clamps()
    stops_at = stop_columns(model, column)
    p: dict[str, Any] = {
        k: [] for k in ("term_elec", "mono_term", "mono_coef", "mono_exp", "knee", "floor", "cref", "c0")
    }
    for i, f in enumerate(model.capacitances):
        p["cref"].append(f.c_ref)
        p["c0"].append(rest_capacitance(f, n))
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
                    p["mono_exp"].extend(int(x) for x in moved(e, column.get(f.electrode, {}), n))
    gains = [force_gain(c, ws) for c in model.coordinates]
    gains += [gains[v] for v in owner]
    p["fgain"] = [a / (2.0 * c.scale) for a, c in zip(gains, model.coordinates)]
    p["fgain"] += [p["fgain"][v] for v in owner]
    stops = stop_constants(model)
    nstop = len(stops["a"]) if stops else 1  # the model card needs the vectors even without stops
    sa, sg = np.zeros((nstop, n)), np.zeros((nstop, n))
    delta, damp = (stops["delta"], stops["damp"]) if stops else (1e-3, 0.0)
    if stops:
        for j, (a, g, pt) in enumerate(zip(stops["a"], stops["gain"], model.contact["points"])):
            # a stop reads its electrode's shifted columns: it follows the gap offset and the comb's
            # geometric etch shift, not a plate's fill shift nor a comb's effective part (stop_columns)
            cols = stops_at.get(pt["electrode"], {})
            sa[j] = moved(a, cols, n)
            sg[j] = np.asarray(moved(g, cols, n)) * np.asarray(gains)
    sr = sa * ws
    p.update({"stop_a": sa.ravel(), "stop_rate": sr.ravel(), "stop_gain": sg.ravel()})
    xs = " ".join([f"xs_{c.name}" for c in model.coordinates] + extra)
    us = " ".join([f"u_{c.name}" for c in model.coordinates] + [f"u_{model.coordinates[v].name}" for v in owner])
    _, scaled = etch_voltages(model)
    ve = " ".join(scaled.get(f.electrode, f"%vd({f.electrode} {model.plate})") for f in model.capacitances)
    cs = " ".join(c_node(f.electrode) for f in model.capacitances)
    return {
        "name": f"{model.name}_es",
        "c_instance": f"[{xs}] NULL NULL NULL [{cs}]",
        "f_instance": f"[{xs}] [{ve}] [{us}] [{us}] NULL",
        "params": [(k, vector(v)) for k, v in p.items()] + [("stop_delta", num(delta)), ("stop_damp", num(damp))],
        "terms": len(p["knee"]),
        "stops": len(stops["a"]) if stops else 0,
    }


def subcircuit(model: MacroModel, noise: bool | None = None) -> str:
    """The complete _xspice.lib text: every mechanical term a linear element, the plate terms,
    forces and stops in the code model's instances (netgen.emit.ngspice for the shared parts)."""
    problem = refusal(model)
    if problem:
        raise ValueError(f"{problem}; fix: emit the B-source form (--format ngspice)")
    ctx = ngspice.mechanics_context(model, noise)
    # the code model's extra columns
    ctx["gap_shift"] = process.gap_networks(model, every=True)
    ctx["etch_shift"] = process.etch_networks(model, stops=True)
    ctx["etch_voltages"] = etch_voltages(model)[0]
    ws = time_scale(model)
    for v, row in enumerate(ctx["coords"]):  # every mechanical term is linear here: VCCS, no parse trees
        row.update({"force_g": ngspice.linear_force_terms(model, v, ws), "force_expr": "", "linear": []})
    for row, f in zip(ctx["fits"], model.capacitances):
        row.update(fit_rows(model, f))
    ctx["xspice"] = code_model_context(model, ws)  # the stops are evaluated inside the code model
    ngspice.add_stops(ctx, model, [], [[] for _ in model.coordinates])
    return render(ngspice.TEMPLATE, **ctx)
