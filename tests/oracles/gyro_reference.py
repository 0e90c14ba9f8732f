"""An independent discrete-time simulation of the gyroscope's sense loop in numpy: the sense mode y
a second-order resonator (filters.Mechanics of the sigma-delta design's channel y) integrated
exactly between sampling instants by the state-transition matrix (scipy.linalg.expm, via
filters.step_map) of the state augmented with the input acceleration, the loop filter and the
1-bit quantiser with the bench's dither as the sigma-delta design made them (filters.Filter), and
the drive an ideal sinusoid x = X cos(w t): on y the Coriolis acceleration -2 Omega x' and the
quadrature acceleration -k_xy x / m. No circuit simulator, no electrostatic nonlinearity, no drive
loop: the yardstick for `netgen gyro`'s noise floor. The in-band noise estimator both are read
with (inband_density) is here too, with its degrees of freedom.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg, signal

from netgen.testbench.sigma_delta.filters import Filter, Mechanics, step_map

# the power correlation of a Hann periodogram's neighbouring bins (|sum w_k w_k+j| / sum w_k^2)^2 of
# the window's frequency kernel (-1/4, 1/2, -1/4): 4/9 at one bin, 1/36 at two
HANN_CORRELATION = (4 / 9, 1 / 36)
FIR_TAPS = 301  # 0.3 ms of the record


def augmented(mech: Mechanics, dc: float, sin_amp: float, cos_amp: float, w: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the state (y, y', 1, sin wt, cos wt) under the acceleration dc + sin_amp sin wt +
    cos_amp cos wt; B the feedback force per unit bit."""
    a2, b2 = mech.continuous()
    a = np.zeros((5, 5))
    a[:2, :2] = a2
    a[1, 2], a[1, 3], a[1, 4] = dc, sin_amp, cos_amp
    a[3, 4], a[4, 3] = w, -w
    return a, np.concatenate([b2 * mech.force, np.zeros(3)])


def simulate(
    mech: Mechanics,
    f: Filter,
    cycles: int,
    drive_w: float,
    drive_amplitude: float,
    rate: float = 0.0,
    k_xy: float = 0.0,
    dc: float = 0.0,
    dither: float = 0.0,
    dither_step: float = 0.0,
    phase: float = 0.0,
) -> dict[str, np.ndarray]:
    """The sense loop for `cycles` periods from rest, the drive x = X cos(w t + phase) from t = 0: per
    period n the sample x[n] = gain y + offset, the comparator input c.u + d (x - x0) + dither
    sin(dither_step n), the bit, the filter update and the force pulse. Returns the bits v (+-1),
    the sample times t (s) and the drive x at those instants (m)."""
    a, b = augmented(mech, dc, 2 * rate * drive_amplitude * drive_w, -k_xy * drive_amplitude / mech.mass, drive_w)
    phi, gamma = step_map(a, b, mech.ts, mech.sample, mech.pulse)
    s = linalg.expm(a * mech.sample * mech.ts) @ np.array([0.0, 0.0, 1.0, math.sin(phase), math.cos(phase)])
    u = np.zeros(f.states)
    dith = dither * np.sin(dither_step * np.arange(cycles))
    v = np.empty(cycles, dtype=np.int8)
    for n in range(cycles):
        x = mech.gain * s[0] + mech.offset
        bit = 1 if float(f.c @ u) + f.d * (x - f.x0) + dith[n] > 0 else -1
        v[n] = bit
        u = f.a @ u + f.bx * (x - f.x0) + f.bv * bit
        s = phi @ s + gamma * bit
    t = (np.arange(cycles) + mech.sample) * mech.ts
    return {"v": v, "t": t, "x": drive_amplitude * np.cos(drive_w * t + phase)}


def inband_density(t: np.ndarray, bits: np.ndarray, ts: float, drive_w: float, band_hz: float) -> tuple[float, float]:
    """(S, nu): the bitstream's one-sided PSD (1/Hz) near the drive frequency, read as
    analysis.rate_noise reads it after demodulation: the bits times 2 sin(w t) (their fitted drive
    tones taken out first), low-passed by a Kaiser FIR (80 dB stopband from about band_hz + 16 kHz:
    the shaped quantisation noise far from the drive would otherwise leak into a short record's
    bins), a Hann periodogram of that over the FIR's |H|^2, its bins from 1 to band_hz averaged and
    halved (2 S at baseband);
    and the average's equivalent chi-square degrees of freedom: K bins of 2 each less their Hann
    correlation, nu = 2 K / (1 + 2 sum_j rho_j)."""
    ref = np.column_stack([np.cos(drive_w * t), np.sin(drive_w * t), np.ones_like(t)])
    x = bits.astype(float)
    rest = x - ref @ np.linalg.lstsq(ref, x, rcond=None)[0]
    taps = signal.firwin(FIR_TAPS, band_hz + 8e3, window=("kaiser", 8.0), fs=1.0 / ts)
    base = np.convolve(rest * 2 * np.sin(drive_w * t), taps, mode="valid")
    f, p = signal.periodogram(base, fs=1.0 / ts, window="hann")
    near = (f > 0) & (f <= band_hz)
    gain = np.abs(signal.freqz(taps, worN=f[near], fs=1.0 / ts)[1]) ** 2
    k = int(np.count_nonzero(near))
    return float(np.mean(p[near] / gain)) / 2, 2 * k / (1 + 2 * sum(HANN_CORRELATION))
