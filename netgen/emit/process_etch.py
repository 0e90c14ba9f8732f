"""The .lib/.va header's statement of the etch laws (netgen.model.process: what recedes, the laws'
errors, the capacitances' ratios and shifts), kept apart from netgen.emit.process's other texts."""

from __future__ import annotations

from ..model import MacroModel
from .common import num, unit_load
from .process_base import declared, poly


def etch_header(e: dict, knots: list[float], state: bool = True) -> str:
    """The header's etch sentence from the model's etch record `e` and the torsion knots (etch / 1 um);
    `state`: the form renders the combs' state factors (etch_neglect)."""
    lo, hi = (x * 1e6 for x in e["range_m"])
    body = (
        "the flexure beams (widths w - 2 etch), the proof mass's outline (sides - 2 etch) and etch holes "
        "(side + 2 etch)"
        if "beam" not in e
        else "the beam (width w - 2 etch"
        + (", its free tip back by etch: length L - etch)" if e["beam"] == "cantilever" else ", length fixed)")
    )
    if "plate" in e:  # a plate's outline (netgen.model.etch_geometry.etched_plate)
        body = (
            "the plate (length and width - 2 etch" if e["plate"] == "piston" else "the disk (radius - etch"
        ) + "; an electrode edge drawn on the plate's recedes with it; given springs stay)"
    return (
        f"etch (m) = lateral over-etch per edge of {body}, valid {lo:g}..{hi:g} um, mass, stiffness "
        "and damping "
        + (
            f"laws within {e['max_rel_error']:.1e}"
            if e["max_rel_error"]
            else "laws exact (power laws of " + ("the sides)" if "plate" in e else "w)")
        )
        + (
            f", piecewise at etch {', '.join(f'{k:g}' for k in knots)} um where "
            + (
                "an electrode's edge meets the beam's or plate's (ek_<j> = (1e6 etch - knot)+)"
                if "beam" in e or "plate" in e
                else "a flexure width meets the thickness (the torsion constant's kink; ek_<j> = (1e6 etch - knot)+)"
            )
            if knots
            else ""
        )
        + etch_neglect(e, state)
        + ("; the a_in load times the etched body's ratio (a cubic in etch)" if e.get("acceleration") else "")
    )


def etch_neglect(e: dict, state: bool = True) -> str:
    """The header's statement of the capacitances under etch: each electrode's C times its ratio
    pc_<electrode> (netgen.model.process.capacitance_laws), a comb's fit read at its etch-shifted state
    xe (gap g + 2 etch, overlap - 2 etch), its state factor where it has one and the form renders it
    (`state`; netgen.model.etch_state), and that law's error over the fit box."""
    if "capacitance_max_rel_error" not in e:
        return " (capacitances not etched)"
    has = "capacitance_stateless_max_rel_error" in e
    tip = [r["state"]["below"] for r in e.get("capacitance", []) if "below" in r.get("state", {})]
    err = e["capacitance_max_rel_error"] if state or not has else e["capacitance_stateless_max_rel_error"]
    combs = any(r.get("shift") and not r.get("fill") for r in e.get("capacitance", []))
    fill = any(r.get("fill") for r in e.get("capacitance", []))
    fitted = any(r.get("stop_shift") for r in e.get("capacitance", []))
    return (
        "; capacitances times pc_<electrode>, a cubic in etch from the extractor at the etched "
        + ("beam" if "beam" in e else "plate" if "plate" in e else "outline, holes")
        + (
            " (piecewise at the knots)"
            if ("beam" in e or "plate" in e) and any(len(r["ratio"]) > 4 for r in e.get("capacitance", []))
            else ""
        )
        + (
            " and fingers, the combs' fits read at x, y shifted by their gap and overlap change (nodes xe_*; the fit's box and the stops move with etch)"
            if combs
            else ""
        )
        + (
            " plus a fitted part across the fingers for the far gap and the fringe (netgen.model.etch_combs; the stops follow the geometric shift)"
            if fitted
            else ""
        )
        + (
            (
                ", the combs' C times a state factor 1 + u P1(xs) + u^2 P2(xs), u = etch / 1 um (netgen.model.etch_state; nodes pr_*)"
                if state and not tip
                else ", the overhanging tip's C times a state factor 1 + v P1(xs) + v^2 P2(xs), "
                f"v = ({tip[0]:g} - etch / 1 um)+ (netgen.model.etch_state; nodes pr_*)"
                if state
                else ", the combs' state factor (netgen.model.etch_state) left out in this form"
            )
            if has
            else ""
        )
        + (
            (
                ", the plates' fits read at z shifted by the edge fringe's effective gap change (nodes xe_z_*; their stops stay)"
                if "plate" in e
                else ", the perforated plates' fits read at z shifted by the fill factor's effective gap change (nodes xe_z_*; their stops stay)"
            )
            if fill
            else ""
        )
        + (
            ", with tscale the product of the two laws times a cross factor 1 + (tscale - 1) (u Q1(xs) + u^2 Q2(xs))"
            " (netgen.model.etch_state; the plain product "
            f"{e['capacitance_product_max_rel_error']:.1e}, with it {e['capacitance_cross_max_rel_error']:.1e} "
            "at the (tscale, etch) box's corners)"
            if state and "capacitance_cross_max_rel_error" in e
            else ""
        )
        + ", "
        + (f"within {err:.1e} over the fit box" if err else "exact")
    )


def etch_columns(model: MacroModel, stops: bool = False) -> list[tuple[str, str, float]]:
    """The distinct etch shifts of the combs' capacitance terms (netgen.model.process.capacitance_laws):
    (node name xe_<q>_<i>, coordinate q, xs_q offset per metre of etch = shift / L_q), in order; with
    `stops` also the geometric shifts the contact stops read where a comb's shift has an effective part
    (stop_shift, netgen.model.etch_combs; the code model's stops read state columns)."""
    if not declared(model, "etch"):
        return []
    scale = {c.name: c.scale for c in model.coordinates}
    out: list[tuple[str, str, float]] = []
    laws = model.process["etch"].get("capacitance", [])
    for key in ("shift", "stop_shift") if stops else ("shift",):  # the stops' columns after the terms'
        for r in laws:
            for q, k in r.get(key, {}).items():
                if not any(c[1] == q and c[2] == k / scale[q] for c in out):
                    out.append((f"xe_{q}_{len(out) + 1}", q, k / scale[q]))
    return out


def etch_states(model: MacroModel, stops: bool = False) -> dict[str, dict[str, str]]:
    """electrode -> {coordinate: the etch-shifted node its capacitance terms read for it} (etch_columns);
    with `stops` the nodes its contact stops read instead: the geometric stop_shift where there is one,
    none for a plate's fill shift (netgen.model.etch_fill: an effective gap, the stops stay)."""
    scale = {c.name: c.scale for c in model.coordinates}
    cols = {(q, k): n for n, q, k in etch_columns(model, stops)}
    out: dict[str, dict[str, str]] = {}
    if not cols:
        return out
    for r in model.process["etch"].get("capacitance", []):
        shift = stop_shift(r) if stops else r.get("shift", {})
        if shift:
            out[r["electrode"]] = {q: cols[(q, k / scale[q])] for q, k in shift.items()}
    return out


def stop_shift(law: dict) -> dict[str, float]:
    """The shift per metre of etch an electrode's contact stops follow: a comb's geometric one (its
    stop_shift where the capacitance's shift has an effective part, netgen.model.etch_combs), none for
    a plate's fill shift (netgen.model.etch_fill)."""
    return {} if law.get("fill") else law.get("stop_shift", law.get("shift", {}))


def etch_networks(model: MacroModel, stops: bool = False) -> list[str]:
    """ngspice lines of the etch-shifted nodes xe = xs_q + (shift / L_q) etch (etch_columns; `stops`: the
    stops' columns too): 1 ohm, a VCCS and a parameter current source, linear."""
    lines = []
    for n, q, k in etch_columns(model, stops):
        lines += [unit_load(n), f"G{n} 0 {n} xs_{q} 0 1", f"I{n} 0 {n} {{{num(k)}*etch}}"]
    return lines


def knots(model: MacroModel) -> list[float]:
    """The mechanics laws' torsion knots (etch / 1 um, netgen.model.etch_knots) where etch is declared."""
    return list((model.process.get("etch") or {}).get("knots", [])) if declared(model, "etch") else []


def knot_params(model: MacroModel) -> list[tuple[str, str]]:
    """(name, expression) of ek_<j> = (1e6 etch - k_j)+ per knot, written (x + abs(x)) / 2: no branch,
    the same text in ngspice's .param and Verilog-A (netgen.model.etch_knots.basis)."""
    out = []
    for j, k in enumerate(knots(model)):
        x = "1e6*etch" if k == 0.0 else f"(1e6*etch - {num(k)})" if k > 0 else f"(1e6*etch + {num(-k)})"
        out.append((f"ek_{j + 1}", f"0.5*({x} + abs({x}))"))
    return out


def etch_ratio(model: MacroModel, ratio: list[float]) -> str:
    """An etch ratio's text: its cubic in 1e6 etch, plus per knot j its truncated powers in ek_<j>."""
    text = poly(ratio[:4], "(1e6*etch)")
    extra = [poly([0.0, *ratio[4 + 3 * j : 7 + 3 * j]], f"ek_{j + 1}") for j in range(len(knots(model)))]
    extra = [e for e in extra if e != "(0)"]
    return f"({' + '.join([text, *extra])})" if extra else text
