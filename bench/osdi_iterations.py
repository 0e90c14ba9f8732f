"""Where the OSDI loop's extra Newton iterations come from: the sigma-delta testbench of ngspice 46
(osdi loop blocks) around the emitted module, the same module with its force nodes fn_<q> rescaled
(the node holds F / (unit / K): K < 1 loosens the absolute part vntol of ngspice's Newton test on
the force, K = 1e-6 all but removes the test), and bench/sigma_delta.py's linear and floor
subcircuits. Iterations and time points are deterministic (no timing here).

    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice .venv/bin/python bench/osdi_iterations.py \
        [--cycles 64] [--scales 1e-3,1e-6] [--states 1e-9,1e6]

Measured (64 periods, T_s = 1 us): emitted 221.8 Newton iterations per period (81.8 accepted and
13.4 rejected time points, 2.33 per point); K = 1e-3 214.8; K = 1e-6 203.9 (2.15 per point);
linear 205.7 (80.1 + 13.6 points, 2.20 per point); floor 169.5 (73.1 + 10.0, 2.04 per point).
The accuracy of the K forms: bench/osdi_newton.py --va (K = 1e-6: z 2.7e-3 of its peak against
solve_ivp, the emitted form 3.1e-4). --states 1e-9,1e-3,1e3,1e6: 210.6, 214.9, 216.8, 217.0
(2-5 % below the emitted form for factors either side of 1: no tolerance of the states binds).
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import sigma_delta as bench

from netgen.emit import osdi, veriloga
from netgen.model import MacroModel
from netgen.testbench.sigma_delta import osdi as sdo
from netgen.testbench.sigma_delta import vacask as sdv

FN = re.compile(r"I\((fn_\w+)\) <\+ V\(fn_\w+\) - \((.*?)\) / ([0-9.e+-]+);")
USE = re.compile(r"\* V\((fn_\w+)\)\)")
STATE = re.compile(r"I\((xs_\w+|u_\w+)\) <\+ ddt\(([^)]*\))\) - (.*);")


def rescaled(text: str, k: float) -> str:
    """The module with fn_<q> holding K times its value (and the velocity equations reading fn / K)."""
    text = FN.sub(lambda m: f"I({m.group(1)}) <+ V({m.group(1)}) - ({m.group(2)}) / {float(m.group(3)) / k!r};", text)
    return USE.sub(lambda m: f"* {1.0 / k!r} * V({m.group(1)}))", text)


def states_scaled(text: str, k: float) -> str:
    """The module with each state equation (integrator capacitance and right-hand side) times k:
    the same solution, other charges and currents for ngspice's truncation-error and abstol tests."""
    return STATE.sub(lambda m: f"I({m.group(1)}) <+ {k!r} * (ddt({m.group(2)}) - ({m.group(3)}));", text)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=64)
    ap.add_argument("--scales", default="1e-3,1e-6", help="comma-separated K of the rescaled force nodes")
    ap.add_argument("--states", default="", help="comma-separated factors k on the state equations (e.g. 1e-9,1e6)")
    ap.add_argument("--model", default=str(bench.MODEL_JSON))
    args = ap.parse_args()
    model = MacroModel.load_json(args.model)
    with tempfile.TemporaryDirectory(prefix="osdi-iterations-") as tmp:
        base = Path(tmp)
        blocks = f"pre_osdi {osdi.compiled(sdv.blocks_source(), 'sigma_delta_blocks', base / 'osdi')}"
        text = veriloga.module(model, noise=False)
        forms = {"emitted": text} | {f"K={k}": rescaled(text, float(k)) for k in args.scales.split(",") if k}
        forms |= {f"states*{k}": states_scaled(text, float(k)) for k in args.states.split(",") if k}
        cases = {
            name: (osdi.subcircuit(model), [f"pre_osdi {osdi.compiled(t, model.name, base / 'osdi')}", blocks])
            for name, t in forms.items()
        }
        cases |= {v: (bench.library(model, v), [blocks]) for v in ("linear", "floor")}
        for name, (lib, ctl) in cases.items():
            r = bench.run_once(
                model, lib, base / re.sub(r"\W", "_", name), 1e-6, args.cycles, False, ctl + [sdo.THREADS], "osdi"
            )
            pts = r["accepted"] + r["rejected"]
            print(
                f"{name:10s} {r['iterations'] / args.cycles:7.1f} iterations per period, {r['accepted'] / args.cycles:5.1f} "
                f"accepted + {r['rejected'] / args.cycles:4.1f} rejected points, {r['iterations'] / pts:.3f} per point",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
