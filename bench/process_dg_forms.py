"""The gap offset dg_drive in the _xspice.lib against the .lib, and the contact stop's shift with dg
(.lib in ngspice 39, .lib and OSDI in ngspice 46): the figures quoted in docs/process.md and
CHANGELOG.md, on examples/piston_process.toml. Run from the repository root:
    .venv/bin/python bench/process_dg_forms.py
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
from support import NGSPICE, ROOT, process_forms

from netgen import emit
from netgen.build import build_model
from netgen.structure import load_structure

# the suite's piston runs (tests/oracles/process_forms.py)
libs, op, resting, run = process_forms.libs, process_forms.op, process_forms.resting, process_forms.run

DGS = (-2e-7, 0.0, 3e-7)


def response(inc, dg: float, folder: Path) -> tuple[float, float, float, float]:
    """Deflection at 2 V, .ac k_eff and m at 2 V, and the rest on the stop under 10 uN (m, N/m, kg, m)."""
    z = float(run(inc, dg, "2", "DC 0\n.op", folder / "op")["v(xz)"].real[0]) * 1e-6
    ac = run(inc, dg, "2", "DC 0 AC 1\n.ac lin 3 5k 30k", folder / "ac")
    w = 2 * np.pi * np.real(ac["frequency"])
    (k, m), *_ = np.linalg.lstsq(np.stack([np.ones_like(w), -(w**2)], axis=1), (1.0 / ac["v(xz)"]).real, rcond=None)
    stop = float(run(inc, dg, "0", "DC -10\n.op", folder / "stop")["v(xz)"].real[0]) * 1e-6
    return z, float(k), float(m), stop


def main() -> None:
    """Print the _xspice.lib's deviations from the .lib and the stop's from the balance at each dg."""
    model = build_model(load_structure(ROOT / "examples/piston_process.toml"))
    folder = Path(tempfile.mkdtemp())
    forms = libs(model, folder)  # ngspice 39 as installed: the code model is built for it
    for dg in DGS:
        lib = response(forms["lib"], dg, folder / f"lib{dg}")
        xs = response(forms["xspice"], dg, folder / f"xspice{dg}")
        print(
            f"xspice - lib at dg {dg:g} m: deflection {xs[0] - lib[0]:.2e} m, k_eff {xs[1] / lib[1] - 1:.2e}, "
            f"m {xs[2] / lib[2] - 1:.2e}, on the stop {xs[3] - lib[3]:.2e} m"
        )
    emit.write_outputs(model, folder, "osdi")
    for release in ("39", "46"):
        os.environ["NETGEN_NGSPICE"] = NGSPICE[release]
        for dg in DGS:
            for form in ("lib", "osdi") if release == "46" else ("lib",):
                z = op(folder, form, dg, folder / f"stop{release}{form}{dg}")
                print(
                    f"ngspice {release} {form} dg {dg:g} m: rest {z:.6e} m, stop surface {-(2e-6 + dg):.3e} m, "
                    f"against the balance {z - resting(model, dg):.2e} m"
                )


if __name__ == "__main__":
    main()
