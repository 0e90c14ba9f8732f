"""Two extractors of one structure together: the structure's plate extractor
(netgen.electrostatics.EXTRACTORS) on the plate electrodes and netgen.electrostatics.comb on the
comb electrodes, their columns merged in port order, so sampling, fitting and the contact model
see one extractor. The optional hooks a part may have beyond the protocol (OPTIONAL: a
calibration record and report, netgen.electrostatics.calibrated) answer for the pair, so a
calibrated plate extractor keeps its calibration beside the combs."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.combs import CombShape
from ..geometry.shapes import Array, Basis, Electrode, Plate
from .base import CapacitanceExtractor, PreparedExtractor, ProbePoints
from .comb import CombExtractor

# hooks beyond the protocol that netgen.build asks for with hasattr (the model's calibration
# entry, the calibration report); a pair has one when a part has it
OPTIONAL = ("calibration", "report")


def split(electrodes: Sequence[Electrode]) -> tuple[list[int], list[int]]:
    """Indices of the plate electrodes and of the comb electrodes."""
    combs = [i for i, e in enumerate(electrodes) if isinstance(e.shape, CombShape)]
    return [i for i in range(len(electrodes)) if i not in combs], combs


class PreparedMixed:
    """The two prepared extractors, answering for all electrodes in port order."""

    def __init__(self, electrodes: Sequence[Electrode], parts: list[tuple[list[int], PreparedExtractor]]):
        self.electrodes, self.parts = tuple(electrodes), [(i, p) for i, p in parts if i]

    def _merge(self, method: str, Q: ArrayLike) -> Array:
        q = np.asarray(Q, dtype=float)
        single = q.ndim == 1
        q = np.atleast_2d(q)
        blocks = [(idx, getattr(p, method)(q)) for idx, p in self.parts]
        out = np.empty((q.shape[0], len(self.electrodes)) + blocks[0][1].shape[2:])
        for idx, b in blocks:
            out[:, idx] = b
        return out[0] if single else out

    def capacitance(self, Q: ArrayLike) -> Array:
        return self._merge("capacitance", Q)

    def gradient(self, Q: ArrayLike) -> Array:
        return self._merge("gradient", Q)

    def min_gap(self, Q: ArrayLike) -> Array:
        return self._merge("min_gap", Q)

    def probe_points(self) -> ProbePoints:
        pts = [(idx, p.probe_points()) for idx, p in self.parts]
        return ProbePoints(
            np.concatenate([p.gap for _, p in pts]),
            np.concatenate([p.phi for _, p in pts]),
            np.concatenate([np.asarray(idx)[p.electrode] for idx, p in pts]).astype(int),
        )


@dataclass(frozen=True)
class MixedExtractor:
    """A plate extractor and the comb extractor side by side."""

    plates: CapacitanceExtractor
    combs: CombExtractor

    @property
    def description(self) -> str:
        return f"{self.plates.description}; {self.combs.description}"

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedMixed:
        ip, ic = split(electrodes)
        parts = [(ic, self.combs.prepare([electrodes[i] for i in ic], plate, basis))]
        if ip:
            parts.insert(0, (ip, self.plates.prepare([electrodes[i] for i in ip], plate, basis)))
        return PreparedMixed(electrodes, parts)

    def __getattr__(self, name: str):
        """An OPTIONAL hook of the part that has it (both: the calibration records merged), else
        AttributeError, so hasattr(pair, hook) says whether a part has it."""
        if name not in OPTIONAL:
            raise AttributeError(name)
        owners = [
            getattr(p, name)
            for p in (self.__dict__.get("plates"), self.__dict__.get("combs"))
            if p is not None and hasattr(p, name)
        ]
        if not owners:
            raise AttributeError(name)
        return owners[0] if len(owners) == 1 or name != "calibration" else (lambda: merged([f() for f in owners]))

    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array:
        """The plate extractor's couplings among the plates; none to or between combs."""
        ip, _ = split(electrodes)
        out = np.zeros((len(electrodes), len(electrodes)))
        if ip:
            out[np.ix_(ip, ip)] = self.plates.coupling([electrodes[i] for i in ip], plate)
        return out


def merged(records: list[dict]) -> dict:
    """Calibration records of two parts as one: sources joined, per-electrode lists concatenated."""
    out: dict = {"source": "; ".join(r.get("source", "") for r in records)}
    for key in ("fringe", "coupling_spread"):
        rows = [row for r in records for row in r.get(key, [])]
        if rows:
            out[key] = rows
    if any("points" in r for r in records):
        out["points"] = max(int(r.get("points", 0)) for r in records)
    return out
