"""Cost of the sigma-delta levitation testbench in ngspice: the model against its floor and baseline.

    .venv/bin/python bench/sigma_delta.py [--cycles 4096] [--repeat 3] [--naive-cycles 64]
                                          [--variants xspice,fast,floor,linear,naive]
                                          [--loops xspice,analog] [--ts 1e-6] [--solvers sparse,klu]

    NETGEN_NGSPICE=~/.cache/netgen/ngspice-46/bin/ngspice .venv/bin/python bench/sigma_delta.py \
        --variants osdi,fast,floor --loops osdi,analog --solvers sparse,klu   # ngspice 46: OSDI and KLU

Runs the testbench of `netgen sigma-delta` (netgen.testbench.sigma_delta.ngspice.testbench, templates/
sigma_delta/tb.cir.j2) around the reference model (netlists/levitated_disk.json) with
different subcircuits in place of the macromodel, each `--repeat` times in this process, and
prints per variant the medians of:

  ms/cycle   wall time of the ngspice run per clock period (parse + transient)
  pts/cycle  accepted ngspice time points per period (`rusage all`), and with rejected ones
  it/pt      Newton iterations per time point (accepted + rejected)
  peak MB    maximum resident memory of the ngspice process (/usr/bin/time)
  z bit      mean of the +-1 z bits (the design aims at 0.5) and F/mg, the momentum balance (mean
             feedback force / weight), the loop check

Variants (the same testbench, clocks, tolerances and tmax; only the subcircuit differs):

  osdi    the _osdi.lib: the model's Verilog-A module compiled by openvaf-r, loaded through OSDI
          (netgen.emit.osdi; ngspice 45+; the netlist sets num_threads=1)
  xspice  the .lib with the plate terms, forces and stops in the compiled XSPICE code model
          netgen_es (netgen.emit.xspice, netgen.sim.codemodel, built on first use); the netlist loads it
          and keeps trtol at 7 (`pre_set xtrtol=7`)
  fast    the emitted .lib (netgen.emit.ngspice.subcircuit: the default)
  nodes   the previous shared-node emission (bench/baselines.py), for what the fast form bought
  naive   the baseline: every charge and force written out inline (bench/baselines.py, no shared
          nodes, no contact); slow, so it runs --naive-cycles periods
  floor   the floor of this circuitry in ngspice: constant capacitors C_i(0) between electrodes
          and plate, and the same linear mass/spring/damper integrators per coordinate, with no
          electrostatic force (the plate falls freely under gravity; the loop is open, the bits
          are constant). This is the "constant capacitors, linear springs" floor.
  linear  the linearisation that still closes the loop: C_i(q) = C_i(0) + grad C_i(0) . q (a
          charge Q = C_i(q) (V_i - V_p), motional current included) and the constant-gradient
          force 1/2 sum_i dC_i/dq (V_i - V_p)^2 (no electrostatic spring, no contact)

and the ratios fast / floor, fast / linear and naive / fast (per time point and per period).

Loops (the testbench around the subcircuit; each variant runs in each loop given, and the ratios
compare variants within one loop):

  xspice  the samplers, lead filters, quantizers, latches and electrode drivers in the compiled
          code model netgen_sdloop (what `netgen sigma-delta --simulator ngspice-xspice` runs,
          around the xspice .lib)
  analog  the same blocks as behavioural sources (what `--simulator ngspice` runs, around the
          fast .lib)
  osdi    the same blocks as the Verilog-A modules VACASK runs (blocks.va), loaded through OSDI
          (what `--simulator ngspice-osdi` runs, around the _osdi.lib)

Solvers (each case runs with each): sparse (ngspice's default Sparse 1.3) and klu (`.options klu`,
built into ngspice 43 and later; `--solvers` defaults to both where the ngspice has KLU).
`--num-threads-1` adds `set num_threads=1` to the code-model decks as well (the OSDI decks always
set it; in ngspice 39 it changes nothing there: those decks have no OpenMP device).

Another device: `--model` its JSON; the testbench is its default loop (loop.design: channels,
electrodes and gravity from the model), e.g. the z accelerometer's compiled loop against its floor:

    .venv/bin/netgen build examples/accelerometer_z.toml -o out/acc_model
    .venv/bin/python bench/sigma_delta.py --model out/acc_model/accelerometer_z.json \
        --variants xspice,floor,linear --loops xspice --solvers sparse

Timings on a shared machine are noisy: the figures are medians of --repeat runs, interleaved
(variant order rotates per repeat), and the load average is printed with them. Point and
iteration counts are deterministic.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from baselines import BASELINES
from support import ROOT

from netgen.emit import ngspice, osdi, veriloga, xspice
from netgen.emit.common import force_gain, num, time_scale
from netgen.model import MacroModel
from netgen.sim import codemodel
from netgen.sim.ngspice import ngspice_path, version
from netgen.sim.rawfile import read_raw
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import ngspice as sdn
from netgen.testbench.sigma_delta import osdi as sdo
from netgen.testbench.sigma_delta import vacask as sdv

MODEL_JSON = ROOT / "netlists" / "levitated_disk.json"
VARIANTS = ("xspice", "osdi", "fast", "nodes", "naive", "floor", "linear")
SOLVERS = ("sparse", "klu")
STATS = {
    "accepted": r"Accepted timepoints\s*=\s*(\d+)",
    "rejected": r"Rejected timepoints\s*=\s*(\d+)",
    "iterations": r"Transient iterations\s*=\s*(\d+)",
    "analysis_s": r"Total analysis time \(seconds\)\s*=\s*([0-9.]+)",
    "load_s": r"Transient load time\s*=\s*([0-9.]+)",
    "equations": r"Circuit Equations\s*=\s*(\d+)",
}


def linearised_subcircuit(model: MacroModel, kind: str) -> str:
    """A subcircuit with the model's ports and mechanics but linear electrostatics (see module doc):
    kind "floor" (constant C_i(0), no force) or "linear" (C_i(0) + grad . xs, constant-gradient force)."""
    ws = time_scale(model)
    x0 = np.zeros(model.ncoords)
    c0 = model.capacitance(x0)[0]
    grad = model.capacitance_gradient(x0)[0] * model.scales[None, :]  # F per unit xs
    plate = model.plate
    lines = [
        f"* {model.name}: linearised benchmark floor ({kind}), bench/sigma_delta.py",
        f".subckt {model.name} " + " ".join(p["name"] for p in model.ports()),
    ]
    for v, c in enumerate(model.coordinates):
        a = force_gain(c, ws)
        n = c.name
        lines += [
            f"Cx_{n} xs_{n} 0 {num(1 / ws)}",
            f"Gx_{n} 0 xs_{n} u_{n} 0 1",
            f"Cu_{n} u_{n} 0 {num(1 / ws)}",
            f"Gf_{n} 0 u_{n} f_{n} 0 {num(a * c.port_units[3])}",
            f"Ex_{n} x_{n} 0 xs_{n} 0 {num(c.scale / c.port_units[1])}",
        ]
        if c.stiffness:
            lines.append(f"Gk_{n} 0 u_{n} xs_{n} 0 {num(-c.stiffness / (c.mass * ws * ws))}")
        if model.acceleration and model.acceleration[v]:  # the inertial load -G_v a_in, a force like f_<q>
            lines.append(f"Ga_{n} 0 u_{n} a_in 0 {num(-a * model.acceleration[v])}")
        if c.damping:
            lines.append(f"Gd_{n} 0 u_{n} u_{n} 0 {num(-c.damping / (c.mass * ws))}")
        if kind == "linear":  # F_v = 1/2 sum_i dC_i/dq_v dv_i^2, scaled like every force of the u node
            terms = [
                f"{num(0.5 * a * grad[i, v] / c.scale)}*v({e.name},{plate})*v({e.name},{plate})"
                for i, e in enumerate(model.electrodes)
                if grad[i, v]
            ]
            lines.append(f"Be_{n} 0 u_{n} I=" + " + ".join(terms).replace("+ -", "- "))
    for i, e in enumerate(model.electrodes):
        if kind == "linear":  # C_i(0) linear, grad . xs on a charge node as the model's .lib does
            cref = float(np.abs(grad[i]).max()) or 1.0
            rest = "".join(f" + {num(grad[i, v] / cref)}*v(xs_{c.name})" for v, c in enumerate(model.coordinates))
            q = ngspice.charge_node(e.name, f"({rest[3:].replace('+ -', '- ')})", plate, cref)
            lines += [f"Cl_{e.name} {e.name} {plate} {num(c0[i])}", q["b"], q["v"], q["c"], q["f"]]
        else:
            lines.append(f"Cq_{e.name} {e.name} {plate} {num(c0[i])}")
    lines.append(f".ends {model.name}")
    return "\n".join(lines) + "\n"


def needs_codemodel(variant: str, loop: str) -> bool:
    """Does the bench netlist of this subcircuit variant and testbench loop load the code models?"""
    return variant == "xspice" or loop == "xspice"


def osdi_control(model: MacroModel, variant: str, loop: str, cache: Path, cpu: str = osdi.GENERIC) -> list[str]:
    """The pre_osdi lines (compiled once into `cache`, for openvaf-r's target `cpu`) of an osdi
    model or loop, and num_threads=1."""
    lines = []
    if variant == "osdi":
        lines.append(f"pre_osdi {osdi.compiled(veriloga.module(model, noise=False), model.name, cache, cpu)}")
    if loop == "osdi":
        lines.append(f"pre_osdi {osdi.compiled(sdv.blocks_source(), 'sigma_delta_blocks', cache, cpu)}")
    return lines + [sdo.THREADS] if lines else []


def library(model: MacroModel, variant: str) -> str:
    if variant in ("floor", "linear"):
        return linearised_subcircuit(model, variant)
    if variant in BASELINES:
        return BASELINES[variant](model, noise=False)
    if variant == "osdi":
        return osdi.subcircuit(model)
    return (xspice if variant == "xspice" else ngspice).subcircuit(model, noise=False)


def run_once(
    model: MacroModel,
    lib_text: str,
    workdir: Path,
    ts: float,
    cycles: int,
    check: bool,
    control: list[str] = (),
    loop: str = "analog",
    solver: str = "sparse",
) -> dict:
    """One ngspice -b run of the testbench with `lib_text` as the model; stats from `rusage all`."""
    workdir.mkdir(parents=True, exist_ok=True)
    lib = workdir / "model.lib"
    lib.write_text(lib_text)
    d = sd.design(model, ts)
    net = sdn.testbench(model, d, lib, cycles, "bench.raw", settings=sdn.Settings(loop, control, chunks=1))
    net = net.replace("write bench.raw", "rusage all\nwrite bench.raw")
    if solver == "klu":
        net = net.replace("\n.control\n", "\n.options klu\n.control\n", 1)
    (workdir / "bench.cir").write_text(net)
    (workdir / "bench.raw").unlink(missing_ok=True)
    # /usr/bin/time reports the peak resident memory of ngspice itself (the rusage of a child forked
    # from this Python process would include the Python image copied before the exec)
    timer = ["/usr/bin/time", "-f", "netgen-maxrss-kb %M"] if Path("/usr/bin/time").exists() else []
    start = time.perf_counter()
    proc = subprocess.Popen(
        timer + [ngspice_path(), "-b", "bench.cir"],
        cwd=workdir,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        stdin=subprocess.DEVNULL,
    )
    text = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - start
    (workdir / "bench.log").write_text(text)
    rss = re.search(r"netgen-maxrss-kb (\d+)", text) or re.search(r"Maximum ngspice program size =\s*([0-9.]+)", text)
    peak = float(rss.group(1)) / 1024 if timer else float(rss.group(1))
    out = {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_mb": peak}
    for key, pattern in STATS.items():
        m = re.search(pattern, text)
        if not m:
            raise RuntimeError(f"ngspice run failed or printed no {key}; see {workdir / 'bench.log'}")
        out[key] = float(m.group(1))
    if check and cycles >= 32:
        clock = sd.per_clock(read_raw(workdir / "bench.raw")[0], d, cycles, model)
        skip = cycles // 8
        out["bit_mean_z"] = float(clock["bits_z"][skip:].mean())  # +-1 bits; the design aims at 0.5
        out["balance"] = sd.gravity_balance(clock, d, skip)["ratio"]
    (workdir / "bench.raw").unlink(missing_ok=True)
    return out


def summarise(runs: list[dict], cycles: int) -> dict:
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    pts = med["accepted"] + med["rejected"]
    return {
        "cycles": cycles,
        "ms_per_cycle": 1e3 * med["wall_s"] / cycles,
        "cpu_ms_per_cycle": 1e3 * med["cpu_s"] / cycles,
        "pts_per_cycle": med["accepted"] / cycles,
        "all_pts_per_cycle": pts / cycles,
        "it_per_pt": med["iterations"] / pts,
        "us_per_it": 1e6 * med["wall_s"] / med["iterations"],
        "peak_mb": med["peak_mb"],
        "equations": med["equations"],
        "load_pct": 100 * med["load_s"] / med["analysis_s"] if med["analysis_s"] else 0.0,
        "bit_mean_z": med.get("bit_mean_z"),
        "balance": med.get("balance"),
        "spread_ms": 1e3 * (max(r["wall_s"] for r in runs) - min(r["wall_s"] for r in runs)) / cycles,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=4096, help="clock periods per run (default 2^12; 65536 for 2^16)")
    ap.add_argument("--naive-cycles", type=int, default=64, help="periods for the slow naive baseline (default 64)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per variant; figures are medians (default 3)")
    ap.add_argument("--ts", type=float, default=1e-6, help="sampling period T_s in s (default 1e-6)")
    ap.add_argument(
        "--variants",
        default="xspice,fast,floor,linear,naive",
        help=f"comma-separated subset of {','.join(VARIANTS)} (default xspice,fast,floor,linear,naive)",
    )
    ap.add_argument(
        "--loops",
        default="xspice,analog",
        help="comma-separated testbench loops: xspice (samplers, quantizers and drivers in the compiled "
        "netgen_sdloop, as --simulator ngspice-xspice runs it) and/or analog (behavioural sources, "
        "as --simulator ngspice); default both",
    )
    ap.add_argument(
        "--solvers",
        default=None,
        help="comma-separated linear solvers: sparse and/or klu (default both if the ngspice has KLU)",
    )
    ap.add_argument("--model", default=str(MODEL_JSON), help="model JSON (default the committed reference)")
    ap.add_argument("--keep", help="keep the run folders here (default: a temporary folder)")
    ap.add_argument(
        "--num-threads-1",
        action="store_true",
        help="add `set num_threads=1` to the code-model decks too (the OSDI decks always set it)",
    )
    args = ap.parse_args(argv)
    variants = [v for v in args.variants.split(",") if v]
    loops = [lp for lp in args.loops.split(",") if lp]
    solvers = [x for x in (args.solvers or ("sparse,klu" if version().klu else "sparse")).split(",") if x]
    bad = (
        [v for v in variants if v not in VARIANTS]
        + [lp for lp in loops if lp not in sdn.LOOPS]
        + [x for x in solvers if x not in SOLVERS]
    )
    if bad or not loops or args.cycles < 64 or args.repeat < 1:
        ap.error(f"unknown variants or loops {bad}" if bad else "need a loop, --cycles >= 64 and --repeat >= 1")
    model = MacroModel.load_json(args.model)
    libs = {v: library(model, v) for v in variants}
    cases = [(v, lp, x) for lp in loops for x in solvers for v in variants]
    control = []
    if any(needs_codemodel(v, lp) for v, lp, _ in cases):
        control = codemodel.control_lines(*sdn.code_models(progress=True))
        control += [sdo.THREADS] if args.num_threads_1 else []
    cache = Path(tempfile.mkdtemp(prefix="netgen-bench-osdi-"))
    extra = {(v, lp): osdi_control(model, v, lp, cache) for v, lp, _ in cases}
    cycles = {v: (args.naive_cycles if v == "naive" else args.cycles) for v in variants}
    load0 = os.getloadavg()
    runs: dict[tuple[str, str, str], list[dict]] = {c: [] for c in cases}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(args.keep or tmp)
        for r in range(args.repeat):
            order = cases[r % len(cases) :] + cases[: r % len(cases)]
            for v, lp, x in order:
                res = run_once(
                    model,
                    libs[v],
                    base / f"{v}_{lp}_{x}",
                    args.ts,
                    cycles[v],
                    check=v not in ("floor",),
                    control=(control if needs_codemodel(v, lp) else []) + extra[(v, lp)],
                    loop=lp,
                    solver=x,
                )
                runs[(v, lp, x)].append(res)
                print(
                    f"  run {r + 1}/{args.repeat} {v} ({lp} loop, {x}): {1e3 * res['wall_s'] / cycles[v]:.1f} ms/cycle",
                    file=sys.stderr,
                    flush=True,
                )
    load1 = os.getloadavg()
    print(
        f"sigma-delta testbench, T_s = {args.ts:g} s, model {model.name}, median of {args.repeat} runs; "
        f"ngspice {ngspice_path()} ({version().label}); load average {load0[0]:.1f} -> {load1[0]:.1f} "
        f"on {os.cpu_count()} CPUs"
    )
    for lp in loops:
        for x in solvers:
            report(lp, {v: summarise(runs[(v, lp, x)], cycles[v]) for v in variants}, x)
    return 0


RUNS_IN = {
    "xspice": ("--simulator ngspice-xspice", "xspice"),
    "analog": ("--simulator ngspice", "fast"),
    "osdi": ("--simulator ngspice-osdi", "osdi"),
}


def report(loop: str, table: dict[str, dict], solver: str = "sparse") -> None:
    """The table, ratios and 2^16 projection of the variants run in one testbench loop and solver."""
    cmd, model = RUNS_IN[loop]
    print(f"\n{loop} loop, {solver} solver ({cmd} runs {model} in it)")
    print(
        f"{'variant':8s} {'cycles':>7s} {'ms/cycle':>9s} {'cpu ms':>7s} {'pts/cyc':>8s} {'all pts':>8s} "
        f"{'it/pt':>6s} {'us/it':>6s} {'load %':>6s} {'eqs':>5s} {'peak MB':>8s} {'z bit':>6s} {'F/mg':>7s}"
    )
    for v, s in table.items():
        bit = "-" if s["bit_mean_z"] is None else f"{s['bit_mean_z']:.3f}"
        bal = "-" if s["balance"] is None else f"{s['balance']:.4f}"
        print(
            f"{v:8s} {s['cycles']:7d} {s['ms_per_cycle']:9.2f} {s['cpu_ms_per_cycle']:7.2f} "
            f"{s['pts_per_cycle']:8.1f} {s['all_pts_per_cycle']:8.1f} {s['it_per_pt']:6.2f} {s['us_per_it']:6.0f} "
            f"{s['load_pct']:6.0f} {s['equations']:5.0f} {s['peak_mb']:8.1f} {bit:>6s} {bal:>7s}"
        )
    for a, b in (
        ("osdi", "floor"),
        ("fast", "osdi"),
        ("xspice", "floor"),
        ("xspice", "linear"),
        ("fast", "xspice"),
        ("fast", "floor"),
        ("fast", "linear"),
        ("nodes", "fast"),
        ("naive", "fast"),
    ):
        if a in table and b in table:
            x, y = table[a], table[b]
            print(
                f"ratio {a}/{b}: {x['ms_per_cycle'] / y['ms_per_cycle']:.2f} per period, "
                f"{x['cpu_ms_per_cycle'] / y['cpu_ms_per_cycle']:.2f} in CPU time, "
                f"{x['us_per_it'] / y['us_per_it']:.2f} per Newton iteration"
            )
    for v in ("xspice", "osdi", "fast"):
        if v not in table:
            continue
        f = table[v]
        goal = 65536 * f["ms_per_cycle"] / 1e3
        print(
            f"{v}: 2^16 periods at this rate: {goal / 60:.1f} min (goal < 10 min, < 9 ms/period); "
            f"peak memory {f['peak_mb']:.0f} MB at {f['cycles']} periods (grows ~27 kB per period; "
            f"goal < 2 GB at 2^16)"
        )


if __name__ == "__main__":
    sys.exit(main())
