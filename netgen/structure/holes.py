"""The etch-hole count of a perforated proof mass: ONE rule for its mass, inertia, fill factor,
plate modes, etched copy and FastCap mesh (ProofMass.holes and netgen.electrostatics.fastcap_mesh)."""

from __future__ import annotations

import math

GRID_TOLERANCE = 1e-9  # relative: a side within this of a whole number of pitches holds that many


def grid_count(side: float, pitch: float) -> int:
    """Whole pitches that fit along `side` (a centred row of that many hole cells): floor(side /
    pitch), taking a quotient within GRID_TOLERANCE below an integer as that integer (floating-point
    `400e-6 // 10e-6` is 39, not 40)."""
    q = side / pitch
    return int(math.floor(q * (1.0 + GRID_TOLERANCE)))
