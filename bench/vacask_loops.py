"""VACASK's step control on the loops beyond the lead filter: the gyroscope (its drive loop, the Verilog-A
Device drive.va, on x; the sense loop on y) and the levitated disk's z in a fourth-order CIFB loop
(blocks.va's sd_statefilter), with the current options and with the previous ones.

    .venv/bin/python bench/vacask_loops.py [--loops gyro,order4,loss] [--variants now,previous]
                                           [--gyro-cycles 1024] [--order4-cycles 512] [--repeat 3]
                                           [--extra "ramp_steps=0.12,0.12 tran_fbr=0.15"] [--order 5]

  now       netgen.testbench.sigma_delta.vacask.OPTIONS, RAMP_STEPS and WINDOW_STEP (the state filter's
            own step bound in its sample-and-hold windows)
  previous  what these loops ran with before: tran_fbr=0.15 tran_lteratio=30 abstol=1e-12, no ramp
            bounds, no window bound
  extra     the current ones with --extra's VACASK options appended (a ramp_steps=F,S or
            ramp_steps=none item sets RAMP_STEPS)

Per loop and variant, the medians over --repeat runs (variant order rotates per repeat; the OSDI
files compiled before, by a 16-period run) of the CPU time (user + system) of the VACASK process per
period, the time points per period and the Newton iterations per point (VACASK's stats), and the
loop's own checks:

  gyro    the drive amplitude's deficit 1 - A / X_d (the AGC law: Delta / G, Delta the loop's
          numerical loss, tests/testbench/test_gyro_drive.py), the drive frequency off sqrt(k_x / m),
          the rate read off the applied 0.4 of full scale and the quadrature force off k_xy A
  loss    the gyroscope's drive loop without amplitude control (G = 1e-9, zero rate, the drive
          test's loss run, 2048 periods by default): Delta, the numerical loss the loop replaces
          beyond b_x (the amplitude's decay rate over the last 7/8, windowed sinusoid fits, over
          b_x / (2 m)); --sense-scale F runs it with the sense loop's V_s times F (the sense loop then
          misreads y, which this loop does not use)
  order4  the first period whose bit differs from the numpy reference loop's
          (tests/oracles/sigma_delta_reference.py; the test's bound 10), and the filter's update on the
          circuit's own held inputs: the largest error of each new state over the state's peak
          (tests/testbench/test_sd_orders_loop.py::test_vacask_state_filter_holds_its_update)
"""

from __future__ import annotations

import argparse
import math
import resource
import statistics
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from support import ROOT
from support import sigma_delta_reference as reference

from netgen.build import build_model
from netgen.emit.ngspice import subcircuit
from netgen.model import MacroModel
from netgen.sim.vacask import stats
from netgen.structure import load_structure
from netgen.testbench.gyro import analysis
from netgen.testbench.gyro import run as gyro_run
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta import design, filters, per_clock
from netgen.testbench.sigma_delta import vacask as sdv
from netgen.testbench.sigma_delta.loopfile import read_structure_loop

GYRO = ROOT / "examples" / "gyroscope_z.toml"
K_XY = 5e-3  # N/m, the gyroscope file's k_xy
TS = 1e-6
# variant -> (extra VACASK options, RAMP_STEPS, WINDOW_STEP)
VARIANTS = {
    "now": ("", sdv.RAMP_STEPS, sdv.WINDOW_STEP),
    "previous": ("tran_fbr=0.15 tran_lteratio=30 abstol=1e-12", None, None),
}


def child_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def use(variant: str) -> None:
    sdv.EXTRA_OPTIONS, sdv.RAMP_STEPS, sdv.WINDOW_STEP = VARIANTS[variant]


class Gyro:
    """The gyroscope at 0.4 of full scale (the drive test's second run)."""

    def __init__(self, work: Path):
        self.model = build_model(load_structure(GYRO))
        self.spec = read_structure_loop(GYRO)
        self.req = GyroRequest(simulator="vacask", progress=False, plots=False)
        self.cx = next(c for c in self.model.coordinates if c.name == "x")
        self.w = math.sqrt(self.cx.stiffness / self.cx.mass)
        fs = sense_design(self.model, self.spec, self.req).channels[0]["full_scale_force_si"]
        self.rate = 0.4 * fs / (2 * self.cx.mass * 4e-6 * self.w)
        self.lib = work / "g.lib"
        self.lib.write_text(subcircuit(self.model))

    def run(self, out: Path, cycles: int) -> tuple[dict, str]:
        req = replace(self.req, cycles=cycles, rate_deg_s=math.degrees(self.rate))
        r = run(self.model, self.lib, out, self.spec, req)["runs"][0]
        return stats(out / sdv.LOG), (
            f"deficit {1 - r['drive_amplitude_m'] / 4e-6:.3e} drive f {r['drive_hz'] / (self.w / 2 / math.pi) - 1:+.1e} "
            f"rate {r['rate_rad_s'] / self.rate - 1:+.4f} quad {r['quadrature_force_n'] / (K_XY * r['drive_amplitude_m']) - 1:+.4f}"
        )


class Loss(Gyro):
    """The drive test's loss run: G = 1e-9, zero rate."""

    def warm(self, out: Path) -> None:
        """Compile the OSDI files (a short gyroscope run; too short for the loss's fits)."""
        Gyro.run(self, out, 16)

    SENSE_SCALE = 1.0  # --sense-scale: the sense loop's V_s times this (the loss run reads x alone)

    def run(self, out: Path, cycles: int) -> tuple[dict, str]:
        design = gyro_run.backend_design
        scale = self.SENSE_SCALE

        def scaled(*args, **kwargs):
            d = design(*args, **kwargs)
            d.vs *= scale
            return d

        gyro_run.backend_design = scaled
        try:
            run(self.model, self.lib, out, self.spec, replace(self.req, cycles=cycles, agc_gain=1e-9))
        finally:
            gyro_run.backend_design = design
        clock = np.load(out / "bitstreams.npz")
        t, x = clock["time_0"], clock["x_x_0"] * 1e-6  # x_x port: 1 V = 1 um
        edges = np.linspace(len(t) // 8, len(t), 9).astype(int)
        mid = [float(np.mean(t[a:b])) for a, b in zip(edges[:-1], edges[1:])]
        amp = [analysis.sinusoid(t[a:b], x[a:b])["amplitude"] for a, b in zip(edges[:-1], edges[1:])]
        delta = -np.polyfit(mid, amp, 1)[0] / float(np.mean(amp)) / (self.cx.damping / (2 * self.cx.mass))
        return stats(out / sdv.LOG), f"Delta {delta:.4f}"


class Order4:
    """The disk's z in the fourth-order CIFB loop of tests/testbench/test_sd_orders_loop.py (ORDER)."""

    ORDER = 4  # --order: 3..5 (a filter of ORDER - 2 states)

    def __init__(self, work: Path):
        self.model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")

    def run(self, out: Path, cycles: int) -> tuple[dict, str]:
        d = design(self.model, TS)
        mech = filters.mechanics_of(self.model, d, "z")
        f = filters.design(mech, self.ORDER, 64, 1.4, "cifb")
        d.channels[0]["filter"], d.channels[0]["dither_v"] = f.as_dict(), 0.0
        states = tuple(f'v("xf_z:{a}{i}")' for a in "mu" for i in range(1, f.states + 1))
        how = sdv.BenchOptions(va=ROOT / "netlists" / "levitated_disk.va", saves=("v(cur_z)",) + states)
        plot = sdv.run_bench(self.model, d, out, cycles, None, False, how)
        dc = filters.dc_acceleration(self.model, d, "z")
        got = per_clock(plot, d, cycles, self.model)["bits_z"]
        ref = reference.simulate(mech, f, cycles, reference.Input(dc))["v"]
        first = int(np.argmax(got != ref)) if np.any(got != ref) else cycles
        return stats(out / sdv.LOG), f"first diff {first:4d} filter update err {update_error(plot, f, d, cycles)}"


def update_error(plot, f, d, cycles: int) -> str:
    """The largest error of each new filter state against the settled update on the circuit's own
    held inputs, over the state's peak (the test's check, without its bound)."""
    r = reference.filter_updates(plot, f, d, cycles)
    u, u_new = r.u, r.u_new
    return "/".join(f"{x:.1e}" for x in np.abs(u[1:] - u_new).max(axis=0) / np.abs(u).max(axis=0))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", default="gyro,order4")
    ap.add_argument("--variants", default="now,previous")
    ap.add_argument("--gyro-cycles", type=int, default=1024)
    ap.add_argument("--order4-cycles", type=int, default=512)
    ap.add_argument("--loss-cycles", type=int, default=2048)
    ap.add_argument("--order", type=int, default=4, help="the order4 loop's order (3..5)")
    ap.add_argument("--sense-scale", type=float, default=1.0, help="the loss loop's sense voltage V_s times this")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--extra", help="VACASK options of the variant 'extra' (ramp_steps=F,S sets RAMP_STEPS)")
    a = ap.parse_args()
    loops, variants = a.loops.split(","), a.variants.split(",")
    if a.extra:
        items = a.extra.split()
        ramps = [i.partition("=")[2] for i in items if i.startswith("ramp_steps=")]
        steps = sdv.RAMP_STEPS
        if ramps:
            steps = None if ramps[-1] == "none" else tuple(float(x) for x in ramps[-1].split(","))  # type: ignore[assignment]
        VARIANTS["extra"] = (" ".join(i for i in items if not i.startswith("ramp_steps=")), steps, sdv.WINDOW_STEP)
        variants = variants if "extra" in variants else variants + ["extra"]
    Order4.ORDER, Loss.SENSE_SCALE = a.order, a.sense_scale
    cycles = {"gyro": a.gyro_cycles, "order4": a.order4_cycles, "loss": a.loss_cycles}
    with tempfile.TemporaryDirectory(prefix="bench_vacask_loops_") as tmp:
        work = Path(tmp)
        benches = {name: {"gyro": Gyro, "order4": Order4, "loss": Loss}[name](work) for name in loops}
        rows: dict[tuple[str, str], list] = {}
        for name, b in benches.items():
            getattr(b, "warm", lambda out: b.run(out, 16))(work / name)  # compiles the OSDI files into work/name/osdi
        for k in range(a.repeat):
            for v in variants[k % len(variants) :] + variants[: k % len(variants)]:
                use(v)
                for name, b in benches.items():
                    cpu = child_cpu()
                    st, checks = b.run(work / name, cycles[name])
                    cpu = child_cpu() - cpu
                    rows.setdefault((name, v), []).append((cpu, st, checks))
                    print(f"  {name} {v}: {1e3 * cpu / cycles[name]:.2f} ms/period  {checks}", file=sys.stderr)
        print(f"{'loop':7s} {'variant':9s} {'periods':>7s} {'cpu ms':>7s} {'pts':>6s} {'it/pt':>5s}  checks (last run)")
        for (name, v), runs in rows.items():
            cpu = statistics.median(r[0] for r in runs) / cycles[name]
            st = runs[-1][1]
            print(
                f"{name:7s} {v:9s} {cycles[name]:7d} {1e3 * cpu:7.2f} {st['accepted'] / cycles[name]:6.1f} "
                f"{st['nr_iterations'] / st['accepted']:5.2f}  {runs[-1][2]}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
