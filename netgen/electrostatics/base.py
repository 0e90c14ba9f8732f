"""The extractor protocol: what the sampling, the fit and the contact model ask of any
capacitance extractor (netgen.electrostatics.EXTRACTORS)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.shapes import Array, Basis, Electrode, Plate


@dataclass(frozen=True)
class ProbePoints:
    """Points on the electrodes where the local gap is watched: the contact model's stop
    candidates (netgen.model.contact). The local gap at point j is gap_j - phi_j . q."""

    gap: Array  # (npts,) undeformed gap of the point's electrode
    phi: Array  # (npts, ncoords) signed basis: gap closed per unit of each coordinate
    electrode: np.ndarray  # (npts,) index of the point's electrode


@runtime_checkable
class PreparedExtractor(Protocol):
    """Capacitances of a fixed electrode set for many coordinate samples Q (nsamples, ncoords)."""

    electrodes: tuple[Electrode, ...]

    def capacitance(self, Q: ArrayLike) -> Array: ...
    def gradient(self, Q: ArrayLike) -> Array: ...
    def min_gap(self, Q: ArrayLike) -> Array: ...
    def probe_points(self) -> ProbePoints: ...


@runtime_checkable
class CapacitanceExtractor(Protocol):
    """Builds a PreparedExtractor: geometry and basis are evaluated once, samples are cheap;
    `coupling` gives the constant electrode-electrode capacitances (nel, nel); `description`
    says in a line what it computes (the model report)."""

    @property
    def description(self) -> str: ...

    def prepare(self, electrodes: Sequence[Electrode], plate: Plate, basis: Basis) -> PreparedExtractor: ...
    def coupling(self, electrodes: Sequence[Electrode], plate: Plate) -> Array: ...
