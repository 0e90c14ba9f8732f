"""The paper's Fig. 3 runs (long): the sigma-delta levitation loop at T_s = 1 us and 3.2 us, the
rigid-body-only model, and a tone on z. Prints the paper reproduction's figures (docs/sigma-delta-validation.md).

    .venv/bin/python examples/sigma_delta_paper.py --cycles 65536 -o out/sigma_delta

Runs go through VACASK by default (netgen.testbench.sigma_delta.vacask: the same loop with the compiled
Verilog-A model, about 10 ms per period on one core, so a 2^16-period run takes ~10-15 min);
--simulator ngspice-xspice runs the ngspice bench compiled (the model's code-model .lib and the
loop's code model, docs/performance.md: 3-9 ms per period depending on the machine, 4-9 min per 2^16-period run);
--simulator ngspice runs the ngspice bench instead (~50-70 ms per period: over an hour per
2^16-period run, in restarted segments). Runs go in parallel, one process each; a run whose
summary.json exists is reused unless --rerun.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd
from netgen.testbench.sigma_delta import vacask as sdv

ROOT = Path(__file__).resolve().parents[1]
STRUCTURE = ROOT / "examples" / "levitated_disk.toml"
RUNS = {
    "ts1": (1e-6, False, None),
    "ts3.2": (3.2e-6, False, None),
    "rigid": (1e-6, True, None),
    "tone": (1e-6, False, "z:0.02:2000"),
}


def one(
    name: str, ts: float, cycles: int, out: Path, rigid: bool, tone: str | None, simulator: str, rerun: bool
) -> dict:
    """One loop run into out/name; returns its summary (without spectra and clock)."""
    folder = out / name
    if (folder / "summary.json").exists() and not rerun:
        s = json.loads((folder / "summary.json").read_text())
        if s.get("cycles") == cycles and s.get("simulator", "ngspice") == simulator:
            return s
    if rigid:
        model, lib = sd.model_for(STRUCTURE, out / "model_rigid", sd.BuildOptions(rigid_only=True), progress=False)
    else:
        model, lib = (
            MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json"),
            ROOT / "netlists" / "levitated_disk.lib",
        )
    s = sd.run(
        model,
        lib,
        folder,
        sd.RunRequest(ts, cycles, sd.Tone.parse(tone) if tone else None, progress=False, simulator=simulator),
    )
    s.pop("clock"), s.pop("spectra")
    return json.loads(json.dumps(s))


def mode_frequency(model: MacroModel, label: str = "3,0c") -> float:
    """Eigenfrequency of a mode from the model (Hz)."""
    return next(
        c.frequency_hz for c in model.coordinates if c.label == label or c.name.endswith(label.replace(",", "_"))
    )


def notch_near(summary: dict, channel: str, f0: float, tol: float = 0.05) -> dict | None:
    """The deepest notch within tol of f0 (or None)."""
    hits = [n for n in summary["channels"][channel]["notches"] if abs(n["freq_hz"] / f0 - 1) < tol]
    return max(hits, key=lambda n: n["depth_db"]) if hits else None


def spectrum_at(folder: Path, channel: str, f0: float, span: float = 0.05) -> dict:
    """PSD (dB) at the bin nearest f0 against the median over +-span*f0 around it (from spectra.npz)."""
    z = np.load(folder / "spectra.npz")
    f, p = z[f"{channel}_f"], z[f"{channel}_psd"]
    k = int(np.argmin(np.abs(f - f0)))
    df = f[1] - f[0]
    near = (np.abs(f - f0) < max(span * f0, 10 * df)) & (np.abs(f - f0) > df)
    lo = int(np.argmin(p[near.nonzero()[0]]))
    return {
        "freq_hz": float(f[k]),
        "psd_db": float(10 * np.log10(p[k])),
        "local_median_db": float(10 * np.log10(np.median(p[near]))),
        "min_in_window_hz": float(f[near][lo]),
        "min_in_window_db": float(10 * np.log10(p[near][lo])),
    }


def slope(folder: Path, channel: str, lo: float, hi: float) -> float:
    """Least-squares slope (dB/decade) of the PSD (dB) against log10 f over lo..hi (spectra.npz)."""
    z = np.load(folder / "spectra.npz")
    f, p = z[f"{channel}_f"], z[f"{channel}_psd"]
    sel = (f >= lo) & (f <= hi)
    return float(np.polyfit(np.log10(f[sel]), 10 * np.log10(p[sel]), 1)[0])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cycles", type=int, default=65536)
    p.add_argument("-o", "--output", default="out/sigma_delta")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--simulator", choices=("vacask", "ngspice", "ngspice-xspice"), default="vacask")
    p.add_argument("--runs", default=",".join(RUNS), help=f"comma-separated subset of {', '.join(RUNS)}")
    p.add_argument("--rerun", action="store_true", help="rerun even if DIR/<run>/summary.json exists")
    p.add_argument(
        "--vacask-options",
        default="",
        help='extra VACASK options, e.g. "tran_fbr=0.25" (netgen.testbench.sigma_delta.vacask.EXTRA_OPTIONS)',
    )
    a = p.parse_args()
    sdv.EXTRA_OPTIONS = a.vacask_options  # inherited by the forked workers
    out = Path(a.output)
    out.mkdir(parents=True, exist_ok=True)
    chosen = [r.strip() for r in a.runs.split(",") if r.strip()]
    unknown = sorted(set(chosen) - set(RUNS))
    if unknown:
        p.error(f"unknown runs {unknown}; choose from {list(RUNS)}")
    if "rigid" in chosen:  # build once, before the pool forks
        sd.model_for(STRUCTURE, out / "model_rigid", sd.BuildOptions(rigid_only=True), progress=False)
    with ProcessPoolExecutor(a.jobs) as pool:
        futures = {
            k: pool.submit(one, k, *RUNS[k][:1], a.cycles, out, RUNS[k][1], RUNS[k][2], a.simulator, a.rerun)
            for k in chosen
        }
        s = {k: f.result() for k, f in futures.items()}
    model = MacroModel.load_json(ROOT / "netlists" / "levitated_disk.json")
    f30 = mode_frequency(model)
    report: dict = {"f_30_hz": f30, "simulator": a.simulator, "cycles": a.cycles, "vacask_options": a.vacask_options}
    for k, v in s.items():
        ts = RUNS[k][0]
        fs = 1 / ts
        alias = abs(f30 - fs * round(f30 / fs))  # where the (3,0) mode lands in [0, fs/2]
        report[k] = {
            "wall_s": v["wall_s"],
            "ms_per_cycle": 1e3 * v["wall_s"] / a.cycles,
            "gravity_ratio": v["gravity_balance"]["ratio"],
            "f_30_in_spectrum_hz": alias,
        }
        for c in sd.CHANNELS:
            ch = v["channels"][c]
            report[k][c] = {
                "notch_30": notch_near(v, c, alias),
                "at_30": spectrum_at(out / k, c, alias),
                "floor_db_per_hz": ch["noise_floor_db_per_hz"],
                "inband_noise_db": ch["inband_noise_db"],
                "slope_db_per_decade": ch.get("slope_db_per_decade"),
                "slope_fs640_fs64_db_per_decade": slope(out / k, c, fs / 640, fs / 64),
                "bit_mean": ch["bit_mean"],
                "peaks": ch["peaks"][:3],
            }
        report[k]["coordinates"] = v["coordinates"]
    if {"ts1", "ts3.2"} <= s.keys():
        report["floor_rise_db"] = {
            c: s["ts3.2"]["channels"][c]["noise_floor_db_per_hz"] - s["ts1"]["channels"][c]["noise_floor_db_per_hz"]
            for c in sd.CHANNELS
        }
        report["inband_noise_rise_db"] = {
            c: s["ts3.2"]["channels"][c]["inband_noise_db"] - s["ts1"]["channels"][c]["inband_noise_db"]
            for c in sd.CHANNELS
        }
    if "tone" in s:
        tz = s["tone"]["channels"]
        report["tone_cross_db"] = {c: tz[c]["tone_level_db"] - tz["z"]["tone_level_db"] for c in ("tilt_x", "tilt_y")}
        report["tone_snr_z_db"] = tz["z"].get("snr_db")
    (out / "paper_report.json").write_text(json.dumps(report, indent=1) + "\n")
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
