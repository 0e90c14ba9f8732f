"""The reduced BEM problem of the sampling tests (tests/electrostatics/test_bem_sampling.py) and
bench/bem_throughput.py: a 100 um disk between two full electrodes 20 um away, coordinates z and
tilt_x, coarse meshes (a few hundred elements, a solve in ~0.1 s)."""

from __future__ import annotations

import math

import numpy as np

from netgen.core.constants import EPS0
from netgen.electrostatics import bem
from netgen.geometry.shapes import AnnularSector, DiskPlate, Electrode

UM = 1e-6
R, GAP = 100 * UM, 20 * UM


def rigid(x, y):
    """z and tilt_x (w = z + theta y) at the points."""
    return np.column_stack([np.ones(np.size(x)), np.asarray(y, dtype=float)])


def reduced() -> bem.PreparedBem:
    """The reduced problem: small coarse meshes (a few hundred elements), a solve in ~0.1 s."""
    els = [
        Electrode(AnnularSector("top", 0.0, R, 0.0, 2 * math.pi), "above", GAP),
        Electrode(AnnularSector("bot", 0.0, R, 0.0, 2 * math.pi), "below", GAP),
    ]
    st = bem.BemSettings(element_to_gap=2.0, edge_to_gap=1.0, element_to_size=0.5, tolerance=1.0, max_levels=2)
    return bem.BemExtractor(eps=EPS0, settings=st).prepare(els, DiskPlate(R), rigid)
