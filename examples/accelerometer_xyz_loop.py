"""The three-axis accelerometer in force feedback on x, y and z: per channel the in-band noise floor
and the noise-shaping slope (tone bins excluded), the level of the run's tone (--tone) in every
channel, and the cross-axis correlation of the bitstreams (raw, and in band), from the folder of
a `netgen sigma-delta` run.

    netgen sigma-delta examples/accelerometer_xyz.toml -o OUT --cycles 16384 --simulator ngspice-xspice \
        --tone a_x:25.55:1953.125
    python examples/accelerometer_xyz_loop.py OUT
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np

from netgen.testbench.sigma_delta.analysis import DC_BINS, band_metrics, psd

NPERSEG = 4096  # Welch segment: 244 Hz bins at T_s = 1 us, 29 in the decade below the band edge


def in_band(bits: np.ndarray, ts: float, fb: float) -> np.ndarray:
    """The bitstream low-passed to the band edge (FFT mask), mean removed."""
    spec = np.fft.rfft(bits - bits.mean())
    spec[np.fft.rfftfreq(len(bits), ts) > fb] = 0.0
    return np.fft.irfft(spec, len(bits))


def analyse(folder: Path) -> dict:
    """Floor, slope, bit mean per channel and the pairwise bit correlations of a run folder."""
    summary = json.loads((folder / "summary.json").read_text())
    data = np.load(folder / "bitstreams.npz")
    ts, osr, skip = summary["ts"], summary["osr"], summary["skip"]
    fb = 0.5 / (ts * osr)
    names = list(summary["channels"])
    bits = {n: np.asarray(data[f"bits_{n}"], float)[skip:] for n in names}
    out = {
        "simulator": summary["simulator"],
        "cycles": summary["cycles"],
        "held": summary["levitation"]["held"],
        "gravity_balance": summary["gravity_balance"]["ratio"],
        "channels": {},
        "correlation": {},
    }
    tone = summary["tone"]["freq"] if summary.get("tone") else None
    for n in names:
        f, p = psd(bits[n], ts, min(len(bits[n]), NPERSEG))
        b = band_metrics(f, p, ts, osr, tone, DC_BINS)
        out["channels"][n] = {
            "bit_mean": float(bits[n].mean()),
            "floor_db_per_hz": b["noise_floor_db_per_hz"],
            "inband_noise_db": b["inband_noise_db"],
            "slope_db_per_decade": b.get("slope_db_per_decade"),
            "tone_db": b.get("tone_level_db"),
            "peak_um": max(abs(summary["coordinates"][n]["min"]), abs(summary["coordinates"][n]["max"])),
        }
    for a, b in itertools.combinations(names, 2):
        raw = float(np.corrcoef(bits[a], bits[b])[0, 1])
        band = float(np.corrcoef(in_band(bits[a], ts, fb), in_band(bits[b], ts, fb))[0, 1])
        out["correlation"][f"{a}-{b}"] = {"bits": raw, "in_band": band}
    return out


def main() -> None:
    """Print the figures of a run folder as JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="output folder of netgen sigma-delta")
    print(json.dumps(analyse(ap.parse_args().folder), indent=1))


if __name__ == "__main__":
    main()
