"""Accuracy of the model through OSDI in ngspice 46 against the B-source .lib and solve_ivp: the
105 us open-loop transient of tests/emit/test_osdi.py (pulses on four electrodes, gravity on z)
per coordinate, at the given reltol values and maximum steps, with the time-point count.

    .venv/bin/python bench/osdi_newton.py [--reltol 1e-3,1e-4] [--tmax 10n,50n] [--va FILE]

--va compiles another Verilog-A text of the same module instead of the emitted one (e.g. the
committed netlists/levitated_disk.va of an earlier version) to compare forms. Measured (ngspice 46,
reltol 1e-3, tmax 10n, max |error| / peak of solve_ivp): z 2.7e-3 with the electrostatic force as a
module variable, 3.1e-4 with it on the force node fn_z (the .lib: 3.2e-4), 15709 time points each.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from support import NGSPICE, ROOT, Bench, reference_transient, transient_drive

from netgen import emit
from netgen.emit import osdi
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice


def main() -> None:
    """Run each (reltol, tmax, form) and print the per-coordinate errors and the time points."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reltol", default="1e-3,1e-4")
    ap.add_argument("--tmax", default="10n,50n")
    ap.add_argument("--va", type=Path, help="compile this .va instead of the emitted module")
    args = ap.parse_args()
    os.environ["NETGEN_NGSPICE"] = NGSPICE["46"]
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    work = Path(tempfile.mkdtemp(prefix="osdi-newton-"))
    emit.write_outputs(model, work, "osdi")
    module = osdi.compiled(args.va.read_text(), "other", work) if args.va else work / "levitated_disk.osdi"
    drive, stop = transient_drive(), 105e-6
    gravity = -model.coordinates[0].mass * 9.81
    sources = {k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)}
    f_ext = np.zeros(model.ncoords)
    f_ext[0] = gravity
    forms = {
        "osdi": (work / "levitated_disk_osdi.lib", [f"pre_osdi {module}", "set num_threads=1"]),
        "lib": (ROOT / "netlists" / "levitated_disk.lib", []),
    }
    for reltol in args.reltol.split(","):
        for tmax in args.tmax.split(","):
            for name, (lib, control) in forms.items():
                bench = Bench(model, lib, control=control, sources=sources, options=f"reltol={reltol} chgtol=1e-18")
                start = time.perf_counter()
                plot = run_ngspice(bench.netlist(f".tran 10n {stop} 0 {tmax} uic"), work / f"{name}_{reltol}_{tmax}")[0]
                wall = time.perf_counter() - start
                node = (lambda s: f"v({osdi.state_node(s)})") if name == "osdi" else (lambda s: f"v(x1.{s})")
                x = np.stack([plot[node(f"xs_{c.name}")] for c in model.coordinates], axis=-1)
                ref = reference_transient(model, drive, f_ext, np.asarray(plot["time"]), stop)
                errs = np.abs(x - ref).max(axis=0) / np.abs(ref).max(axis=0)
                print(
                    f"{name:5s} reltol={reltol} tmax={tmax} points={len(plot['time'])} wall={wall:.2f}s  "
                    + " ".join(f"{c.name}={e:.2e}" for c, e in zip(model.coordinates, errs)),
                    flush=True,
                )


if __name__ == "__main__":
    main()
