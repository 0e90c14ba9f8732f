"""The loop-order bench's figures beyond analysis.band_metrics (the spectra and in-band figures
are analysis.psd and band_metrics with the band from DC_BINS): the test-tone frequency and the
dynamic-range curve (SNR against the input amplitude, with the maximum stable amplitude).
Used by the loop-order bench (bench/sigma_delta_orders.py) for circuit and numpy runs alike.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .analysis import band_metrics, psd

# the first bin above DC lies in the Hann main lobe of the bitstream's mean (a DC input such as
# gravity makes it large: in a fourth-order loop at a mean bit of 0.5 that one bin held -83.6 dB
# against -95 dB for the rest of the band), so the bench's noise starts at bin 2
DC_BINS = 2


def tone_frequency(ts: float, nperseg: int, osr: float, fraction: float = 0.25) -> float:
    """A test-tone frequency at the centre of a PSD bin near `fraction` of the band edge."""
    df = 1.0 / (ts * nperseg)
    return df * max(3, round(fraction * 0.5 / (ts * osr) / df))


def dynamic_range(
    run: Callable[[float], tuple[np.ndarray, bool]],
    amplitudes: np.ndarray,
    ts: float,
    osr: float,
    tone_hz: float,
    nperseg: int | None = None,
    skip: int = 0,
) -> dict:
    """SNR against input amplitude (fractions of full scale): `run(a)` gives the bitstream and
    whether the loop held; the maximum stable amplitude is the largest held amplitude below the
    first that was lost; the dynamic range is the amplitude span from SNR = 0 dB (extrapolated on
    the 1 dB/dB line from the smallest amplitude) to the peak SNR."""
    rows, max_stable, lost = [], None, False
    for a in np.asarray(amplitudes, dtype=float):
        v, held = run(float(a))
        m = band_metrics(*psd(v[skip:], ts, nperseg), ts, osr, tone_hz, DC_BINS) if held else {}  # lost: no SNR
        rows.append(
            {
                "amplitude": float(a),
                "amplitude_dbfs": float(20 * np.log10(a)),
                "held": held,
                "sqnr_db": m.get("snr_db"),
                "noise_db": m.get("inband_noise_db"),
            }
        )
        lost = lost or not held
        if held and not lost:
            max_stable = float(a)
    held = [r for r in rows if r["held"]]
    if not held:
        return {"rows": rows, "max_stable_amplitude": None, "peak_sqnr_db": None, "dynamic_range_db": None}
    best = max(held, key=lambda r: r["sqnr_db"])
    low = min(held, key=lambda r: r["amplitude"])
    zero_db = low["amplitude_dbfs"] - low["sqnr_db"]  # input level of SNR = 0 dB
    return {
        "rows": rows,
        "max_stable_amplitude": max_stable,
        "peak_sqnr_db": best["sqnr_db"],
        "dynamic_range_db": float(best["amplitude_dbfs"] - zero_db),
    }
