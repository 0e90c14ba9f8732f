"""A rigid rectangular proof mass on flexures (kind "proof_mass"): any of the six rigid-body
coordinates x, y, z, rot_z, tilt_x, tilt_y with the mass and the inertia tensor of the
perforated rectangle, and the flexure stiffness per coordinate (netgen.mechanics.flexures:
a 3-D frame solve of the named suspension, closed forms beside it in the report; or given
numbers; or none: a free body). The flexures' own mass is not added (reported as a fraction).
Small-angle kinematics (netgen.mechanics.base.KINEMATICS)."""

from __future__ import annotations

import math

import numpy as np

from ..structure import Structure
from . import flexures
from .base import KINEMATICS, RIGID, Mechanics, RigidBasis


def second_moments(c) -> tuple[float, float]:
    """(int x^2 dA, int y^2 dA) over the rectangle minus its centred square hole grid (m^4)."""
    ix, iy = c.width * c.length**3 / 12, c.length * c.width**3 / 12
    nx, ny = c.holes()
    if nx and ny:
        px = (np.arange(nx) - (nx - 1) / 2) * c.hole_pitch
        py = (np.arange(ny) - (ny - 1) / 2) * c.hole_pitch
        one = c.hole**4 / 12
        ix -= ny * float(np.sum(c.hole**2 * px**2) + nx * one)
        iy -= nx * float(np.sum(c.hole**2 * py**2) + ny * one)
    return ix, iy


def inertia(c) -> dict[str, float]:
    """Mass (kg) and moments of inertia about the centre (kg m^2) per rigid-body coordinate;
    the tilts include the thickness term m t^2 / 12."""
    rho_t = c.density * c.thickness
    ix, iy = second_moments(c)
    m = c.mass
    return {"x": m, "y": m, "z": m, "rot_z": rho_t * (ix + iy),
            "tilt_x": rho_t * iy + m * c.thickness**2 / 12, "tilt_y": rho_t * ix + m * c.thickness**2 / 12}


def stiffness(c) -> tuple[dict[str, float], dict]:
    """Spring per rigid-body coordinate and the report of its source."""
    f = c.flexure
    if f.type == "none":
        return {k: 0.0 for k in RIGID}, {"type": "none", "note": "a free body: no springs"}
    if f.type == "given":
        given = dict(f.given)
        keys = {"x": "k_x", "y": "k_y", "z": "k_z", "rot_z": "k_rot", "tilt_x": "k_tilt_x", "tilt_y": "k_tilt_y"}
        return {k: given.get(v, 0.0) for k, v in keys.items()}, {"type": "given", "given": given}
    half = (c.length / 2, c.width / 2)
    solved = flexures.frame_stiffness(f, *half, c.youngs_modulus, c.poisson_ratio)
    rigid = flexures.frame_stiffness(f, *half, c.youngs_modulus, c.poisson_ratio, rigid_truss=True)
    closed = flexures.closed_form(f, c.youngs_modulus, c.poisson_ratio)
    report = {"type": f.type, "source": "3-D Euler-Bernoulli frame solve of the suspension (netgen.mechanics.frame)",
              "frame_N_per_m": {k: solved[k] for k in flexures.AXES}, "coupling_max": solved["coupling"],
              "closed_form_N_per_m": closed, "closed_form_source": flexures.SOURCES[f.type],
              "frame_rigid_truss_over_closed_form": {k: rigid[k] / closed[k] for k in closed},
              "flexure_mass_fraction": flexure_mass(c) / c.mass}
    return {k: solved[k] for k in flexures.AXES}, report


def flexure_mass(c) -> float:
    """The beams' mass (kg): left out of the model, reported beside the proof mass."""
    f = c.flexure
    beams = {"clamped_guided": 4 * f.length * f.width, "folded": 8 * f.length * f.width,
             "crab_leg": 4 * (f.length * f.width + f.thigh_length * f.thigh_width)}.get(f.type, 0.0)
    return beams * f.thickness * c.density


def mechanics(s: Structure) -> Mechanics:
    """The proof mass's rigid-body coordinates with their inertias and flexure springs."""
    c = s.conductor
    names = list(s.coordinates.rigid)
    inert, (springs, spring_report) = inertia(c), stiffness(c)
    masses = np.array([inert[n] for n in names])
    stiff = np.array([springs[n] for n in names])
    freqs = np.sqrt(stiff / masses) / (2 * math.pi)
    report = {"kind": "proof_mass", "mass_kg": c.mass, "holes": list(c.holes()),
              "inertia_kg_m2": {k: v for k, v in inert.items() if k in ("rot_z", "tilt_x", "tilt_y")},
              "flexure": spring_report, "kinematics": KINEMATICS}
    return Mechanics(names, [RIGID[n][0] for n in names], [RIGID[n][1] for n in names], [""] * len(names),
                     masses, stiff, freqs, RigidBasis(names), report)
