"""Instruction counts of the sigma-delta testbench under callgrind, per Newton iteration and per
period, for the model variants of bench/sigma_delta.py (independent of the machine's load).

    .venv/bin/python bench/callgrind.py [--cycles 16] [--variants xspice,fast,floor] [--loops analog,xspice]
                                        [--keep DIR]

Runs `valgrind --tool=callgrind ngspice -b bench.cir` on the bench netlist of each variant (the
same testbench as bench/sigma_delta.py, `cycles` periods at T_s = 1 us) and prints the total,
the Newton iterations, and every function above 2 % of the instructions per iteration. The
ngspice binary is stripped: its functions show as addresses (the recursive parse-tree walk of
the B-sources is the one marked '2; the sparse LU is called once per iteration; XSPICE's load
loop MIFload, 0x598db0 in Debian's 39.3 build, once per code-model type). Needs valgrind
(`apt-get install valgrind`; not part of .ci/setup, the suite does not use it).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from sigma_delta import MODEL_JSON, VARIANTS, library, needs_codemodel, osdi_control

from netgen.model import MacroModel
from netgen.sim import codemodel
from netgen.sim.ngspice import ngspice_path
from netgen.sim.vacask import tools as vacask_tools
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import ngspice as sdn
from netgen.testbench.sigma_delta import vacask as sdv

LINE = re.compile(r"\s*([\d,]+) \(\s*([\d.]+)%\)\s+(\S+)")


def profile(model: MacroModel, variant: str, cycles: int, folder: Path, loop: str = "analog") -> dict:
    """One callgrind run of the bench around `variant` (testbench blocks `loop`); prints its counts
    and returns the total instructions and Newton iterations."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.lib").write_text(library(model, variant))
    cm = needs_codemodel(variant, loop)
    control = codemodel.control_lines(*sdn.code_models(progress=False)) if cm else []
    # generic x86-64: valgrind 3.19 stops at the AVX-512 instructions openvaf-r's default (native) emits here
    control += osdi_control(model, variant, loop, folder / "osdi", cpu="generic")
    net = sdn.testbench(
        model,
        sd.design(model, 1e-6),
        folder / "model.lib",
        cycles,
        "bench.raw",
        settings=sdn.Settings(loop, control, chunks=1),
    )
    (folder / "bench.cir").write_text(net.replace("write bench.raw", "rusage all\nwrite bench.raw"))
    with open(folder / "bench.log", "w") as log:  # ngspice -b may exit 1 after a complete run
        # --trace-children: NETGEN_NGSPICE may be a wrapper script that execs the binary (ngspice 46, .ci/setup)
        subprocess.run(
            [
                "valgrind",
                "--tool=callgrind",
                "--trace-children=yes",
                "--callgrind-out-file=callgrind.out",
                ngspice_path(),
                "-b",
                "bench.cir",
            ],
            cwd=folder,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    found = re.search(r"Transient iterations\s*=\s*(\d+)", (folder / "bench.log").read_text())
    if not found:
        raise SystemExit(f"bench/callgrind.py: the {variant} run did not finish; see {folder / 'bench.log'}")
    iterations = int(found.group(1))
    report = subprocess.run(
        ["callgrind_annotate", "callgrind.out"], cwd=folder, capture_output=True, text=True, check=True
    ).stdout
    total = int(re.search(r"([\d,]+) \(100.0%\)\s+PROGRAM TOTALS", report).group(1).replace(",", ""))
    print(
        f"{variant} ({loop} loop): {total / 1e6:.0f}M instructions, {iterations} Newton iterations ({iterations / cycles:.0f} "
        f"per period), {total / iterations / 1e3:.0f}k per iteration, {total / cycles / 1e6:.1f}M per period"
    )
    for line in report.splitlines():
        m = LINE.match(line)
        if m and float(m.group(2)) > 2.0 and "TOTALS" not in line:
            count = int(m.group(1).replace(",", ""))
            print(f"    {count / iterations / 1e3:7.1f}k per iteration {m.group(2):>6} %  {m.group(3)[:70]}")
    return {"instructions": total, "iterations": iterations}


def vacask_run(model: MacroModel, cycles: int, folder: Path) -> tuple[int, int]:
    """Total instructions and Newton iterations of one callgrind run of VACASK on the loop of
    `netgen sigma-delta --simulator vacask` (T_s = 1 us, the model's Verilog-A for generic x86-64)."""
    folder.mkdir(parents=True, exist_ok=True)
    model_osdi = sdv.compile_model(model, folder / "osdi", cpu="generic")
    blocks_osdi = sdv.compile_blocks(folder / "osdi", cpu="generic")
    net = sdv.testbench(model, sd.design(model, 1e-6), model_osdi, blocks_osdi, cycles, folder=folder)
    (folder / "bench.sim").write_text(net)
    done = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=callgrind.out", vacask_tools()[1], "bench.sim"],
        cwd=folder,
        capture_output=True,
        text=True,
    )
    (folder / "bench.log").write_text(done.stdout + done.stderr)
    found = re.search(r"NR solver iterations:\s*(\d+)", done.stdout)
    if not found:
        raise SystemExit(f"bench/callgrind.py: the VACASK run did not finish; see {folder / 'bench.log'}")
    report = subprocess.run(
        ["callgrind_annotate", "callgrind.out"], cwd=folder, capture_output=True, text=True, check=True
    ).stdout
    total = int(re.search(r"([\d,]+) \(100.0%\)\s+PROGRAM TOTALS", report).group(1).replace(",", ""))
    return total, int(found.group(1))


def profile_vacask(model: MacroModel, cycles: int, folder: Path) -> dict:
    """Instructions and Newton iterations of `cycles` periods of the VACASK loop: the difference of
    runs of 2 x cycles and cycles periods, so VACASK's start (loading, elaboration, about 120M
    instructions for the reference disk, 20 % of an 8-period run) is not counted as periods."""
    i1, n1 = vacask_run(model, cycles, folder / "short")
    i2, n2 = vacask_run(model, 2 * cycles, folder / "long")
    print(
        f"vacask: {(i2 - i1) / 1e6:.0f}M instructions, {n2 - n1} Newton iterations ({(n2 - n1) / cycles:.0f} per period), "
        f"{(i2 - i1) / (n2 - n1) / 1e3:.0f}k per iteration, {(i2 - i1) / cycles / 1e6:.1f}M per period (start {(2 * i1 - i2) / 1e6:.0f}M)"
    )
    return {"instructions": i2 - i1, "iterations": n2 - n1}


def main(argv: list[str] | None = None) -> int:
    if not shutil.which("valgrind") or not shutil.which("callgrind_annotate"):
        raise SystemExit("bench/callgrind.py needs valgrind: apt-get install valgrind")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=16, help="clock periods (default 16; ~1-4 min per variant)")
    ap.add_argument("--variants", default="xspice,fast,floor", help=f"comma-separated subset of {','.join(VARIANTS)}")
    ap.add_argument("--model", default=str(MODEL_JSON), help="model JSON (default the committed reference)")
    ap.add_argument(
        "--loops",
        default="analog",
        help="comma-separated testbench loops: analog (behavioural "
        "sources), xspice (the compiled netgen_sdloop) and/or osdi (blocks.va through OSDI, ngspice 45+); "
        "default analog",
    )
    ap.add_argument("--keep", help="keep the run folders (netlists, callgrind.out) here")
    args = ap.parse_args(argv)
    variants = args.variants.split(",")
    loops = args.loops.split(",")
    bad = [v for v in variants if v not in VARIANTS] + [lp for lp in loops if lp not in sdn.LOOPS]
    if bad or args.cycles < 1:
        ap.error(f"unknown variants {bad}" if bad else "need --cycles >= 1")
    model = MacroModel.load_json(args.model)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(args.keep or tmp)
        for lp in loops:
            for v in variants:
                profile(model, v, args.cycles, base / f"{v}_{lp}", lp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
