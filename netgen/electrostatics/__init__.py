"""The electrostatics stage: capacitance extractors behind one protocol (netgen.electrostatics.base),
their registry, and the sampling of C(q) (netgen.electrostatics.sampling)."""

from __future__ import annotations

from typing import Callable

from ..errors import StructureError
from ..geometry.shapes import Plate
from . import parallel_plate
from .base import CapacitanceExtractor, PreparedExtractor, ProbePoints

# [electrostatics] extractor -> builder(structure, plate outline): one line per extractor
EXTRACTORS: dict[str, Callable[..., CapacitanceExtractor]] = {
    "parallel_plate": parallel_plate.from_structure,
}


def extractor(s, plate: Plate) -> CapacitanceExtractor:
    """The extractor a structure names (s: netgen.structure.Structure), or a StructureError
    that lists the known ones."""
    name = s.electrostatics.extractor
    if name not in EXTRACTORS:
        raise StructureError(s.source, "electrostatics.extractor", f"unknown extractor {name!r}",
                             f"use one of {', '.join(EXTRACTORS)}")
    return EXTRACTORS[name](s, plate)


__all__ = ["EXTRACTORS", "CapacitanceExtractor", "PreparedExtractor", "ProbePoints", "extractor"]
