"""The knots of the flexures' etch laws (netgen.model.process.etch_laws): where an etched beam's width
w - 2 etch passes its thickness t, the frame's Saint-Venant torsion constant (netgen.mechanics.frame.
torsion_constant, Roark's J = A B^3 (1/3 - 0.21 (B/A) (1 - B^4 / 12 A^4)) with A = max(w, t), B =
min(w, t)) changes formula: J is continuous there (0.1408 t^4) but its slope in w jumps, dJ/dw =
(1/3 - 0.07) t^3 = 0.2633 t^3 on the wide side and (1 - 0.84 + 0.14) t^3 = 0.30 t^3 on the narrow
one (14 % apart), and every stiffness the legs' torsion enters (z, the tilts) inherits the kink. One cubic in etch across it missed accelerometer_xyz's
k by 1.7e-3 (2 um legs on a 2 um layer: the kink at the nominal).

The law is then a cubic plus, per knot k inside the etch range, truncated powers c1 (u - k)+ + c2
(u - k)+^2 + c3 (u - k)+^3 of u = etch / 1 um ((x)+ = max(x, 0)): two cubics that join at the knot
in value, each free in slope (the space of continuous piecewise cubics with that knot). Without a
knot in the range the law is the cubic, as before (its text unchanged).

A beam conductor has no torsion knot but may have edge knots (edge_knots): where an electrode's edge
is drawn on the beam's own (examples/cantilever.toml: x 0..150 um, y the drawn width), the etched
beam's edge passes the electrode's there, and the facing area's slope in etch jumps (an under-etched
beam overhangs the electrode, an over-etched one does not). The capacitance ratio takes those knots;
where the cantilever's receded tip passes an electrode's far end (tip_knots) the overhanging tip,
where the mode deflects most, makes the ratio depend on the state on the longer side only, which
netgen.model.etch_state's factor carries in (k - u)+."""

from __future__ import annotations

from typing import Any

import numpy as np

ETCH_UNIT = 1e-6  # m: the etch laws are polynomials in etch / 1 um
PER_PIECE = 5  # re-runs per piece between breakpoints (ends included): 4 unknowns each, 1 to spare


def etch_knots(s: Any, lo: float, hi: float) -> tuple[float, ...]:
    """The etches (in units of ETCH_UNIT, sorted) strictly inside (lo, hi) m where an etched flexure
    width (beam, truss, thigh: netgen.model.process.etched) equals the flexures' thickness; () without."""
    c = s.conductor
    f = getattr(c, "flexure", None)
    t = (getattr(f, "thickness", 0.0) or getattr(c, "thickness", 0.0)) if f is not None else 0.0
    if not t:
        return ()
    widths = {getattr(f, k) for k in ("width", "truss_width", "thigh_width") if getattr(f, k, 0.0)}
    return tuple(sorted({(w - t) / 2 / ETCH_UNIT for w in widths if lo < (w - t) / 2 < hi}))


def edge_knots(s: Any, lo: float, hi: float) -> tuple[float, ...]:
    """The etches (etch / ETCH_UNIT, sorted) strictly inside (lo, hi) m where a beam conductor's etched
    edge (netgen.model.etch_geometry.etched_beam: sides at +-(w - 2 etch) / 2, a cantilever's tip at
    L - etch) meets one of its electrodes' edges; () for other conductors."""
    c = s.conductor
    if getattr(c, "kind", "") in ("piston", "free_disk"):
        return plate_knots(s, lo, hi)
    if getattr(c, "kind", "") not in ("cantilever", "clamped_clamped_beam"):
        return ()
    at: set[float] = set()
    for e in s.electrode_sets:
        y0, y1 = getattr(e, "y0", None), getattr(e, "y1", None)
        if y0 is None or y1 is None:
            continue
        at.update({c.width / 2 - y1, c.width / 2 + y0})
    at.update(tip_knots(s, lo, hi).values())
    return tuple(sorted({round(e / ETCH_UNIT, 12) + 0.0 for e in at if lo < e < hi}))


def plate_knots(s: Any, lo: float, hi: float) -> tuple[float, ...]:
    """The etches (etch / ETCH_UNIT, sorted) strictly inside (lo, hi) m where a plate's etched edge
    (netgen.model.etch_geometry.etched_plate: a piston's sides at +-(L - 2 etch) / 2, a disk's rim at
    R - etch) meets an electrode's edge drawn off the plate's (an edge drawn on it moves with it)."""
    c = s.conductor
    at: set[float] = set()
    for e in s.electrode_sets:
        if c.kind == "piston":
            x0, x1, y0, y1 = c.outline()
            edges = ((e.x0, x0, 1.0), (e.x1, x1, -1.0), (e.y0, y0, 1.0), (e.y1, y1, -1.0))
            at.update(inward * (v - drawn) for v, drawn, inward in edges if v != drawn)
        else:
            at.update(c.radius - b for _, b in e.rings if b != c.radius)
    return tuple(sorted({round(e / ETCH_UNIT, 12) + 0.0 for e in at if lo < e < hi}))


def tip_knots(s: Any, lo: float, hi: float) -> dict[str, float]:
    """electrode -> the etch (m) strictly inside (lo, hi) where a cantilever's receded tip L - etch
    meets the electrode's far end x1 (below it, the tip overhangs the electrode); {} otherwise."""
    c = s.conductor
    if getattr(c, "kind", "") != "cantilever":
        return {}
    ends = {e.name: c.length - e.x1 for e in s.electrode_sets if getattr(e, "x1", None) is not None}
    return {n: k for n, k in ends.items() if lo < k < hi}


def record_knots(s: Any, lo: float, hi: float) -> tuple[float, ...]:
    """The etch record's knots (etch / ETCH_UNIT, sorted): the flexures' torsion knots and a beam's edge
    knots (a beam has no flexure, a proof mass no edge knots: one list, the laws share its basis)."""
    return tuple(sorted(set(etch_knots(s, lo, hi)) | set(edge_knots(s, lo, hi))))


def knot_points(lo: float, hi: float, knots: tuple[float, ...]) -> tuple[float, ...]:
    """The etches (m) the mechanics are re-run at with knots: PER_PIECE evenly over each piece between
    lo, the knots and hi (shared ends once), and the nominal 0."""
    ends = [lo, *(k * ETCH_UNIT for k in knots), hi]
    pts = {0.0}
    for a, b in zip(ends, ends[1:]):
        pts.update(float(x) for x in np.linspace(a, b, PER_PIECE))
    return tuple(sorted(pts))


def basis(u: Any, knots: tuple[float, ...]) -> np.ndarray:
    """The law's basis at u (etch / 1 um): 1, u, u^2, u^3, then per knot (u - k)+, its square and cube."""
    u = np.atleast_1d(np.asarray(u, dtype=float))
    cols = [u**0, u, u**2, u**3]
    for k in knots:
        p = np.maximum(u - k, 0.0)
        cols += [p, p**2, p**3]
    return np.column_stack(cols)


def knot_value(coeffs: list[float], u: float, knots: tuple[float, ...]) -> float:
    """A knotted etch ratio at u = etch / 1 um (the arithmetic the emitters render); a plain cubic's
    four numbers read as that cubic (its knot columns 0)."""
    c = np.zeros(4 + 3 * len(knots))
    c[: len(coeffs)] = coeffs
    return float(basis(u, knots)[0] @ c)


def identity(knots: tuple[float, ...]) -> list[float]:
    """The ratio that is 1 at every etch, in the knotted law's length."""
    return [1.0] + [0.0] * (3 + 3 * len(knots))
