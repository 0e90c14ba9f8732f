"""Which side is converged on the z accelerometer's ramped-feedback loop: ngspice-xspice at
reltol, absolute tolerances, maximum step and equal steps per drive edge (Design.ramp_steps), the
FMU loop at its tolerance, and the FMU loop against an independent integration of the same
MacroModel (8 minutes, 133 s of CPU, on a loaded 2-core machine; most of it in the reltol 1e-7 runs):

    .venv/bin/python bench/fmu_convergence.py [--cycles 512] [--check 130] [-o out/fmu_convergence]

Prints per run the first period whose bit differs from the FMU loop's at tolerance 1e-10 and the
pairwise first differences (table); the largest difference of the FMU loop's charge-amplifier
samples from scipy's DOP853 (rtol 1e-13) integration of MacroModel.accelerations with the FMU's
bits over the first --check periods, in dither amplitudes; and an open-loop ramp (the top electrode
to V_fb over 20 ns every period, 20 periods, gravity on) in ngspice at reltol and maximum step
against DOP853: ngspice's relative displacement error. Writes OUT/fmu_convergence.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

import numpy as np
from fmu_loop import example, xspice_run
from scipy.integrate import solve_ivp

from netgen.sim import codemodel
from netgen.sim.ngspice import ngspice_path
from netgen.sim.rawfile import read_raw
from netgen.testbench.sigma_delta import fmu

TIGHT = {"abstol": 1e-20, "vntol": 1e-14}
# (label, reltol, absolute tolerances, maximum step in T_s, equal steps per drive edge; 0: ngspice's own)
NGSPICE = [
    (f"reltol {r:g}{' tight' if a else ''} tmax {m:g}{f' ramp {n}' if n else ''}", r, a, m, n)
    for r, a, m, n in [
        (1e-3, {}, 0.05, 0), (1e-4, {}, 0.05, 0), (1e-5, {}, 0.05, 0), (1e-6, {}, 0.05, 0), (1e-5, {}, 0.01, 0),
        (1e-6, {}, 0.01, 0), (1e-3, TIGHT, 0.05, 0), (1e-5, TIGHT, 0.05, 0), (1e-6, TIGHT, 0.05, 0),
        (1e-6, TIGHT, 0.01, 0), (1e-7, TIGHT, 0.05, 0), (1e-7, TIGHT, 0.01, 0), (1e-3, {}, 0.001, 0),
        (1e-6, TIGHT, 0.001, 0), (1e-3, {}, 0.05, 10), (1e-3, TIGHT, 0.05, 20), (1e-4, TIGHT, 0.05, 20),
        (1e-5, TIGHT, 0.05, 20), (1e-6, TIGHT, 0.05, 10), (1e-6, TIGHT, 0.05, 20),
        (1e-6, TIGHT, 0.05, 40), (1e-6, TIGHT, 0.05, 80), (1e-6, TIGHT, 0.01, 40), (1e-7, TIGHT, 0.05, 20),
        (1e-7, TIGHT, 0.05, 40), (1e-7, TIGHT, 0.05, 80),
    ]
]  # fmt: skip
FMU_TOLERANCES = (1e-8, 1e-9, 1e-10, 1e-11, 1e-12)


def first_difference(a: np.ndarray, b: np.ndarray) -> int:
    """The first period whose bits differ (the length if none)."""
    diff = np.nonzero(a != b)[0]
    return int(diff[0]) if len(diff) else len(a)


def ngspice_bits(out: Path, cycles: int, reltol: float, tol: dict, tmax: float, steps: int) -> np.ndarray:
    """The ngspice-xspice loop's bits with the design at these tolerances, maximum step and ramp steps."""
    return xspice_run(out, cycles, reltol=reltol, tmax=tmax, ramp_steps=steps, **tol)["clock"]["bits_z"]


def independent(ex, periods: int) -> float:
    """max |cur_FMU - cur_DOP853| / dither amplitude over `periods` with the FMU loop's bits: the
    MacroModel's equations integrated by scipy piece by piece with the same drives."""
    model, d = ex.design()
    lp = fmu.Loop.of(d)
    got = fmu.run(model, d, periods, tolerance=1e-10)
    bits = (got["bits_z"] > 0).astype(float)
    y, before, cur = np.zeros(2 * model.ncoords), 0.0, np.zeros(periods)
    nc = model.ncoords
    for n in range(periods):
        for a, b, sa, sb, fa, fb in fmu.segments(lp):
            sel = lp.selection(np.array([before if b <= lp.t_latch else bits[n]]))
            t0, t1 = (n + a) * lp.ts, (n + b) * lp.ts

            def rhs(t, s, sel=sel, t0=t0, t1=t1, sa=sa, sb=sb, fa=fa, fb=fb):
                w = (t - t0) / (t1 - t0)
                v = sa + w * (sb - sa) + sel * (fa + w * (fb - fa))
                return np.r_[s[nc:], model.accelerations(s[:nc], s[nc:], v, 0.0, a_frame=d.inputs["a_in"])]

            y = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-13, atol=1e-20).y[:, -1]
            if b == lp.t_sample:
                q = model.electrode_charges(y[:nc], sb + sel * fb, 0.0)[0]
                cur[n] = (lp.weights @ q)[0]
        before = bits[n]
    return float(np.abs(got["cur_z"] - cur).max() / lp.dither_amp[0])


OPEN_LOOP = """* open-loop ramp
.include "{lib}"
X1 top bottom plate f_z x_z a_in {name}
Vt top 0 PULSE(0 {v!r} 0.49u 20n 20n 0.44u 1u)
Vb bottom 0 DC 0
Vp plate 0 0
Vf f_z 0 0
Va a_in 0 {a!r}
.options reltol={reltol!r} abstol=1e-20 vntol=1e-14
.control
pre_codemodel '{cm}'
tran 1e-10 20u 0 {tmax!r} uic
write open.raw time v(x1.xs_z)
.endc
.end
"""
OPEN_CASES = [(1e-3, 50e-9), (1e-4, 50e-9), (1e-5, 50e-9), (1e-6, 50e-9), (1e-3, 5e-9), (1e-3, 1e-9), (1e-3, 0.2e-9)]


def open_loop(ex, folder: Path) -> dict[str, float | None]:
    """ngspice's scaled displacement after 20 ramped feedback pulses, relative to DOP853 (None:
    the run stopped early); folder holds the run's _xspice.lib."""
    model, d = ex.design()
    P = (0.0, d.vfb, 0.49e-6, 20e-9, 20e-9, 0.44e-6, 1e-6)
    edges = (0.49e-6, 0.51e-6, 0.95e-6, 0.97e-6)
    corners = sorted({k * 1e-6 + c for k in range(20) for c in edges} | {0.0, 20e-6})
    y = np.zeros(2)
    for t0, t1 in zip(corners[:-1], corners[1:]):
        va, vb = fmu.pulse(P, t0 + 1e-3 * (t1 - t0)), fmu.pulse(P, t1 - 1e-3 * (t1 - t0))
        slope = (vb - va) / (0.998 * (t1 - t0))
        v0 = va - slope * 1e-3 * (t1 - t0)

        def rhs(t, s, v0=v0, slope=slope, t0=t0):
            v = np.array([v0 + slope * (t - t0), 0.0])
            return np.r_[s[1], model.accelerations(s[:1], s[1:], v, 0.0, a_frame=d.inputs["a_in"])]

        y = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-13, atol=1e-22).y[:, -1]
    lib = next(folder.glob("*_xspice.lib"))
    cm = codemodel.build(codemodel.MODEL, progress=lambda m: None)
    out = {}
    for reltol, tmax in OPEN_CASES:
        text = OPEN_LOOP.format(
            lib=lib.name, name=model.name, v=d.vfb, a=d.inputs["a_in"], reltol=reltol, cm=cm, tmax=tmax
        )
        (folder / "open.cir").write_text(text)
        (folder / "open.raw").unlink(missing_ok=True)
        subprocess.run([ngspice_path(), "-b", "open.cir"], cwd=folder, capture_output=True, timeout=600)
        plot = read_raw(folder / "open.raw")[-1] if (folder / "open.raw").exists() else None
        done = plot is not None and abs(np.asarray(plot["time"]).real[-1] - 20e-6) < 1e-12
        x = np.asarray(plot["v(x1.xs_z)"]).real[-1] if done else None
        out[f"reltol {reltol:g} tmax {tmax:g} s"] = None if x is None else float(x / y[0] - 1.0)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=512)
    p.add_argument("--check", type=int, default=130, help="periods of the independent integration")
    p.add_argument("-o", "--output", default="out/fmu_convergence")
    args = p.parse_args()
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    ex = example()
    model, d = ex.design()
    runs = {f"FMU tolerance {t:g}": fmu.run(model, d, args.cycles, tolerance=t)["bits_z"] for t in FMU_TOLERANCES}
    for k, (label, reltol, tol, tmax, steps) in enumerate(NGSPICE):
        runs[f"ngspice {label}"] = ngspice_bits(out / f"ngspice{k}", args.cycles, reltol, tol, tmax, steps)
    names = list(runs)
    table = {a: {b: first_difference(runs[a], runs[b]) for b in names} for a in names}
    for a in names:
        print(f"{a:40s} first bit != FMU: {table[a]['FMU tolerance 1e-10']}")
    drift = independent(ex, args.check)
    print(f"FMU vs DOP853 over {args.check} periods: {drift:.3g} dither amplitudes")
    ramps = open_loop(ex, out / "ngspice0")
    for k, v in ramps.items():
        print(f"open-loop ramps, ngspice {k}: displacement error {v if v is None else f'{v:+.2e}'}")
    result = {"cycles": args.cycles, "first_difference": table, "fmu_vs_dop853_dither_amplitudes": drift}
    result["open_loop_relative_error"] = ramps
    (out / "fmu_convergence.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
