"""From the gyroscope run's per-period samples to its figures: the drive's frequency, amplitude and
phase (a least-squares sinusoid on x), the sense bitstream demodulated with that phase into the
Coriolis (in phase with the drive velocity) and quadrature (in phase with the drive displacement)
force components, and their rates; the scale factor and linearity of a rate sweep; the rate noise
density from the bitstream's spectrum at the drive frequency; the bitstream's spectrum for the plot.

The balance behind it: the loop holds y near 0, so its mean feedback force cancels the Coriolis
force -2 m Omega x' and the quadrature force -k_xy x on y; with x = X cos(theta) the bits s = +-1
(force F_fb s) carry s ~ c0 + a cos(theta) + b sin(theta) with b F_fb = -2 m Omega X w and
a F_fb = k_xy X, so Omega = -b F_fb / (2 m X w) and the design's scale factor, b per rad/s, is
2 m X w / F_fb (of the opposite sign)."""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize, signal

DEG = math.pi / 180


def sinusoid(t: np.ndarray, x: np.ndarray) -> dict:
    """Frequency (rad/s), amplitude, phase and offset of the best sinusoid through x(t): the FFT
    peak, refined by least squares on the frequency (the linear coefficients solved at each)."""
    n = len(x)
    spectrum = np.abs(np.fft.rfft((x - np.mean(x)) * np.hanning(n)))
    dt = float(np.mean(np.diff(t)))
    w0 = 2 * math.pi * np.argmax(spectrum[1:]) / (n * dt) + 2 * math.pi / (n * dt)

    def residual(w: float) -> float:
        return float(np.sum((x - basis(t, w) @ coefficients(t, x, w)) ** 2))

    step = 2 * math.pi / (n * dt)
    w = optimize.minimize_scalar(residual, bounds=(w0 - 2 * step, w0 + 2 * step), method="bounded").x
    c, s, off = coefficients(t, x, w)
    return {
        "w": float(w),
        "amplitude": float(math.hypot(c, s)),
        "phase": float(math.atan2(-s, c)),
        "offset": float(off),
    }


def basis(t: np.ndarray, w: float) -> np.ndarray:
    return np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])


def coefficients(t: np.ndarray, y: np.ndarray, w: float) -> np.ndarray:
    return np.linalg.lstsq(basis(t, w), y, rcond=None)[0]


def demodulate(t: np.ndarray, bits: np.ndarray, x: np.ndarray, mass: float, full_scale_force: float) -> dict:
    """The rate and quadrature (rad/s, as rates: force / (2 m X w)) read from the bits against the
    drive x (m) sampled at the same instants t; a, b the bits' components along cos and sin of the
    drive phase theta (x = X cos theta)."""
    drive = sinusoid(t, x)
    w, amp = drive["w"], drive["amplitude"]
    theta = w * t + drive["phase"]
    ref = np.column_stack([np.cos(theta), np.sin(theta), np.ones_like(t)])
    a, b, c0 = np.linalg.lstsq(ref, bits.astype(float), rcond=None)[0]
    per_rate = 2 * mass * amp * w / full_scale_force  # bits' b per rad/s (design)
    return {
        "drive_hz": w / (2 * math.pi),
        "drive_amplitude_m": amp,
        "sin_component": float(b),
        "cos_component": float(a),
        "bit_mean": float(c0),
        "rate_rad_s": float(-b / per_rate),
        "quadrature_rad_s": float(a / per_rate),
        "quadrature_force_n": float(a * full_scale_force),
        "design_scale_factor_per_rad_s": float(per_rate),
    }


def rate_noise(t: np.ndarray, bits: np.ndarray, ts: float, drive_w: float, per_rate: float) -> dict:
    """The rate noise density (deg/s/rtHz): the one-sided PSD S (1/Hz, Welch) of the bitstream less
    its fitted drive-frequency components (the signal's tone, whose window lobe would otherwise
    dominate), averaged over +-10 % of the drive frequency; demodulated (times 2 sin theta and
    low-passed) it gives 2 S at low frequency in the sin component, so sqrt(2 S) / per_rate rad/s/rtHz.
    Also the standard deviation that noise puts on a rate read over the run, N / sqrt(2 T)."""
    rest = bits.astype(float) - basis(t, drive_w) @ coefficients(t, bits.astype(float), drive_w)
    f, p = signal.welch(rest, fs=1.0 / ts, window="hann", nperseg=min(len(bits), 1024))
    near = (f > 0.9 * drive_w / (2 * math.pi)) & (f < 1.1 * drive_w / (2 * math.pi))
    s = float(np.mean(p[near])) if near.any() else float("nan")
    density = math.sqrt(2 * s) / per_rate
    return {
        "rate_noise_deg_s_rthz": density / DEG,
        "bit_psd_at_drive_per_hz": s,
        "rate_read_sigma_rad_s": density / math.sqrt(2 * len(bits) * ts),
    }


def sweep_fit(rates: list[float], readings: list[float]) -> dict:
    """Scale factor (reading per applied rate, slope of the least-squares line), offset and the
    largest deviation from the line as a fraction of the sweep's full extent (the nonlinearity)."""
    r, y = np.asarray(rates), np.asarray(readings)
    slope, offset = np.polyfit(r, y, 1)
    dev = y - (slope * r + offset)
    span = float(np.max(np.abs(slope * r)))
    return {
        "slope": float(slope),
        "offset_rad_s": float(offset),
        "nonlinearity_of_full_scale": float(np.max(np.abs(dev)) / span) if span else float("nan"),
    }
