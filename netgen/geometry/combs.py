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


@dataclass(frozen=True)
class Finger:
    """One moving finger as a box hanging on the proof mass: its rectangle [x0, x1] x [y0, y1] at
    rest (m) and its thickness (m), the mid-plane the mass's (exact for a finger of the full layer
    thickness, the comb's default: netgen.mechanics.proof_mass.finger_inertia)."""

    x0: float
    x1: float
    y0: float
    y1: float
    thickness: float

    @property
    def area(self) -> float:
        return (self.x1 - self.x0) * (self.y1 - self.y0)


def moving_fingers(electrode_sets, outline: tuple[float, float, float, float] | None = None) -> list[Finger]:
    """The distinct moving fingers of the structure's combs: each comb's fingers from root to tip
    (CombShape.finger_tips, `length` back along -engage, `width` across), cut along the finger at the
    mass's `outline` (x0, x1, y0, y1; a root drawn inside the mass is the mass's own area) and dropped
    if nothing is left; a finger two combs face (a differential pair on its two sidewalls: the same
    tips, length and width) counted once."""
    seen: dict[tuple, Finger] = {}
    for e in electrode_sets:
        if getattr(e, "kind", "") not in ("lateral_comb", "transverse_comb"):
            continue
        shape = CombShape.of(e)
        half = shape.across * shape.width / 2
        k = 0 if shape.orientation == "x" else 1
        for tip in shape.finger_tips():
            root = tip - shape.engage * shape.length
            lo, hi = sorted((tip[k], root[k]))
            if outline is not None:  # the part beyond the mass's edge on the tip's side
                edge_lo, edge_hi = outline[2 * k], outline[2 * k + 1]
                lo, hi = (max(lo, edge_hi), hi) if shape.engage[k] > 0 else (lo, min(hi, edge_lo))
            if hi <= lo:
                continue
            a, b = sorted((tip[1 - k] - half[1 - k], tip[1 - k] + half[1 - k]))
            box = (lo, hi, a, b) if k == 0 else (a, b, lo, hi)
            f = Finger(float(box[0]), float(box[1]), float(box[2]), float(box[3]), float(shape.thickness))
            seen.setdefault(tuple(round(v / 1e-12) for v in (f.x0, f.x1, f.y0, f.y1, f.thickness)), f)
    return list(seen.values())
