"""Comb-finger arrays as shapes: where the faces of the moving fingers are, which way they face,
at what gap, and where the finger tips are, in the proof mass's frame at rest (x, y in m).
netgen.electrostatics.comb turns them into capacitances; netgen.geometry.layout maps the
structure file's CombElectrode here (CombShape.of)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..structure import CombElectrode
from .shapes import Array, Plate, empty


@dataclass(frozen=True)
class Face:
    """One side of one moving finger facing a fixed finger: the moving finger's tip (at rest),
    the unit normal toward the fixed finger, the gap at rest and the overlap at rest."""

    tip: tuple[float, float]
    normal: tuple[float, float]
    gap: float


@dataclass(frozen=True)
class CombShape(CombElectrode):
    """A comb array as a shape: the structure file's CombElectrode (its fields and their meaning)
    with the geometry of its faces and tips."""

    @classmethod
    def of(cls, e: CombElectrode) -> CombShape:
        """The shape of a structure file's comb electrode (every field of it, by dataclasses.fields)."""
        return cls(**{f.name: getattr(e, f.name) for f in fields(CombElectrode)})

    @property
    def axis(self) -> np.ndarray:
        """Unit vector along the fingers."""
        return np.array([1.0, 0.0]) if self.orientation == "x" else np.array([0.0, 1.0])

    @property
    def across(self) -> np.ndarray:
        """Unit vector across the fingers (the gaps' direction)."""
        return np.array([0.0, 1.0]) if self.orientation == "x" else np.array([1.0, 0.0])

    @property
    def engage(self) -> np.ndarray:
        """Unit vector from the moving fingers' roots to their tips (toward the fixed comb's base)."""
        return self.axis * (1.0 if self.root == "+" else -1.0)

    @property
    def slot(self) -> float:
        return 0.0

    def finger_tips(self) -> Array:
        """(fingers, 2) positions of the moving fingers' tips at rest."""
        offsets = (np.arange(self.fingers) - (self.fingers - 1) / 2) * self.pitch
        base = np.asarray(self.center) + self.engage * self.overlap / 2
        return base[None, :] + offsets[:, None] * self.across[None, :]

    def faces(self) -> list[Face]:
        """Every facing pair of sidewalls: a lateral comb both sides of each finger at `gap`; a
        transverse comb its `side` at `gap` and the other side at `anti_gap` (if any)."""
        sides = (
            [(1.0, self.gap), (-1.0, self.gap)]
            if self.kind == "lateral_comb"
            else [(1.0 if self.side == "+" else -1.0, self.gap)]
            + ([(-1.0 if self.side == "+" else 1.0, self.anti_gap)] if self.anti_gap else [])
        )
        out = []
        for tip in self.finger_tips():
            for sign, gap in sides:
                n = sign * self.across
                out.append(Face(tuple(tip + n * self.width / 2), tuple(n), gap))
        return out

    def area(self) -> float:
        """Facing sidewall area at rest (m^2)."""
        return len(self.faces()) * self.overlap * self.thickness

    def quadrature(self, plate: Plate, order: int = 0) -> tuple[Array, Array, Array]:
        """The faces' overlap midpoints, each weighted with its facing area (the fit's first guess)."""
        pts = np.array([np.asarray(f.tip) - self.engage * self.overlap / 2 for f in self.faces()])
        return pts[:, 0], pts[:, 1], np.full(len(pts), self.overlap * self.thickness)

    def boundary(self, plate: Plate) -> list:
        """No plate-edge pieces (the fringe of the plate extractor does not apply)."""
        return []

    def edge_points(self, plate: Plate, order: int = 0) -> tuple[Array, Array, Array]:
        return empty()

    def extent(self) -> float:
        """Farthest point of the fingers from the origin (m): the small-angle report's lever."""
        ends = np.concatenate([self.finger_tips(), self.finger_tips() - self.engage * self.length])
        return float(np.max(np.hypot(ends[:, 0], ends[:, 1])))
