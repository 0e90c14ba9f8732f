"""A rigid rectangular plate on linear springs (kind "piston"): coordinates z (and tilt_x,
tilt_y), masses m, I_x = m W^2/12, I_y = m L^2/12, springs from the structure file."""

from __future__ import annotations

import math

import numpy as np

from ..structure import Structure
from .base import RIGID, Mechanics, rigid_basis


def mechanics(s: Structure) -> Mechanics:
    """The piston's rigid-body coordinates with their springs."""
    c = s.conductor
    rigid = list(s.coordinates.rigid)
    inertia = {"z": c.mass, "tilt_x": c.mass * c.width**2 / 12, "tilt_y": c.mass * c.length**2 / 12}
    springs = {"z": c.stiffness, "tilt_x": c.tilt_stiffness, "tilt_y": c.tilt_stiffness}
    masses = np.array([inertia[r] for r in rigid])
    stiff = np.array([springs[r] for r in rigid])
    return Mechanics(
        rigid,
        [RIGID[r][0] for r in rigid],
        [RIGID[r][1] for r in rigid],
        [""] * len(rigid),
        masses,
        stiff,
        np.sqrt(stiff / masses) / (2 * math.pi),
        rigid_basis(rigid),
        {
            "kind": "piston",
            "mass_kg": c.mass,
            "spring_N_per_m": c.stiffness,
            "tilt_spring_N_m_per_rad": c.tilt_stiffness,
        },
    )
