"""What the electrode-electrode couplings do to the sigma-delta loop: two `netgen sigma-delta ...
--tone z:A:F` runs of the same model, without and with couplings (docs/calibration.md), side by
side. Per channel: bit mean, in-band floor, the tone's line and its crosstalk into the other
channels (Welch, as bench/tone_coupling.py), the readout gain (the z line's level, i.e. force to
bitstream), and how many bits differ; a PNG with both runs' spectra per channel:

    .venv/bin/python bench/couplings_sigma_delta.py PLAIN_DIR COUPLED_DIR [--png out.png] [--nperseg 1024]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from netgen.core.plots import plt, save
from netgen.testbench.sigma_delta import CHANNELS, psd


def measure(folder: Path, nperseg: int) -> dict:
    """Per channel of one run: bit mean, floor (summary.json), tone line in dB re F_fb^2, spectrum."""
    s = json.loads((folder / "summary.json").read_text())
    bits = np.load(folder / "bitstreams.npz")
    f0 = s["tone"]["freq"]
    out = {"summary": s, "bits": {c: bits[f"bits_{c}"] for c in CHANNELS}, "channels": {}}
    for c in CHANNELS:
        f, pw = psd(bits[f"bits_{c}"][s["skip"] :], s["ts"], nperseg)
        k = int(np.argmin(np.abs(f - f0)))
        line = 10 * np.log10(np.sum(pw[k - 1 : k + 2]) * (f[1] - f[0]))
        out["channels"][c] = {
            "bit_mean": s["channels"][c]["bit_mean"],
            "floor": s["channels"][c]["noise_floor_db_per_hz"],
            "line_db": float(line),
            "f": f,
            "psd": pw,
        }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("plain", type=Path)
    p.add_argument("coupled", type=Path)
    p.add_argument("--png", type=Path)
    p.add_argument("--nperseg", type=int, default=1024)
    args = p.parse_args()
    runs = {"without": measure(args.plain, args.nperseg), "with": measure(args.coupled, args.nperseg)}
    s = runs["without"]["summary"]
    print(
        f"{s['cycles']} periods, T_s {s['ts']:g} s, tone {s['tone']['freq']:g} Hz on z, Welch segments of {args.nperseg}"
    )
    print(
        f"{'channel':8s} {'couplings':9s} {'bit mean':>9s} {'floor dB/Hz':>12s} {'tone line dB':>13s} {'re z dB':>8s}"
    )
    for c in CHANNELS:
        for label, r in runs.items():
            ch, z = r["channels"][c], r["channels"]["z"]
            floor = "n/a" if ch["floor"] is None else f"{ch['floor']:.1f}"
            print(
                f"{c:8s} {label:9s} {ch['bit_mean']:+9.4f} {floor:>12s} {ch['line_db']:13.2f} {ch['line_db'] - z['line_db']:+8.1f}"
            )
        diff = int(np.sum(runs["without"]["bits"][c] != runs["with"]["bits"][c]))
        print(
            f"{c:8s} differing bits: {diff} of {len(runs['without']['bits'][c])}; line change "
            f"{runs['with']['channels'][c]['line_db'] - runs['without']['channels'][c]['line_db']:+.2f} dB"
        )
    if args.png:
        fig, axes = plt.subplots(1, len(CHANNELS), figsize=(4.2 * len(CHANNELS), 3.4), sharey=True)
        for ax, c in zip(axes, CHANNELS):
            for label, r in runs.items():
                ch = r["channels"][c]
                ax.loglog(ch["f"][1:], ch["psd"][1:], lw=0.8, label=f"{label} couplings")
            ax.set_title(c)
            ax.set_xlabel("Hz")
        axes[0].set_ylabel("bitstream PSD (1/Hz)")
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        save(fig, args.png)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
