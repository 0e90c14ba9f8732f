"""Held latch levels of the sigma-delta loop against the comparator input at the latch instant.

    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice .venv/bin/python bench/sigma_delta_latch.py \
        [--simulators ngspice-osdi,vacask,ngspice] [--cycles 512] [--skip 64] [--ts 1e-6]

Runs the levitated-disk reference model (netlists/levitated_disk.json, the fixture of
tests/testbench/test_sigma_delta_osdi.py) through each back end and prints per channel: how many
held levels (analysis.per_clock's latch_<c>, sampled mid feedback phase) lie more than 1e-3 from
0 or 1, the largest distance, and the comparator input y + dither at the end of the latch
window (cmp_<c>) in units of the comparator width vcmp: the smallest |y| / vcmp of all periods, of
the partial periods, and the largest |y| / vcmp among the partial ones, against the comparator's
stated resolution (Design.latch_resolution). Also the CPU time per period of the whole run.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd

ROOT = Path(__file__).resolve().parents[1]
CLEAN = 1e-3  # a held level this close to 0 or 1 counts as regenerated


def cpu() -> float:
    """CPU seconds of this process and its finished children (the simulators)."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def report(clock: dict, d, skip: int) -> None:
    """The per-channel table of held levels against |y| / vcmp."""
    res = getattr(d, "latch_resolution", None)
    for c in d.names:
        level = clock[f"latch_{c}"][skip:]
        err = np.minimum(np.abs(level), np.abs(level - 1.0))
        partial = err > CLEAN
        line = f"  {c:7s} partial {int(partial.sum()):4d}/{len(err)}  max|err| {err.max():.3g}"
        if f"cmp_{c}" in clock:
            y = np.abs(clock[f"cmp_{c}"][skip:]) / d.vcmp
            line += f"  min|y|/vcmp all {y.min():.3g}"
            if partial.any():
                line += f"  partial: |y|/vcmp {y[partial].min():.3g}..{y[partial].max():.3g}"
                worst = np.argsort(-err)[:3]
                line += "  worst (err, |y|/vcmp): " + ", ".join(f"({err[i]:.3g}, {y[i]:.3g})" for i in worst)
            if res is not None:
                line += f"  |y| < resolution ({res / d.vcmp:.3g} vcmp): {int((y < res / d.vcmp).sum())}"
        print(line)
        hist, edges = np.histogram(err, bins=[0, 1e-6, 1e-3, 0.01, 0.05, 0.1, 0.2, 0.3, 0.5])
        print("          |err| histogram " + " ".join(f"<{e:g}:{h}" for e, h in zip(edges[1:], hist)))


def main() -> None:
    """Run each simulator on the reference model and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--simulators", default="ngspice-osdi,vacask")
    ap.add_argument("--cycles", type=int, default=512)
    ap.add_argument("--skip", type=int, default=64)
    ap.add_argument("--ts", type=float, default=1e-6)
    a = ap.parse_args()
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    lib = ROOT / "netlists" / "levitated_disk.lib"
    for sim in a.simulators.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            c0, w0 = cpu(), time.perf_counter()
            s = sd.run(model, lib, Path(tmp), a.ts, a.cycles, progress=False, plots=False, skip=a.skip, simulator=sim)
            c1, w1 = cpu(), time.perf_counter()
            clock = dict(np.load(Path(tmp) / "bitstreams.npz"))
        d = sd.design(model, a.ts)
        print(
            f"{sim}: {a.cycles} periods, CPU {(c1 - c0) / a.cycles * 1e3:.2f} ms/period "
            f"(wall {(w1 - w0) / a.cycles * 1e3:.2f} ms/period, compiling included)"
        )
        report(clock, d, a.skip)
        for c in d.names:
            f, p = s["spectra"][c]
            shaping = 10 * np.log10(p[f >= 0.25 / a.ts].mean() / p[(f > 0) & (f <= 1 / 32 / a.ts)].mean())
            print(f"  {c:7s} PSD mean f_s/4..f_s/2 over 0..f_s/32: {shaping:.1f} dB")


if __name__ == "__main__":
    main()
