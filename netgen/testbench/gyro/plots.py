"""The gyroscope run's figures: the sense bitstream's spectrum around the drive frequency and the
rate sweep's reading against the applied rate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

from ...core.plots import plt, save
from .analysis import DEG


def spectrum(bits: np.ndarray, ts: float, drive_hz: float, path: Path, name: str) -> None:
    """Welch PSD of the sense bitstream (1/Hz of the fed-back force squared), the drive marked."""
    f, p = signal.welch(bits.astype(float), fs=1.0 / ts, window="hann", nperseg=min(len(bits), 1024))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.loglog(f[1:], p[1:])
    ax.axvline(drive_hz, color="k", ls=":", label=f"drive {drive_hz / 1e3:.3f} kHz")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("bitstream PSD (1/Hz)")
    ax.set_title(f"{name}: sense bitstream")
    ax.legend()
    fig.tight_layout()
    save(fig, path)


def sweep(rates: list[float], readings: list[float], path: Path, name: str) -> None:
    """Reading against applied rate (deg/s), with the deviation from the line."""
    r, y = np.asarray(rates) / DEG, np.asarray(readings) / DEG
    slope, off = np.polyfit(r, y, 1)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    a1.plot(r, y, "o-")
    a1.set_ylabel("rate read (deg/s)")
    a1.set_title(f"{name}: rate sweep")
    a2.plot(r, y - (slope * r + off), "o-")
    a2.set_ylabel("deviation from the line (deg/s)")
    a2.set_xlabel("rate applied (deg/s)")
    fig.tight_layout()
    save(fig, path)
