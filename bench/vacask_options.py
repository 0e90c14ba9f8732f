"""VACASK's step options in the sigma-delta loop: time points and CPU per period against the
mechanics' accuracy, the check of tests/testbench/test_sigma_delta_vacask.py for each option set
(its loop and integration: tests/oracles/sigma_delta_vacask.py).

    .venv/bin/python bench/vacask_options.py [OPTIONS ...]     # e.g. - "tran_fbr=0.25" "tran_lteratio=100"

Each argument is a set of VACASK options appended to netgen.testbench.sigma_delta.vacask.OPTIONS
("-": none, the default), and optionally ramp_steps=F,S (the step bounds on the feedback and sense
ramps, netgen.testbench.sigma_delta.vacask.RAMP_STEPS; ramp_steps=none: none) or fn_scale=K (the
module with its force nodes fn_<q> holding K times the force, bench/osdi_iterations.py's `rescaled`:
K = 1e-6 all but removes their Newton test, K = 1e-3 loosens its absolute part). The previous
options: 'tran_fbr=0.15 tran_lteratio=30 abstol=1e-12 ramp_steps=none'. For each, the test's
512-period VACASK run of the reference disk (T_s = 1 us), then the test's independent integration (solve_ivp of the mechanics driven by the
bits VACASK produced, 48 periods) and its latch check; prints the time points and Newton
iterations per period (VACASK's stats), the CPU time of the VACASK process per period, the largest
error of z and of the other coordinates against the integration (of each one's peak, raw; the
test takes z's feedback impulse gain out first and bounds the others by 1.5 %), the mean z bit, the
momentum balance (the test: within its balance_bound terms, ~2.6e-3), the noise
shaping per channel z/tilt_x/tilt_y (the test's: PSD over f_s/4..f_s/2 at least 15 dB over the PSD
below f_s/32; the mechanics check replays VACASK's bits and so cannot see a readout that lost its
accuracy, this one can) and the held latch levels off 0/1 (unexplained, partial, largest).
"""

from __future__ import annotations

import resource
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from osdi_iterations import rescaled
from support import ROOT
from support import sigma_delta_vacask as check  # the loop and the check of the VACASK test

from netgen.model import MacroModel
from netgen.sim.vacask import stats
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import vacask as sdv

RAMP_STEPS = sdv.RAMP_STEPS  # the default


def child_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def one(model: MacroModel, extra: str, out: Path) -> str:
    """The line of one option set; its ramp_steps=F,S item sets netgen.testbench.sigma_delta.vacask.RAMP_STEPS
    (ramp_steps=none: no ramp bounds), fn_scale=K rescales the module's force nodes, every other item
    is a VACASK option."""
    items = [] if extra == "-" else extra.split()
    va = ROOT / "netlists" / "levitated_disk.va"
    check.LIB = ROOT / "netlists" / "levitated_disk.lib"
    for k in [i.partition("=")[2] for i in items if i.startswith("fn_scale=")][-1:]:
        (out / "fn").mkdir(parents=True, exist_ok=True)
        check.LIB = out / "fn" / "levitated_disk.lib"  # the run compiles the .va beside its .lib
        shutil.copy(ROOT / "netlists" / "levitated_disk.lib", check.LIB)
        va = check.LIB.with_suffix(".va")
        va.write_text(rescaled((ROOT / "netlists" / "levitated_disk.va").read_text(), float(k)))
    ramps = [i.partition("=")[2] for i in items if i.startswith("ramp_steps=")]
    sdv.RAMP_STEPS = RAMP_STEPS
    if ramps:
        sdv.RAMP_STEPS = None if ramps[-1] == "none" else tuple(float(x) for x in ramps[-1].split(","))
    sdv.EXTRA_OPTIONS = " ".join(i for i in items if not i.startswith(("ramp_steps=", "fn_scale=")))
    sdv.compile_model(model, out / "osdi", va)
    sdv.compile_blocks(out / "osdi")
    cpu = child_cpu()
    s = check.run(model, out, "vacask", check.CYCLES, check.SKIP)
    cpu = child_cpu() - cpu
    st = stats(out / sdv.LOG)
    clock = s["clock"]
    ref = check.replay(model, sd.design(model, check.TS), clock, check.REPLAY)
    err = {
        c.name: float(np.abs(clock[f"x_{c.name}"][: check.REPLAY] - ref[:, i]).max() / np.abs(ref[:, i]).max())
        for i, c in enumerate(model.coordinates)
    }
    print("  per coordinate: " + " ".join(f"{k} {v:.4f}" for k, v in err.items()), file=sys.stderr)
    ch = s["channels"]
    latches = [
        (ch[c]["unexplained_latches"], ch[c]["partial_latches"], ch[c]["max_latch_error"]) for c in check.CHANNELS
    ]
    fs = 1 / check.TS
    shaping = []  # the test's noise-shaping figure per channel: PSD over fs/4..fs/2 against below fs/32, dB
    for c in check.CHANNELS:
        f, p = s["spectra"][c]
        shaping.append(10 * np.log10(p[f >= fs / 4].mean() / p[(f > 0) & (f <= fs / 32)].mean()))
    return (
        f"{extra:32s} {st['accepted'] / check.CYCLES:6.1f} {st['nr_iterations'] / st['accepted']:5.2f} "
        f"{1e3 * cpu / check.CYCLES:7.2f} {err['z']:7.3f} {max(v for k, v in err.items() if k != 'z'):7.4f} "
        f"{ch['z']['bit_mean']:6.4f} {s['gravity_balance']['ratio']:7.4f} "
        + "/".join(f"{x:.1f}" for x in shaping)
        + f"  {sum(u + p for u, p, _ in latches)} / {max(m for _, _, m in latches):.1e}"
    )


def main(argv: list[str] | None = None) -> int:
    sets = (argv if argv is not None else sys.argv[1:]) or ["-"]
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    print(f"VACASK options appended to {sdv.OPTIONS!r}; {check.CYCLES} periods, {check.REPLAY} replayed")
    print(
        f"{'options':32s} {'pts':>6s} {'it/pt':>5s} {'cpu ms':>7s} {'z err':>7s} {'others':>7s} {'z bit':>6s} "
        f"{'F/mg':>7s} {'shaping dB':>14s}  latches"
    )
    with tempfile.TemporaryDirectory(prefix="bench_vacask_options_") as tmp:
        for k, extra in enumerate(sets):
            print(one(model, extra, Path(tmp) / str(k)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
