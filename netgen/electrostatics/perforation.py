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

A plate of thickness t: the field that enters the open part of a hole (side h - 2 d) from the gap
leaks, through a sheet, out to the top face, and the electrode below sees no plate there; through
a plate it meets the hole's walls. How deep it reaches them follows from the hole's slowest Laplace
mode with conducting walls, sin(pi x / h) sin(pi y / h) exp(-k z), k = sqrt(2) pi / h: the walls
recover a fraction

    phi(t) = beta (1 - exp(-k t))      of the open part's missing charge, F = 1 - (1 - phi) (max(h - 2 d, 0) / p)^2,

so t = 0 is the sheet exactly, and a plate a few 1 / k thick (1 / k = 0.225 h) the deep-hole
limit beta. beta is fitted to FastCap solutions of a 2 um plate with h / p = 0.6 at g / p = 0.2
and 0.4 (bench/fastcap_thick_holes.py) and checked at h / p = 0.4 and at other thicknesses.
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
# beta, the share of an open hole's missing charge that a deep hole's walls recover: the fit to FastCap's
# F of thick plates (docs/fastcap.md, 'Perforated plates')
PERFORATION_WALL_SHARE = 0.32


@dataclass(frozen=True)
class Perforation:
    """A square etch-hole grid (hole side, pitch, plate thickness in m; thickness 0: a sheet) and its
    effective fill factor F(g)."""

    hole: float
    pitch: float
    strength: float = PERFORATION_STRENGTH
    ln_a: float = PERFORATION_LN_A
    thickness: float = 0.0
    wall_share: float = PERFORATION_WALL_SHARE

    def __post_init__(self) -> None:
        """Refuse a grid that is not one (hole >= pitch, non-positive sizes)."""
        if not (0.0 <= self.hole < self.pitch):
            raise ValueError(f"a hole grid needs 0 <= hole < pitch, got hole {self.hole:g} m, pitch {self.pitch:g} m")
        if self.thickness < 0.0:
            raise ValueError(f"a hole grid needs thickness >= 0, got {self.thickness:g} m")

    def wall_fraction(self) -> float:
        """phi = beta (1 - exp(-sqrt(2) pi t / h)): the share of the open holes' missing charge the walls recover."""
        if self.thickness == 0.0 or self.hole == 0.0:
            return 0.0
        return -self.wall_share * math.expm1(-math.sqrt(2.0) * math.pi * self.thickness / self.hole)

    def fringe_length(self, g: ArrayLike) -> Array:
        """d(g) = (B g / pi) ln(1 + A h / g): how far the field reaches in under each rim (m)."""
        g = np.asarray(g, dtype=float)
        return self.strength * g / math.pi * np.log1p(math.exp(self.ln_a) * self.hole / g)

    def fill(self, g: ArrayLike) -> Array:
        """F(g) = 1 - (1 - phi) (max(h - 2 d, 0) / p)^2: the electrode's charge over that of a solid plate."""
        r = np.maximum(self.hole - 2.0 * self.fringe_length(g), 0.0)
        return 1.0 - (1.0 - self.wall_fraction()) * (r / self.pitch) ** 2

    def derivative(self, g: ArrayLike) -> Array:
        """dF/dg = 4 (1 - phi) (h - 2 d) d'(g) / p^2 while the hole is open (0 once closed)."""
        g = np.asarray(g, dtype=float)
        x = math.exp(self.ln_a) * self.hole / g
        dd = self.strength * (np.log1p(x) - x / (1.0 + x)) / math.pi
        r = np.maximum(self.hole - 2.0 * self.fringe_length(g), 0.0)
        return 4.0 * (1.0 - self.wall_fraction()) * r * dd / self.pitch**2
