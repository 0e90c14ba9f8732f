"""The beams' mode shapes carry a sign from a fixed place (netgen.mechanics.beam.first_peaks): the
first grid point from the clamp at x = 0 whose deflection is within 1e-6 of the mode's largest is
positive (checked here on a finer grid at 1e-4: far above rounding, far below the gap to a lower lobe). An antisymmetric mode (the clamped-clamped beam's second) has two equal lobes, and picking
the larger by rounding flipped its sign under another CPU's BLAS kernels."""

from __future__ import annotations

import numpy as np
import pytest

from netgen.mechanics.beam import beam_modes, first_peaks
from netgen.structure import load_structure
from tests.fixtures import ROOT


@pytest.mark.parametrize("name", ["cantilever", "cc_beam"])
def test_first_lobe_is_positive(name):
    modes = beam_modes(load_structure(ROOT / "examples" / f"{name}.toml").conductor, 3)
    xs = np.linspace(0.0, modes.length, 2001)
    shapes = modes.shape(xs)
    for k in range(shapes.shape[1]):
        big = np.abs(shapes[:, k]) >= (1 - 1e-4) * np.max(np.abs(shapes[:, k]))  # the peaks, grid-coarse
        assert shapes[np.argmax(big), k] > 0, (name, k)  # the one nearest the clamp


def test_equal_lobes_pick_the_first():
    """Two lobes equal but for a last-digit difference either way: the first is the peak."""
    x = np.linspace(0.0, 1.0, 101)
    odd = np.sin(2 * np.pi * x)
    for tilt in (1 + 1e-15, 1 - 1e-15):
        shape = np.where(x > 0.5, odd * tilt, odd)[:, None]
        assert first_peaks(shape)[0] == 25
