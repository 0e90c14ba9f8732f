"""A dielectric layer on an electrode in the multipole extractor (netgen.electrostatics.fastcap)
against the series-capacitor closed form and the analytic extractor.

    .venv/bin/python bench/fastcap_dielectric.py guarded --eps-r 7.5 --element-to-gap 2
    .venv/bin/python bench/fastcap_dielectric.py piston --side 100

guarded: the sense square of tests/electrostatics/test_fastcap_dielectric.py (tests/oracles/fastcap_guarded.py: a layered box
electrode whose face is split into a 20 um sense square and an 8 um guard ring, 2 um under a
plate) against eps0 L^2 / g_eff, g_eff = g - t_d + t_d / eps_r: the solver's deviation beside its
own error bar, at the settings given (the suite runs element_to_gap 1).

piston: a square plate over an electrode of the same size (2 um gap, --t-d um of a layer of
--eps-r, 0.2 um of nitride by default), rigid: FastCap with the layer, with the layer at eps_r = 1
(the electrode's box alone), without the layer, and on the coated sheet's equivalent conductor
("step": a box from the sheet up to g_eff, h_s = t_d (1 - 1/eps_r) tall; a coat on a conductor is its
surface moved out by h_s, to first order), on the layered electrode's first-order equivalent
("equivalent": a box t_d + h_s tall up to g_eff) and on a sheet at g_eff, each against the
parallel-plate extractor with its edge fringe (netgen.electrostatics.parallel_plate.EdgeFringe) and
the same layer (with and without its edge step, parallel_plate.layer_step), and against the closed
form eps0 A / g_eff (no fringe). --edge-to-gap 0.0625 resolves the rim on the 0.1-0.2 um steps.
Wall and process time per Maxwell matrix.

    .venv/bin/python bench/fastcap_dielectric.py piston --side 100 --t-d 0.1 --eps-r 3.9
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from fastcap_common import add_size_arguments, report, settings
from support import fastcap_guarded

from netgen.core.constants import EPS0
from netgen.electrostatics import fastcap
from netgen.electrostatics.parallel_plate import ParallelPlateExtractor
from netgen.geometry.shapes import Electrode, Rectangle, RectPlate

SENSE, T_D, G = fastcap_guarded.SENSE, fastcap_guarded.T_D, fastcap_guarded.G
guarded_levels = fastcap_guarded.guarded_levels

UM = 1e-6


def timed(f):
    """(result, wall s, process s) of f()."""
    w, p = time.perf_counter(), time.process_time()
    out = f()
    return out, time.perf_counter() - w, time.process_time() - p


def guarded(eps_r: float, st: fastcap.FastcapSettings) -> dict:
    """The guarded sense square against the closed form."""
    m, wall, cpu = timed(lambda: fastcap.converged(guarded_levels(eps_r, st), 1.0, st, ("p", "s", "g")))
    ref = EPS0 * SENSE**2 / (G - T_D + T_D / eps_r)
    return {
        "eps_r": eps_r,
        "C_fF": -m.matrix[0, 1] * 1e15,
        "closed_form_fF": ref * 1e15,
        "deviation": -m.matrix[0, 1] / ref - 1.0,
        "error_bar": m.error,
        "mesh_error": m.settings["mesh_error"],
        "order_error": m.settings["order_error"],
        "panels": [r["panels"] for r in m.settings["solves"]],
        "wall_s": wall,
        "cpu_s": cpu,
    }


def piston(side: float, t_d: float, eps_r: float, st: fastcap.FastcapSettings) -> dict:
    """FastCap and the analytic extractor on the layered piston (and FastCap without the layer,
    and on the layer's equivalent step)."""
    h = side / 2
    plate = RectPlate(-h, h, -h, h)

    def basis(x, y):
        return np.ones((np.size(x), 1))

    out: dict = {"side_um": side / UM, "t_d_um": t_d / UM, "eps_r": eps_r}
    layered = Electrode(Rectangle("d", -h, h, -h, h), "below", G, "d", t_d, eps_r)
    g_eff = layered.field_gap()
    # "box": the layer at eps_r = 1, invisible to the field: what the electrode's box (FastCap2
    # needs one under a layer) adds over a sheet, to separate it from the layer's own effect;
    # "step": a plain conductor from the sheet (gap G) up to g_eff, the coated sheet's equivalent
    # "equivalent": the layered electrode's own first-order equivalent, a box t_d + h_s tall up to
    # g_eff; "sheet_at_g_eff": a sheet there (the step alone is "step" minus it)
    h_s = G - g_eff
    cases = {
        "layer": (G, t_d, eps_r),
        "box": (G, t_d, 1.0),
        "none": (G, 0.0, 1.0),
        "step": (g_eff, h_s, 1.0),
        "equivalent": (g_eff, t_d + h_s, 1.0),
        "sheet_at_g_eff": (g_eff, 0.0, 1.0),
    }
    for name, (g, t, e_r) in cases.items():
        e = Electrode(Rectangle("d", -h, h, -h, h), "below", g, "d", t, e_r)
        prepared = fastcap.FastcapExtractor(settings=st).prepare([e], plate, basis)
        m, wall, cpu = timed(lambda p=prepared: p.maxwell(np.zeros(1)))
        same = layered if name in ("layer", "step", "equivalent") else e
        analytic, no_step = (
            ParallelPlateExtractor(layer_step=k).prepare([same], plate, basis).capacitance(np.zeros(1))[0]
            for k in (True, False)
        )
        c = m.plate_electrode[0]
        out[name] = {
            "fastcap_fF": c * 1e15,
            "error_bar": m.error,
            "analytic_fF": analytic * 1e15,
            "analytic_minus_fastcap": analytic / c - 1.0,
            "analytic_without_step_minus_fastcap": no_step / c - 1.0,
            "closed_form_fF": EPS0 * side**2 / e.field_gap() * 1e15,
            "fastcap_over_closed_form": c / (EPS0 * side**2 / e.field_gap()) - 1.0,
            "panels": [r["panels"] for r in m.settings["solves"]],
            "wall_s": wall,
            "cpu_s": cpu,
        }
    return out


def main() -> None:
    """Parse the arguments, run one case, print (and optionally store) the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case", choices=["guarded", "piston"])
    ap.add_argument("--eps-r", type=float, default=7.5)
    ap.add_argument("--side", type=float, default=100.0, help="piston side in um")
    ap.add_argument("--t-d", type=float, default=T_D / UM, help="piston's layer thickness in um")
    add_size_arguments(ap, 0.25, 2.0)
    a = ap.parse_args()
    st = settings(a)
    res = guarded(a.eps_r, st) if a.case == "guarded" else piston(a.side * UM, a.t_d * UM, a.eps_r, st)
    res["settings"] = {"edge_to_gap": st.edge_to_gap, "element_to_gap": st.element_to_gap}
    report(res, a.json)


if __name__ == "__main__":
    main()
