"""Stiffness of a proof mass's flexures: closed forms from the literature and the same
suspension solved as a 3-D frame (netgen.mechanics.frame), for the six rigid-body motions.

Closed forms (Euler-Bernoulli beams, rigid trusses, knees and mass, shear neglected):
- clamped_guided, four beams of length L along the axis (Senturia, "Microsystem Design",
  ch. 9, guided-end beam): across k = 4 E t w^3 / L^3, vertical 4 E w t^3 / L^3, along 4 E w t / L.
- folded (Tang's folded flexure, eight beams on two rigid trusses; Fedder, PhD thesis 1994,
  ch. 3, rigid-truss limit): across k = 2 E t w^3 / L^3, vertical 2 E w t^3 / L^3, along
  2 E w t / L (inner and outer beams axially in series).
- crab_leg (Fedder 1994, ch. 3, by Castigliano's theorem): each leg a shin and a thigh at a right
  angle, its mass end guided (no rotation: four mirrored legs); the unit-load integrals of the
  bending (and, out of plane, torsion) moments along both members give the leg's flexibility,
  inverted with the end rotations held at zero. Evaluated exactly (polynomial integrals).
The frame solve is the model's source for every coordinate (it also gives k_rot and the tilts,
which have no closed form here); the closed forms stand beside it in the report.
"""

from __future__ import annotations

import numpy as np

from ..structure.flexures import Flexure
from .frame import Frame, Section

AXES = ("x", "y", "z", "tilt_x", "tilt_y", "rot_z")  # frame DOF order: u, v, w, rx, ry, rz
SOURCES = {
    "clamped_guided": "Senturia, Microsystem Design (2001), ch. 9: four clamped-guided beams, 12 E I / L^3 each "
    "across, E A / L along",
    "folded": "Fedder, PhD thesis (UC Berkeley, 1994), ch. 3 / Tang's folded flexure: eight beams on two rigid "
    "trusses, inner and outer beams in series",
    "crab_leg": "Fedder, PhD thesis (1994), ch. 3: crab legs by Castigliano's theorem (bending and torsion of "
    "shin and thigh, mass end guided, rigid knee)",
}


def section(f: Flexure, width: float, youngs_modulus: float, poisson_ratio: float) -> Section:
    """A flexure beam's cross-section."""
    return Section(width, f.thickness, youngs_modulus, youngs_modulus / (2.0 * (1.0 + poisson_ratio)))


def place(axis: str, along: float, across: float) -> tuple[float, float]:
    """(x, y) of a point `along` the beam axis and `across` it."""
    return (along, across) if axis == "x" else (across, along)


def suspension(
    f: Flexure,
    half_length: float,
    half_width: float,
    youngs_modulus: float,
    poisson_ratio: float,
    rigid_truss: bool = False,
    elements: int = 8,
) -> Frame:
    """The flexure as a frame around a mass of half sizes (x, y), attached at its edges facing
    the beam axis; `rigid_truss` makes trusses and knees 1e4 times stiffer (the closed forms' limit)."""
    frame = Frame()
    beam = section(f, f.width, youngs_modulus, poisson_ratio)
    edge, side = (half_length, half_width) if f.axis == "x" else (half_width, half_length)
    for s_along in (1.0, -1.0):
        if f.type == "clamped_guided":
            for s_across in (1.0, -1.0):
                a, b = (
                    place(f.axis, s_along * edge, s_across * side / 2),
                    place(f.axis, s_along * (edge + f.length), s_across * side / 2),
                )
                frame.member(a, b, beam, elements)
                frame.tied.add(frame.node(*a))
                frame.clamped.add(frame.node(*b))
        elif f.type == "folded":
            truss = section(f, f.truss_width, youngs_modulus * (1e4 if rigid_truss else 1.0), poisson_ratio)
            inner, outer, top = side / 2, side / 2 + f.spacing, s_along * (edge + f.length)
            for s_across in (1.0, -1.0):
                frame.member(
                    place(f.axis, s_along * edge, s_across * inner),
                    place(f.axis, top, s_across * inner),
                    beam,
                    elements,
                )
                frame.member(
                    place(f.axis, s_along * edge, s_across * outer),
                    place(f.axis, top, s_across * outer),
                    beam,
                    elements,
                )
                frame.tied.add(frame.node(*place(f.axis, s_along * edge, s_across * inner)))
                frame.clamped.add(frame.node(*place(f.axis, s_along * edge, s_across * outer)))
                frame.member(place(f.axis, top, s_across * inner), place(f.axis, top, s_across * outer), truss, 2)
            frame.member(place(f.axis, top, -inner), place(f.axis, top, inner), truss, 4)
        elif f.type == "crab_leg":
            thigh = section(f, f.thigh_width, youngs_modulus, poisson_ratio)
            for s_across in (1.0, -1.0):
                root = place(f.axis, s_along * edge, s_across * side / 2)
                knee = place(f.axis, s_along * (edge + f.length), s_across * side / 2)
                anchor = place(f.axis, s_along * (edge + f.length), s_across * (side / 2 + f.thigh_length))
                frame.member(root, knee, beam, elements)
                frame.member(knee, anchor, thigh, elements)
                frame.tied.add(frame.node(*root))
                frame.clamped.add(frame.node(*anchor))
    return frame


def frame_stiffness(
    f: Flexure,
    half_length: float,
    half_width: float,
    youngs_modulus: float,
    poisson_ratio: float,
    rigid_truss: bool = False,
) -> dict[str, float]:
    """Diagonal stiffness per rigid-body coordinate from the frame solve (N/m, N*m/rad), and
    the largest off-diagonal coupling (relative) as 'coupling'."""
    k = suspension(f, half_length, half_width, youngs_modulus, poisson_ratio, rigid_truss).body_stiffness()
    d = np.sqrt(np.abs(np.diag(k)))
    rel = np.abs(k) / np.outer(d, d) - np.eye(6)
    return {name: float(k[i, i]) for i, name in enumerate(AXES)} | {"coupling": float(rel.max())}


def across_along(f: Flexure, k_across: float, k_along: float) -> dict[str, float]:
    """The closed forms' across/along-axis stiffnesses as k_x, k_y."""
    return {"x": k_across, "y": k_along} if f.axis == "y" else {"x": k_along, "y": k_across}


def closed_form(f: Flexure, youngs_modulus: float, poisson_ratio: float) -> dict[str, float]:
    """k_x, k_y, k_z (N/m) of the suspension from the closed forms in the module docstring."""
    e, w, t, L = youngs_modulus, f.width, f.thickness, f.length
    if f.type in ("clamped_guided", "folded"):
        n = 4.0 if f.type == "clamped_guided" else 2.0
        return across_along(f, n * e * t * w**3 / L**3, n * e * w * t / L) | {"z": n * e * w * t**3 / L**3}
    g = e / (2.0 * (1.0 + poisson_ratio))
    shin, thigh = section(f, f.width, e, poisson_ratio), section(f, f.thigh_width, e, poisson_ratio)
    k_along, k_across, k_z = crab_leg_leg(f.length, f.thigh_length, shin, thigh, e, g)
    return across_along(f, 4 * k_across, 4 * k_along) | {"z": 4 * k_z}


def _integral(a: tuple[float, float], b: tuple[float, float], length: float) -> float:
    """int_0^L (a0 + a1 s)(b0 + b1 s) ds, exactly."""
    return a[0] * b[0] * length + (a[0] * b[1] + a[1] * b[0]) * length**2 / 2 + a[1] * b[1] * length**3 / 3


def _guided(flex: np.ndarray, translations: list[int]) -> np.ndarray:
    """Stiffness of the end translations with the end rotations held at zero: d = C f with
    d_R = 0 gives d_T = (C_TT - C_TR C_RR^-1 C_RT) f_T."""
    rot = [i for i in range(len(flex)) if i not in translations]
    t = np.ix_(translations, translations)
    reduced = flex[t] - flex[np.ix_(translations, rot)] @ np.linalg.solve(
        flex[np.ix_(rot, rot)], flex[np.ix_(rot, translations)]
    )
    return np.linalg.inv(reduced)


def crab_leg_leg(
    shin: float, thigh: float, s_shin: Section, s_thigh: Section, e: float, g: float
) -> tuple[float, float, float]:
    """One crab leg's guided-end stiffnesses (along the shin, across it, vertical), by
    Castigliano: the shin runs from the loaded mass end B along +a for `shin`, the thigh from
    the knee across (+c) for `thigh` to the clamped anchor. Moments at a point P from the end
    loads: M = M_B + (B - P) x F, each component affine in the arc length."""
    # in plane: loads (F_a, F_c, M_z); shin points P = (s, 0), thigh points P = (shin, u)
    # bending moment m_z(P) = M_z + (B - P) x F |_z with B = (0, 0): -(P_a F_c - P_c F_a)
    shin_m = [(0.0, 0.0), (0.0, -1.0), (1.0, 0.0)]  # m_z per unit F_a, F_c, M_z: (const, slope in s)
    thigh_m = [(0.0, 1.0), (-shin, 0.0), (1.0, 0.0)]  # P = (shin, u): -(shin F_c - u F_a)
    flex = np.array(
        [
            [
                _integral(shin_m[i], shin_m[j], shin) / (e * s_shin.i_inplane)
                + _integral(thigh_m[i], thigh_m[j], thigh) / (e * s_thigh.i_inplane)
                for j in range(3)
            ]
            for i in range(3)
        ]
    )
    k_in = _guided(flex, [0, 1])
    # out of plane: loads (F_z, M_a, M_c); M(P) = M_B + (B - P) x (0, 0, F_z) = M_B + (-P_c F_z, P_a F_z, 0)
    # shin (axis a): torsion = M_a = M_a_B, bending = M_c = M_c_B + s F_z
    # thigh (axis c): torsion = M_c = M_c_B + shin F_z, bending = M_a = M_a_B - u F_z
    shin_t, shin_b = [(0.0, 0.0), (1.0, 0.0), (0.0, 0.0)], [(0.0, 1.0), (0.0, 0.0), (1.0, 0.0)]
    thigh_t, thigh_b = [(shin, 0.0), (0.0, 0.0), (1.0, 0.0)], [(0.0, -1.0), (1.0, 0.0), (0.0, 0.0)]
    flex_z = np.array(
        [
            [
                _integral(shin_t[i], shin_t[j], shin) / (g * s_shin.torsion)
                + _integral(shin_b[i], shin_b[j], shin) / (e * s_shin.i_vertical)
                + _integral(thigh_t[i], thigh_t[j], thigh) / (g * s_thigh.torsion)
                + _integral(thigh_b[i], thigh_b[j], thigh) / (e * s_thigh.i_vertical)
                for j in range(3)
            ]
            for i in range(3)
        ]
    )
    k_z = _guided(flex_z, [0])
    return float(k_in[0, 0]), float(k_in[1, 1]), float(k_z[0, 0])
