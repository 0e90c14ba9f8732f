"""A THICK perforated plate (a square etch-hole grid through a slab of thickness t) over an electrode,
solved with the multipole extractor, against the fill factor the parallel-plate extractor uses
(netgen.electrostatics.perforation: the sheet's fringe length plus the hole walls' term, which
vanishes at t = 0). The periodic-cell argument and the guarded box electrode are those of
bench/fastcap_perforated.py (F = C_sense g / (eps0 A_sense)); here the hole walls are meshed graded
towards both faces (h_edge rows at the rims, growing inwards), so the fine sizes fit.

    cd bench && OMP_NUM_THREADS=1 nice -n 10 ../.venv/bin/python fastcap_thick_holes.py --hole-over-pitch 0.6 --gap 2 --thickness 2
    cd bench && ../.venv/bin/python fastcap_thick_holes.py --count --thickness 4       # panels only

Sizes default to the fine ones of the sheet calibration (edge-to-gap 0.125, element-to-gap 1.0).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from fastcap_common import add_size_arguments, guarded_levels, report, settings
from fastcap_perforated import UM, frame

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.bem_mesh import Sizes, graded
from netgen.electrostatics.fastcap_mesh import Panels
from netgen.electrostatics.perforation import Perforation

ASPECT = 4.0  # wall panels at most this long along the rim over their height at the rim


def graded_square(x0: float, x1: float, y0: float, y1: float, sz: Sizes) -> np.ndarray:
    """A square outline, counter-clockwise, its points graded from h_edge at the corners."""
    x, y = graded(x0, x1, sz), graded(y0, y1, sz)
    return np.concatenate(
        [
            np.column_stack([x[:-1], np.full(len(x) - 1, y0)]),
            np.column_stack([np.full(len(y) - 1, x1), y[:-1]]),
            np.column_stack([x[::-1][:-1], np.full(len(x) - 1, y1)]),
            np.column_stack([np.full(len(y) - 1, x0), y[::-1][:-1]]),
        ]
    )


def graded_wall(outline: np.ndarray, z0: float, z1: float, sz: Sizes) -> np.ndarray:
    """The wall along a closed outline between z0 and z1, rows graded from h_edge at both rims."""
    zs = graded(z0, z1, sz)
    a, b = outline, np.roll(outline, -1, axis=0)
    rows = []
    for lo, hi in zip(zs[:-1], zs[1:]):
        rows.append(
            np.stack(
                [np.column_stack([p, np.full(len(p), z)]) for p, z in ((a, lo), (b, lo), (b, hi), (a, hi))],
                axis=1,
            )
        )
    return np.concatenate(rows)


def thick_plate(cells: int, pitch: float, hole: float, thickness: float, gap: float, sz: Sizes) -> Panels:
    """The plate of `thickness`, its lower face `gap` above z = 0: both faces, every hole's wall
    (graded along the rim from h_edge at the corners, at most ASPECT h_edge long) and the outer rim."""
    c, m = cells * pitch / 2, (pitch - hole) / 2
    origins = [(-c + i * pitch, -c + j * pitch) for i in range(cells) for j in range(cells)]
    lower = np.concatenate([q for x, y in origins for q in frame(x, y, pitch, hole, sz, gap)])
    upper = lower.copy()
    upper[:, :, 2] += thickness
    along = Sizes(sz.h_edge, min(sz.h_max, ASPECT * sz.h_edge), sz.growth)
    parts = [lower, upper, graded_wall(graded_square(-c, c, -c, c, sz), gap, gap + thickness, sz)]
    for x, y in origins:
        rim = graded_square(x + m, x + pitch - m, y + m, y + pitch - m, along)
        parts.append(graded_wall(rim, gap, gap + thickness, sz))
    return Panels(np.concatenate(parts))


def main() -> None:
    """Solve one thick hole grid and print its effective fill factor beside the form's."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hole-over-pitch", type=float, default=0.6)
    ap.add_argument("--pitch", type=float, default=10.0, help="um")
    ap.add_argument("--gap", type=float, default=2.0, help="um")
    ap.add_argument("--thickness", type=float, default=2.0, help="plate thickness in um (> 0)")
    ap.add_argument("--cells", type=int, default=6)
    ap.add_argument("--sense", type=int, default=2)
    add_size_arguments(ap, 0.125, 1.0)
    ap.add_argument("--count", action="store_true", help="count panels only")
    a = ap.parse_args()
    if a.thickness <= 0.0:
        ap.error("--thickness must be > 0 (a sheet: bench/fastcap_perforated.py)")
    pitch, gap, t = a.pitch * UM, a.gap * UM, a.thickness * UM
    hole = a.hole_over_pitch * pitch
    st = settings(a)
    lv = guarded_levels(a.cells, a.sense, pitch, gap, st, lambda sz: thick_plate(a.cells, pitch, hole, t, gap, sz))
    panels = [sum(len(p) for p in x) for x in lv]
    if a.count:
        print(json.dumps({"panels": panels}))
        return
    w, p = time.perf_counter(), time.process_time()
    m = fastcap.converged(lv, 1.0, st, ("p", "s", "g"))
    f = -m.matrix[0, 1] * gap / (EPS0 * (a.sense * pitch) ** 2)
    form = float(Perforation(hole, pitch, thickness=t).fill(gap))
    sheet = float(Perforation(hole, pitch).fill(gap))
    res = {
        "hole_over_pitch": a.hole_over_pitch,
        "pitch_um": a.pitch,
        "gap_um": a.gap,
        "thickness_um": a.thickness,
        "sizes": [a.edge_to_gap, a.element_to_gap],
        "effective_fill": f,
        "error_bar": m.error,
        "form": form,
        "form_minus_fastcap": form / f - 1.0,
        "sheet_form_minus_fastcap": sheet / f - 1.0,
        "panels": [r["panels"] for r in m.settings["solves"]],
        "wall_s": time.perf_counter() - w,
        "cpu_s": time.process_time() - p,
    }
    report(res, a.json)


if __name__ == "__main__":
    main()
