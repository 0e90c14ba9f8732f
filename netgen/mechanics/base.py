"""The mechanics stage's output, shared by every conductor kind: the generalized coordinates
(names, kinds, units, masses, stiffnesses, frequencies), the vertical displacement basis, and
optionally a nonlinear strain energy; plus the rigid-body fields and the inertial participation."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..geometry.layout import plate_outline
from ..structure import Structure

# rigid-body coordinate -> (kind, SI unit); every other coordinate is an eigenmode in m
RIGID = {"z": ("translation", "m"), "tilt_x": ("rotation", "rad"), "tilt_y": ("rotation", "rad")}


def rigid_field(name: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Vertical displacement per unit rigid-body coordinate: z 1, tilt_x y, tilt_y -x (small angles)."""
    return {"z": np.ones_like(x), "tilt_x": y, "tilt_y": -x}[name]


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


def participation(s: Structure, m: Mechanics, order: int = 96) -> list[float]:
    """Inertial participation G_v = rho h int phi_v dA over the plate (Gauss quadrature): the
    generalized force per unit frame acceleration. Values below 1e-6 of sqrt(M_v m) (free-plate
    modes and tilts about the centre, zero by symmetry up to round-off) are set to exactly 0."""
    plate = plate_outline(s)
    x, y, weights = plate.area_rule(order)
    phi = m.basis(x, y)                                                  # (points, ncoords)
    gam = s.conductor.density * s.conductor.thickness * (weights @ phi)
    total = s.conductor.density * s.conductor.thickness * plate.area()
    return [0.0 if abs(v) < 1e-6 * math.sqrt(mv * total) else float(v) for v, mv in zip(gam, m.masses)]
