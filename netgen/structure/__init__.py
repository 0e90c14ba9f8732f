"""The structure stage: the TOML file a user writes, validated into frozen dataclasses
(netgen.structure.parse). Conductor kinds: netgen.structure.conductors.CONDUCTORS."""

from ..core.errors import StructureError
from .conductors import CONDUCTORS, Beam, FreeDisk, Piston, ProofMass
from .electrodes import CombElectrode, ElectrodeSet, RectElectrode
from .holes import grid_count
from .parse import load_structure, parse_structure
from .schema import (
    ALL_RIGID,
    IN_PLANE_COORDINATES,
    MAX_GRID_POINTS,
    RIGID_COORDINATES,
    Coordinates,
    Damping,
    ElectrostaticsOptions,
    FemOptions,
    FitOptions,
    Imports,
    Sampling,
    Structure,
    mode_name,
)

__all__ = [
    "ALL_RIGID",
    "CONDUCTORS",
    "CombElectrode",
    "IN_PLANE_COORDINATES",
    "ProofMass",
    "MAX_GRID_POINTS",
    "RIGID_COORDINATES",
    "Beam",
    "Coordinates",
    "Damping",
    "ElectrodeSet",
    "ElectrostaticsOptions",
    "FemOptions",
    "FitOptions",
    "FreeDisk",
    "Imports",
    "Piston",
    "RectElectrode",
    "Sampling",
    "Structure",
    "StructureError",
    "load_structure",
    "grid_count",
    "mode_name",
    "parse_structure",
]
