"""The guarded layered electrode of tests/electrostatics/test_fastcap_dielectric.py and
bench/fastcap_dielectric.py: one layered box electrode whose face is split into a central sense
square and the guard ring around it, G under a plate of the same width, meshed at both levels of the
multipole extractor (netgen.electrostatics.fastcap). The sense square carries the charge of an
infinite parallel plate over its area, eps0 SENSE^2 / (G - T_D + T_D / eps_r) (the test module's
docstring says why and to what tolerance)."""

from __future__ import annotations

import numpy as np

from netgen.electrostatics import fastcap
from netgen.electrostatics.fastcap_mesh import Layered, Panels, layered_panels, rect_panels
from netgen.geometry.shapes import Electrode, Rectangle

UM = 1e-6
G, T_D = 2 * UM, 0.2 * UM
SENSE, GUARD = 20 * UM, 8 * UM


def guarded_levels(eps_r: float, st: fastcap.FastcapSettings) -> list[list]:
    """Both mesh levels of the guarded layered electrode (module docstring): plate, sense, guard.
    The layer's top face is the split face moved up, so interface and conductor panels align."""
    a, c = SENSE / 2, SENSE / 2 + GUARD
    levels = []
    for k in range(2):
        sz = st.sizes(G - T_D, k)
        box = layered_panels(Electrode(Rectangle("g", -c, c, -c, c), "below", G, "g", T_D, eps_r), sz, 0.0, 1.0)
        sense = rect_panels(-a, a, -a, a, sz, 0.0)
        pieces = [(-c, c, -c, -a), (-c, c, a, c), (-c, -a, -a, a), (a, c, -a, a)]
        ring = np.concatenate([rect_panels(*p, sz, 0.0).corners for p in pieces])
        top = np.concatenate([sense.corners, ring])
        top[:, :, 2] += T_D
        n_top = len(rect_panels(-c, c, -c, c, sz, 0.0))  # the box's own top face, replaced by `top`
        interface = Panels(np.concatenate([top, box.interface.corners[n_top:]]))
        refs = np.concatenate([top.mean(axis=1) - [0.0, 0.0, T_D / 2], box.refs[n_top:]])
        empty = Panels(np.zeros((0, 4, 3)))
        levels.append(
            [
                rect_panels(-c, c, -c, c, sz, G),
                Layered(sense, empty, empty, np.zeros((0, 3)), eps_r),
                Layered(Panels(ring), box.rest, interface, refs, eps_r),
            ]
        )
    return levels
