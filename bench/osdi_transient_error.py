"""Where the OSDI transient's error comes from (tests/emit/test_osdi.py,
test_transient_matches_scipy_and_the_b_source_lib): the same 105 us transient of the levitated
disk through the OSDI module and through the B-source .lib in ngspice 46, per time step and reltol,
each against solve_ivp and against each other (max |difference| of each coordinate over its peak),
and with one electrode voltage perturbed by 1e-12 relative (another CPU's rounding: how far the
step placement moves the result).

    .venv/bin/python bench/osdi_transient_error.py [STEP_RELTOL ...]   (e.g. 10n_1e-06; default all)

prints one line per (step, reltol, perturbation): the largest error over the coordinates and the
coordinate it is on, for OSDI-ref, lib-ref and OSDI-lib.
"""

from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from support import NGSPICE, ROOT, Bench, reference_transient, transient_drive

from netgen import emit
from netgen.emit import osdi
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice

STOP = 105e-6


def run(model, lib, control, drive, step, reltol, folder):
    """Scaled coordinates (time, x) of one transient."""
    gravity = -model.coordinates[0].mass * 9.81
    sources = {k: p.spice() for k, p in drive.items()} | {"plate": "0", "f_z": repr(gravity / 1e-6)}
    bench = Bench(model, lib, control=control, sources=sources, options=f"reltol={reltol} chgtol=1e-18")
    plot = run_ngspice(bench.netlist(f".tran {step} {STOP} 0 {step} uic"), folder)[0]
    if control:
        x = np.stack([plot[f"v({osdi.state_node(f'xs_{c.name}')})"] for c in model.coordinates], axis=-1)
    else:
        x = np.stack([plot[f"v(x1.xs_{c.name})"] for c in model.coordinates], axis=-1)
    return np.asarray(plot["time"]), x


def worst(model, a, b, peak):
    err = np.abs(a - b).max(axis=0) / peak
    return f"{err.max():.2e} ({model.coordinates[int(err.argmax())].name})"


def main() -> None:
    only = sys.argv[1:]  # e.g. 10n_1e-06 (default: all)
    os.environ["NETGEN_NGSPICE"] = NGSPICE["46"]
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    tmp = Path(tempfile.mkdtemp())
    emit.write_outputs(model, tmp / "b", "osdi")
    control = [f"pre_osdi {tmp / 'b' / 'levitated_disk.osdi'}", "set num_threads=1"]
    gravity = -model.coordinates[0].mass * 9.81
    f_ext = np.zeros(model.ncoords)
    f_ext[0] = gravity
    base = transient_drive()
    for step, reltol, eps in (
        ("10n", 1e-5, 0.0),
        ("10n", 1e-5, 1e-12),
        ("10n", 1e-4, 0.0),
        ("10n", 1e-6, 0.0),
        ("10n", 1e-7, 0.0),
        ("5n", 1e-5, 0.0),
        ("5n", 1e-7, 0.0),
    ):
        if only and step + f"_{reltol:g}" not in only:
            continue
        drive = dict(base)
        if eps:
            p = drive["top_r2s1"]
            drive["top_r2s1"] = replace(p, v2=p.v2 * (1 + eps))
        tag = f"{step}_{reltol}_{eps}"
        t, x = run(model, tmp / "b" / "levitated_disk_osdi.lib", control, drive, step, reltol, tmp / f"o{tag}")
        tl, xl = run(model, ROOT / "netlists" / "levitated_disk.lib", [], drive, step, reltol, tmp / f"l{tag}")
        ref = reference_transient(model, drive, f_ext, t, STOP)
        refl = reference_transient(model, drive, f_ext, tl, STOP)
        peak = np.abs(ref).max(axis=0)
        xi = np.stack([np.interp(tl, t, x[:, v]) for v in range(model.ncoords)], axis=-1)
        print(
            f"step {step} reltol {reltol:g} eps {eps:g}: points {len(t)}/{len(tl)};"
            f" osdi-ref {worst(model, x, ref, peak)}; lib-ref {worst(model, xl, refl, peak)};"
            f" osdi-lib {worst(model, xi, xl, peak)}",
            flush=True,
        )


if __name__ == "__main__":
    main()
