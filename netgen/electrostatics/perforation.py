"""The effective fill factor F(g) of a perforated plate (a square grid of square etch holes, side h
on pitch p) facing an electrode at gap g: the plate's charge on the electrode per area, over
eps / g, with the fringe under the holes' rims counted.

The field reaches in under each hole's rim: a hole seen from the electrode looks smaller by a
fringe length d on each side, so the hole grid acts as a solid plate with holes of side h - 2 d:

    F(g) = 1 - (max(h - 2 d, 0) / p)^2,      d(g) = (B g / pi) ln(1 + A h / g).

d has the form of a plate edge's fringe over a plane (conformal map: growing as (g / pi) ln(h / g)
for wide holes, h >> g), here fed from both faces (the rim's underside and the field leaking
through the hole from above), so its strength B is fitted rather than 1; for narrow holes
(h << g) d -> B A h / pi, 0.46 h. Limits: F -> 1 - (h / p)^2 (the plain solid fraction) as
g / p -> 0; F -> 1 as h -> 0 (as 1 - 0.006 (h / p)^2); for g >> h it tends to 1 - 0.006 (h / p)^2
rather than 1 (0.2 % low at h / p = 0.6). B and ln A are fitted to FastCap solutions of a thin
plate with h / p = 0.6 at g / p = 0.1, 0.2, 0.4 (bench/fastcap_perforated.py, fine panels;
docs/fastcap.md, 'Perforated plates').

A plate of thickness t: the holes have walls, and the field entering a hole from the gap ends on
them instead of leaking through to the top face. The walls add the fringe of a thick plate edge
over a plane (Palmer's thick-edge term, (g / pi) ln(1 + 2 tau + 2 sqrt(tau + tau^2)) =
(2 g / pi) asinh(sqrt(tau)), tau = wall height / g), but only as deep as the field reaches into
the hole: in a square hole of side h with conducting walls the slowest Laplace mode,
sin(pi x / h) sin(pi y / h) exp(-k z), decays with k = sqrt(2) pi / h, so the wall counts over
t_e = (1 - exp(-k t)) / k. The hole then looks smaller by

    w(g) = (2 B_w g / pi) asinh(sqrt(t_e / g))      on each side, F = 1 - (max(h - 2 d - 2 w, 0) / p)^2,

which vanishes at t = 0 (the sheet's F exactly) and saturates for t >> 1 / k. Its strength B_w is
fitted to FastCap solutions of a 2 um plate with h / p = 0.6 (bench/fastcap_thick_holes.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.shapes import Array

# B and ln A of the fringe length d = (B g / pi) ln(1 + A h / g): the least-squares fit to FastCap's
# F of a sheet (docs/fastcap.md, 'Perforated plates')
PERFORATION_STRENGTH = 1.40
PERFORATION_LN_A = 0.036
# B_w of the hole walls' term w = (2 B_w g / pi) asinh(sqrt(t_e / g)) (docs/fastcap.md, 'Perforated plates')
PERFORATION_WALL_STRENGTH = 1.0


@dataclass(frozen=True)
class Perforation:
    """A square etch-hole grid (hole side, pitch, plate thickness in m; thickness 0: a sheet) and its
    effective fill factor F(g)."""

    hole: float
    pitch: float
    strength: float = PERFORATION_STRENGTH
    ln_a: float = PERFORATION_LN_A
    thickness: float = 0.0
    wall_strength: float = PERFORATION_WALL_STRENGTH

    def __post_init__(self) -> None:
        """Refuse a grid that is not one (hole >= pitch, non-positive sizes)."""
        if not (0.0 <= self.hole < self.pitch):
            raise ValueError(f"a hole grid needs 0 <= hole < pitch, got hole {self.hole:g} m, pitch {self.pitch:g} m")
        if self.thickness < 0.0:
            raise ValueError(f"a hole grid needs thickness >= 0, got {self.thickness:g} m")

    def wall_depth(self) -> float:
        """t_e = (1 - exp(-k t)) / k, k = sqrt(2) pi / h: how deep the field reaches the walls (m)."""
        if self.thickness == 0.0 or self.hole == 0.0:
            return 0.0
        k = math.sqrt(2.0) * math.pi / self.hole
        return -math.expm1(-k * self.thickness) / k

    def wall_length(self, g: ArrayLike) -> Array:
        """w(g) = (2 B_w g / pi) asinh(sqrt(t_e / g)): the holes' walls' share of the rim fringe (m)."""
        g = np.asarray(g, dtype=float)
        return 2.0 * self.wall_strength * g / math.pi * np.arcsinh(np.sqrt(self.wall_depth() / g))

    def fringe_length(self, g: ArrayLike) -> Array:
        """d(g) = (B g / pi) ln(1 + A h / g): how far the field reaches in under each rim (m)."""
        g = np.asarray(g, dtype=float)
        return self.strength * g / math.pi * np.log1p(math.exp(self.ln_a) * self.hole / g)

    def fill(self, g: ArrayLike) -> Array:
        """F(g) = 1 - (max(h - 2 d - 2 w, 0) / p)^2: the electrode's charge over that of a solid plate."""
        return 1.0 - (self._open(g) / self.pitch) ** 2

    def _open(self, g: ArrayLike) -> Array:
        """h - 2 d - 2 w, the hole's side as the electrode sees it (0 once closed)."""
        return np.maximum(self.hole - 2.0 * (self.fringe_length(g) + self.wall_length(g)), 0.0)

    def derivative(self, g: ArrayLike) -> Array:
        """dF/dg = 4 (h - 2 d - 2 w) (d'(g) + w'(g)) / p^2 while the hole is open (0 once closed)."""
        g = np.asarray(g, dtype=float)
        x = math.exp(self.ln_a) * self.hole / g
        dd = self.strength * (np.log1p(x) - x / (1.0 + x)) / math.pi
        s = np.sqrt(self.wall_depth() / g)
        dw = 2.0 * self.wall_strength * (np.arcsinh(s) - s / (2.0 * np.sqrt(1.0 + s * s))) / math.pi
        return 4.0 * self._open(g) * (dd + dw) / self.pitch**2
