"""The sigma-delta levitation loop in VACASK against ngspice: cost per clock period, same loop.

    .venv/bin/python bench/sigma_delta_vacask.py [--cycles 1024] [--ngspice-cycles 256] [--repeat 3]
                                                 [--variants vacask,vacask-previous,vacask-native,vacask-fast,ngspice] [--ts 1e-6]

Runs the loop of `netgen sigma-delta` (netgen.testbench.sigma_delta.loop) around the reference model
(netlists/levitated_disk.json) in

  vacask       netgen.testbench.sigma_delta.vacask: the compiled Verilog-A model (netlists/levitated_disk.va)
               and the loop blocks of netgen/testbench/sigma_delta/blocks.va, default options
               (netgen.testbench.sigma_delta.vacask.OPTIONS and RAMP_STEPS: tran_fbr=1/3, tran_lteratio=100,
               abstol=1e-6 and step bounds on the ramps, within the bounds of
               tests/testbench/test_sigma_delta_vacask.py)
  vacask-previous  the previous options (tran_fbr=0.15 tran_lteratio=30 abstol=1e-12, no ramp
               bounds: 99 points per period against 68)
  vacask-native  the same as vacask, the Verilog-A compiled for this machine's CPU (openvaf-r --target_cpu
               native, what `netgen sigma-delta --native` does)
  vacask-fast  the previous options with VACASK's default corner steps (tran_fbr=0.25; with tran_lteratio=10
               it had 114 points per period and z 6.9 % of its peak off solve_ivp in 48 periods, over the
               test's 6 %)
  ngspice      the ngspice bench (templates/sigma_delta/tb.cir.j2 with netlists/levitated_disk.lib)

each --repeat times in this process (variant order rotates per repeat), and prints per variant
the medians of:

  ms/cycle   wall time of the simulator run per clock period (VACASK: compile excluded, cached)
  cpu ms     CPU time (user + system) of the simulator process per period, what a loaded machine
             does not inflate; the Python side (raw-file read, per-clock sampling) apart as py ms
  pts/cycle  accepted time points per period (VACASK: its `print stats`; ngspice: raw file rows)
  it/pt      Newton iterations per accepted time point (VACASK only)
  peak MB    maximum resident memory of any simulator child process so far (getrusage)
  z bits     mean z bit and the momentum balance (mean feedback force / weight): the loop check

and the ratio ngspice / VACASK per period and the projected time of 2^16 periods (CPU + py). The
per-period cost is stationary after the first few periods, so ngspice runs fewer periods by
default (it costs ~0.1-0.4 s per period). Timings on a shared machine are noisy: the load
average is printed with them; point and iteration counts are deterministic.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

from support import ROOT

from netgen.emit.osdi import GENERIC, NATIVE
from netgen.model import MacroModel
from netgen.sim.vacask import stats as vacask_stats
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import ngspice as sdn
from netgen.testbench.sigma_delta import vacask as sdv

JSON = ROOT / "netlists" / "levitated_disk.json"
LIB = ROOT / "netlists" / "levitated_disk.lib"
VA = ROOT / "netlists" / "levitated_disk.va"
# variant -> (extra VACASK options, openvaf-r target CPU, ramp step bounds: vacask.RAMP_STEPS); ngspice: None
PREVIOUS = "tran_fbr=0.15 tran_lteratio=30 abstol=1e-12"
VARIANTS = {
    "vacask": ("", GENERIC, sdv.RAMP_STEPS),
    "vacask-previous": (PREVIOUS, GENERIC, None),
    "vacask-native": ("", NATIVE, sdv.RAMP_STEPS),
    "vacask-fast": (PREVIOUS + " tran_fbr=0.25", GENERIC, None),
    "ngspice": None,
}


def child_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_one(model: MacroModel, variant: str, ts: float, cycles: int, work: Path, cache: Path) -> dict:
    """One loop run; wall time of the simulator, counts, and the loop check."""
    d = sd.design(model, ts)
    out = work / variant
    start, cpu0, py0 = time.perf_counter(), child_cpu(), time.process_time()
    if VARIANTS[variant] is None:
        bench = sdn.testbench(model, d, LIB.resolve(), cycles, "sigma_delta.raw")
        plot = sdn.simulate(bench, out, ts * cycles, progress=False)
        wall = time.perf_counter() - start
        pts, its = len(plot["time"]) - 1, None
    else:
        options, cpu, sdv.RAMP_STEPS = VARIANTS[variant]
        how = sdv.BenchOptions(va=VA, cache=cache, options=options, cpu=cpu)
        plot = sdv.run_bench(model, d, out, cycles, progress=False, how=how)
        wall = time.perf_counter() - start
        st = vacask_stats(out / sdv.LOG)
        pts, its = st["accepted"], st["nr_iterations"] / st["accepted"]
    cpu = child_cpu() - cpu0
    clock = sd.per_clock(plot, d, cycles, model)
    py = time.process_time() - py0
    del plot
    for raw in out.glob("*.raw"):
        raw.unlink()
    skip = cycles // 8
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return {
        "ms_per_cycle": 1e3 * wall / cycles,
        "cpu_ms": 1e3 * cpu / cycles,
        "py_ms": 1e3 * py / cycles,
        "pts_per_cycle": pts / cycles,
        "it_per_pt": its,
        "peak_mb": peak,
        "z_bit": float(clock["bits_z"][skip:].mean()),
        "balance": sd.gravity_balance(clock, d, skip)["ratio"],
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=1024, help="VACASK periods per run (default 1024)")
    p.add_argument("--ngspice-cycles", type=int, default=256, help="ngspice periods per run (default 256)")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--ts", type=float, default=1e-6)
    a = p.parse_args(argv)
    variants = [v for v in a.variants.split(",") if v]
    unknown = sorted(set(variants) - set(VARIANTS))
    if unknown:
        p.error(f"unknown variants {unknown}; choose from {list(VARIANTS)}")
    model = MacroModel.load_json(JSON)
    results: dict[str, list[dict]] = {v: [] for v in variants}
    with tempfile.TemporaryDirectory(prefix="bench_sd_vacask_") as tmp:
        work, cache = Path(tmp), Path(tmp) / "osdi"
        for v in variants:  # compile once per target CPU, outside the timings
            if VARIANTS[v] is not None:
                sdv.compile_model(model, cache, VA, VARIANTS[v][1])
                sdv.compile_blocks(cache, VARIANTS[v][1])
        for r in range(a.repeat):
            order = variants[r % len(variants) :] + variants[: r % len(variants)]
            for v in order:
                cycles = a.ngspice_cycles if VARIANTS[v] is None else a.cycles
                res = run_one(model, v, a.ts, cycles, work, cache)
                results[v].append(res)
                print(
                    f"  repeat {r + 1}: {v:12s} {cycles} periods, {res['ms_per_cycle']:.2f} ms/period, {res['cpu_ms']:.2f} ms CPU",
                    file=sys.stderr,
                )
    load = os.getloadavg()
    print(
        f"sigma-delta loop, {model.name}, T_s = {a.ts * 1e6:g} us; VACASK {a.cycles} / ngspice {a.ngspice_cycles} "
        f"periods, median of {a.repeat}; load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} CPUs"
    )
    print(
        f"{'variant':13s} {'ms/cycle':>9s} {'cpu ms':>7s} {'py ms':>6s} {'pts/cycle':>10s} {'it/pt':>6s} {'peak MB':>8s} "
        f"{'z bits':>7s} {'balance':>8s} {'2^16 periods (CPU)':>19s}"
    )
    med = {}
    for v in variants:
        rs = results[v]
        m = {k: statistics.median(r[k] for r in rs) if rs[0][k] is not None else None for k in rs[0]}
        med[v] = m
        its = f"{m['it_per_pt']:6.2f}" if m["it_per_pt"] is not None else f"{'-':>6s}"
        print(
            f"{v:13s} {m['ms_per_cycle']:9.2f} {m['cpu_ms']:7.2f} {m['py_ms']:6.2f} {m['pts_per_cycle']:10.1f} {its} "
            f"{m['peak_mb']:8.0f} {m['z_bit']:7.3f} {m['balance']:8.4f} "
            f"{(m['cpu_ms'] + m['py_ms']) * 65536 / 6e4:15.1f} min"
        )
    if "ngspice" in med:
        for v in variants:
            if v != "ngspice":
                print(
                    f"ngspice / {v}: {med['ngspice']['ms_per_cycle'] / med[v]['ms_per_cycle']:.1f}x per period, "
                    f"{med['ngspice']['cpu_ms'] / med[v]['cpu_ms']:.1f}x in CPU time"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
