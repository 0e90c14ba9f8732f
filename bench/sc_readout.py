"""Long figures of the transistor-level switched-capacitor readout (examples/sc_readout.inc) around
the committed z accelerometer, per ngspice release:

    OMP_NUM_THREADS=1 .venv/bin/python bench/sc_readout.py [--releases 46,39] [--periods 4096]
        [--fractions 0,0.25,-0.25,0.5,-0.5] [--scale-periods 192] [--skip 32]
        [--reltol-periods 128] [--cost-periods 10] [--charge-periods 4096] [--charge-options reltol=1e-4] [--out out/sc_readout]
        [--impulse-periods 64] [--threads-periods 16] [--step-periods 64] [--start-periods 64]
        [--start-accels 0,3] [--only threads,impulse,scale,maxstep,start,held,cost,reltol,charge]

The parts, in this order (the long runs last, so the short figures come first):
- threads: CPU per period at the simulator's default OpenMP threads (ngspice 39: 2, 46: 8 from
  its spinit) against `set num_threads=1` (what every other part runs at), the bits compared;
- impulse: each bit's feedback impulse from the simulated electrode voltages against the design
  d T_s F1, the settling time constant that shortfall implies, and the slope and offset errors it
  makes of the design formula (docs/embedding.md, "Scale factor");
- maxstep: the example's 20 ns maximum step against a whole period's: held, bits, points, CPU;
- start: the transient from `uic` against from the operating point, at --start-accels;
- scale: the bit mean over --scale-periods at each acceleration (--fractions of the full scale
  d F1 / G, tests/oracles/sc_readout.full_scale) against the force balance (tests/oracles/
  sc_readout.balance, from the model JSON): the least-squares slope d mean / d a against the
  design slope, in %, and the offset at a = 0;
- cost: CPU seconds of the ngspice process per period, the model against the fixed-capacitor
  testbench (examples/accelerometer_z_sc_fixed.cir's circuit), --cost-periods runs taken in turn,
  three each, the ratio of the medians (the shared machine's load swings, so runs taken in turn);
- reltol: --reltol-periods at reltol 1e-3 (ngspice's default) and 1e-4 (the example's): max |z|
  after --skip, the bit mean against the balance (the comparator's effective offset in bits and as
  a position), the longest run of equal bits (a limit cycle shows as long runs), points per period;
- held: one run of --periods at the first fraction: periods held (max |z| after --skip against
  the 2 um gap), wall and CPU time, and the bitstream's noise shaping: the Welch PSD of the +-1
  bits, its slope in dB/decade in band (f_s/1024..f_s/128, oversampling 64) and over the first
  decade above (f_s/128..f_s/12.8), drawn in OUT/sc_readout_psd_<release>.png.
OMP_NUM_THREADS=1 keeps numpy to one thread; it does not reach ngspice, whose `num_threads`
(set to 1 by the netlists, tests/oracles/sc_readout.ONE_THREAD) overrides it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.signal import welch
from support import NGSPICE, oracle, using_ngspice

from netgen.model import MacroModel
from netgen.sim import ngspice

sc = oracle("sc_readout")
GAP_NM = 2000.0  # the accelerometer's gap (netlists/accelerometer_z/accelerometer_z.lib: touch amplitude)
BANDS = {"in band": (1 / 1024, 1 / 128), "decade above": (1 / 128, 1 / 12.8)}


def psd(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD (per unit f/f_s) of the +-1 bitstream, 1024-bit segments."""
    return welch(2 * bits - 1, fs=1.0, nperseg=min(1024, len(bits) // 4))


def slopes(f: np.ndarray, p: np.ndarray) -> dict[str, float]:
    """PSD slope (dB/decade) over each of BANDS, least squares in log f."""
    out = {}
    for name, (lo, hi) in BANDS.items():
        band = (f >= lo) & (f <= hi)
        out[name] = float(np.polyfit(np.log10(f[band]), 10 * np.log10(p[band]), 1)[0]) if band.sum() > 1 else np.nan
    return out


def draw(f: np.ndarray, p: np.ndarray, fit: dict[str, float], title: str, path: Path) -> None:
    """The PSD with the two bands' slopes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.loglog(f[1:], p[1:], lw=0.8, label="bitstream PSD (Welch, 1024)")
    for name, (lo, hi) in BANDS.items():
        ax.axvspan(lo, hi, alpha=0.08 if name == "in band" else 0.16, label=f"{name}: {fit[name]:+.1f} dB/decade")
    ax.set_xlabel("f / f_s")
    ax.set_ylabel("PSD (1/(f/f_s))")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def longest_run(bits: np.ndarray) -> int:
    """The longest run of equal bits."""
    edges = np.flatnonzero(np.diff(bits) != 0)
    return int(np.diff(np.concatenate([[-1], edges, [len(bits) - 1]])).max())


def held(work: Path, model: MacroModel, a: float, rel: str, args) -> None:
    """The long run: periods held, wall and CPU time, noise shaping with its PNG."""
    r = sc.run(work, a, args.periods, name="held", timeout=6 * 3600)
    after = r.time > args.skip * sc.TS
    zmax = np.abs(r.x_um[after]).max() * 1e3
    print(
        f"  held {args.periods} periods at {a:.3g} m/s^2: max |z| {zmax:.3g} nm after {args.skip} periods "
        f"({zmax / GAP_NM:.1e} of the gap; whole run {np.abs(r.x_um).max() * 1e3:.3g} nm); "
        f"wall {r.wall:.0f} s, CPU {r.cpu:.0f} s ({r.cpu / args.periods * 1e3:.0f} ms/period, "
        f"{r.points / args.periods:.0f} points/period)"
    )
    bits = r.bits[args.skip :]
    print(f"  bit mean {bits.mean():.4f} against the balance {sc.balance(model, a):.4f}")
    f, p = psd(bits)
    fit = slopes(f, p)
    png = Path(args.out) / f"sc_readout_psd_{rel}.png"
    draw(f, p, fit, f"ngspice {rel}: {len(bits)} bits at a = {a:.3g} m/s^2", png)
    print("  shaping: " + ", ".join(f"{k} {v:+.1f} dB/decade" for k, v in fit.items()) + f" ({png})")


def cost(work: Path, a: float, args) -> None:
    """CPU of the ngspice process per period, model against fixed capacitors, runs taken in turn."""
    per: dict[bool, list[float]] = {True: [], False: []}
    pts: dict[bool, list[int]] = {True: [], False: []}
    for _ in range(3):
        for model in (True, False):
            r = sc.run(work, a, args.cost_periods, model=model, name=f"cost{int(model)}")
            per[model].append(r.cpu / args.cost_periods)
            pts[model].append(r.points // args.cost_periods)
    m, f = np.median(per[True]), np.median(per[False])
    print(
        f"  cost ({args.cost_periods} periods, median of 3): model {m * 1e3:.0f} ms/period "
        f"({per[True][0] * 1e3:.0f}, {per[True][1] * 1e3:.0f}, {per[True][2] * 1e3:.0f}; {pts[True][0]} points), "
        f"fixed {f * 1e3:.0f} ms/period ({per[False][0] * 1e3:.0f}, {per[False][1] * 1e3:.0f}, "
        f"{per[False][2] * 1e3:.0f}; {pts[False][0]} points), ratio {m / f:.2f}"
    )


def scale(work: Path, model: MacroModel, args) -> None:
    """Bit means at each acceleration against the force balance: slope error and offset. Each mean
    is taken net of the momentum the mass gained over the averaged periods (tests/oracles/
    sc_readout.momentum_mean), which leaves the per-bit impulses' error plus at most two bits over
    the N periods."""
    fs = sc.full_scale(model)
    acc = [float(x) * fs for x in args.fractions.split(",")]
    means, raw = [], []
    for a in acc:
        r = sc.run(work, a, args.scale_periods, name="scale")
        raw.append(r.bits[args.skip :].mean())
        means.append(sc.momentum_mean(model, r, args.skip))
        z = r.x_um[r.time > args.skip * sc.TS] * 1e-6
        print(
            f"  a = {a:+6.3f} m/s^2: mean {raw[-1]:.4f}, net of the momentum {means[-1]:.4f}, balance "
            f"{sc.balance(model, a):.4f} (at the mean z {z.mean() * 1e9:+.2f} nm: {sc.balance(model, a, z.mean()):.4f}), "
            f"max |z| {np.abs(z).max() * 1e9:.3g} nm, CPU {r.cpu:.0f} s",
            flush=True,
        )
    n = args.scale_periods - args.skip
    want, off0 = np.polyfit(acc, [sc.balance(model, a) for a in acc], 1)
    for name, m in (("net of the momentum", means), ("raw bit means", raw)):
        got, off = np.polyfit(acc, m, 1)
        print(
            f"  {name}: scale factor {got:.5f} per m/s^2 against the design {want:.5f} (full scale "
            f"{fs:.4g} m/s^2): {100 * (got / want - 1):+.2f} %; offset {off - off0:+.4f} bits "
            f"({(off - off0) / want:+.3f} m/s^2)"
        )
    print(f"  resolution of each net mean: 2/N = {2 / n:.4f} bits")


def reltols(work: Path, model: MacroModel, a: float, args) -> None:
    """The loop at reltol 1e-3 and 1e-4."""
    slope = sc.balance(model, 1.0) - sc.balance(model, 0.0)
    for rt in ("1e-3", "1e-4"):
        r = sc.run(work, a, args.reltol_periods, options=f"reltol={rt}", name=f"rt{rt}")
        bits = r.bits[args.skip :]
        err = bits.mean() - sc.balance(model, a)
        z = r.x_um[r.time > args.skip * sc.TS] * 1e3
        print(
            f"  reltol {rt}: max |z| {np.abs(z).max():.3g} nm (mean {z.mean():+.3g} nm), bit mean {bits.mean():.4f} "
            f"- balance = {err:+.4f} ({err / slope:+.3f} m/s^2), longest run of equal bits {longest_run(bits)}, "
            f"{r.cpu / args.reltol_periods * 1e3:.0f} ms/period, {r.points / args.reltol_periods:.0f} points/period"
        )


VS = 0.5  # the sense step on each electrode (examples/sc_readout.inc: VCM +- Vs)
START = 0.02e-6  # phf on: the feedback window is START .. START + sc.WINDOW
# settling losses in V^2 * tau of an electrode-plate voltage moving from its sense level to its
# feedback level with one time constant tau (V(t) = V_end + (V_start - V_end) e^(-t/tau)):
#   int (V(t)^2 - V_end^2) dt = -2 V_end (V_end - V_start) tau + (V_end - V_start)^2 tau / 2
# bit 1: top -Vs -> V_fb, bottom +Vs -> 0 (its pull down, Vs^2 tau / 2, counts against the push);
# bit 0: bottom +Vs -> V_fb, top -Vs -> 0
LOSS = {
    1: 2 * sc.V_FB * (sc.V_FB + VS) - (sc.V_FB + VS) ** 2 / 2 + VS**2 / 2,
    0: 2 * sc.V_FB * (sc.V_FB - VS) - (sc.V_FB - VS) ** 2 / 2 + VS**2 / 2,
}


def impulse(work: Path, model: MacroModel, a: float, args) -> None:
    """Each bit's feedback impulse from the simulated electrode and plate voltages (MacroModel.
    electrostatic_force at the simulated z, integrated over the window on ngspice's own points)
    against the design d T_s F1: the shortfalls e1, e0, the settling time constant each implies
    (LOSS), and what they make of the design formula: slope x 2 / (2 - e1 - e0), offset
    (e1 - e0) / 4 bits; the rest of each period (sense phases, gaps) as a mean force in bits."""
    n = args.impulse_periods
    text = sc.netlist(a, n).replace(".save v(qb) v(x_z)", ".save v(qb) v(x_z) v(top) v(bottom) v(plate)")
    plot = ngspice.run_ngspice(text, work, "impulse")[0]
    t = np.real(plot["time"])
    v = {k: np.real(plot[f"v({k})"]) for k in ("qb", "x_z", "top", "bottom", "plate")}
    xs = (v["x_z"] * 1e-6 / model.coordinates[0].scale)[:, None]
    force = model.electrostatic_force(xs, np.stack([v["top"], v["bottom"]], axis=1), v["plate"])[:, 0]
    bits = np.interp(np.arange(n) * sc.TS + sc.T_BIT, t, v["qb"]) > 0.9
    f1 = sc.sc_force(model)[0]
    design = sc.WINDOW * f1
    per: dict[int, list[float]] = {0: [], 1: []}
    rest = []
    for k in range(args.skip // 4 + 1, n):
        lo, hi, end = k * sc.TS + START, k * sc.TS + START + sc.WINDOW, (k + 1) * sc.TS
        per[int(bits[k - 1])].append(integral(t, force, lo, hi))
        rest.append(integral(t, force, k * sc.TS, lo) + integral(t, force, hi, end))
    e = {b: 1 - abs(np.mean(per[b])) / design for b in (0, 1)}
    tau = {b: e[b] * sc.V_FB**2 * sc.WINDOW / LOSS[b] for b in (0, 1)}
    print(
        f"  impulse per bit ({n} periods): bit 1 short of d T_s F1 by {100 * e[1]:.2f} % (tau {tau[1] * 1e9:.1f} ns), "
        f"bit 0 by {100 * e[0]:.2f} % (tau {tau[0] * 1e9:.1f} ns): slope {100 * (2 / (2 - e[1] - e[0]) - 1):+.2f} %, "
        f"offset {(e[1] - e[0]) / 4:+.4f} bits; sense phases and gaps {np.mean(rest) / (2 * design):+.4f} bits; "
        f"mean plate in the window {np.mean(v['plate'][(t % sc.TS > 0.3e-6) & (t % sc.TS < 0.7e-6)]):.4f} V"
    )


def integral(t: np.ndarray, y: np.ndarray, lo: float, hi: float) -> float:
    """int_lo^hi y dt, trapezoidal on the simulator's points and the interpolated ends."""
    inside = (t > lo) & (t < hi)
    tt = np.concatenate([[lo], t[inside], [hi]])
    yy = np.concatenate([[np.interp(lo, t, y)], y[inside], [np.interp(hi, t, y)]])
    return float(np.sum((yy[1:] + yy[:-1]) * np.diff(tt)) / 2)


def charge(work: Path, model: MacroModel, args) -> None:
    """The never-reset charge amplifier (tests/oracles/sc_readout.charge_netlist) over
    --charge-periods, at --charge-options (ngspice's defaults unless given): the clamped model's output drift against the fixed capacitors' (and the
    derived bound, sc_readout.drift_bound), and the moving model's collected charge against
    MacroModel.plate_charge along the simulated z."""
    n = args.charge_periods
    drift, quiet = {}, {}
    for sensor in ("clamped", "fixed", "moving"):
        before, start = sc.children_cpu(), time.monotonic()
        plot = ngspice.run_ngspice(sc.charge_netlist(sensor, n, args.charge_options), work / sensor, sensor, 6 * 3600)[
            0
        ]
        cpu, wall = sc.children_cpu() - before, time.monotonic() - start
        v = quiet[sensor] = sc.quiet(plot, n)
        points = len(plot["time"])
        if sensor == "moving":
            raw, swing = sc.charge_error(model, v)
            err, _ = sc.charge_error(model, v, quiet["fixed"])
            xs = v["x_z"] * 1e-6 / model.coordinates[0].scale
            print(
                f"  charge, moving ({n} periods, xs {xs.min():+.3f}..{xs.max():+.3f}): max |Cf dV - dQ_plate| "
                f"{raw:.3g} C = {raw / swing:.2e} of the {swing:.3g} C swing; net of the fixed run's leakage "
                f"{err:.3g} C = {err / swing:.2e} (limit 1e-3); {points} points, CPU {cpu:.0f} s, wall {wall:.0f} s"
            )
        else:
            even = v["out"][::2]
            drift[sensor] = even[-1] - even[0]
            print(
                f"  charge, {sensor} ({n} periods): output drift {drift[sensor]:+.3e} V, {points} points, CPU {cpu:.0f} s"
            )
    diff = abs(drift["clamped"] - drift["fixed"])
    print(f"  clamped - fixed drift {diff:.3e} V against the bound {sc.drift_bound(n):.3e} V")


def threads(work: Path, model: MacroModel, a: float, args) -> None:
    """CPU per period with the simulator's default OpenMP threads against `set num_threads=1`
    (tests/oracles/sc_readout.ONE_THREAD), runs taken in turn, and whether the two give the same
    bits and trajectory (the threads only share the BSIM4 load: the numbers must not change)."""
    runs = {}
    for t in (0, 1, 0, 1):
        r = sc.run(work, a, args.threads_periods, threads=t, name=f"threads{t}")
        runs.setdefault(t, []).append(r)
    d, one = runs[0][0], runs[1][0]
    same = np.array_equal(d.bits, one.bits) and len(d.time) == len(one.time)
    dz = np.abs(d.x_um - one.x_um).max() * 1e3 if len(d.time) == len(one.time) else np.nan
    for t, rs in runs.items():
        label = "num_threads=1" if t else "default threads"
        print(
            f"  {label}: CPU {', '.join(f'{r.cpu / args.threads_periods * 1e3:.0f}' for r in rs)} ms/period, "
            f"wall {', '.join(f'{r.wall / args.threads_periods * 1e3:.0f}' for r in rs)} ms/period, "
            f"{rs[0].points / args.threads_periods:.0f} points/period"
        )
    print(f"  same bits and time points: {same}; max |z difference| {dz:.3g} nm")


def maxstep(work: Path, model: MacroModel, a: float, args) -> None:
    """The example's 20 ns maximum step (ngspice's default for the 20 ns .tran step) against one
    of a whole period (2 us: the clocks' breakpoints and the truncation-error control alone set
    the steps): max |z| after --skip, bit mean, points and CPU per period, the bits compared."""
    runs = {}
    for tmax in (None, sc.TS):
        r = runs[tmax] = sc.run(work, a, args.step_periods, tmax=tmax, name="maxstep")
        z = np.abs(r.x_um[r.time > args.skip * sc.TS]).max() * 1e3
        print(
            f"  max step {20e-9 if tmax is None else tmax:.0e} s: max |z| {z:.4g} nm after {args.skip} periods, "
            f"bit mean {r.bits[args.skip :].mean():.4f}, {r.points / args.step_periods:.0f} points/period, "
            f"CPU {r.cpu / args.step_periods * 1e3:.0f} ms/period"
        )
    differ = int(np.sum(runs[None].bits != runs[sc.TS].bits))
    print(f"  bits that differ: {differ} of {args.step_periods}")


def start(work: Path, model: MacroModel, a: float, args) -> None:
    """The transient from `uic` against from ngspice's operating point, at each --start-accels:
    z at t = 0, max |z| after --skip, z at the end, bit mean against the balance."""
    for acc in (float(x) for x in args.start_accels.split(",")):
        for how in ("uic", ""):
            r = sc.run(work, acc, args.start_periods, start=how, name="start")
            after = r.x_um[r.time > args.skip * sc.TS] * 1e3
            print(
                f"  a = {acc:+.3g} m/s^2, {how or 'operating point'}: z(0) {r.x_um[0] * 1e3:+.4g} nm, "
                f"max |z| {np.abs(after).max():.4g} nm after {args.skip} periods, z(end) {after[-1]:+.4g} nm, "
                f"bit mean {r.bits[args.skip :].mean():.4f} against the balance {sc.balance(model, acc):.4f}"
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--releases", default="46,39")
    p.add_argument("--periods", type=int, default=4096)
    p.add_argument("--fractions", default="0,0.25,-0.25,0.5,-0.5")
    p.add_argument("--scale-periods", type=int, default=192)
    p.add_argument("--reltol-periods", type=int, default=128)
    p.add_argument("--skip", type=int, default=32)
    p.add_argument("--cost-periods", type=int, default=10)
    p.add_argument("--out", default="out/sc_readout")
    p.add_argument("--charge-periods", type=int, default=4096)
    p.add_argument("--charge-options", default="", help="the charge runs' .options (default: none)")
    p.add_argument("--impulse-periods", type=int, default=64)
    p.add_argument("--threads-periods", type=int, default=16)
    p.add_argument("--step-periods", type=int, default=64)
    p.add_argument("--start-periods", type=int, default=64)
    p.add_argument("--start-accels", default="0,3")
    p.add_argument("--only", default="threads,impulse,scale,maxstep,start,held,cost,reltol,charge")
    args = p.parse_args()
    model = MacroModel.load_json(sc.MODEL_JSON)
    a0 = float(args.fractions.split(",")[0]) * sc.full_scale(model)
    parts = args.only.split(",")
    for rel in args.releases.split(","):
        with using_ngspice(rel), tempfile.TemporaryDirectory() as tmp:
            print(f"ngspice {rel} ({NGSPICE[rel]})", flush=True)
            work = Path(tmp)
            for part in parts:
                PARTS[part](work, model, a0, rel, args)


PARTS = {
    "impulse": lambda work, model, a0, rel, args: impulse(work, model, a0, args),
    "scale": lambda work, model, a0, rel, args: scale(work, model, args),
    "held": held,
    "cost": lambda work, model, a0, rel, args: cost(work, a0, args),
    "reltol": lambda work, model, a0, rel, args: reltols(work, model, a0, args),
    "charge": lambda work, model, a0, rel, args: charge(work, model, args),
    "threads": lambda work, model, a0, rel, args: threads(work, model, a0, args),
    "maxstep": lambda work, model, a0, rel, args: maxstep(work, model, a0, args),
    "start": lambda work, model, a0, rel, args: start(work, model, a0, args),
}


if __name__ == "__main__":
    main()
