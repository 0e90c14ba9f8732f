"""Loop orders 2-5 on one channel of a sigma-delta force-feedback loop: the numpy reference
(tests/oracles/sigma_delta_reference.py) and, with --circuit, the compiled ngspice loop
(--simulator ngspice-xspice's bench with the channel's filter in netgen_sdloop), side by side.

    .venv/bin/python bench/sigma_delta_orders.py [--cycles 65536] [--orders 2,3,4,5] [--circuit] [-o DIR]

Order 2 is the lead compensator (lead2), orders 3-5 the CIFB electromechanical loops designed
from an NTF with the per-order H_inf (filters.design). The device is the levitated disk's z
channel (netlists/levitated_disk.json), or with --model examples/accelerometer_z.toml a structure
built here with its [loop] (the filter set through [loop.filter], the tone through a_in): gravity
needs a mean bit of 0.5, i.e. a DC input at
-6 dBFS, on which a tone (--tone-fs of full scale, at a quarter of the band edge) is added
through f_z. Per order it prints the in-band noise floor (dB re F_fb^2/Hz, median), in-band
noise, SQNR of the tone, noise-shaping slope over the decade below the band edge, whether the
mass held (|z| within --hold of the gap), and with --circuit the circuit's figures and their
difference to the reference. --dr adds the reference's dynamic-range curve (tone amplitude
sweep on top of gravity). Results also go to DIR/orders.json. Orders 3-5 run with the feedback
step (Timing.fb_edge 0, their default); --fb-edge 0.02 gives the ramped feedback whose integration
error set the circuit's old flat in-band floor (bench/sigma_delta_impulse.py measures it).
--loop LOOP.toml replaces the model's loop description; --model DIR/levitated_disk.json of
runner.model_for(..., rigid_only=True) runs the rigid-body disk (bench/sigma_delta_cross_impulse.py
splits the disk's z floor by the terms the single-channel reference leaves out).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from support import sigma_delta_reference as reference

from netgen.build import build_model
from netgen.model import MacroModel
from netgen.structure import load_structure
from netgen.testbench.sigma_delta import (
    Choices,
    Tone,
    analysis,
    design,
    filters,
    ngspice,
    read_loop_file,
    read_structure_loop,
)
from netgen.testbench.sigma_delta.analysis import band_metrics, psd
from netgen.testbench.sigma_delta.kinds import FILTERS
from netgen.testbench.sigma_delta.loopfile import LoopSpec

H_INF = {3: 1.5, 4: 1.4, 5: 1.5}  # the disk's (the accelerometer's order 5 needs 1.3: --h-inf 1.3)
NPERSEG = 8192


def load(model_path: str, loop: str | None = None):
    """The MacroModel and its loop description: a model .json (the disk's defaults) or a
    structure .toml built here with its [loop] table (examples/accelerometer_z.toml); --loop
    FILE's (`loop`) replaces either (the disk's z alone: channels = ["z"])."""
    if model_path.endswith(".toml"):
        model, spec = build_model(load_structure(model_path), progress=False), read_structure_loop(model_path)
    else:
        model, spec = MacroModel.load_json(model_path), LoopSpec()
    return model, read_loop_file(loop) if loop else spec


def setup(
    model_path: str,
    ts: float,
    order: int,
    osr: float,
    h_inf: float | None,
    reltol: float = 1e-3,
    fb_edge: float | None = None,
    loop: str | None = None,
):
    """Model, Design, mechanics, filter of the first channel at this order: lead2, or cifb through
    the [loop.filter] path (designed inside loop.design, no dither) on a structure's [loop]; on a
    model .json (the disk) only its first channel (z) gets the cifb filter, by the same design step.
    The feedback edge: `fb_edge` if given, else the design's default (a step for cifb: Timing.fb_edge;
    on the disk, whose tilts keep lead2, the step is set here for orders above 2)."""
    model, spec = load(model_path, loop)
    table = {"kind": "cifb", "order": order, "osr": float(osr), "h_inf": h_inf or H_INF.get(order, 1.5)}
    if order > 2 and model_path.endswith(".toml"):
        spec = replace(spec, filter=table)
    if fb_edge is not None or (order > 2 and not model_path.endswith(".toml")):
        spec = replace(spec, timing={**spec.timing, "fb_edge": 0.0 if fb_edge is None else fb_edge})
    d = design(model, ts, Choices(reltol=reltol), spec=spec)
    ch = d.channels[0]
    if order > 2 and not model_path.endswith(".toml"):
        ch["filter"], ch["dither_v"] = FILTERS["cifb"].design(model, d, ch, table), 0.0
    mech = filters.mechanics_of(model, d, ch["name"])
    return model, d, mech, filters.Filter.from_dict(ch["filter"]) if order > 2 else filters.lead2(d.lead)


def dc_input(model: MacroModel, d, mech: filters.Mechanics) -> float:
    """The first channel's DC input acceleration: gravity and the sense phase's mean force."""
    return filters.dc_acceleration(model, d, d.channels[0]["name"])


def figures(v: np.ndarray, ts: float, osr: float, tone_hz: float) -> dict:
    """The in-band figures of a bitstream after its first eighth (the band from analysis.DC_BINS)."""
    f, p = psd(v[len(v) // 8 :], ts, NPERSEG)
    return band_metrics(f, p, ts, osr, tone_hz, analysis.DC_BINS)


def run_reference(args, order: int) -> dict:
    """The numpy loop of this order: figures, max |z| and time."""
    model, d, mech, f = setup(args.model, args.ts, order, args.osr, args.h_inf, fb_edge=args.fb_edge, loop=args.loop)
    tone = analysis.tone_frequency(args.ts, NPERSEG, args.osr)
    start = time.perf_counter()
    r = reference.simulate(
        mech,
        f,
        args.cycles,
        reference.Input(dc_input(model, d, mech), args.tone_fs * mech.full_scale, tone),
        dither=d.channels[0]["dither_v"],
        dither_step=d.channels[0]["dither_step"],
    )
    gap = min(e.gap for e in model.electrodes)
    out = {
        "wall_s": time.perf_counter() - start,
        "held": reference.stable(r, args.hold * gap),
        "max_z_over_gap": float(np.max(np.abs(r["q"])) / gap),
        "bit_mean": float(r["v"].mean()),
        **figures(r["v"], args.ts, args.osr, tone),
        "filter": f.as_dict(),
        "full_scale": mech.full_scale,
    }
    if args.dr:
        out["dynamic_range"] = dynamic_range(args, model, d, mech, f, tone)
    return out


def dynamic_range(args, model, d, mech, f, tone: float) -> dict:
    """SNR against the tone amplitude (on top of gravity), reference loop, 2^15 periods each."""
    gap = min(e.gap for e in model.electrodes)

    def run(a: float):
        r = reference.simulate(
            mech,
            f,
            2**15,
            reference.Input(dc_input(model, d, mech), a * mech.full_scale, tone),
            dither=d.channels[0]["dither_v"],
            dither_step=d.channels[0]["dither_step"],
        )
        return r["v"], reference.stable(r, args.hold * gap)

    amps = [1e-3, 3e-3, 0.01, 0.03, 0.1, 0.2, 0.3, 0.4, 0.45, 0.5]
    return analysis.dynamic_range(run, amps, args.ts, args.osr, tone, NPERSEG // 2, skip=4096)


def run_circuit(args, order: int) -> dict:
    """The compiled ngspice loop (netgen_sdloop with the z channel's filter), segmented."""
    model, d, mech, f = setup(args.model, args.ts, order, args.osr, args.h_inf, args.reltol, args.fb_edge, args.loop)
    tone_hz = analysis.tone_frequency(args.ts, NPERSEG, args.osr)
    out = Path(args.out) / f"order{order}"
    out.mkdir(parents=True, exist_ok=True)
    lib, control = ngspice.xspice_library(model, out, ngspice.code_models(False))
    name = d.channels[0]["name"]
    tone = (
        Tone("a_in", args.tone_fs * mech.full_scale, tone_hz)
        if model.acceleration  # m/s^2 on a_in
        else Tone(name, args.tone_fs * mech.full_scale * mech.mass * 1e6, tone_hz)
    )  # uN on f_z
    start = time.perf_counter()
    clock, breakpoints, segments = ngspice.run_segments(
        model, d, lib, out, args.cycles, tone, False, ngspice.Settings("xspice", control, segment=args.segment)
    )
    wall = time.perf_counter() - start
    v = clock[f"bits_{name}"].astype(float)
    np.savez_compressed(out / "bitstreams.npz", **clock)
    gap = min(e.gap for e in model.electrodes)
    zmax = float(np.max(np.abs(clock[f"x_{name}"])) * 1e-6)  # x_ port: 1 V = 1 um
    res = {
        "wall_s": wall,
        "periods": int(len(v)),
        "max_z_over_gap": zmax / gap,
        "bit_mean": float(v.mean()),
        "held": bool(len(v) == args.cycles and zmax <= args.hold * gap),
        "segments": segments["ngspice_runs"],
        "missed_corner_cuts": len(breakpoints["segments_cut_at_a_missed_corner"]),
        "missed_corners_kept": breakpoints["periods_with_a_missed_corner"],
    }
    if len(v) >= 4 * NPERSEG:
        res.update(figures(v, args.ts, args.osr, tone_hz))
    return res


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="netlists/levitated_disk.json")
    p.add_argument("--ts", type=float, default=1e-6)
    p.add_argument("--cycles", type=int, default=65536)
    p.add_argument("--orders", default="2,3,4,5")
    p.add_argument("--osr", type=float, default=64)
    p.add_argument("--h-inf", type=float, default=None, help=f"H_inf for every order (default per order: {H_INF})")
    p.add_argument("--tone-fs", type=float, default=0.1, help="tone amplitude, fraction of full scale")
    p.add_argument("--hold", type=float, default=0.01, help="the mass held: |z| below this fraction of the gap")
    p.add_argument("--circuit", action="store_true", help="also run the compiled ngspice loop")
    p.add_argument("--dr", action="store_true", help="the reference's dynamic-range curve")
    p.add_argument("--reltol", type=float, default=1e-3, help="the circuit simulator's relative tolerance")
    p.add_argument(
        "--fb-edge",
        type=float,
        default=None,
        help="feedback edge width, fraction of T_s (default: "
        "the design's, a step for orders 3-5; 0.02 gives the ramps that set the old flat floor)",
    )
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument(
        "--segment", type=int, default=None, help="periods per ngspice segment (0: one run; default: the bench's)"
    )
    p.add_argument("--loop", default=None, help="a loop description (LOOP.toml) replacing the model's")
    p.add_argument("-o", "--out", default="out/sigma_delta_orders")
    args = p.parse_args()
    orders = [int(o) for o in args.orders.split(",")]
    Path(args.out).mkdir(parents=True, exist_ok=True)
    results = {o: {"reference": run_reference(args, o)} for o in orders}
    if args.circuit:
        with ProcessPoolExecutor(args.jobs) as pool:
            for o, res in zip(orders, pool.map(run_circuit, [args] * len(orders), orders)):
                results[o]["circuit"] = res
    report(results, args)
    (Path(args.out) / "orders.json").write_text(json.dumps({str(k): v for k, v in results.items()}, indent=1) + "\n")


def report(results: dict, args) -> None:
    """One line per order and run, then the circuit - reference differences."""
    keys = ("noise_floor_db_per_hz", "inband_noise_db", "snr_db", "slope_db_per_decade")
    print(
        f"{args.cycles} periods, OSR {args.osr:g}, DC -6 dBFS (gravity) + tone {20 * np.log10(args.tone_fs):.1f} dBFS"
        + (f", circuit at reltol {args.reltol:g}" if args.circuit else "")
    )
    print(
        f"{'order':<6}{'run':<10}{'floor dB/Hz':>12}{'noise dB':>10}{'SQNR dB':>9}{'slope':>7}{'held':>6}"
        f"{'max|z|/gap':>12}{'wall s':>8}"
    )
    for o, runs in results.items():
        for name, r in runs.items():
            vals = "".join(
                f"{r[k]:>{w}.1f}" if r.get(k) is not None else f"{'-':>{w}}" for k, w in zip(keys, (12, 10, 9, 7))
            )
            print(f"{o:<6}{name:<10}{vals}{str(r['held']):>6}{r['max_z_over_gap']:>12.2e}{r['wall_s']:>8.1f}")
        if "circuit" in runs and "snr_db" in runs["circuit"]:
            c, ref = runs["circuit"], runs["reference"]
            print(
                f"{'':<6}{'c - ref':<10}" + "".join(f"{c[k] - ref[k]:>+{w}.1f}" for k, w in zip(keys, (12, 10, 9, 7)))
            )
    for o, runs in results.items():
        dr = runs["reference"].get("dynamic_range")
        if dr:
            print(
                f"order {o} reference dynamic range: max stable tone {dr['max_stable_amplitude']} FS, peak SQNR "
                f"{dr['peak_sqnr_db']:.1f} dB, DR {dr['dynamic_range_db']:.1f} dB; "
                + ", ".join(
                    f"{r['amplitude']:g}:{r['sqnr_db']:.0f}" if r["held"] else f"{r['amplitude']:g}:lost"
                    for r in dr["rows"]
                )
            )


if __name__ == "__main__":
    main()
