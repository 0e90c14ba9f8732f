"""An independent discrete-time simulation of the gyroscope's sense loop in numpy: the sense mode y
a second-order resonator (filters.Mechanics of the sigma-delta design's channel y) integrated
exactly between sampling instants by the state-transition matrix (scipy.linalg.expm, via
filters.step_map) of the state augmented with the input acceleration, the loop filter and the
1-bit quantiser with the bench's dither as the sigma-delta design made them (filters.Filter), and
the drive an ideal sinusoid x = X cos(w t): on y the Coriolis acceleration -2 Omega x' and the
quadrature acceleration -k_xy x / m, and optionally the sense damping's thermal force (white,
Gaussian, one value per period). No circuit simulator, no electrostatic nonlinearity, no drive
loop: the yardstick for `netgen gyro`'s noise floor. The noise estimators both are read with
(inband_density, band_density) are here too, with their degrees of freedom.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg, signal, stats

from netgen.testbench.sigma_delta import filters
from netgen.testbench.sigma_delta.filters import Filter, Mechanics, step_map

K_B = 1.380649e-23  # J/K
# examples/gyroscope_z.toml's quadrature coupling k_xy (N/m) and netgen gyro's default drive amplitude (m)
K_XY, X_D = 5e-3, 4e-6

# The Brownian variant of examples/gyroscope_z.toml (brownian_variant): the sense damped to Q_y = 10
# (b_y 200 times the vacuum's), the damping's thermal force on, and a fourth-order CIFB sense loop
# (H_inf 1.5). Why: at Q_y = 2000 and the lead2 loop the quantisation floor near the drive lies
# above the Brownian one; raising b_y raises the Brownian force sqrt(4 k_B T b_y) (+23 dB) while
# the force-feedback quantisation floor grows far less (lead2: +4 dB from Q_y 2000 to 20, as the
# sense resonance's notch at the drive flattens; it is the quantiser's noise, not the damper's),
# and the fourth-order loop's in-band noise shaping takes it 10-20 dB down: the reference loop puts it
# 13.5-14 dB under the Brownian floor over the drive +-4 kHz (17-19 dB over +-2 kHz), 2^16 periods.
BROWNIAN_EDITS = (
    ("q_factor = { x = 2000, y = 2000 }", "q_factor = { x = 2000, y = 10 }\nnoise = true"),
    ("[loop.channels.y]", '[loop.filter]\nkind = "cifb"\norder = 4\nh_inf = 1.5\n\n[loop.channels.y]'),
)
BROWNIAN_Q_Y = 10.0


def brownian_variant(example_text: str) -> str:
    """examples/gyroscope_z.toml's text with the BROWNIAN_EDITS (ValueError if a key moved)."""
    for old, new in BROWNIAN_EDITS:
        if old not in example_text:
            raise ValueError(f"examples/gyroscope_z.toml no longer has {old!r}: update BROWNIAN_EDITS")
        example_text = example_text.replace(old, new)
    return example_text


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
    force_noise: float = 0.0,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """The sense loop for `cycles` periods from rest, the drive x = X cos(w t + phase) from t = 0: per
    period n the sample x[n] = gain y + offset, the comparator input c.u + d (x - x0) + dither
    sin(dither_step n), the bit, the filter update and the force pulse. `force_noise`: the one-sided
    PSD (N^2/Hz) of a white force on y, one Gaussian value of variance force_noise / (2 T_s) held
    over each period (its PSD is force_noise sinc^2(f T_s): 1 - 6e-4 at 13 kHz and 1 MHz). Returns
    the bits v (+-1), the sample times t (s) and the drive x at those instants (m)."""
    a, b = augmented(mech, dc, 2 * rate * drive_amplitude * drive_w, -k_xy * drive_amplitude / mech.mass, drive_w)
    phi, gamma = step_map(a, b, mech.ts, mech.sample, mech.pulse)
    held = ((mech.sample, mech.sample + 1.0, 1.0),)  # a force constant from one sample to the next
    kick = step_map(a, np.concatenate([mech.continuous()[1], np.zeros(3)]), mech.ts, mech.sample, held)[1]
    forces = np.random.default_rng(seed).normal(0.0, math.sqrt(force_noise / (2 * mech.ts)), cycles)
    s = linalg.expm(a * mech.sample * mech.ts) @ np.array([0.0, 0.0, 1.0, math.sin(phase), math.cos(phase)])
    u = np.zeros(f.states)
    dith = dither * np.sin(dither_step * np.arange(cycles))
    v = np.empty(cycles, dtype=np.int8)
    for n in range(cycles):
        x = mech.gain * s[0] + mech.offset
        bit = 1 if float(f.c @ u) + f.d * (x - f.x0) + dith[n] > 0 else -1
        v[n] = bit
        u = f.a @ u + f.bx * (x - f.x0) + f.bv * bit
        s = phi @ s + gamma * bit + kick * forces[n]
    t = (np.arange(cycles) + mech.sample) * mech.ts
    return {"v": v, "t": t, "x": drive_amplitude * np.cos(drive_w * t + phase)}


def simulate_design(
    model,
    design,
    cycles: int,
    phase: float = 0.0,
    *,
    rate: float = 0.0,
    drive_amplitude: float = X_D,
    k_xy: float = K_XY,
    force_noise: float = 0.0,
    seed: int = 0,
) -> dict:
    """simulate() with every loop argument taken from the MacroModel and netgen gyro's sense-loop
    design (the channel y of netgen.testbench.gyro.run.sense_design): the mechanics, the filter,
    the DC acceleration, the dither, and the drive at the model's x resonance. Adds `drive_w`
    (rad/s), `per_rate` (the design's scale factor 2 m X w / F_fb, bits per rad/s) and
    `full_scale_force` (F_fb, N) to the result."""
    mech, ch = filters.mechanics_of(model, design, "y"), design.channels[0]
    cx = next(c for c in model.coordinates if c.name == "x")
    w = math.sqrt(cx.stiffness / cx.mass)
    r = simulate(
        mech,
        Filter.from_dict(ch["filter"]),
        cycles,
        w,
        drive_amplitude,
        rate=rate,
        k_xy=k_xy,
        dc=filters.dc_acceleration(model, design, "y"),
        dither=ch["dither_v"],
        dither_step=ch["dither_step"],
        phase=phase,
        force_noise=force_noise,
        seed=seed,
    )
    fb = ch["full_scale_force_si"]
    return r | {"drive_w": w, "per_rate": 2 * mech.mass * drive_amplitude * w / fb, "full_scale_force": fb}


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


def band_density(t: np.ndarray, bits: np.ndarray, ts: float, drive_w: float, band_hz: float) -> tuple[float, float]:
    """(S, nu): the bitstream's one-sided PSD (1/Hz) averaged over the drive frequency +-band_hz (its
    fitted drive tones taken out first; a Hann periodogram, no demodulation), and the average's
    equivalent chi-square degrees of freedom as in inband_density. Both sidebands count, and the
    quadrature phase as well as the rate phase: for noise that is flat over the band (the thermal
    force) this reads the level of the rate channel's 2 S with twice the degrees of freedom."""
    ref = np.column_stack([np.cos(drive_w * t), np.sin(drive_w * t), np.ones_like(t)])
    x = bits.astype(float)
    rest = x - ref @ np.linalg.lstsq(ref, x, rcond=None)[0]
    f, p = signal.periodogram(rest, fs=1.0 / ts, window="hann")
    near = np.abs(f - drive_w / (2 * math.pi)) <= band_hz
    k = int(np.count_nonzero(near))
    return float(np.mean(p[near])), 2 * k / (1 + 2 * sum(HANN_CORRELATION))


def segment_readings(run: dict, skip: int, length: int, read, ts: float, band_hz: float) -> list[float]:
    """`read` (inband_density or band_density) on each whole `length`-period piece of a reference run
    after its first `skip` periods: readings of the circuit's record length, so the spread among them
    is the spread of the circuit's one reading, whatever the noise's distribution."""
    n = (len(run["v"]) - skip) // length
    pieces = (slice(skip + i * length, skip + (i + 1) * length) for i in range(n))
    return [read(run["t"][k], run["v"][k], ts, run["drive_w"], band_hz)[0] for k in pieces]


def prediction_interval(runs: list[list[float]], quantile: float) -> tuple[float, float]:
    """(low, high): the two-sided `quantile` prediction interval of one more reading drawn like the
    readings of `runs` (each run's pieces, segment_readings), their logarithms taken as normal:
    exp(m +- t_{n_e - 1} s sqrt(1 + deff / n)), m and s the logs' mean and standard deviation over all
    n pieces. Pieces of one run are not quite independent (the loop's slow states span them), so the
    mean counts as n_e = n / deff pieces, deff = 1 + (k - 1) rho the design effect of k pieces per
    run with the intraclass correlation rho of a one-way analysis of variance (0 if negative). Why not
    chi-square: the loop's bits are not Gaussian noise and their band power fluctuates together
    across bins (the Brownian variant's readings over 7168 periods spread as chi2 with 29 degrees
    of freedom, not the 60 a Hann bin count gives: bench/gyroscope.py --dof)."""
    x = np.log(np.asarray(runs, dtype=float))  # (runs, pieces)
    g, k = x.shape
    n = g * k
    within = float(np.mean(np.var(x, axis=1, ddof=1)))
    between = float(np.var(np.mean(x, axis=1), ddof=1)) if g > 1 else 0.0
    rho = max(0.0, (between - within / k) / (between - within / k + within)) if within > 0 else 0.0
    deff = 1 + (k - 1) * rho
    s = float(np.std(x, ddof=1))
    half = stats.t.ppf(1 - quantile / 2, n / deff - 1) * s * math.sqrt(1 + deff / n)
    return math.exp(float(np.mean(x)) - half), math.exp(float(np.mean(x)) + half)
