"""The electrostatics stage: capacitance extractors behind one protocol (netgen.electrostatics.base),
their registry, and the sampling of C(q) (netgen.electrostatics.sampling)."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from ..core.constants import EPS0
from ..core.errors import StructureError
from ..geometry.shapes import Plate
from ..structure import CombElectrode, Structure
from . import bem, calibrated, fastcap, parallel_plate
from .base import CapacitanceExtractor, PreparedExtractor, ProbePoints
from .comb import CombExtractor
from .mixed import MixedExtractor


@runtime_checkable
class ExtractorBuilder(Protocol):
    """An extractor's `from_structure`: the extractor a structure's [electrostatics] settings and
    plate outline describe (s: netgen.structure.Structure)."""

    def __call__(self, s: Structure, plate: Plate, /) -> CapacitanceExtractor: ...


# [electrostatics] extractor -> builder(structure, plate outline): one line per extractor
EXTRACTORS: dict[str, ExtractorBuilder] = {
    "parallel_plate": parallel_plate.from_structure,
    "calibrated": calibrated.from_structure,
    "bem": bem.from_structure,
    "fastcap": fastcap.from_structure,
}


def extractor(s, plate: Plate) -> CapacitanceExtractor:
    """The extractor a structure names (s: netgen.structure.Structure), or a StructureError
    that lists the known ones, composed with what else the structure needs: a couplings file's
    constant couplings beside an extractor that has none of its own, and the comb extractor for
    comb electrodes (compose)."""
    name = s.electrostatics.extractor
    if name not in EXTRACTORS:
        raise StructureError(
            s.source, "electrostatics.extractor", f"unknown extractor {name!r}", f"use one of {', '.join(EXTRACTORS)}"
        )
    chosen = EXTRACTORS[name](s, plate)
    if s.electrostatics.couplings is not None and not hasattr(chosen, "calibration"):  # the file's couplings beside it
        chosen = calibrated.with_file_couplings(s, chosen)
    if any(isinstance(e, CombElectrode) for e in s.electrode_sets):
        chosen = compose(
            chosen, CombExtractor(EPS0 * s.electrostatics.relative_permittivity, s.electrostatics.comb_model, s.source)
        )
    return chosen


def compose(plates: CapacitanceExtractor, combs: CapacitanceExtractor) -> CapacitanceExtractor:
    """The one composition step: `plates` answers for the plate electrodes and `combs` for the comb
    electrodes (netgen.electrostatics.mixed), with the optional hooks of either part (a calibrated
    extractor's record and report) kept, so any plate extractor, calibrated ones too, reaches comb
    structures."""
    return MixedExtractor(plates, combs)


__all__ = ["EXTRACTORS", "CapacitanceExtractor", "PreparedExtractor", "ProbePoints", "compose", "extractor"]
