"""PNGs of a sigma-delta run: the three normalised spectra, the coordinates per clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...plots import plt, save
from .loop import CHANNELS


def plot_spectra(summary: dict, path: Path, title: str) -> Path:
    """PNG of the three normalised spectra (dB re F_fb^2/Hz against log frequency)."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for ax, c in zip(axes, CHANNELS):
        f, p = summary["spectra"][c]
        ax.semilogx(f[1:], 10 * np.log10(p[1:]), lw=0.7)
        ax.axvline(summary["fs_hz"] / 2 / summary["osr"], color="k", ls=":", lw=0.7)
        ax.set_ylabel(f"{c}: dB re F_fb^2/Hz")
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_title(title)
    axes[-1].set_xlabel("frequency (Hz)")
    fig.tight_layout()
    return save(fig, path, dpi=110)


def plot_states(clock: dict, path: Path) -> Path:
    """PNG of the coordinates per clock (port units) over the run."""
    keys = [k for k in clock if k.startswith("x_")]
    fig, axes = plt.subplots(len(keys), 1, figsize=(8, 1.4 * len(keys) + 1), sharex=True)
    for ax, k in zip(np.atleast_1d(axes), keys):
        ax.plot(clock["time"] * 1e3, clock[k], lw=0.5)
        ax.set_ylabel(k, fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("time (ms)")
    fig.tight_layout()
    return save(fig, path, dpi=100)
