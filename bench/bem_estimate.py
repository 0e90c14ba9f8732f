"""Closed-form element estimate (netgen.electrostatics.bem_mesh.estimate_elements) against the
mesher's real count, on the small disk of tests/electrostatics/test_bem_settings.py and a
rectangle, over a few settings. Run: .venv/bin/python bench/bem_estimate.py"""

from __future__ import annotations

import math

from netgen.electrostatics.bem import BemSettings
from netgen.electrostatics.bem_mesh import electrode_sheet, estimate_elements, thick_plate
from netgen.geometry.shapes import AnnularSector, DiskPlate, Electrode, Rectangle, RectPlate


def real(plate, thickness, electrodes, sizes) -> int:
    """Triangles the mesher builds for one level."""
    n = len(thick_plate(plate, thickness, sizes).triangles)
    return n + sum(len(electrode_sheet(e, sizes, e.sign * (thickness / 2 + e.gap)).triangles) for e in electrodes)


def cases():
    """(name, plate, thickness, electrodes, gap) of the compared geometries."""
    g = 20e-6
    disk = DiskPlate(100e-6)
    ring = [Electrode(AnnularSector("top", 0.0, 100e-6, 0.0, 2 * math.pi), "above", g)]
    quad = [
        Electrode(AnnularSector(f"q{k}", 20e-6, 100e-6, k * math.pi / 2, (k + 1) * math.pi / 2, 4e-6), "below", g)
        for k in range(4)
    ]
    rect = RectPlate(-150e-6, 150e-6, -60e-6, 60e-6)
    pads = [Electrode(Rectangle("L", -140e-6, -10e-6, -50e-6, 50e-6), "below", 5e-6)]
    yield "disk+ring", disk, 2e-6, ring, g
    yield "disk+quadrants", disk, 0.0, quad, g
    yield "rect+pad", rect, 2e-6, pads, 5e-6


if __name__ == "__main__":
    print(f"{'case':16s} {'edge':>6s} {'elem':>6s} {'real':>8s} {'estimate':>9s} {'ratio':>6s}")
    for name, plate, t, els, gap in cases():
        for edge, elem in ((0.5, 4.0), (0.25, 2.0), (0.1, 2.0), (0.05, 1.0), (0.01, 1.0)):
            st = BemSettings(edge_to_gap=edge, element_to_gap=elem)
            sizes = st.sizes(gap, 0, plate.size)
            r, e = real(plate, t, tuple(els), sizes), estimate_elements(plate, t, tuple(els), sizes)
            print(f"{name:16s} {edge:6g} {elem:6g} {r:8d} {e:9.0f} {e / r:6.2f}")
