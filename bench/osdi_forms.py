"""Two Verilog-A forms of the same model in the OSDI sigma-delta loop of ngspice 46, against the loop's
floor, interleaved in one process: the emitted module ("now") and another text of it ("other",
e.g. an earlier netlists/levitated_disk.va), CPU per period, Newton iterations and time points.

    git show HEAD~1:netlists/levitated_disk.va > /tmp/old.va
    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice nice -n 10 .venv/bin/python bench/osdi_forms.py /tmp/old.va \
        [--cycles 256] [--repeat 5]

Measured (the clamp's exp only below the knee, against the form before it; load 13, median of 5):
other 5.41, now 5.30 ms of CPU per period, floor 2.89: 1.87x -> 1.83x; 205.8 Newton iterations and
77.4 time points per period in both forms.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

import sigma_delta as bench

from netgen.emit import osdi, veriloga
from netgen.model import MacroModel
from netgen.testbench.sigma_delta import osdi as sdo
from netgen.testbench.sigma_delta import vacask as sdv


def main() -> int:
    """Run now / other / floor in turn (order reversed every other round); print the medians."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("other", type=Path, help="the other .va text of the model's module")
    ap.add_argument("--model", default=str(bench.MODEL_JSON), help="model JSON (default the committed reference)")
    ap.add_argument("--cycles", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    model = MacroModel.load_json(args.model)
    with tempfile.TemporaryDirectory(prefix="osdi-forms-") as tmp:
        base = Path(tmp)
        blocks = f"pre_osdi {osdi.compiled(sdv.blocks_source(), 'sigma_delta_blocks', base / 'osdi')}"

        def control(text: str) -> list[str]:
            return [f"pre_osdi {osdi.compiled(text, model.name, base / 'osdi')}", blocks, sdo.THREADS]

        cases = {
            "now": (osdi.subcircuit(model), control(veriloga.module(model, noise=False))),
            "other": (osdi.subcircuit(model), control(args.other.read_text(encoding="utf-8"))),
            "floor": (bench.library(model, "floor"), [blocks, sdo.THREADS]),
        }
        runs: dict[str, list[dict]] = {k: [] for k in cases}
        for r in range(args.repeat):
            for k in list(cases) if r % 2 == 0 else list(cases)[::-1]:
                lib, ctl = cases[k]
                runs[k].append(
                    bench.run_once(model, lib, base / k, 1e-6, args.cycles, check=False, control=ctl, loop="osdi")
                )
    med = {k: {q: statistics.median(x[q] for x in v) for q in v[0]} for k, v in runs.items()}
    for k, m in med.items():
        print(
            f"{k:6s} {1e3 * m['cpu_s'] / args.cycles:6.2f} ms CPU per period, {m['iterations'] / args.cycles:6.1f} "
            f"Newton iterations, {m['accepted'] / args.cycles:5.1f} time points"
            + ("" if k == "floor" else f", {m['cpu_s'] / med['floor']['cpu_s']:.2f}x the floor")
        )
    print(f"load {os.getloadavg()[0]:.1f}, {args.repeat} rounds of {args.cycles} periods")
    return 0


if __name__ == "__main__":
    sys.exit(main())
