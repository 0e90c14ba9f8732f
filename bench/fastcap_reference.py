"""The reference disk (examples/levitated_disk.toml) at its own gap with the multipole extractor
(netgen.electrostatics.fastcap): each electrode's C, dC/dz and dC/dtilt_x against the analytic
extractor (parallel plate + edge fringe), the solver's own error bar (Richardson correction of two
mesh levels + the change from expansion order 4 to 6), the adjacent couplings against the dense
BEM's extrapolation (docs/bem.md: 1.41 / 2.08 / 2.83 fF), and the peak memory and time per solve.

    .venv/bin/python bench/fastcap_reference.py --count          # panels per level, no solve
    .venv/bin/python bench/fastcap_reference.py --gap-over-r 0.0063 --json out.json
    .venv/bin/python bench/fastcap_reference.py --gap-over-r 0.0063 --edge-to-gap 0.5 --element-to-gap 4

dC/dz and dC/dtilt_x come from one forward solve along both, split by the y-mirror symmetry
(bem_reference_disk.separate); the analytic extractor is differenced over the same step, so the
one-sided bias cancels in the comparison. Peak RSS is the process's (one g/R per process).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np
from bem_reference_disk import adjacent_pairs, mirrors, separate, structure

from netgen.electrostatics import EXTRACTORS
from netgen.electrostatics.fastcap import FastcapExtractor, FastcapSettings
from netgen.geometry.layout import electrodes, plate_outline
from netgen.mechanics import mechanics

BEM_COUPLINGS_FF = {"inner": 1.41, "outer": 2.08, "inner-outer": 2.83}


def peak_gb() -> float:
    """Peak resident memory of this process so far (GB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9


def run(gr: float, st: FastcapSettings, count: bool) -> dict:
    """Panels (and, unless count, the solves and comparisons) at g/R = gr."""
    s = structure(gr)
    m = mechanics(s)
    plate, shapes = plate_outline(s), electrodes(s)
    fx = FastcapExtractor(eps_r=s.electrostatics.relative_permittivity, thickness=s.conductor.thickness, settings=st)
    pf = fx.prepare(shapes, plate, m.basis)
    panels = [sum(len(p) for p in pf.panels(np.zeros(pf.ncoords), k)) for k in range(2)]
    out: dict = {"g_over_r": gr, "panels": panels, "settings": {**st.__dict__}}
    print(f"g/R {gr}: panels {panels}", file=sys.stderr, flush=True)
    if count:
        return out
    pp = EXTRACTORS["parallel_plate"](s, plate).prepare(shapes, plate, m.basis)
    q0 = np.zeros(pf.ncoords)
    t0 = time.perf_counter()
    centre = pf.maxwell(q0)
    out["centre_s"], out["peak_gb_centre"] = time.perf_counter() - t0, peak_gb()
    print(f"  centre: {out['centre_s']:.0f} s, peak {out['peak_gb_centre']:.2f} GB", file=sys.stderr, flush=True)
    amp = np.abs(pf.geometry.probe.phi).max(axis=0)
    steps = {n: 0.01 * pf.gap / amp[m.names.index(n)] for n in ("z", "tilt_x")}
    dq = np.zeros(pf.ncoords)
    for n in steps:
        dq[m.names.index(n)] = steps[n]
    t1 = time.perf_counter()
    plus = pf.maxwell(dq)
    out["step_s"], out["peak_gb"] = time.perf_counter() - t1, peak_gb()
    mirror = mirrors(shapes)
    g_fc = separate(plus.plate_electrode - centre.plate_electrode, mirror, steps)
    c_pp = pp.capacitance(q0)
    g_pp = separate(pp.capacitance(dq) - c_pp, mirror, steps)
    rows = []
    for i, e in enumerate(shapes):
        rows.append(
            {
                "electrode": e.name,
                "C_fF": centre.plate_electrode[i] * 1e15,
                "pp_minus_fc_C": c_pp[i] / centre.plate_electrode[i] - 1.0,
                "pp_minus_fc_dz": g_pp["z"][i] / g_fc["z"][i] - 1.0,
                "pp_minus_fc_dtilt": (g_pp["tilt_x"][i] / g_fc["tilt_x"][i] - 1.0)
                if abs(g_fc["tilt_x"][i]) > 0
                else None,
            }
        )
    pairs = adjacent_pairs(shapes)
    coupling = centre.coupling
    out.update(
        rows=rows,
        error=centre.error,
        mesh_error=centre.settings["mesh_error"],
        order_error=centre.settings["order_error"],
        asymmetry=centre.settings["asymmetry"],
        solves=centre.settings["solves"],
        adjacent_fF=sorted({round(coupling[i, j] * 1e15, 4) for i, j in pairs}),
        to_infinity_fF=(centre.to_infinity * 1e15).tolist(),
    )
    return out


def main() -> None:
    """Parse arguments, run one g/R, print and optionally write JSON."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gap-over-r", type=float, default=3.0 / 473.0)
    ap.add_argument("--edge-to-gap", type=float, default=FastcapSettings.edge_to_gap)
    ap.add_argument("--element-to-gap", type=float, default=FastcapSettings.element_to_gap)
    ap.add_argument("--order", type=int, default=FastcapSettings.expansion_order)
    ap.add_argument("--check-order", type=int, default=FastcapSettings.check_order)
    ap.add_argument("--budget-gb", type=float, default=8.0)
    ap.add_argument("--count", action="store_true", help="count panels only")
    ap.add_argument("--json")
    a = ap.parse_args()
    st = FastcapSettings(
        edge_to_gap=a.edge_to_gap,
        element_to_gap=a.element_to_gap,
        expansion_order=a.order,
        check_order=a.check_order,
        memory_budget=a.budget_gb * 1e9,
    )
    out = run(a.gap_over_r, st, a.count)
    print(json.dumps(out, indent=1, default=float))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)


if __name__ == "__main__":
    main()
