"""Figures of a sigma-delta bitstream, on scipy.signal: the Welch spectrum (the +-1 bits, i.e.
the fed-back force over its level), the in-band quantization-noise floor and noise power,
SQNR/SNR of an input tone, the noise-shaping slope over the decade below the band edge, and the
dynamic-range curve (SNR against the input amplitude, with the maximum stable amplitude).
Used by the loop-order bench (bench/sigma_delta_orders.py) for circuit and numpy runs alike.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import signal

TONE_BINS = 3          # a Hann window's main lobe: +-3 bins hold the tone's power
# the first bin above DC lies in the Hann main lobe of the bitstream's mean (a DC input such as
# gravity makes it large: in a fourth-order loop at a mean bit of 0.5 that one bin held -83.6 dB
# against -95 dB for the rest of the band), so the noise starts at bin 2
DC_BINS = 2


def spectrum(v: np.ndarray, ts: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch PSD (Hann, 50 % overlap, mean removed) of a +-1 bitstream, 1/Hz."""
    n = nperseg or min(len(v), max(256, len(v) // 8))
    return signal.welch(np.asarray(v, dtype=float), fs=1.0 / ts, window="hann", nperseg=n, detrend="constant")


def band(f: np.ndarray, p: np.ndarray, fb: float, tone_hz: float | None = None) -> dict:
    """In band [DC_BINS df, fb]: the noise floor (median PSD, dB/Hz), the noise power (dB, tone bins
    excluded), the tone power (dB re the +-1 full scale squared: a sine of amplitude A gives
    A^2/2) and SQNR = tone - noise; slope (dB/decade) of the noise over [fb/10, fb]."""
    df = f[1] - f[0]
    inb = (f >= DC_BINS * df) & (f <= fb)
    if inb.sum() < 4:
        raise ValueError(f"the band 0..{fb:g} Hz holds {int(inb.sum())} PSD bins: run more periods")
    near = inb & (np.abs(f - tone_hz) <= TONE_BINS * df) if tone_hz else np.zeros_like(inb)
    noise = inb & ~near
    out = {"band_hz": float(fb), "bins": int(noise.sum()),
           "floor_db_per_hz": float(10 * np.log10(np.median(p[noise]))),
           "noise_db": float(10 * np.log10(np.sum(p[noise]) * df)),
           "slope_db_per_decade": slope(f, p, fb, noise)}
    if tone_hz:
        out["tone_db"] = float(10 * np.log10(np.sum(p[near]) * df + 1e-300))
        out["sqnr_db"] = out["tone_db"] - out["noise_db"]
    return out


def slope(f: np.ndarray, p: np.ndarray, fb: float, keep: np.ndarray | None = None) -> float:
    """Noise-shaping slope: the least-squares line of 10 log10 PSD against log10 f over the
    decade below the band edge (tone bins excluded through `keep`), dB/decade."""
    sel = (f >= fb / 10) & (f <= fb) & (keep if keep is not None else True)
    if sel.sum() < 4:
        raise ValueError(f"the decade below {fb:g} Hz holds {int(sel.sum())} PSD bins: run more periods")
    return float(np.polyfit(np.log10(f[sel]), 10 * np.log10(p[sel]), 1)[0])


def tone_frequency(ts: float, nperseg: int, osr: float, fraction: float = 0.25) -> float:
    """A test-tone frequency at the centre of a PSD bin near `fraction` of the band edge."""
    df = 1.0 / (ts * nperseg)
    return df * max(3, round(fraction * 0.5 / (ts * osr) / df))


def dynamic_range(run: Callable[[float], tuple[np.ndarray, bool]], amplitudes: np.ndarray, ts: float,
                  fb: float, tone_hz: float, nperseg: int | None = None, skip: int = 0) -> dict:
    """SNR against input amplitude (fractions of full scale): `run(a)` gives the bitstream and
    whether the loop held; the maximum stable amplitude is the largest held amplitude below the
    first that was lost; the dynamic range is the amplitude span from SNR = 0 dB (extrapolated on
    the 1 dB/dB line from the smallest amplitude) to the peak SNR."""
    rows, max_stable, lost = [], None, False
    for a in np.asarray(amplitudes, dtype=float):
        v, held = run(float(a))
        m = band(*spectrum(v[skip:], ts, nperseg), fb, tone_hz) if held else {}     # a lost loop has no SNR
        rows.append({"amplitude": float(a), "amplitude_dbfs": float(20 * np.log10(a)), "held": held,
                     "sqnr_db": m.get("sqnr_db"), "noise_db": m.get("noise_db")})
        lost = lost or not held
        if held and not lost:
            max_stable = float(a)
    held = [r for r in rows if r["held"]]
    if not held:
        return {"rows": rows, "max_stable_amplitude": None, "peak_sqnr_db": None, "dynamic_range_db": None}
    best = max(held, key=lambda r: r["sqnr_db"])
    low = min(held, key=lambda r: r["amplitude"])
    zero_db = low["amplitude_dbfs"] - low["sqnr_db"]          # input level of SNR = 0 dB
    return {"rows": rows, "max_stable_amplitude": max_stable, "peak_sqnr_db": best["sqnr_db"],
            "dynamic_range_db": float(best["amplitude_dbfs"] - zero_db)}
