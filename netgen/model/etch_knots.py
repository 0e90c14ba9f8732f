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
knot in the range the law is the cubic, as before (its text unchanged)."""

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
    """A knotted etch ratio at u = etch / 1 um (the arithmetic the emitters render)."""
    return float(basis(u, knots)[0] @ np.asarray(coeffs, dtype=float))


def identity(knots: tuple[float, ...]) -> list[float]:
    """The ratio that is 1 at every etch, in the knotted law's length."""
    return [1.0] + [0.0] * (3 + 3 * len(knots))
