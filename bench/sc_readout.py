"""Long figures of the transistor-level switched-capacitor readout (examples/sc_readout.inc) around
the committed z accelerometer, per ngspice release:

    OMP_NUM_THREADS=1 .venv/bin/python bench/sc_readout.py [--releases 39,46] [--periods 4096]
        [--accels 3,-3,0,5] [--scale-periods 512] [--skip 64] [--reltol-periods 256]
        [--cost-periods 10]

- held: one run of --periods at the first acceleration: max |z| after --skip, and the bitstream's
  noise shaping (scipy.signal.welch of the +-1 bits: the PSD slope in dB/decade over f_s/64..f_s/8,
  and the mean over f_s/4..f_s/2 against 0..f_s/32);
- scale factor: the bit mean over --scale-periods at each acceleration against the force balance
  (tests/oracles/sc_readout.balance, from the model JSON): the slope d mean / d a against the design
  slope, in %;
- cost: CPU seconds per period of the model against the fixed-capacitor testbench
  (examples/accelerometer_z_sc_fixed.cir's circuit), short runs taken in turn, and time points;
- reltol: --reltol-periods at 1e-3 (the default) and 1e-4: max |z|, bit mean, CPU per period.
OMP_NUM_THREADS=1: Debian's ngspice 39 loads BSIM4 with OpenMP threads, which only contend on a
shared 2-core machine.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from scipy.signal import welch
from support import NGSPICE, oracle, using_ngspice

from netgen.model import MacroModel

sc = oracle("sc_readout")


def shaping(bits: np.ndarray) -> tuple[float, float]:
    """PSD slope (dB/decade, f_s/64..f_s/8) and high-band over low-band mean (dB) of the +-1 bits."""
    f, p = welch(2 * bits - 1, fs=1.0, nperseg=min(1024, len(bits) // 4))
    band = (f >= 1 / 64) & (f <= 1 / 8)
    slope = np.polyfit(np.log10(f[band]), 10 * np.log10(p[band]), 1)[0]
    low = (f > 0) & (f <= 1 / 32)
    if not low.any():  # a run too short for a bin below f_s/32
        return float(slope), float("nan")
    return float(slope), float(10 * np.log10(p[f >= 0.25].mean() / p[low].mean()))


def held(work: Path, a: float, args) -> None:
    """The long run: max |z|, shaping and its cost."""
    r = sc.run(work, a, args.periods, name="held")
    slope, gain = shaping(r.bits[args.skip :])
    zmax = np.abs(r.x_um[r.time > args.skip * sc.TS]).max() * 1e3
    print(
        f"  held {args.periods} periods at {a} m/s^2: max |z| {zmax:.3g} nm (whole run {np.abs(r.x_um).max() * 1e3:.3g})"
    )
    print(f"  shaping: PSD slope {slope:.1f} dB/decade, high/low band {gain:.1f} dB")
    print(f"  cost: {r.cpu / args.periods * 1e3:.0f} ms/period ({r.points / args.periods:.0f} points)")


def cost(work: Path, a: float, args) -> None:
    """CPU per period, model against fixed capacitors, in short runs taken in turn (--cost-periods,
    three each): on a shared machine the load swings by 5x over minutes, so one long run of each
    compares loads, not circuits; the ratio of the medians."""
    per = {True: [], False: []}
    for _ in range(3):
        for model in (True, False):
            r = sc.run(work, a, args.cost_periods, model=model, name=f"cost{int(model)}")
            per[model].append(r.cpu / args.cost_periods)
    m, f = np.median(per[True]), np.median(per[False])
    print(f"  cost in turn: model {m * 1e3:.0f} ms/period, fixed {f * 1e3:.0f} ms/period, ratio {m / f:.2f}")


def scale(work: Path, model: MacroModel, args) -> None:
    """Bit means at each acceleration against the force balance, and the slope error."""
    acc = [float(a) for a in args.accels.split(",")]
    means = []
    for a in acc:
        r = sc.run(work, a, args.scale_periods, name=f"a{a}")
        means.append(r.bits[args.skip :].mean())
        print(
            f"  a = {a:5.2f}: mean {means[-1]:.4f}, balance {sc.balance(model, a):.4f}, max |z| {np.abs(r.x_um).max() * 1e3:.3g} nm"
        )
    got = np.polyfit(acc, means, 1)[0]
    want = np.polyfit(acc, [sc.balance(model, a) for a in acc], 1)[0]
    print(f"  scale factor {got:.5f} per m/s^2 against {want:.5f}: {100 * (got / want - 1):+.2f} %")


def reltols(work: Path, a: float, args) -> None:
    """The loop at reltol 1e-3 and 1e-4."""
    for rt in ("1e-3", "1e-4"):
        r = sc.run(work, a, args.reltol_periods, options=f"reltol={rt}", name=f"rt{rt}")
        print(
            f"  reltol {rt}: max |z| {np.abs(r.x_um[r.time > args.skip * sc.TS]).max() * 1e3:.3g} nm, "
            f"mean {r.bits[args.skip :].mean():.4f}, {r.cpu / args.reltol_periods * 1e3:.0f} ms/period, "
            f"{r.points / args.reltol_periods:.0f} points/period"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--releases", default="39,46")
    p.add_argument("--periods", type=int, default=4096)
    p.add_argument("--accels", default="3,-3,0,5")
    p.add_argument("--scale-periods", type=int, default=512)
    p.add_argument("--reltol-periods", type=int, default=256)
    p.add_argument("--skip", type=int, default=64)
    p.add_argument("--cost-periods", type=int, default=10)
    args = p.parse_args()
    model = MacroModel.load_json(sc.MODEL_JSON)
    a0 = float(args.accels.split(",")[0])
    for rel in args.releases.split(","):
        with using_ngspice(rel), tempfile.TemporaryDirectory() as tmp:
            print(f"ngspice {rel} ({NGSPICE[rel]})")
            work = Path(tmp)
            held(work, a0, args)
            cost(work, a0, args)
            scale(work, model, args)
            if args.reltol_periods:
                reltols(work, a0, args)


if __name__ == "__main__":
    main()
