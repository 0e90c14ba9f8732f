"""The z accelerometer's second-order loop (examples/accelerometer_z.toml), measured as a sensor:

    .venv/bin/python bench/sigma_delta_accelerometer.py [-o out/acc_bench] [--cycles 16384]
        [--long 65536] [--jobs 2] [--simulator ngspice-xspice]

- DC sweep: the bitstream mean against a DC acceleration on a_in (no gravity) from -0.9 to +0.9
  of full scale at the gravity-sized V_fb: scale factor, offset and the largest residual from the
  line in % of full scale (netgen.testbench.sigma_delta.analysis.scale_factor), and the proof
  mass's largest excursion in % of the gap at each input;
- amplitude sweep: a tone on a_in (f_s/512) from 0.1 to 1.2 of full scale: whether the loop held,
  the largest excursion in % of the gap, SQNR (sine fit; analysis.tone_fit) and the shaping slope;
  the maximum stable amplitude is the largest one below which every run held;
- a long run with gravity (--long periods): the in-band floor and the noise-shaping slope.

Full scale: the acceleration a bit mean of +-1 stands for, F_fs / m (Design.channels[0]
["full_scale_force_si"]). Writes DIR/accelerometer.json and DIR/linearity.png, prints a table.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.build import build_model
from netgen.emit import write_outputs
from netgen.model import MacroModel
from netgen.structure import load_structure
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import analysis, loopfile, plots

STRUCTURE = ROOT / "examples" / "accelerometer_z.toml"
TS = 1e-6


def one(args: tuple) -> dict:
    """One run (in a worker): kind "dc" (acceleration a), "tone" (amplitude a) or "long"."""
    kind, a, json_path, lib, out, cycles, simulator, vfb, freq = args
    model = MacroModel.load_json(json_path)
    loop = sd.read_structure_loop(STRUCTURE)
    tone = None
    check = True
    volts = loopfile.LoopSettings.of(loop.settings.given() | {"feedback_voltage": vfb})
    if kind == "dc":
        loop = replace(loop, settings=volts, input=loopfile.InputSpec({"a_in": a}, None, default=False))
    elif kind == "tone":
        loop = replace(loop, settings=volts, input=loopfile.InputSpec({"a_in": 0.0}, None, default=False))
        tone, check = sd.Tone("a_in", a, freq), False  # past full scale: measure, do not refuse
    # check False: an under-designed loop built anyway (to see how a lost plate is reported)
    step = simulator in ("ngspice-xspice", "vacask")  # runner.STEP_BACKENDS
    d = None if check else sd.design(model, TS, spec=loop, tone=tone or loop.input.tone, balance_check=False, step=step)
    request = sd.RunRequest(
        TS, cycles, tone, progress=False, plots=False, simulator=simulator, loop=loop, skip=cycles // 8, designed=d
    )
    s = sd.run(model, Path(lib), Path(out), request)
    gap = model.coordinates[0].scale
    done = len(s["clock"]["time"])  # fewer than cycles if the mass was lost
    x = np.abs(s["clock"]["x_z"][min(cycles // 8, done // 2) :]) * 1e-6
    ch = s["channels"]["z"]
    return {
        "kind": kind,
        "input": a,
        "held": s["levitation"]["held"],
        "bit_mean": ch["bit_mean"],
        "max_x_pct_gap": float(100 * x.max(initial=0.0) / gap),
        "floor_db_per_hz": ch.get("noise_floor_db_per_hz"),
        "slope_db_per_decade": ch.get("slope_db_per_decade"),
        "sqnr_db": ch.get("sqnr_db"),
        "tone_amplitude_bits": ch.get("tone_amplitude_bits"),
        "wall_s": s["wall_s"],
        "cycles": s["cycles"],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", default="out/acc_bench")
    ap.add_argument("--cycles", type=int, default=16384, help="periods per sweep run (default 16384)")
    ap.add_argument("--long", type=int, default=65536, help="periods of the long gravity run (0: none)")
    ap.add_argument("--points", type=int, default=13, help="DC sweep points (default 13)")
    ap.add_argument(
        "--amplitudes", default="0.1,0.2,0.3,0.5,0.7,0.8,0.9,1.0,1.1,1.2", help="tone amplitudes in units of full scale"
    )
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--simulator", default="ngspice-xspice", choices=list(sd.BACKENDS))
    args = ap.parse_args(argv)
    out = Path(args.output)
    (out / "model").mkdir(parents=True, exist_ok=True)
    model = build_model(load_structure(STRUCTURE), progress=False)
    write_outputs(model, out / "model", "all")
    js, lib = out / "model" / f"{model.name}.json", out / "model" / f"{model.name}.lib"
    d = sd.design(model, TS, spec=sd.read_structure_loop(STRUCTURE))
    fs_acc = d.channels[0]["full_scale_force_si"] / model.coordinates[0].mass
    freq = 1 / TS / 512
    runs = [
        ("dc", float(a), js, lib, out / f"dc_{k}", args.cycles, args.simulator, d.vfb, freq)
        for k, a in enumerate(np.linspace(-0.9, 0.9, args.points) * fs_acc)
    ]
    runs += [
        ("tone", float(f) * fs_acc, js, lib, out / f"tone_{f}", args.cycles, args.simulator, d.vfb, freq)
        for f in map(float, args.amplitudes.split(","))
    ]
    if args.long:
        runs.append(("long", 9.81, js, lib, out / "long", args.long, args.simulator, d.vfb, freq))
    res = []
    with ProcessPoolExecutor(args.jobs) as ex:
        for r in ex.map(one, runs):  # each result kept as it comes
            res.append(r)
            (out / "runs.jsonl").open("a").write(json.dumps(r) + "\n")
    dc = [r for r in res if r["kind"] == "dc"]
    fit = analysis.scale_factor([r["input"] for r in dc], [r["bit_mean"] for r in dc], fs_acc)
    tones = [r for r in res if r["kind"] == "tone"]
    stable = 0.0
    for r in sorted(tones, key=lambda r: r["input"]):
        if not r["held"]:
            break
        stable = r["input"]
    within = [r for r in res if r["kind"] != "tone" or r["input"] <= stable]
    summary = {
        "vfb": d.vfb,
        "full_scale_m_s2": fs_acc,
        "scale_factor_per_m_s2": fit["scale_factor"],
        "scale_factor_ideal": 1 / fs_acc,
        "offset": fit["offset"],
        "max_nonlinearity_pct_fs": fit["max_nonlinearity_pct_fs"],
        "max_stable_amplitude_m_s2": stable,
        "max_stable_amplitude_fs": stable / fs_acc,
        "max_x_pct_gap_up_to_stable": max(r["max_x_pct_gap"] for r in within),
        "runs": res,
    }
    (out / "accelerometer.json").write_text(json.dumps(summary, indent=1) + "\n")
    plots.plot_linearity(
        [r["input"] for r in dc],
        [r["bit_mean"] for r in dc],
        fit,
        out / "linearity.png",
        f"{model.name}: bit mean vs DC acceleration ({args.simulator}, {args.cycles} periods)",
    )
    print(
        f"V_fb {d.vfb} V, full scale {fs_acc:.4g} m/s^2 ({fs_acc / 9.81:.3f} g); {args.simulator}, {args.cycles} periods per run"
    )
    print(
        f"DC sweep: scale factor {fit['scale_factor']:.6g} per m/s^2 (1/FS = {1 / fs_acc:.6g}), offset "
        f"{fit['offset']:+.2e}, max nonlinearity {fit['max_nonlinearity_pct_fs']:.4f} % FS"
    )
    print(
        f"{'kind':5s} {'input':>10s} {'held':>5s} {'bit mean':>9s} {'max x %gap':>10s} {'floor':>7s} {'slope':>6s} {'SQNR':>6s}"
    )
    for r in res:
        fmt = lambda v, f: "-" if v is None else format(v, f)  # noqa: E731
        print(
            f"{r['kind']:5s} {r['input']:10.4g} {str(r['held']):>5s} {r['bit_mean']:+9.5f} {r['max_x_pct_gap']:10.4f} "
            f"{fmt(r['floor_db_per_hz'], '7.1f'):>7s} {fmt(r['slope_db_per_decade'], '6.1f'):>6s} {fmt(r['sqnr_db'], '6.1f'):>6s}"
        )
    print(
        f"maximum stable tone amplitude {stable:.4g} m/s^2 ({stable / fs_acc:.2f} FS); proof mass within "
        f"{summary['max_x_pct_gap_up_to_stable']:.4f} % of the gap at every input up to it"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
