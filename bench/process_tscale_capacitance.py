"""tscale's capacitance law (netgen.model.process.thickness_capacitance): the figures quoted in
docs/process.md and CHANGELOG.md. accelerometer_xyz with textbook combs (tests/oracles/process_cases.
xyz_thick) and its perforated mass on crab legs without combs (process_cases.perforated), built with
tscale and rebuilt at 0.9 and 1.1 times the 2 um layer: the stated error, and the capacitances at 100
points against the rebuilds' fits with the law and without it (the perforated case's fits are coarse,
4.4e-3, so its figures are not asserted by a test). Run from the repository root:
    .venv/bin/python bench/process_tscale_capacitance.py
"""

from __future__ import annotations

import time

import numpy as np
from support import process_cases

from netgen.build import build_model
from netgen.model.process import capacitance_at
from netgen.structure import parse_structure

PROCESS = '\n[process]\nparameters = ["tscale"]\n'


def perforated(tscale: float = 1.0, process: str = "") -> str:
    """process_cases.perforated (crab legs, 40 x 40 holes, z plates, no combs) at tscale times 2 um."""
    text = process_cases.perforated(process=process)
    assert text.count('thickness = "2.0 um"') == 1
    return text.replace('thickness = "2.0 um"', f'thickness = "{2.0 * tscale!r} um"')


def report(label: str, text) -> None:
    t0 = time.perf_counter()
    nominal = build_model(parse_structure(text(1.0, PROCESS), "case.toml"))
    law = nominal.process["tscale"]
    names = [r["electrode"] for r in law.get("capacitance_laws", [])]
    print(f"{label}: laws on {names}, stated {law.get('capacitance_max_rel_error', 0.0):.2g}, "
          f"fits {max(f.max_rel_error for f in nominal.capacitances):.2g}, build {time.perf_counter() - t0:.1f} s")  # fmt: skip
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, nominal.ncoords))
    for tscale in (0.9, 1.1):
        model = build_model(parse_structure(text(tscale), "case.toml"))
        ref = model.capacitance(x * nominal.scales / model.scales)
        for group, keep in (("combs", "xy"), ("plates", "z")):
            cols = [k for k, f in enumerate(nominal.capacitances) if f.electrode[0] in keep]
            if not cols:
                continue
            got = np.abs(capacitance_at(nominal, x, tscale=tscale)[:, cols] / ref[:, cols] - 1).max()
            dropped = np.abs(capacitance_at(nominal, x)[:, cols] / ref[:, cols] - 1).max()
            print(f"  tscale {tscale}: {group} against the rebuild {got:.2g} (without the law {dropped:.2g})")


if __name__ == "__main__":
    report("accelerometer_xyz, textbook combs", lambda t, p="": process_cases.xyz_thick(t, p))
    report("perforated crab-leg mass, no combs", perforated)
