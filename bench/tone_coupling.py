"""How far below z does a tone applied on z appear in the tilt bitstreams? Reads a `netgen
sigma-delta ... --tone z:A:F` output folder and measures each channel's line at F with a finer
Welch resolution than summary.json's (which takes 1/8 of the run per segment: at 8192 periods
its +-3-bin tone window spans +-3.3 kHz of tilt noise and bounds the coupling from above):

    .venv/bin/python bench/tone_coupling.py DIR [--nperseg 4096]

prints per channel the power in the 3 bins around F (dB re F_fb^2) and its difference to z.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from netgen.testbench.sigma_delta import CHANNELS, psd


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path)
    p.add_argument("--nperseg", type=int, default=4096)
    args = p.parse_args()
    s = json.loads((args.folder / "summary.json").read_text())
    bits = np.load(args.folder / "bitstreams.npz")
    f0 = s["tone"]["freq"]
    level = {}
    for c in CHANNELS:
        f, pw = psd(bits[f"bits_{c}"][s["skip"] :], s["ts"], args.nperseg)
        k = int(np.argmin(np.abs(f - f0)))
        level[c] = 10 * np.log10(np.sum(pw[k - 1 : k + 2]) * (f[1] - f[0]))
    print(
        f"{args.folder}: {s['cycles']} periods, tone {f0:g} Hz, Welch segments of {args.nperseg} ({f[1] - f[0]:.0f} Hz bins)"
    )
    for c in CHANNELS:
        print(f"{c:8s} line {level[c]:7.1f} dB   {level[c] - level['z']:+6.1f} dB re z")


if __name__ == "__main__":
    main()
