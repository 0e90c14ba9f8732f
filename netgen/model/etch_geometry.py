"""The etched geometry: a structure, beam or comb with its device layer's edges receded by a lateral
etch bias (netgen.model.process re-runs the mechanics and the extractor on it), and the combs' shifts
that stand for the etch in their fits."""

from __future__ import annotations

import dataclasses
from typing import Any

from ..structure import Structure
from ..structure.process_table import BEAM_KINDS, PLATE_KINDS


def etched(s: Structure, etch: float) -> Structure:
    """The structure with its device layer etched by `etch` per edge (m; negative: under-etch); a beam
    conductor as etched_beam. A proof mass: flexure beam, truss and thigh widths w - 2 etch, the proof
    mass's outline (length, width) - 2 etch and its etch holes' side + 2 etch on the drawn grid (pitch
    and count stay: lithography places them). Beam lengths and the beams' spacing (centre to centre)
    stay: they are set by the anchors' and the mass's edges, which recede together. The electrodes are
    not moved (etch_record states how much the capacitances would change)."""
    c: Any = s.conductor
    if c.kind in BEAM_KINDS:
        return dataclasses.replace(s, conductor=etched_beam(c, etch))
    if c.kind in PLATE_KINDS:
        return etched_plate(s, etch)
    f = c.flexure
    w = {k: getattr(f, k) - 2 * etch for k in ("width", "truss_width", "thigh_width") if getattr(f, k)}
    outline = {"length": c.length - 2 * etch, "width": c.width - 2 * etch}
    holes = {"hole": c.hole + 2 * etch, "hole_grid": c.holes()} if c.hole else {}
    changed = dataclasses.replace(c, flexure=dataclasses.replace(f, **w), **outline, **holes)
    sets = tuple(etched_comb(e, etch) if is_comb(e) else e for e in s.electrode_sets)
    return dataclasses.replace(s, conductor=changed, electrode_sets=sets)


def etched_plate(s: Structure, etch: float) -> Structure:
    """A plate etched by `etch` per edge: a piston's length and width - 2 etch (centred: every side
    recedes by etch), a free disk's radius - etch; its springs given as numbers stay. An electrode edge
    drawn on the plate's edge (the default "under the whole plate", a ring reaching the rim) moves with
    it: the designer drew the electrode as the plate, so its overlap is the etched plate's; an edge drawn
    elsewhere stays (one past the plate does not limit the overlap, netgen.model.etch_knots.plate_knots
    marks where the plate's edge passes one inside the range)."""
    c: Any = s.conductor
    if c.kind == "piston":
        x0, x1, y0, y1 = c.outline()
        new = dataclasses.replace(c, length=c.length - 2 * etch, width=c.width - 2 * etch)

        def edge(v: float, drawn: float, inward: float) -> float:
            return v + inward * etch if v == drawn else v

        sets = tuple(
            dataclasses.replace(
                e, x0=edge(e.x0, x0, 1.0), x1=edge(e.x1, x1, -1.0), y0=edge(e.y0, y0, 1.0), y1=edge(e.y1, y1, -1.0)
            )
            for e in s.electrode_sets
        )
        return dataclasses.replace(s, conductor=new, electrode_sets=sets)
    rings = [
        dataclasses.replace(e, rings=tuple((a, b - etch if b == c.radius else b) for a, b in e.rings))
        for e in s.electrode_sets
    ]
    return dataclasses.replace(s, conductor=dataclasses.replace(c, radius=c.radius - etch), electrode_sets=tuple(rings))


def etched_beam(c: Any, etch: float) -> Any:
    """A beam conductor etched by `etch` per edge: width w - 2 etch; a cantilever's free tip recedes by
    etch (length L - etch), its clamp stays (the anchor's edge, set by the anchor opening under the
    layer, not by this etch); a clamped-clamped beam's length stays (both ends on anchors). The
    x axis keeps its origin at the clamp, so the electrodes stay where they are drawn."""
    length = c.length - etch if c.kind == "cantilever" else c.length
    return dataclasses.replace(c, width=c.width - 2 * etch, length=length)


def is_comb(e: Any) -> bool:
    """A comb electrode (netgen.structure.electrodes.CombElectrode): fingers, not a plate."""
    return getattr(e, "kind", "") in ("lateral_comb", "transverse_comb")


def etched_comb(e: Any, etch: float) -> Any:
    """A comb with every finger sidewall and end receded by `etch`: finger width - 2 etch, gaps + 2
    etch (the far side's too), overlap - 2 etch (both comb's tips recede); the finger length (root and
    tip recede together), the pitch and the overlap's centre stay."""
    anti = e.anti_gap + 2 * etch if e.anti_gap else 0.0
    return dataclasses.replace(
        e, width=e.width - 2 * etch, gap=e.gap + 2 * etch, anti_gap=anti, overlap=e.overlap - 2 * etch
    )


def comb_shifts(s: Structure, names: list[str]) -> dict[str, dict[str, float]]:
    """electrode -> {coordinate: shift per metre of etch} of the combs: the etched comb is, for the
    parallel-plate part of its capacitance, the drawn one with the mass moved by these: a transverse
    comb's gap g + 2 etch is the fingers moved 2 etch away across (-sign), and every comb's overlap
    L0 - 2 etch is them moved 2 etch back along the fingers (-engage); a coordinate the model lacks
    is left out (its part goes into the ratio and its error)."""
    out: dict[str, dict[str, float]] = {}
    for e in s.electrode_sets:
        if not is_comb(e):
            continue
        across = "y" if e.orientation == "x" else "x"
        shift = {e.orientation: -2.0 * (1.0 if e.root == "+" else -1.0)}
        if e.kind == "transverse_comb":
            shift[across] = -2.0 * (1.0 if e.side == "+" else -1.0)
        out[e.name] = {q: k for q, k in shift.items() if q in names}
    return out


def comb_across(s: Structure, names: list[str]) -> dict[str, str]:
    """electrode -> the coordinate across its fingers (the one closing its gaps) of each transverse
    comb whose coordinate the model has (netgen.model.etch_combs fits an effective shift along it)."""
    out = {}
    for e in s.electrode_sets:
        across = "y" if getattr(e, "orientation", "") == "x" else "x"
        if getattr(e, "kind", "") == "transverse_comb" and across in names:
            out[e.name] = across
    return out


def scaled(s: Structure, tscale: float = 1.0, escale: float = 1.0) -> Structure:
    """The structure with the device layer (conductor, flexures and comb fingers) tscale times as
    thick and Young's modulus escale times as large (kinds without a modulus keep their given springs)."""
    c: Any = s.conductor  # every conductor kind is a dataclass with a thickness
    changes: dict = {"thickness": c.thickness * tscale}
    if hasattr(c, "youngs_modulus"):
        changes["youngs_modulus"] = c.youngs_modulus * escale
    flex = getattr(c, "flexure", None)
    if flex is not None and flex.thickness:
        changes["flexure"] = dataclasses.replace(flex, thickness=flex.thickness * tscale)
    sets = tuple(dataclasses.replace(e, thickness=e.thickness * tscale) if is_comb(e) else e for e in s.electrode_sets)
    return dataclasses.replace(s, conductor=dataclasses.replace(c, **changes), electrode_sets=sets)
