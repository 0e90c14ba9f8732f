"""An exact-kinematics Python model of the reference sigma-delta z loop, for the noise floor.

The rigid plate's z under gravity and the feedback force of each period (constant-acceleration
segments: sample at 0.28 T_s, feedback 0.50-0.94 T_s), the lead filter y = 0.8 prev - x, and a
comparator that is either an exact sign or the benches' tanh of width vcmp (in metres of z:
the bench's 1 V at the lead-filter output is 1/34.57 um of z) followed by the latch settling
(e^-5) and the bit() restore. It isolates what the loop itself does from the simulators:

    .venv/bin/python bench/sigma_delta_ideal_loop.py [--cycles 65536]

prints the median bitstream PSD (dB re F_fb^2/Hz) per band and the number of soft decisions
(|bit| not within 1e-3 of 1) for an exact sign and for comparator widths of 1 uV and 1 nV; then,
for an exact sign, the noise-shaping slope over f_s/640..f_s/64 (the summary's
slope_db_per_decade) at five operating points (gravity scaled so that the mean bit runs from
about 0.42 to 0.54) without and with the benches' comparator dither (a sine at f_s (1/2 - 0.0218),
amplitude Design.dither x a_fb T_s^2).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import signal

MASS, TS, F_ON, G = 1.6377e-8, 1e-6, 0.7415e-6, 9.81  # kg, s, N while feedback is on, m/s^2
SEGMENTS = [(0.22, 0.0), (0.44, 1.0), (0.34, 0.0)]  # (fraction of T_s, feedback on) from a sample
METRES_PER_VOLT = 1e-6 / 34.57  # z readout of the reference bench


def run(
    cycles: int,
    vcmp: float | None,
    lead: float = 0.8,
    settle: float = np.exp(-5),
    g_scale: float = 1.0,
    dither: float = 0.0,
) -> tuple[np.ndarray, int]:
    """Bits (+-1) of the loop and the count of soft decisions; vcmp None = exact sign. g_scale
    scales gravity (moves the operating point); dither is the comparator dither's amplitude as a
    fraction of a_fb T_s^2 (a sine at f_s (1/2 - 0.0218), as in the benches' z channel)."""
    x = v = prev = 0.0
    latch = 0.5
    bits, soft = np.empty(cycles), 0
    d = dither * F_ON / MASS * TS**2 * np.sin(2 * np.pi * (0.5 - 0.0218) * np.arange(cycles))
    for n in range(cycles):
        y = lead * prev - x + d[n]
        prev = x
        if vcmp is None:
            b = 1.0 if y > 0 else -1.0
        else:
            q = 0.5 + 0.5 * np.tanh(y / (vcmp * METRES_PER_VOLT))
            latch = q + (latch - q) * settle
            b = 2 * (0.5 + 0.5 * np.tanh(40 * (latch - 0.5))) - 1
        soft += abs(abs(b) - 1) > 1e-3
        bits[n] = 1.0 if b > 0 else -1.0
        for frac, on in SEGMENTS:
            dt = frac * TS
            a = on * F_ON * b / MASS - G * g_scale
            x, v = x + v * dt + 0.5 * a * dt * dt, v + a * dt
    return bits, soft


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cycles", type=int, default=65536)
    args = p.parse_args()
    bands = [(500, 2000), (2000, 8000), (8000, 16000), (16000, 64000)]
    print(f"{'comparator':<12}" + "".join(f"{f'{lo / 1e3:g}-{hi / 1e3:g} kHz':>14}" for lo, hi in bands) + "  soft")
    for name, vcmp in (("exact sign", None), ("tanh 1 uV", 1e-6), ("tanh 1 nV", 1e-9)):
        bits, soft = run(args.cycles, vcmp)
        f, psd = signal.welch(bits[args.cycles // 8 :], fs=1 / TS, nperseg=min(8192, args.cycles // 8))
        cols = [10 * np.log10(np.median(psd[(f > lo) & (f < hi)])) for lo, hi in bands]
        print(f"{name:<12}" + "".join(f"{c:14.1f}" for c in cols) + f"  {soft}")
    print("\nslope dB/decade over f_s/640..f_s/64 (mean bit in brackets), exact sign:")
    for dither in (0.0, 0.2):
        row = []
        for g_scale in (0.85, 0.9, 1.0, 1.015, 1.1):
            bits, _ = run(args.cycles, None, g_scale=g_scale, dither=dither)
            f, psd = signal.welch(bits[args.cycles // 8 :], fs=1 / TS, nperseg=min(8192, args.cycles // 8))
            sel = (f >= 1 / (640 * TS)) & (f <= 1 / (64 * TS))
            slope = np.polyfit(np.log10(f[sel]), 10 * np.log10(psd[sel]), 1)[0]
            row.append(f"{slope:5.1f} ({bits[args.cycles // 8 :].mean():+.2f})")
        print(f"dither {dither:<5}" + "  ".join(row))


if __name__ == "__main__":
    main()
