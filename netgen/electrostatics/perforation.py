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
docs/fastcap.md, 'Perforated plates'); the plate's thickness does not enter.
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


@dataclass(frozen=True)
class Perforation:
    """A square etch-hole grid (hole side, pitch in m) and its effective fill factor F(g)."""

    hole: float
    pitch: float
    strength: float = PERFORATION_STRENGTH
    ln_a: float = PERFORATION_LN_A

    def __post_init__(self) -> None:
        """Refuse a grid that is not one (hole >= pitch, non-positive sizes)."""
        if not (0.0 <= self.hole < self.pitch):
            raise ValueError(f"a hole grid needs 0 <= hole < pitch, got hole {self.hole:g} m, pitch {self.pitch:g} m")

    def fringe_length(self, g: ArrayLike) -> Array:
        """d(g) = (B g / pi) ln(1 + A h / g): how far the field reaches in under each rim (m)."""
        g = np.asarray(g, dtype=float)
        return self.strength * g / math.pi * np.log1p(math.exp(self.ln_a) * self.hole / g)

    def fill(self, g: ArrayLike) -> Array:
        """F(g) = 1 - (max(h - 2 d, 0) / p)^2: the electrode's charge over that of a solid plate."""
        r = np.maximum(self.hole - 2.0 * self.fringe_length(g), 0.0)
        return 1.0 - (r / self.pitch) ** 2

    def derivative(self, g: ArrayLike) -> Array:
        """dF/dg = 4 (h - 2 d) d'(g) / p^2 while the hole is open (0 once closed)."""
        g = np.asarray(g, dtype=float)
        x = math.exp(self.ln_a) * self.hole / g
        dd = self.strength * (np.log1p(x) - x / (1.0 + x)) / math.pi
        r = np.maximum(self.hole - 2.0 * self.fringe_length(g), 0.0)
        return 4.0 * r * dd / self.pitch**2
