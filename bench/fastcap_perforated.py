"""A perforated plate (a square etch-hole grid, as conductor.hole / hole_pitch of a proof mass)
over an electrode, solved with the multipole extractor (netgen.electrostatics.fastcap), against
the fill factor 1 - (hole / pitch)^2, the solid plate, and the fringe-corrected fill factor the
parallel-plate extractor uses (netgen.electrostatics.perforation, fitted on this bench's fine-panel
solves: --edge-to-gap 0.125 --element-to-gap 1.0; the default sizes are 1-3 % off here).

    .venv/bin/python bench/fastcap_perforated.py --hole-over-pitch 0.4
    .venv/bin/python bench/fastcap_perforated.py --hole-over-pitch 0.6 --thickness 2

Periodic-cell argument with a guard: the plate is cells x cells holes of `pitch`; the electrode
2 um below is a box whose face is split into the central sense x sense cells (the sense
conductor) and the ring around them (the guard, with the box's back and walls), both at 0 V. The
sense region lies `(cells - sense) / 2` pitches inside the plate's outer edge (10 gaps at the
defaults), where the outer fringe has decayed (exp(-pi x / g)), so its charge per area is that of
an infinite perforated plate: F = C_sense g / (eps0 A_sense) is the effective (fringe-corrected)
fill factor of the hole grid. The plate is a sheet (thickness 0) or a slab with the holes' walls.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from fastcap_common import add_size_arguments, guarded_levels, report, settings

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.bem_mesh import Sizes
from netgen.electrostatics.fastcap_mesh import Panels, rect_panels, walls
from netgen.electrostatics.perforation import Perforation

UM = 1e-6


def frame(x0: float, y0: float, pitch: float, hole: float, sz: Sizes, z: float) -> list[np.ndarray]:
    """One cell's solid frame around its centred hole: four rectangles' panels."""
    m = (pitch - hole) / 2
    parts = [
        (x0, x0 + pitch, y0, y0 + m),
        (x0, x0 + pitch, y0 + pitch - m, y0 + pitch),
        (x0, x0 + m, y0 + m, y0 + pitch - m),
        (x0 + pitch - m, x0 + pitch, y0 + m, y0 + pitch - m),
    ]
    return [rect_panels(*p, sz, z).corners for p in parts]


def square(x0: float, x1: float, y0: float, y1: float, h: float) -> np.ndarray:
    """A square outline, counter-clockwise, points at most h apart."""
    n = max(1, int(np.ceil((x1 - x0) / h)))
    t = np.linspace(0.0, 1.0, n + 1)[:-1]
    return np.concatenate(
        [
            np.column_stack([x0 + t * (x1 - x0), np.full(n, y0)]),
            np.column_stack([np.full(n, x1), y0 + t * (y1 - y0)]),
            np.column_stack([x1 - t * (x1 - x0), np.full(n, y1)]),
            np.column_stack([np.full(n, x0), y1 - t * (y1 - y0)]),
        ]
    )


def plate(cells: int, pitch: float, hole: float, thickness: float, gap: float, sz: Sizes) -> Panels:
    """The perforated plate, its lower face `gap` above z = 0: a sheet, or two faces, the outer
    rim and every hole's wall."""
    c = cells * pitch / 2
    origins = [(-c + i * pitch, -c + j * pitch) for i in range(cells) for j in range(cells)]
    lower = np.concatenate([q for x, y in origins for q in frame(x, y, pitch, hole, sz, gap)])
    if thickness <= 0.0:
        return Panels(lower)
    upper = lower.copy()
    upper[:, :, 2] += thickness
    h = sz.h_edge
    rims = [walls(square(-c, c, -c, c, h), gap, gap + thickness, h)[0].corners]
    for x, y in origins:
        m = (pitch - hole) / 2
        rims.append(walls(square(x + m, x + pitch - m, y + m, y + pitch - m, h), gap, gap + thickness, h)[0].corners)
    return Panels(np.concatenate([lower, upper, *rims]))


def main() -> None:
    """Solve one hole grid and print the effective fill factor beside the analytic ones."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hole-over-pitch", type=float, default=0.4)
    ap.add_argument("--pitch", type=float, default=10.0, help="um")
    ap.add_argument("--gap", type=float, default=2.0, help="um")
    ap.add_argument("--thickness", type=float, default=0.0, help="plate thickness in um (0: a sheet)")
    ap.add_argument("--cells", type=int, default=6)
    ap.add_argument("--sense", type=int, default=2)
    add_size_arguments(ap, 0.25, 2.0)
    a = ap.parse_args()
    pitch, gap = a.pitch * UM, a.gap * UM
    hole = a.hole_over_pitch * pitch
    st = settings(a)
    w, p = time.perf_counter(), time.process_time()
    lv = guarded_levels(
        a.cells, a.sense, pitch, gap, st, lambda sz: plate(a.cells, pitch, hole, a.thickness * UM, gap, sz)
    )
    m = fastcap.converged(lv, 1.0, st, ("p", "s", "g"))
    area = (a.sense * pitch) ** 2
    f = -m.matrix[0, 1] * gap / (EPS0 * area)
    fill = 1.0 - a.hole_over_pitch**2
    res = {
        "hole_over_pitch": a.hole_over_pitch,
        "pitch_um": a.pitch,
        "gap_um": a.gap,
        "thickness_um": a.thickness,
        "cells": a.cells,
        "sense_cells": a.sense,
        "effective_fill": f,
        "error_bar": m.error,
        "fill_factor": fill,
        "fill_factor_minus_fastcap": fill / f - 1.0,
        "solid_plate_minus_fastcap": 1.0 / f - 1.0,
        "form": float(Perforation(hole, pitch).fill(gap)),
        "form_minus_fastcap": float(Perforation(hole, pitch).fill(gap)) / f - 1.0,
        "panels": [r["panels"] for r in m.settings["solves"]],
        "wall_s": time.perf_counter() - w,
        "cpu_s": time.process_time() - p,
    }
    report(res, a.json)


if __name__ == "__main__":
    main()
