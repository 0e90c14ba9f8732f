"""tscale's capacitance law (netgen.model.process.thickness_capacitance): the figures quoted in
docs/process.md and CHANGELOG.md. accelerometer_xyz with textbook combs (tests/oracles/process_cases.
xyz_thick) and its perforated mass on crab legs without combs (process_cases.perforated), built with
tscale and rebuilt at 0.9 and 1.1 times the 2 um layer: the stated error, and the capacitances at 100
points against the rebuilds' fits with the law and without it (the perforated case's fits are coarse,
4.4e-3, so its figures are not asserted by a test). With --field2d: accelerometer_xyz with its field2d
combs (the 2-D section tables at the five thicknesses are shipped: netgen/electrostatics/comb_tables),
the same figures per comb and the modal frequencies against the rebuilds. Run from the repository root:
    .venv/bin/python bench/process_tscale_capacitance.py [--field2d]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from support import process_cases

from netgen.build import build_model
from netgen.electrostatics.sampling import check_points
from netgen.model.process import capacitance_at, coordinate_values
from netgen.structure import parse_structure

PROCESS = '\n[process]\nparameters = ["tscale"]\n'


def perforated(tscale: float = 1.0, process: str = "") -> str:
    """process_cases.perforated (crab legs, 40 x 40 holes, z plates, no combs) at tscale times 2 um."""
    text = process_cases.perforated(process=process)
    assert text.count('thickness = "2.0 um"') == 1
    return text.replace('thickness = "2.0 um"', f'thickness = "{2.0 * tscale!r} um"')


def field2d(tscale: float = 1.0, process: str = "") -> str:
    """process_cases.xyz_thick with accelerometer_xyz's own field2d combs."""
    return process_cases.xyz_thick(tscale, process).replace('comb_model = "textbook"', 'comb_model = "field2d"')


def nominal_structure(text):
    """The [sampling] of the nominal structure (its fit box)."""
    return parse_structure(text(1.0), "case.toml").sampling


def frequencies(nominal, model, tscale: float) -> None:
    """The law's modal frequencies against the rebuild's, per coordinate."""
    rel = []
    for v, c in enumerate(model.coordinates):
        m, k, _ = coordinate_values(nominal.process, v, tscale=tscale)
        rel.append(f"{c.name} {math.sqrt(k / m) / math.sqrt(c.stiffness / c.mass) - 1:+.1e}")
    print(f"  tscale {tscale}: frequencies against the rebuild: {', '.join(rel)}")


def report(label: str, text, modes: bool = False) -> None:
    t0 = time.perf_counter()
    nominal = build_model(parse_structure(text(1.0, PROCESS), "case.toml"))
    law = nominal.process["tscale"]
    names = [r["electrode"] for r in law.get("capacitance_laws", [])]
    bare = law.get("capacitance_stateless_max_rel_error")
    states = [r["electrode"] for r in law.get("capacitance_laws", []) if "state" in r]
    if states:  # the combs' state factors (netgen.model.etch_state with u = tscale - 1)
        print(f"{label}: state factors on {states}; stated without them {bare:.2g}")
    print(f"{label}: laws on {names}, stated {law.get('capacitance_max_rel_error', 0.0):.2g}, "
          f"fits {max(f.max_rel_error for f in nominal.capacitances):.2g}, build {time.perf_counter() - t0:.1f} s")  # fmt: skip
    x = np.random.default_rng(5).uniform(-0.15, 0.15, (100, nominal.ncoords))
    half = np.abs(check_points(nominal_structure(text), 32, nominal.ncoords)).max(axis=0)  # the box's corners
    whole = np.random.default_rng(1).uniform(-1.0, 1.0, (2000, nominal.ncoords)) * half
    for tscale in (0.9, 1.1):
        model = build_model(parse_structure(text(tscale), "case.toml"))
        ratio = nominal.scales / model.scales
        ref = model.capacitance(x * ratio)
        for group, keep in (("combs", "xy"), ("plates", "z")):
            cols = [k for k, f in enumerate(nominal.capacitances) if f.electrode[0] in keep]
            if not cols:
                continue
            got = np.abs(capacitance_at(nominal, x, tscale=tscale)[:, cols] / ref[:, cols] - 1).max()
            dropped = np.abs(capacitance_at(nominal, x)[:, cols] / ref[:, cols] - 1).max()
            print(f"  tscale {tscale}: {group} against the rebuild {got:.2g} (without the law {dropped:.2g})")
            box = capacitance_at(nominal, whole, tscale=tscale)[:, cols] / model.capacitance(whole * ratio)[:, cols]
            print(f"  tscale {tscale}: {group} over the whole fit box (2000 points) {np.abs(box - 1).max():.2g}")
        print(f"  tscale {tscale}: rebuild's fits {max(f.max_rel_error for f in model.capacitances):.2g}")
        if modes:
            frequencies(nominal, model, tscale)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--field2d", action="store_true", help="accelerometer_xyz with its field2d combs")
    if ap.parse_args().field2d:
        report("accelerometer_xyz, field2d combs", field2d, modes=True)
    else:
        report("accelerometer_xyz, textbook combs", lambda t, p="": process_cases.xyz_thick(t, p))
        report("perforated crab-leg mass, no combs", perforated)
