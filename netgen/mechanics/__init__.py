"""The mechanics stage: generalized coordinates of the conductor (rigid-body motions and
eigenmodes) with their masses, stiffnesses, damping and displacement shapes.

KINDS maps a conductor kind (netgen.structure.conductors.CONDUCTORS) to the module whose
`mechanics(structure)` gives its coordinates; data from an external FEM tool replace it through
netgen.mechanics.imported (chosen by netgen.build).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from ..core.errors import StructureError
from ..structure import Structure
from . import beam, free_disk, piston, proof_mass
from .base import Mechanics, StrainEnergy, body_mass, participation, rigid_basis


@runtime_checkable
class MechanicsKind(Protocol):
    """A conductor kind's mechanics: its coordinates with masses, stiffnesses, damping and shapes
    (a module with this function satisfies it)."""

    def mechanics(self, s: Structure) -> Mechanics: ...


# conductor kind -> module with mechanics(structure) -> Mechanics: one line per kind
KINDS: dict[str, MechanicsKind] = {
    "free_disk": free_disk,
    "piston": piston,
    "clamped_clamped_beam": beam,
    "cantilever": beam,
    "proof_mass": proof_mass,
}


def mechanics(s: Structure) -> Mechanics:
    """The coordinates of the structure's conductor kind, or a StructureError listing the kinds
    that have mechanics."""
    kind = s.conductor.kind
    if kind not in KINDS:
        raise StructureError(
            s.source, "conductor.kind", f"conductor kind {kind!r} has no mechanics", f"use one of {', '.join(KINDS)}"
        )
    return KINDS[kind].mechanics(s)


__all__ = [
    "KINDS",
    "Mechanics",
    "MechanicsKind",
    "StrainEnergy",
    "body_mass",
    "mechanics",
    "participation",
    "rigid_basis",
]
