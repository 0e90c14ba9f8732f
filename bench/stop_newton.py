"""Newton iterations of the .op that pushes accelerometer_xyz (textbook combs, etch declared:
tests/oracles/process_cases.xyz_text) by 20 uN along x onto comb xp_t's sidewall stop, per form:
the .lib in ngspice 39 and 46, the _xspice.lib in ngspice 39, OSDI in ngspice 46 and VACASK, over
round-off-level variants of the push (20 uN + j 1e-14, j = 0..VARIANTS-1), at three option sets:
ngspice's defaults, reltol 1e-12 / vntol 1e-12 V, and the tests' former reltol 1e-12 / vntol 1e-15 V.

    .venv/bin/python bench/stop_newton.py [--variants 9] [--etches -1e-7,4e-8,1e-7] [--timeout 20]
    .venv/bin/python bench/stop_newton.py --sensitivity
    .venv/bin/python bench/stop_newton.py --model xyz.json   # a build of that structure (netgen build's JSON)

--sensitivity prints instead the rest's relative sensitivities d ln q / d ln c to the parts of the
model's rest (tests/oracles/process_cases.pushed_rest), whose sums bound how far the .lib's 11-digit
B-source numbers move it (tests/emit/test_process_etch_forms.py, REST_REL and FULL_REL).

Prints, per form, option set and etch, the iteration counts (`timeout` where ngspice ran past
--timeout seconds) and the spread of the rest x over the variants. Run it under
OPENBLAS_NUM_THREADS=1 and without to see the build's rounding change nothing but the last column
at vntol 1e-12 (docs/contact.md, "Newton at a stop").
"""

from __future__ import annotations

import argparse
import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from support import NGSPICE, process_cases

from netgen import emit
from netgen.build import build_model
from netgen.emit import ngspice as emit_ngspice
from netgen.model import MacroModel
from netgen.sim import vacask
from netgen.structure import parse_structure
from netgen.testbench.sigma_delta import ngspice as sdn

STRUCTURE = process_cases.xyz_etch_text()
OPTIONS = {
    "default": "",
    "vntol 1e-12": ".options reltol=1e-12 vntol=1e-12 abstol=1e-20",
    "vntol 1e-15": ".options reltol=1e-12 vntol=1e-15 abstol=1e-20",
}
PUSH = 20e-6  # N along x, the tests' push (tests/emit/test_process_etch_forms.PUSH, in uN there)
PINS = "0 0 0 0 0 0 0 0 0 0 0 fx x0 0 x1 0 x2 0 x3 0 x4 0 x5 0 0 0"


def deck(include: Path, etch: float, push: str, options: str, control: list[str]) -> str:
    """The push .op with the iteration count and x printed to the log."""
    lines = [*control, "set num_threads=1", "run", "rusage totiter", "set numdgt=16", "print v(x0)"]
    return "\n".join(
        [
            "* push",
            f".include {include}",
            f"Vf fx 0 DC {push}",
            f"X1 {PINS} accelerometer_xyz etch={etch!r}",
            options,
            ".op",
            ".control",
            *lines,
            ".endc",
            ".end",
            "",
        ]
    )


def ngspice_run(exe: str, cir: Path, timeout: float) -> tuple[int | None, float | None]:
    """(Newton iterations, x in um) of one batch run; (None, None) past the timeout."""
    try:
        out = subprocess.run([exe, "-b", cir.name], cwd=cir.parent, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, None
    it = re.search(r"Total iterations = (\d+)", out.stdout)
    x = re.search(r"^v\(x0\) = (\S+)", out.stdout, re.M)
    return (int(it.group(1)) if it else None), (float(x.group(1)) if x else None)


def vacask_run(work: Path, etch: float, push: str) -> tuple[int | None, float | None]:
    """(NR iterations, x in um) of VACASK's op at its default tolerances."""
    va = (work / "accelerometer_xyz.va").read_text()
    start = va.index("module accelerometer_xyz(") + len("module accelerometer_xyz(")
    pins = va[start : va.index(")", start)].replace(",", " ").split()
    fixed = [f"v_{p} ({p} 0) vsource dc=0" for p in pins if not p.startswith("x_") and p != "f_x"]
    net = "\n".join(
        [
            "push",
            "ground 0",
            f'load "{work / "accelerometer_xyz.osdi"}"',
            f"model mems accelerometer_xyz etch={etch!r}",
            "model vsource vsource",
            f"x1 ({' '.join(pins)}) mems",
            *fixed,
            f"v_f_x (f_x 0) vsource dc={push}",
            "control",
            "  analysis op1 op",
            "  print stats",
            "endc",
            "",
        ]
    )
    run = work / f"vacask_{etch}_{push}"
    plot = vacask.run_vacask(net, run, analysis="op1")
    return vacask.stats(run / "circuit.log").get("nr_iterations"), float(np.ravel(plot["x_x"])[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=int, default=9)
    ap.add_argument("--etches", default="-1e-7,4e-8,1e-7")
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--sensitivity", action="store_true", help="print the rest's sensitivities, no simulation")
    ap.add_argument("--model", type=Path, help="the model JSON of that structure, built already (default: build it)")
    args = ap.parse_args()
    model = MacroModel.load_json(args.model) if args.model else build_model(parse_structure(STRUCTURE, "xyz.toml"))
    if args.sensitivity:
        for etch in (float(e) for e in args.etches.split(",")):
            sensitivity(model, etch)
        return
    work = Path(tempfile.mkdtemp(prefix="stop-newton-"))
    (work / "xyz.lib").write_text(emit_ngspice.subcircuit(model))
    xlib, xcontrol = sdn.xspice_library(model, work, sdn.code_models(False))
    emit.write_outputs(model, work, "osdi")
    forms = {
        "lib ngspice 39": (NGSPICE["39"], work / "xyz.lib", []),
        "lib ngspice 46": (NGSPICE["46"], work / "xyz.lib", []),
        "xspice ngspice 39": (NGSPICE["39"], xlib.resolve(), xcontrol),
        "osdi ngspice 46": (
            NGSPICE["46"],
            work / "accelerometer_xyz_osdi.lib",
            [f"pre_osdi {work / 'accelerometer_xyz.osdi'}"],
        ),
    }
    pushes = [f"{PUSH * 1e6 + j * 1e-14:.17g}" for j in range(args.variants)]
    for etch in (float(e) for e in args.etches.split(",")):
        for name, (exe, lib, control) in forms.items():
            for tag, options in OPTIONS.items():
                runs = []
                for j, push in enumerate(pushes):
                    cir = work / f"{name.split()[0]}_{etch}_{j}.cir"
                    cir.write_text(deck(lib, etch, push, options, control))
                    runs.append(ngspice_run(exe, cir, args.timeout))
                report(f"{name}, {tag}", etch, runs)
        report("vacask, default", etch, [vacask_run(work, etch, push) for push in pushes])


def sensitivity(model, etch: float, h: float = 1e-7) -> None:
    """d ln q / d ln c of the pushed rest (x, rot_z) per part, and the sums over the .lib's B-source
    parts (push gain, springs, stop offset) and over all."""
    rest = np.array(process_cases.pushed_rest(model, etch, PUSH))
    rows = {}
    for part in process_cases.PUSH_PARTS:
        moved = np.array(process_cases.pushed_rest(model, etch, PUSH, {part: 1 + h}))
        rows[part] = (moved / rest - 1) / h
    b_source = sum(abs(rows[k]) for k in ("push", "k_x", "k_rot_z", "offset"))
    every = sum(abs(r) for r in rows.values())
    parts = "  ".join(f"{k} {r[0]:+.3f} {r[1]:+.3f}" for k, r in rows.items())
    print(
        f"etch {etch:+.0e}  (x, rot_z): {parts}  B-source sum {b_source[0]:.3f} {b_source[1]:.3f}  all {every[0]:.3f} {every[1]:.3f}"
    )


def report(label: str, etch: float, runs: list[tuple[int | None, float | None]]) -> None:
    """One line: iterations per variant and the spread of x (um) over those that finished."""
    its = ["timeout" if it is None else str(it) for it, _ in runs]
    xs = [x for _, x in runs if x is not None]
    spread = max(xs) - min(xs) if xs else float("nan")
    print(f"etch {etch:+.0e}  {label:32s} iterations {' '.join(its)}  x spread {spread:.2e} um", flush=True)


if __name__ == "__main__":
    main()
