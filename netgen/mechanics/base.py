"""The mechanics stage's output, shared by every conductor kind: the generalized coordinates
(names, kinds, units, masses, stiffnesses, frequencies), the vertical displacement basis, and
optionally a nonlinear strain energy; plus the rigid-body fields and the inertial participation."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..geometry.combs import Finger, moving_fingers
from ..geometry.layout import plate_outline
from ..geometry.shapes import RectPlate
from ..structure import Structure

# rigid-body coordinate -> (kind, SI unit); every other coordinate is an eigenmode in m
RIGID = {
    "x": ("translation", "m"),
    "y": ("translation", "m"),
    "z": ("translation", "m"),
    "rot_z": ("rotation", "rad"),
    "tilt_x": ("rotation", "rad"),
    "tilt_y": ("rotation", "rad"),
}

# Small-angle kinematics of the rigid-body coordinates, for a point (x, y) of the mid-plane:
# displacement (u_x, u_y, u_z) = (X - rot_z y, Y + rot_z x, Z + tilt_x y - tilt_y x), i.e. the
# rotation matrix to first order in the angles (tilt_x about +x, tilt_y about +y, rot_z about +z;
# the in-plane motion of the mid-plane under the tilts, and every product of angles, are dropped).
# netgen.mechanics.proof_mass reports where this is off by more than 0.1 % (small_angle_report).
KINEMATICS = (
    "small-angle rigid-body kinematics at the mid-plane: u_x = x - rot_z*Y, u_y = y + rot_z*X, "
    "u_z = z + tilt_x*Y - tilt_y*X (X, Y: the point's rest position; first order in the angles)"
)


def rigid_field(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Vertical displacement per unit rigid-body coordinate: z 1, tilt_x y, tilt_y -x (small
    angles); the in-plane coordinates x, y, rot_z move nothing vertically."""
    if name in ("x", "y", "rot_z"):
        return np.zeros_like(x)
    return {"z": np.ones_like(x), "tilt_x": y, "tilt_y": -x}[name]


def in_plane_field(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """In-plane displacement (npts, 2) per unit rigid-body coordinate: x (1, 0), y (0, 1),
    rot_z (-y, x); the out-of-plane coordinates move the mid-plane vertically only."""
    zero, one = np.zeros_like(x), np.ones_like(x)
    return np.stack({"x": (one, zero), "y": (zero, one), "rot_z": (-y, x)}.get(name, (zero, zero)), axis=-1)


class RigidBasis:
    """basis(x, y) -> (npts, ncoords) vertical displacement of the rigid-body coordinates `names`
    (the basis every extractor takes), with `in_plane(x, y)` -> (npts, 2, ncoords) beside it for
    the extractors of in-plane electrodes (netgen.electrostatics.comb)."""

    def __init__(self, names: list[str] | tuple[str, ...]):
        self.names = tuple(names)

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.stack([rigid_field(n, x, y) for n in self.names], axis=-1)

    def in_plane(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.stack([in_plane_field(n, np.asarray(x, float), np.asarray(y, float)) for n in self.names], axis=-1)


def rigid_basis(names: list[str] | tuple[str, ...] = ("z", "tilt_x", "tilt_y")) -> Callable:
    """basis(x, y) -> (npts, len(names)) of the rigid-body fields."""

    def basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.stack([rigid_field(n, x, y) for n in names], axis=-1)

    return basis


@dataclass(frozen=True)
class StrainEnergy:
    """Strain energy beyond 1/2 K q^2: U(q) in J at coordinates q (npts, ncoords) in SI; the
    model stage fits it over the sampled box (netgen.fit.energy)."""

    energy: Callable[[np.ndarray], np.ndarray]
    description: str
    degrees: tuple[int, ...] = (4,)  # the polynomial's total degrees (netgen.fit.energy.fit_energy)


@dataclass
class Mechanics:
    """Stage output: coordinates (without scales yet) and the vertical displacement basis."""

    names: list[str]
    kinds: list[str]
    units: list[str]
    labels: list[str]
    masses: np.ndarray
    stiffnesses: np.ndarray
    frequencies: np.ndarray
    basis: Callable[[np.ndarray, np.ndarray], np.ndarray]
    report: dict
    strain_energy: StrainEnergy | None = None


BodyPart = tuple[np.ndarray, np.ndarray, np.ndarray, float, float]


def mass_rule(s: Structure, order: int = 96) -> list[BodyPart]:
    """The body as parts (x, y, Gauss weights, areal density kg/m^2, thickness): the plate first (a
    perforated proof mass's areal density carries its solid fraction, `fill_factor`), then each
    moving comb finger hanging on it (finger_rule)."""
    c: Any = s.conductor
    x, y, w = plate_outline(s).area_rule(order)
    parts = [(x, y, w, c.density * c.thickness * getattr(c, "fill_factor", 1.0), c.thickness)]
    fingers = moving_fingers(s.electrode_sets, c.outline()) if c.kind == "proof_mass" else []
    return parts + finger_rule(c.density, fingers)


def finger_rule(density: float, fingers: Sequence[Finger]) -> list[BodyPart]:
    """Each moving comb finger (netgen.geometry.combs.moving_fingers) as a body part: 4 x 8 Gauss
    points over its rectangle, areal density rho t, its thickness."""
    out = []
    for f in fingers:
        fx, fy, fw = RectPlate(f.x0, f.x1, f.y0, f.y1).area_rule(4)
        out.append((fx, fy, fw, density * f.thickness, f.thickness))
    return out


def body_mass(s: Structure) -> float:
    """The moving mass (kg): the conductor's, plus a proof mass's moving comb fingers (rho t w L each)."""
    c: Any = s.conductor
    fingers = moving_fingers(s.electrode_sets, c.outline()) if c.kind == "proof_mass" else []
    return float(c.mass + sum(c.density * f.thickness * f.area for f in fingers))


def participation(s: Structure, m: Mechanics, order: int = 96) -> list[float]:
    """Inertial participation G_v = int phi_v dm over the body (mass_rule: the plate and the moving
    fingers, which an internal mode turns with the plate's edge at their roots, RectPlateModes.shape;
    Gauss quadrature): the generalized force per unit frame acceleration. Values below 1e-6 of
    sqrt(M_v m) (free-plate modes and tilts about the centre, zero by symmetry up to round-off) are
    set to exactly 0."""
    parts = mass_rule(s, order)
    gam, total = np.zeros(len(m.names)), 0.0
    for x, y, w, rho_h, _ in parts:
        gam = gam + rho_h * (w @ m.basis(x, y))  # basis: (points, ncoords)
        total += rho_h * float(np.sum(w))
    return [0.0 if abs(v) < 1e-6 * math.sqrt(mv * total) else float(v) for v, mv in zip(gam, m.masses)]
