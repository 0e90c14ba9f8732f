"""The derived bound on the sigma-delta loop's mechanics (tests/oracles/sigma_delta_vacask.py's
mechanics_bound: impulse gain, the trapezoidal rule's frequency error at maxstep, the backward-Euler
step after each breakpoint, the sample's interpolation) against a run's tilts and modes, and whether
it catches a planted error: the independent integration replayed with every feedback impulse
(1 + plant) times its own (V_fb scaled by sqrt(1 + plant)).

    .venv/bin/python bench/sigma_delta_mechanics_bound.py [--simulator ngspice-osdi] [--plants 0,0.014]

One run of the reference disk's loop (T_s = 1 us, 128 periods; ngspice-osdi in ngspice 46, the other
ngspice back ends in $NETGEN_NGSPICE or the default), then per
plant the replay of its first --replay periods (~6 s each). Prints per coordinate the error of its
peak, the bound's terms and their sum, and pass/FAIL (the test asserts error < sum); for z, its
error per period against impulse_bound (the test asserts a ratio below 1). --gain and
--first are the bound's simulator numbers (tests/testbench/test_sigma_delta_vacask.py's
NGSPICE_GAIN 7e-3 and NGSPICE_FIRST 0.1; for VACASK --gain 4.0e-3 --first 0.25 --orders1 2, its
larger ramp gain, ramp step bound and backward-Euler steps per corner).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
from pathlib import Path

import numpy as np
from support import NGSPICE, ROOT
from support import sigma_delta_vacask as check

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd


def main() -> None:
    """Run once, replay per plant, print the bound's verdicts."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--simulator", default="ngspice-osdi")
    ap.add_argument("--plants", default="0,0.014", help="comma-separated relative feedback impulse errors")
    ap.add_argument("--replay", type=int, default=32)
    ap.add_argument("--gain", type=float, default=7e-3)
    ap.add_argument("--first", type=float, default=0.1)
    ap.add_argument("--orders1", type=int, default=1, help="backward-Euler steps after a corner (VACASK: 2)")
    args = ap.parse_args()
    if args.simulator == "ngspice-osdi":  # OSDI 0.5: ngspice 45 and later; the others run in the default ngspice
        os.environ.setdefault("NETGEN_NGSPICE", NGSPICE["46"])
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    d = sd.design(model, check.TS)
    with tempfile.TemporaryDirectory() as tmp:
        clock = check.run(model, Path(tmp), args.simulator, 128, 64)["clock"]
    for plant in (float(p) for p in args.plants.split(",")):
        planted = dataclasses.replace(d, vfb=d.vfb * np.sqrt(1 + plant))
        ref, vel = check.replay(model, planted, clock, args.replay, velocities=True)
        bounds = check.mechanics_bound(model, d, clock, ref, vel, args.gain, args.first, args.orders1)
        print(f"{args.simulator}, planted feedback impulse error {plant:.2e}:")
        second, z_terms = check.impulse_bound(model, d, clock, ref, args.gain, None, args.first, args.orders1)
        ratio = second / sum(z_terms.values())
        parts = " ".join(f"{k} {np.median(v / sum(z_terms.values())):.2f}" for k, v in z_terms.items())
        print(f"  z        per-period error at most {ratio.max():.3f} of its bound (median shares: {parts})")
        for i, c in enumerate(model.coordinates[1:], start=1):
            err = np.abs(clock[f"x_{c.name}"][: args.replay] - ref[:, i]).max() / np.abs(ref[:, i]).max()
            terms = bounds[c.name]
            total = sum(terms.values())
            parts = " ".join(f"{k} {v:.2e}" for k, v in terms.items())
            print(f"  {c.name:8s} error {err:.2e}  bound {total:.2e} ({parts})  {'pass' if err < total else 'FAIL'}")


if __name__ == "__main__":
    main()
