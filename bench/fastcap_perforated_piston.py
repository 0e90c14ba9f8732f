"""A perforated piston through the extractors: the multipole extractor with the etch holes meshed
(netgen.electrostatics.fastcap, FastcapExtractor(perforation=...)) against the parallel-plate
extractor with the fringe-corrected fill factor F(g) (netgen.electrostatics.perforation), each
over its own solid piston, at several gaps; the memory and time estimate beside what the solve took.

    .venv/bin/python bench/fastcap_perforated_piston.py --side 40 --hole-over-pitch 0.5 --gaps 2,3
    .venv/bin/python bench/fastcap_perforated_piston.py --side 80 --hole-over-pitch 0.5 --gaps 2,3
    .venv/bin/python bench/fastcap_perforated_piston.py --side 40 --hole-over-pitch 0.5 --thickness 2

The piston: a square plate of `side` (a centred grid of floor(side / pitch) holes per side, as a
proof mass counts them) over an electrode of its own size at `gap` (the plate moved rigidly from
the first gap, on the panels of the first gap), a sheet or `thickness` thick (the holes walled).
The ratio perforated / solid cancels the analytic outer-edge fringe, which is the same in both; the
analytic side's F(g) carries the plate's thickness (the hole walls' term), as from_structure builds it.
Default sizes here are the fine ones (edge_to_gap 0.125, element_to_gap 1: docs/fastcap.md,
'Perforated plates', says why).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from fastcap_common import add_size_arguments, report, settings

from netgen.electrostatics import fastcap
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor
from netgen.electrostatics.perforation import Perforation
from netgen.geometry.shapes import Electrode, Rectangle, RectPlate

UM = 1e-6


def rigid(x, y):
    """The piston's one coordinate: rigid z."""
    return np.ones((np.size(x), 1))


def solve(side: float, gaps: list[float], perf: Perforation | None, thickness: float, st) -> dict:
    """FastCap and the parallel-plate extractor on one piston (perforated or solid) at every gap."""
    h = side / 2
    plate = RectPlate(-h, h, -h, h)
    e = Electrode(Rectangle("d", -h, h, -h, h), "below", gaps[0])
    prepared = fastcap.FastcapExtractor(settings=st, thickness=thickness, perforation=perf).prepare([e], plate, rigid)
    estimate = prepared.estimate()
    q = np.array([[g - gaps[0]] for g in gaps])
    w, p = time.perf_counter(), time.process_time()
    ms = [prepared.maxwell(row) for row in q]
    wall, cpu = time.perf_counter() - w, time.process_time() - p
    analytic = ParallelPlateExtractor(perforation=perf).prepare([e], plate, rigid).capacitance(q)[:, 0]
    return {
        "fastcap_fF": [m.plate_electrode[0] * 1e15 for m in ms],
        "error_bar": [m.error for m in ms],
        "analytic_fF": (analytic * 1e15).tolist(),
        "analytic_minus_fastcap": [a / m.plate_electrode[0] - 1.0 for a, m in zip(analytic, ms)],
        "panels": [r["panels"] for r in ms[0].settings["solves"]],
        "estimate": estimate,
        "wall_s_per_point": wall / len(gaps),
        "cpu_s_per_point": cpu / len(gaps),
    }


def main() -> None:
    """Solve the perforated and the solid piston, print the JSON (and store it with --json)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--side", type=float, default=40.0, help="um")
    ap.add_argument("--pitch", type=float, default=10.0, help="um")
    ap.add_argument("--hole-over-pitch", type=float, default=0.5)
    ap.add_argument("--gaps", default="2,3", help="um, comma-separated (panels sized for the first)")
    ap.add_argument("--thickness", type=float, default=0.0, help="um (0: a sheet)")
    add_size_arguments(ap, 0.125, 1.0)
    a = ap.parse_args()
    st = settings(a)
    gaps = [float(g) * UM for g in a.gaps.split(",")]
    perf = Perforation(a.hole_over_pitch * a.pitch * UM, a.pitch * UM, thickness=a.thickness * UM)
    res: dict = {
        "side_um": a.side,
        "hole_over_pitch": a.hole_over_pitch,
        "gaps_um": a.gaps,
        "thickness_um": a.thickness,
    }
    for name, pf in (("perforated", perf), ("solid", None)):
        res[name] = solve(a.side * UM, gaps, pf, a.thickness * UM, st)
    p, s = res["perforated"], res["solid"]
    ratio_fc = np.array(p["fastcap_fF"]) / np.array(s["fastcap_fF"])
    ratio_pp = np.array(p["analytic_fF"]) / np.array(s["analytic_fF"])
    res["ratio_fastcap"] = ratio_fc.tolist()
    res["ratio_analytic"] = ratio_pp.tolist()
    res["ratio_analytic_minus_fastcap"] = (ratio_pp / ratio_fc - 1.0).tolist()
    res["form_F"] = perf.fill(np.array(gaps)).tolist()
    res["plain_fill"] = 1.0 - a.hole_over_pitch**2
    report(res, a.json)


if __name__ == "__main__":
    main()
