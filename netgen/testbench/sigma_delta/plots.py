"""PNGs of a sigma-delta run: the normalised spectra (one panel per channel), the coordinates per clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.plots import plt, save


def plot_spectra(summary: dict, path: Path, title: str) -> Path:
    """PNG of the channels' normalised spectra (dB re F_fb^2/Hz against log frequency)."""
    names = list(summary["channels"])
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 3 * len(names)), sharex=True, squeeze=False)
    axes = axes[:, 0]
    for ax, c in zip(axes, names):
        f, p = summary["spectra"][c]
        ax.semilogx(f[1:], 10 * np.log10(p[1:]), lw=0.7)
        ax.axvline(summary["fs_hz"] / 2 / summary["osr"], color="k", ls=":", lw=0.7)
        annotate(ax, summary["channels"][c])
        ax.set_ylabel(f"{c}: dB re F_fb^2/Hz")
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_title(title)
    axes[-1].set_xlabel("frequency (Hz)")
    fig.tight_layout()
    return save(fig, path, dpi=110)


def annotate(ax, ch: dict) -> None:
    """The channel's figures on its spectrum: in-band floor, shaping-slope fit, SNR of the tone."""
    band = ch.get("band_hz") or [None, None]
    text = []
    if ch.get("noise_floor_db_per_hz") is not None and band[0]:
        ax.hlines(ch["noise_floor_db_per_hz"], band[0], band[1], color="C1", lw=1.2)
        text.append(f"floor {ch['noise_floor_db_per_hz']:.1f} dB/Hz")
    fit = ch.get("slope_fit")
    if fit:
        fr = np.array(fit["band_hz"])
        ax.plot(fr, fit["db_at_1hz"] + ch["slope_db_per_decade"] * np.log10(fr), color="C3", lw=1.2)
        text.append(f"slope {ch['slope_db_per_decade']:.1f} dB/dec")
    if ch.get("snr_db") is not None:
        text.append(f"SNR {ch['snr_db']:.1f} dB")
    text.append(f"bit mean {ch['bit_mean']:+.4f}")
    ax.text(0.01, 0.95, ", ".join(text), transform=ax.transAxes, va="top", fontsize=8)


def plot_linearity(
    inputs: np.ndarray, bit_means: np.ndarray, fit: dict, path: Path, title: str, unit: str = "m/s^2"
) -> Path:
    """PNG of the bitstream mean against the applied DC input, with the scale-factor line and the
    residuals in % of full scale (analysis.scale_factor)."""
    x = np.asarray(inputs, float)
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    a.plot(x, bit_means, "o", ms=4)
    a.plot(x, fit["scale_factor"] * x + fit["offset"], "k-", lw=0.7)
    a.set_ylabel("bitstream mean")
    a.set_title(title)
    b.plot(x, np.array(fit["residuals"]) / abs(fit["scale_factor"]) / fit["full_scale_input"] * 100, "o-", ms=3)
    b.set_ylabel("residual (% FS)")
    b.set_xlabel(f"input ({unit})")
    for ax in (a, b):
        ax.grid(True, lw=0.3)
    fig.tight_layout()
    return save(fig, path, dpi=100)


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
