"""Do the ngspice and VACASK sigma-delta runs give the same spectra? (targets: notch frequency
within 2 %, in-band noise floor within 2 dB). Reads two `netgen sigma-delta` output folders:

    .venv/bin/netgen sigma-delta examples/levitated_disk.toml --model netlists/levitated_disk.json \\
        --cycles 65536 -o out/ng                         # ngspice, about 50 min
    .venv/bin/netgen sigma-delta examples/levitated_disk.toml --model netlists/levitated_disk.json \\
        --cycles 65536 --simulator vacask -o out/va      # about 10 min
    .venv/bin/python bench/compare_simulators.py out/ng out/va

and prints, per channel, both in-band floors and their difference, the notch nearest the
model's (3,0) eigenfrequency in each, and the wall time per period of each run; then each run's
floor in the first and the second half of its record (same PSD bins): how far one run's floor
moves by itself, against which a difference between the simulators has to be read.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from support import ROOT

from netgen.model import MacroModel
from netgen.testbench import sigma_delta as sd


def notch_near(channel: dict, f0: float, tol: float = 0.05) -> dict | None:
    """The deepest detected notch within tol of f0, or None."""
    hits = [n for n in channel["notches"] if abs(n["freq_hz"] / f0 - 1) < tol]
    return max(hits, key=lambda n: n["depth_db"]) if hits else None


def half_floors(folder: Path, summary: dict, channel: str) -> tuple[float, float]:
    """In-band floor (median PSD, dB re F_fb^2/Hz, as summary.json's) of each half of the analysed
    record, with the whole record's Welch segment length so both use the same bins."""
    bits = np.load(folder / "bitstreams.npz")[f"bits_{channel}"][summary["skip"] :].astype(float)
    n = min(len(bits), max(256, len(bits) // 8))
    fb = 0.5 / summary["ts"] / summary["osr"]
    out = []
    for part in (bits[: len(bits) // 2], bits[len(bits) // 2 :]):
        f, p = sd.psd(part, summary["ts"], nperseg=min(n, len(part)))
        out.append(float(10 * np.log10(np.median(p[(f > 0) & (f <= fb)]))))
    return out[0], out[1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("first", type=Path, help="output folder of one run (e.g. ngspice)")
    p.add_argument("second", type=Path, help="output folder of the other run (e.g. VACASK)")
    p.add_argument("--model", type=Path, default=ROOT / "netlists" / "levitated_disk.json")
    args = p.parse_args()
    runs = [json.loads((d / "summary.json").read_text()) for d in (args.first, args.second)]
    model = MacroModel.load_json(args.model)
    f0 = next(c.frequency_hz for c in model.coordinates if c.name == "m3_0c")
    names = [r.get("simulator", "ngspice") for r in runs]
    print(
        f"runs: {names[0]} {runs[0]['cycles']} periods ({runs[0]['wall_s'] / runs[0]['cycles'] * 1e3:.1f} ms "
        f"each), {names[1]} {runs[1]['cycles']} periods ({runs[1]['wall_s'] / runs[1]['cycles'] * 1e3:.1f} ms "
        f"each); (3,0) mode {f0:.0f} Hz"
    )
    print(f"{'channel':<8} {'floor ' + names[0]:>16} {'floor ' + names[1]:>16} {'diff dB':>8}   notches near (3,0)")
    for c in ("z", "tilt_x", "tilt_y"):
        a, b = (r["channels"][c] for r in runs)
        fa, fb = a["noise_floor_db_per_hz"], b["noise_floor_db_per_hz"]
        na, nb = notch_near(a, f0), notch_near(b, f0)
        notch = (
            "none in either"
            if not (na or nb)
            else (
                f"{na['freq_hz']:.0f} Hz ({na['depth_db']:.1f} dB) / {nb['freq_hz']:.0f} Hz ({nb['depth_db']:.1f} dB), "
                f"{(na['freq_hz'] / nb['freq_hz'] - 1) * 100:+.2f} %"
                if na and nb
                else f"only in one: {na or nb}"
            )
        )
        print(f"{c:<8} {fa:16.1f} {fb:16.1f} {fa - fb:8.1f}   {notch}")
    print(f"{'channel':<8} {'halves ' + names[0]:>22} {'halves ' + names[1]:>22}")
    for c in ("z", "tilt_x", "tilt_y"):
        h = [half_floors(d, r, c) for d, r in zip((args.first, args.second), runs)]
        print(f"{c:<8} {h[0][0]:11.1f} {h[0][1]:10.1f} {h[1][0]:11.1f} {h[1][1]:10.1f}")


if __name__ == "__main__":
    main()
