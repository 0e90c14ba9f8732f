"""The electrostatics stage: capacitance extractors behind one protocol (netgen.electrostatics.base),
their registry, and the sampling of C(q) (netgen.electrostatics.sampling)."""

from __future__ import annotations

from typing import Callable

from ..constants import EPS0
from ..errors import StructureError
from ..geometry.shapes import Plate
from ..structure import CombElectrode
from . import bem, calibrated, parallel_plate
from .base import CapacitanceExtractor, PreparedExtractor, ProbePoints
from .comb import CombExtractor
from .mixed import MixedExtractor

# [electrostatics] extractor -> builder(structure, plate outline): one line per extractor
EXTRACTORS: dict[str, Callable[..., CapacitanceExtractor]] = {
    "parallel_plate": parallel_plate.from_structure,
    "calibrated": calibrated.from_structure,
    "bem": bem.from_structure,
}


def extractor(s, plate: Plate) -> CapacitanceExtractor:
    """The extractor a structure names (s: netgen.structure.Structure), or a StructureError
    that lists the known ones; with comb electrodes it answers for the plates beside the comb
    extractor (netgen.electrostatics.mixed)."""
    name = s.electrostatics.extractor
    if name not in EXTRACTORS:
        raise StructureError(s.source, "electrostatics.extractor", f"unknown extractor {name!r}",
                             f"use one of {', '.join(EXTRACTORS)}")
    chosen = EXTRACTORS[name](s, plate)
    if s.electrostatics.couplings is not None and name == "parallel_plate":     # the file's couplings beside it
        chosen = calibrated.with_file_couplings(s, chosen)
    if any(isinstance(e, CombElectrode) for e in s.electrode_sets):
        return MixedExtractor(chosen, CombExtractor(EPS0 * s.electrostatics.relative_permittivity,
                                                       s.electrostatics.comb_model, s.source))
    return chosen


__all__ = ["EXTRACTORS", "CapacitanceExtractor", "PreparedExtractor", "ProbePoints", "extractor"]
