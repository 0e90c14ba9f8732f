"""The .lib/.va header's statement of the etch laws (netgen.model.process: what recedes, the laws'
errors, the capacitances' ratios and shifts), kept apart from netgen.emit.process's other texts."""

from __future__ import annotations


def etch_header(e: dict, knots: list[float]) -> str:
    """The header's etch sentence from the model's etch record `e` and the torsion knots (etch / 1 um)."""
    lo, hi = (x * 1e6 for x in e["range_m"])
    body = (
        "the flexure beams (widths w - 2 etch), the proof mass's outline (sides - 2 etch) and etch holes "
        "(side + 2 etch)"
        if "beam" not in e
        else "the beam (width w - 2 etch"
        + (", its free tip back by etch: length L - etch)" if e["beam"] == "cantilever" else ", length fixed)")
    )
    return (
        f"etch (m) = lateral over-etch per edge of {body}, valid {lo:g}..{hi:g} um, mass, stiffness "
        "and damping "
        + (f"laws within {e['max_rel_error']:.1e}" if e["max_rel_error"] else "laws exact (power laws of w)")
        + (
            f", piecewise at etch {', '.join(f'{k:g}' for k in knots)} um where a flexure width meets "
            "the thickness (the torsion constant's kink; ek_<j> = (1e6 etch - knot)+)"
            if knots
            else ""
        )
        + etch_neglect(e)
        + ("; the a_in load times the etched body's ratio (a cubic in etch)" if e.get("acceleration") else "")
    )


def etch_neglect(e: dict) -> str:
    """The header's statement of the capacitances under etch: each electrode's C times its ratio
    pc_<electrode> (netgen.model.process.capacitance_laws), a comb's fit read at its etch-shifted state
    xe (gap g + 2 etch, overlap - 2 etch), and that law's error over the fit box."""
    if "capacitance_max_rel_error" not in e:
        return " (capacitances not etched)"
    err = e["capacitance_max_rel_error"]
    combs = any(r.get("shift") and not r.get("fill") for r in e.get("capacitance", []))
    fill = any(r.get("fill") for r in e.get("capacitance", []))
    fitted = any(r.get("stop_shift") for r in e.get("capacitance", []))
    return (
        "; capacitances times pc_<electrode>, a cubic in etch from the extractor at the etched "
        + ("beam" if "beam" in e else "outline, holes")
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
            ", the perforated plates' fits read at z shifted by the fill factor's effective gap change (nodes xe_z_*; their stops stay)"
            if fill
            else ""
        )
        + ", "
        + (f"within {err:.1e} over the fit box" if err else "exact")
    )
